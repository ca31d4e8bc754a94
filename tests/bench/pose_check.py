"""Cost of the narrow phase's per-geom pose test (a developer's tool).

    python tests/bench/pose_check.py

`collide._kernels.manifold._pose_refused` (a proper rotation within `bounds.ORTHO_TOL` and a position
within `bounds.MAX_POSITION`, the bodies' test) against the finiteness test it replaced
(`_finite_pose`) and an empty loop, each in a compiled loop over 200,000 random geoms of 256
(cache-resident poses): nanoseconds a geom, medians of 9 runs, three rounds. The per-step kernel
tests both geoms of each candidate pair. (Session 61's figures in ``contacts.txt`` were taken on
`_pose_error`, which returned an int; the loop now adds a branch on a bool.)
"""

from __future__ import annotations

import time

import numba as nb
import numpy as np
from scipy.spatial.transform import Rotation

from collide._kernels.manifold import _finite_pose, _pose_refused


@nb.njit
def _new(xpos, xmat, idx):
    s = 0
    for g in idx:
        s += 1 if _pose_refused(xpos, xmat, g) else 0
    return s


@nb.njit
def _old(xpos, xmat, idx):
    s = 0
    for g in idx:
        s += 0 if _finite_pose(xpos, xmat, g) else 1
    return s


@nb.njit
def _empty(xpos, xmat, idx):
    s = 0
    for g in idx:
        s += g & 1
    return s


def main() -> None:
    G = 256
    rng = np.random.default_rng(0)
    xmat = Rotation.random(G, random_state=1).as_matrix().copy()
    xpos = rng.normal(size=(G, 3))
    idx = rng.integers(0, G, 200_000).astype(np.int64)
    fns = {"_pose_refused": _new, "_finite_pose": _old, "empty loop": _empty}
    for f in fns.values():
        assert f(xpos, xmat, idx) == (int(np.sum(idx & 1)) if f is _empty else 0)  # compiled; every pose taken
    for _ in range(3):
        row = []
        for name, f in fns.items():
            ts = []
            for _ in range(9):
                t = time.perf_counter()
                f(xpos, xmat, idx)
                ts.append(time.perf_counter() - t)
            row.append(f"{name} {np.median(ts) / len(idx) * 1e9:.2f}")
        print("ns a geom: " + ", ".join(row))


if __name__ == "__main__":
    main()
