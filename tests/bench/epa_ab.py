"""A/B of `collide._kernels.epa.epa` between two copies of the package, interleaved in one process
(a developer's tool).

    python tests/bench/epa_ab.py DIR/NAME_A DIR/NAME_B [TOL]

Each ``DIR/NAME`` holds a copy of the ``collide`` package under a name of its own
(``mkdir -p /tmp/e/a && git archive REV collide | tar -x -C /tmp/e/a && mv /tmp/e/a/collide
/tmp/e/a/c_before``); its imports are relative, so it runs its own kernels. The cases (also
`epa_curved.py`'s, from here): 150 random poses each of box-ellipsoid, ellipsoid-ellipsoid and
cylinder-cylinder pairs of 1-2 cm shapes (seed 1), GJK's final simplex taken once per pair, EPA at
the absolute tolerance TOL (default 1e-11, the contacts' 1e-9 of the sizes at this scale). Per
pair, each copy's 20 calls are timed five times, the copies' order alternating, and the best of
the five kept (a drift of this shared machine hits both copies alike). Printed per kind: the mean
time per call of each copy, B's over A's, both copies' iterations and how many pairs' results
(``res``, iterations) differ between the copies.
"""

from __future__ import annotations

import importlib
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit
from scipy.spatial.transform import Rotation

BOX = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * np.array([0.02, 0.015, 0.01])
NONE = np.zeros((0, 3))
CASES = {"box-ellipsoid": ((0, np.zeros(4), BOX), (3, np.array([0.012, 0.01, 0.02, 0.0]), NONE)),
         "ellipsoid-ellipsoid": ((3, np.array([0.02, 0.01, 0.015, 0.0]), NONE),
                                 (3, np.array([0.012, 0.01, 0.02, 0.0]), NONE)),
         "cylinder-cylinder": ((1, np.array([0.01, 0.02, 0.0, 0.0]), NONE),
                               (1, np.array([0.012, 0.015, 0.0, 0.0]), NONE))}


def poses(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # One case's rotations of A and B and B's position (A at the origin), 5-20 mm apart.
    ra = Rotation.random(random_state=rng.integers(1 << 30)).as_matrix()
    rb = Rotation.random(random_state=rng.integers(1 << 30)).as_matrix()
    pb = rng.normal(size=3)
    pb *= rng.uniform(0.005, 0.02) / np.linalg.norm(pb)
    return ra, rb, pb


def _runner(name: str):
    # The timed loop, compiled against copy ``name``'s kernels.
    borrow = importlib.import_module(name + "._kernels._ptr").borrow
    epa = importlib.import_module(name + "._kernels.epa").epa
    gjk = importlib.import_module(name + "._kernels.gjk")
    gjk_within, overlap = gjk.gjk_within, gjk.OVERLAP

    @njit
    def run(ka, pra, pta, ra, pa, kb, prb, ptb, rb, pb, tol, reps, res, e32):
        e = borrow(e32)
        sa = (ka, borrow(pra), borrow(pta), e, e, borrow(ra), borrow(pa))
        sb = (kb, borrow(prb), borrow(ptb), e, e, borrow(rb), borrow(pb))
        W, WA, WB = np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((4, 3))
        lam, v, dirn, p1, p2 = np.zeros(4), np.zeros(3), np.zeros(4), np.zeros(3), np.zeros(3)
        hints = np.array([-1, -1])
        st, n, lower, _, _ = gjk_within(sa, sb, np.zeros(3), hints, tol, np.inf, 128, W, WA, WB, lam, v, dirn,
                                        p1, p2)
        if st != overlap:
            return -1
        r = borrow(res)
        h = np.empty(2, np.int64)
        its = 0
        for _ in range(reps):
            h[0], h[1] = hints[0], hints[1]
            _, _, its = epa(sa, sb, W, WA, WB, n, h, tol, 128, lower, r)
        return its

    return run


def main() -> None:
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    copies = [Path(c).resolve() for c in sys.argv[1:3]]
    tol = float(sys.argv[3]) if len(sys.argv) > 3 else 1e-11
    if copies[0].name == copies[1].name:
        sys.exit("epa_ab.py: give each copy a folder name of its own")
    for c in copies:
        sys.path.insert(0, str(c.parent))
    runs = [_runner(c.name) for c in copies]
    e32 = np.zeros(1, np.int32)
    print(f"# EPA A/B, tolerance {tol:g}: A = {copies[0]}, B = {copies[1]}")
    for name, (A, B) in CASES.items():
        rng = np.random.default_rng(1)
        tot = [0.0, 0.0]
        its = [0, 0]
        pairs = differ = 0
        for _ in range(150):
            ra, rb, pb = poses(rng)
            args = (A[0], A[1], A[2], ra, np.zeros(3), B[0], B[1], B[2], rb, pb, tol)
            res = [np.empty(13), np.empty(13)]
            it = [runs[k](*args, 1, res[k], e32) for k in range(2)]
            if it[0] < 0 or it[1] < 0:
                continue
            pairs += 1
            differ += int(it[0] != it[1] or not np.array_equal(res[0], res[1]))
            best = [np.inf, np.inf]
            for r in range(5):
                for k in ((0, 1) if r % 2 == 0 else (1, 0)):
                    t0 = time.perf_counter()
                    runs[k](*args, 20, res[k], e32)
                    best[k] = min(best[k], time.perf_counter() - t0)
            for k in range(2):
                tot[k] += best[k] / 20
                its[k] += it[k]
        print(f"{name:<20} pairs {pairs}  us/call A {tot[0] / pairs * 1e6:6.2f}  B {tot[1] / pairs * 1e6:6.2f}  "
              f"B/A {tot[1] / tot[0]:.3f}  iterations A {its[0] / pairs:.1f} B {its[1] / pairs:.1f}  "
              f"results differ {differ}")


if __name__ == "__main__":
    main()
