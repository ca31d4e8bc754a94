"""One copy of the package's `pair_distance` on ellipsoid pairs near contact, in a numba loop (a developer's tool).

    python tests/bench/ellipsoid_ab.py DIR DEPTH

``DIR`` holds a copy of the ``collide`` package (``git archive <commit> collide | tar -x -C DIR``);
run it once per copy (each with its own ``NUMBA_CACHE_DIR``) to compare two. Per pair kind (shadow_hand's
scale: a 3 x 4 x 2 cm ellipsoid against a box, a smaller ellipsoid, a 60-point mesh, a capsule and a
cylinder), 200 random rotations and directions; each pair is placed at its touching distance and then
moved by -1 mm .. +DEPTH along its normal (penetrating up to DEPTH). Printed: per kind, the penetrating
and separated pairs' mean time per call (best of 3 runs of 50) and mean iterations (GJK's plus EPA's),
at the contacts' tolerance (1e-9 of the two sizes).
"""
import sys
import time

sys.path.insert(0, sys.argv[1])  # the copy under test, before any installed one

import numpy as np  # noqa: E402
from numba import njit  # noqa: E402

from collide import Cylinder, Ellipsoid, PointCloud  # noqa: E402
from collide._kernels import distance as kd  # noqa: E402
from collide.support import support_data  # noqa: E402
from collide.testing.surfaces import random_rotation  # noqa: E402

DEPTH = float(sys.argv[2])


@njit(cache=True)
def _loop(sa, sb, tol, d0, reps, out):
    for _ in range(reps):
        kd.pair_distance(sa, sb, tol, d0, -1, -1, 128, out)


def main() -> None:
    rng = np.random.default_rng(5)
    box = PointCloud(np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
                     * [0.02, 0.015, 0.01])
    ell = Ellipsoid([0.03, 0.04, 0.02])
    d = rng.normal(size=(60, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    cases = {"box-ellipsoid": (box, ell), "ellipsoid-ellipsoid": (Ellipsoid([0.015, 0.01, 0.007]), ell),
             "ellipsoid-mesh": (ell, PointCloud(d * [0.02, 0.015, 0.012])),
             "capsule-ellipsoid": (PointCloud([[0, 0, -0.02], [0, 0, 0.02]], 0.01), ell),
             "cylinder-ellipsoid": (Cylinder(0.015, 0.02), ell)}
    out = np.empty(kd.OUT_SIZE)
    zero = np.zeros(3)
    print(sys.argv[1], "depths up to", DEPTH)
    for name, (a, b) in cases.items():
        da, db = support_data(a), support_data(b)
        tol = 1e-9 * (da.size + db.size)
        res = {"pen": [], "sep": []}
        its = {"pen": [], "sep": []}
        rr = np.random.default_rng(1)
        for _ in range(200):
            ra, rb = random_rotation(rr), random_rotation(rr)
            u = rr.normal(size=3)
            u /= np.linalg.norm(u)
            ta = np.zeros(3)
            tb = u * 0.2
            _loop(da.posed(ra, ta), db.posed(rb, tb), tol, zero, 1, out)
            tb = tb - (out[kd.OUT_DISTANCE] + rr.uniform(-0.001, DEPTH)) * out[kd.OUT_NORMAL:kd.OUT_NORMAL + 3]
            sa, sb = da.posed(ra, ta), db.posed(rb, tb)
            _loop(sa, sb, tol, zero, 1, out)
            key = "pen" if out[kd.OUT_DISTANCE] < 0 else "sep"
            best = np.inf
            for _ in range(3):
                t0 = time.perf_counter()
                _loop(sa, sb, tol, zero, 50, out)
                best = min(best, time.perf_counter() - t0)
            res[key].append(best / 50 * 1e6)
            its[key].append(out[kd.OUT_ITERATIONS])
        print(f"{name:22s} pen {len(res['pen']):3d} {np.mean(res['pen']):6.2f} us {np.mean(its['pen']):5.1f} it | "
              f"sep {len(res['sep']):3d} {np.mean(res['sep']):6.2f} us {np.mean(its['sep']):5.1f} it")


if __name__ == "__main__":
    main()
