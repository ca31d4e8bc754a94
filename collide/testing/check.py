"""Brute-force twins of `collide.mujoco.Collider.check_batch`, and random configurations.

- `all_filtered_pairs`: every geom pair that passes the articulation's filters, explicit pairs
  included, from `brute.filter_passing_pairs` (a mask over all pairs; no blocks, no tree).
- `brute_force_min_distance`: the closest of given pairs by `collide.contacts.geom_distance`
  called on every one of them (no bounds, no pruning): the minimum ``check_batch`` must equal.
- `random_configurations`: configurations of a MuJoCo-style model, inside its joint limits or
  partly outside them, for tests, benchmarks and demos.
"""

from __future__ import annotations

import math

import numpy as np

from .. import contacts as _contacts
from ..articulation import Articulation
from .brute import filter_passing_pairs

__all__ = ["all_filtered_pairs", "brute_force_min_distance", "random_configurations"]

# mjtJoint
_FREE, _BALL, _SLIDE, _HINGE = 0, 1, 2, 3


def all_filtered_pairs(art: Articulation, no_function=None) -> np.ndarray:
    """``(P, 2) int64``: the dynamic path's filter-passing pairs and the explicit pairs, sorted,
    without pairs of two geoms flagged in ``no_function (G,) bool`` (planes always)."""
    g1, g2 = filter_passing_pairs(art)
    pairs = np.concatenate([np.stack([g1, g2], axis=1), np.sort(art.pairs.reshape(-1, 2), axis=1)])
    nf = art.geom_is_plane.copy()
    if no_function is not None:
        nf |= np.asarray(no_function, bool)
    pairs = pairs[~(nf[pairs[:, 0]] & nf[pairs[:, 1]])]
    return np.unique(pairs, axis=0).reshape(-1, 2)


def brute_force_min_distance(table: _contacts.GeomTable, pairs, geom_xpos, geom_xmat,
                             distmax: float) -> tuple[float, tuple[int, int]]:
    """Closest of ``pairs`` at the given geom poses, by `collide.contacts.geom_distance` on each.

    Parameters
    ----------
    table : collide.contacts.GeomTable
    pairs : (P, 2) int array_like
    geom_xpos : (G, 3) float64
    geom_xmat : (G, 9) or (G, 3, 3) float64
    distmax : float
        Finite.

    Returns
    -------
    dist : float
        The smallest signed distance below ``distmax``, else ``inf``.
    pair : (int, int)
        Its pair (the first in ``pairs``' order among equal distances), else ``(-1, -1)``.
    """
    best, arg = math.inf, (-1, -1)
    for g1, g2 in np.asarray(pairs).tolist():
        if table.cls[g1] == 2 or table.cls[g2] == 2:  # height field / SDF: no distance
            continue
        d, _ = _contacts.geom_distance(table, g1, g2, geom_xpos, geom_xmat, distmax)
        if d < distmax and d < best:
            best, arg = d, (g1, g2)
    return best, arg


def random_configurations(model, n: int, rng: np.random.Generator, outside: float = 0.0) -> np.ndarray:
    """``(n, nq) float64`` configurations of a model with MuJoCo's joint arrays.

    Limited hinges and slides uniform in their range (widened by ``outside`` of its length on
    each side for a fraction ``outside`` of the rows: configurations beyond the limits);
    unlimited hinges uniform in ``[-pi, pi]``, unlimited slides within 0.2 of ``qpos0``; ball
    joints and free joints' rotations uniform for half the rows, within 0.3 rad of ``qpos0``'s
    for the rest; free joints' positions within 0.2 of ``qpos0``'s (up to 0.4 higher).

    Parameters
    ----------
    model : mujoco.MjModel
        Reads ``nq``, ``qpos0``, ``njnt``, ``jnt_type``, ``jnt_qposadr``, ``jnt_limited``,
        ``jnt_range``.
    n : int
    rng : numpy.random.Generator
    outside : float, default 0
        In ``[0, 1]``.
    """
    q = np.tile(np.asarray(model.qpos0, dtype=np.float64), (n, 1))
    far = rng.random(n) < outside

    def rotations(base: np.ndarray) -> np.ndarray:
        u = rng.normal(size=(n, 4))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        axis = rng.normal(size=(n, 3))
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        ang = rng.uniform(0.0, 0.3, n)
        small = np.concatenate([np.cos(ang / 2)[:, None], np.sin(ang / 2)[:, None] * axis], axis=1)
        w0, x0, y0, z0 = base
        w, x, y, z = small.T
        near = np.stack([w0 * w - x0 * x - y0 * y - z0 * z, w0 * x + x0 * w + y0 * z - z0 * y,
                         w0 * y - x0 * z + y0 * w + z0 * x, w0 * z + x0 * y - y0 * x + z0 * w], axis=1)
        return np.where((rng.random(n) < 0.5)[:, None], u, near)

    for j in range(int(model.njnt)):
        a = int(model.jnt_qposadr[j])
        t = int(model.jnt_type[j])
        if t == _FREE:
            q[:, a:a + 3] += rng.uniform(-0.2, 0.2, (n, 3)) + np.array([0.0, 0.0, 0.2]) * rng.random((n, 1))
            q[:, a + 3:a + 7] = rotations(np.asarray(model.qpos0[a + 3:a + 7], dtype=np.float64))
        elif t == _BALL:
            q[:, a:a + 4] = rotations(np.asarray(model.qpos0[a:a + 4], dtype=np.float64))
        elif bool(model.jnt_limited[j]):
            lo, hi = (float(v) for v in model.jnt_range[j])
            w = (hi - lo) * outside
            q[:, a] = np.where(far, rng.uniform(lo - w, hi + w, n), rng.uniform(lo, hi, n))
        elif t == _HINGE:
            q[:, a] = rng.uniform(-np.pi, np.pi, n)
        else:
            q[:, a] += rng.uniform(-0.2, 0.2, n)
    return q
