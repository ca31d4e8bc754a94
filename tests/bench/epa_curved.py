"""EPA alone on penetrating curved pairs, by tolerance (a developer's tool).

    python tests/bench/epa_curved.py [TOL]

150 random poses each of box-ellipsoid, ellipsoid-ellipsoid and cylinder-cylinder pairs of
1-2 cm shapes (shadow_hand's and humanoid100's kinds), the second's centre 5-20 mm from the
first's, random rotations (seed 1); GJK's final simplex is taken once per pair, then
`collide._kernels.epa.epa` is timed over 50 calls (min of 3) on borrowed arrays (as the narrow
phase passes them) at the absolute tolerance TOL (default 1e-11, the contacts' 1e-9 of the
sizes' sum at this scale; MuJoCo's ``ccd_tolerance`` is 1e-6, its ``ccd_iterations`` 35).
Printed per kind: mean time per call, mean iterations, time per iteration.
"""
import sys
import time

import numpy as np

from epa_ab import CASES, _runner, poses  # the same cases and timed loop, on the installed package

TOL = float(sys.argv[1]) if len(sys.argv) > 1 else 1e-11
E32 = np.zeros(1, np.int32)
run = _runner("collide")
print(f"# EPA on penetrating curved pairs, tolerance {TOL:g} (python tests/bench/epa_curved.py {TOL:g})")
for name, (A, B) in CASES.items():
    rng = np.random.default_rng(1)
    total = iters = n = 0
    for _ in range(150):
        ra, rb, pb = poses(rng)
        res = np.empty(13)
        args = (A[0], A[1], A[2], ra, np.zeros(3), B[0], B[1], B[2], rb, pb, TOL)
        it = run(*args, 1, res, E32)
        if it < 0:
            continue
        best = np.inf
        for _ in range(3):
            t0 = time.perf_counter()
            run(*args, 50, res, E32)
            best = min(best, time.perf_counter() - t0)
        total += best / 50
        iters += it
        n += 1
    print(f"{name:<20} pairs {n}  us/call {total / n * 1e6:6.2f}  iterations {iters / n:5.1f}  "
          f"ns/iteration {total / iters * 1e9:4.0f}")
