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
from numba import njit
from scipy.spatial.transform import Rotation

from collide._kernels._ptr import borrow
from collide._kernels.epa import epa
from collide._kernels.gjk import OVERLAP, gjk_within

TOL = float(sys.argv[1]) if len(sys.argv) > 1 else 1e-11
E32 = np.zeros(1, np.int32)
BOX = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * np.array([0.02, 0.015, 0.01])


@njit
def run(ka, pra, pta, ra, pa, kb, prb, ptb, rb, pb, tol, reps, res, e32):
    e = borrow(e32)
    sa = (ka, borrow(pra), borrow(pta), e, e, borrow(ra), borrow(pa))
    sb = (kb, borrow(prb), borrow(ptb), e, e, borrow(rb), borrow(pb))
    W, WA, WB = np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((4, 3))
    lam, v, dirn, p1, p2 = np.zeros(4), np.zeros(3), np.zeros(4), np.zeros(3), np.zeros(3)
    hints = np.array([-1, -1])
    st, n, lower, scale, it = gjk_within(sa, sb, np.zeros(3), hints, tol, np.inf, 128, W, WA, WB, lam, v, dirn,
                                         p1, p2)
    if st != OVERLAP:
        return -1
    r = borrow(res)
    h = np.empty(2, np.int64)
    its = 0
    for _ in range(reps):
        h[0], h[1] = hints[0], hints[1]
        _, _, its = epa(sa, sb, W, WA, WB, n, h, tol, 128, lower, r)
    return its


NONE = np.zeros((0, 3))
CASES = {"box-ellipsoid": ((0, np.zeros(4), BOX), (3, np.array([0.012, 0.01, 0.02, 0.0]), NONE)),
         "ellipsoid-ellipsoid": ((3, np.array([0.02, 0.01, 0.015, 0.0]), NONE),
                                 (3, np.array([0.012, 0.01, 0.02, 0.0]), NONE)),
         "cylinder-cylinder": ((1, np.array([0.01, 0.02, 0.0, 0.0]), NONE), (1, np.array([0.012, 0.015, 0.0, 0.0]), NONE))}
print(f"# EPA on penetrating curved pairs, tolerance {TOL:g} (python tests/bench/epa_curved.py {TOL:g})")
for name, (A, B) in CASES.items():
    rng = np.random.default_rng(1)
    total = iters = n = 0
    for _ in range(150):
        ra = Rotation.random(random_state=rng.integers(1 << 30)).as_matrix()
        rb = Rotation.random(random_state=rng.integers(1 << 30)).as_matrix()
        pb = rng.normal(size=3)
        pb *= rng.uniform(0.005, 0.02) / np.linalg.norm(pb)
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
