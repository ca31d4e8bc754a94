"""Brute-force twins of the exact minimum-volume OBB (``fit_obb(method="exact")``).

- `edge_pair_search`: O'Rourke's families sampled densely, with none of the exact search's
  machinery (no Gauss-map arcs, no screening, no hill climbing, no bounds): for every ordered
  pair of hull edge directions ``(d1, d2)`` (and ``d1 = d2``), the axes ``a(t)`` on the whole
  circle orthogonal to ``d1``, ``b = a x d2 / |a x d2|``, ``c = a x b``, on a grid of ``t`` in
  ``[0, pi)``, where ``a`` is a face normal and where it is orthogonal to a third edge; every
  box measured on all hull vertices; the best families refined around their best sample (a
  fine grid, then a bounded scalar search).
- `multistart_polish`: random rotations, each improved by Nelder-Mead on a rotation vector
  (`polish`, also a local-optimality check of a given box).
- `brute_force_obb`: the better of the two.
- `min_area_rectangle`: a flat cloud's least rectangle, by a dense search over its angle.

All minimise ``prod(extent_i + 2 radius)``, the volume of the box of ``hull(points) ⊕ ball``.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from scipy.optimize import minimize, minimize_scalar
from scipy.spatial import ConvexHull

from .surfaces import random_rotation

__all__ = [
    "box_volumes", "brute_force_obb", "edge_pair_search", "hull_edges", "min_area_rectangle",
    "multistart_polish", "polish",
]


def box_volumes(points: np.ndarray, radius: float, rotations: np.ndarray) -> np.ndarray:
    """Volumes ``(k,)`` of the boxes with axes ``rotations`` ``(k, 3, 3)`` (columns) around
    ``points`` ``(n, 3)``, each extent grown by ``2 radius``."""
    proj = np.einsum("nj,kja->kna", points, rotations)
    return np.prod(proj.max(axis=1) - proj.min(axis=1) + 2.0 * radius, axis=1)


def _basis(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # Two unit vectors (k, 3) completing the unit directions d (k, 3) to orthonormal frames.
    helper = np.eye(3)[np.argmin(np.abs(d), axis=1)]
    x = np.cross(d, helper)
    x /= np.linalg.norm(x, axis=1)[:, None]
    return x, np.cross(d, x)


def hull_edges(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hull vertices ``(m, 3)``, the unit directions ``(E, 3)`` of the hull's edges and the unit
    normals ``(F, 3)`` of its faces.

    Full-rank clouds: Qhull's triangles' sides (diagonals of merged facets included: a
    superset does no harm) and normals. Flat clouds: the sides of the polygon, and the plane's
    normal. Collinear ones: the segment, no normal.
    """
    c = points - points.mean(axis=0)
    _, s, vt = np.linalg.svd(c, full_matrices=False)
    rank = int(np.sum(s > 1e-12 * s[0])) if len(s) and s[0] > 0 else 0
    if rank <= 1:
        i, j = np.argmin(c @ vt[0]), np.argmax(c @ vt[0])
        return points[[i, j]], vt[:1], np.zeros((0, 3))
    if rank == 2:
        xy = c @ vt[:2].T
        ring = ConvexHull(xy).vertices
        verts = points[ring]
        sides = verts[np.r_[1:len(ring), 0]] - verts
        normals = vt[2:3]
    else:
        hull = ConvexHull(points)
        verts = points[hull.vertices]
        tri = hull.simplices
        sides = np.concatenate([points[tri[:, 1]] - points[tri[:, 0]], points[tri[:, 2]] - points[tri[:, 1]],
                                points[tri[:, 0]] - points[tri[:, 2]]])
        normals = hull.equations[:, :3]
    sides /= np.linalg.norm(sides, axis=1)[:, None]
    sides *= np.where(sides[:, [0]] < 0, -1.0, 1.0)  # one sign per line, then deduplicate
    _, keep = np.unique(np.round(sides, 12), axis=0, return_index=True)
    return verts, sides[np.sort(keep)], normals


def _family_frames(d1: np.ndarray, d2: np.ndarray, t: np.ndarray) -> np.ndarray:
    # Rotations (len(d2), len(t), 3, 3) with columns a(t) on the circle orthogonal to d1,
    # b = a x d2 / |a x d2| (any unit vector orthogonal to a where a is parallel to d2), a x b.
    x, y = _basis(d1[None])
    a = np.cos(t)[:, None] * x + np.sin(t)[:, None] * y  # (T, 3)
    a = np.broadcast_to(a, (len(d2), len(t), 3))
    b = np.cross(a, d2[:, None, :])
    nb = np.linalg.norm(b, axis=2)
    fallback = np.broadcast_to(d1, a.shape)  # a = +-d2: d1 is orthogonal to a (the limit of b)
    b = np.where(nb[..., None] > 1e-12, b / np.maximum(nb, 1e-300)[..., None], fallback)
    return np.stack([a, b, np.cross(a, b)], axis=-1)


@nb.njit(cache=True)
def _grid(points, radius, dirs, t):
    # Volumes (E, E, T) of the boxes of family (d_i, d_j) at every t[i] (E, T): plain loops over
    # every vertex, no support tracking.
    ne, nt, n = dirs.shape[0], t.shape[1], points.shape[0]
    out = np.empty((ne, ne, nt))
    a, b, c = np.empty(3), np.empty(3), np.empty(3)
    for i in range(ne):
        d1 = dirs[i]
        k = int(np.argmin(np.abs(d1)))
        helper = np.zeros(3)
        helper[k] = 1.0
        x = np.cross(d1, helper)
        x /= np.linalg.norm(x)
        y = np.cross(d1, x)
        for j in range(ne):
            for s in range(nt):
                a[:] = np.cos(t[i, s]) * x + np.sin(t[i, s]) * y
                b[:] = np.cross(a, dirs[j])
                nb_ = np.linalg.norm(b)
                if nb_ > 1e-12:
                    b /= nb_
                else:
                    b[:] = d1  # a = +-d2: d1 is orthogonal to a (the limit of b)
                c[:] = np.cross(a, b)
                vol = 1.0
                for u in (a, b, c):
                    lo, hi = np.inf, -np.inf
                    for v in range(n):
                        p = points[v, 0] * u[0] + points[v, 1] * u[1] + points[v, 2] * u[2]
                        lo, hi = min(lo, p), max(hi, p)
                    vol *= hi - lo + 2.0 * radius
                out[i, j, s] = vol
    return out


def edge_pair_search(points, radius: float = 0.0, samples: int = 360, refine: int = 64):
    """Best box over O'Rourke's edge-pair families, sampled on ``samples`` values of ``t``, where
    ``a`` is a face normal (the face-flush boxes) and where ``a`` is orthogonal to a third edge
    (the boxes flush with three edges), the ``refine`` best families refined around their best
    sample. Returns ``(volume, rotation (3, 3))``."""
    points = np.asarray(points, dtype=np.float64)
    verts, dirs, normals = hull_edges(points)
    c = np.ascontiguousarray(verts - verts.mean(axis=0))
    grid = np.arange(samples) * (np.pi / samples)
    x, y = _basis(dirs)
    ts = []
    for i, d in enumerate(dirs):
        on = normals[np.abs(normals @ d) < 1e-9]
        across = np.arctan2(-(dirs @ x[i]), dirs @ y[i]) % np.pi  # a orthogonal to another edge
        ts.append(np.concatenate([grid, np.arctan2(on @ y[i], on @ x[i]) % np.pi, across]))
    t = np.full((len(dirs), max(len(x) for x in ts)), grid[0])
    for i, ti in enumerate(ts):
        t[i, :len(ti)] = ti
    vols = _grid(c, float(radius), np.ascontiguousarray(dirs), t)
    best_vol, best_rot = np.inf, np.eye(3)
    step = np.pi / samples
    per_family = vols.min(axis=2)
    for f in np.argsort(per_family, axis=None)[:refine]:  # the best families, each at its best t
        i, j = np.unravel_index(f, per_family.shape)
        k = int(np.argmin(vols[i, j]))

        def along(tt, i=i, j=j):
            return float(box_volumes(c, radius, _family_frames(dirs[i], dirs[j:j + 1], np.array([tt]))[0])[0])

        # a fine grid over the neighbouring steps (the volume has many kinks there), then a
        # bounded scalar search around its best point, twice
        lo, hi, best_t = t[i, k] - step, t[i, k] + step, t[i, k]
        for _ in range(2):
            fine = np.linspace(lo, hi, 101)
            fv = box_volumes(c, radius, _family_frames(dirs[i], dirs[j:j + 1], fine)[0])
            best_t = fine[int(np.argmin(fv))]
            lo, hi = best_t - (hi - lo) / 100, best_t + (hi - lo) / 100
        res = minimize_scalar(along, bounds=(lo, hi), method="bounded", options={"xatol": 1e-14})
        for tt, v in ((t[i, k], float(vols[i, j, k])), (best_t, along(best_t)), (res.x, float(res.fun))):
            if v < best_vol:
                best_vol = v
                best_rot = _family_frames(dirs[i], dirs[j:j + 1], np.array([tt]))[0, 0]
    return best_vol, best_rot


def _rodrigues(w: np.ndarray) -> np.ndarray:
    theta = float(np.linalg.norm(w))
    if theta == 0.0:
        return np.eye(3)
    k = w / theta
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(theta) * kx + (1.0 - np.cos(theta)) * (kx @ kx)


def polish(points, radius: float, rotation) -> tuple[float, np.ndarray]:
    """Nelder-Mead on a rotation vector from ``rotation``: ``(volume, rotation)`` of the best
    box found near it (a local-optimality check of a box)."""
    points = np.asarray(points, dtype=np.float64)
    verts = hull_edges(points)[0]
    c = verts - verts.mean(axis=0)
    r0 = np.asarray(rotation, dtype=np.float64)

    def vol(w):
        return float(box_volumes(c, radius, (r0 @ _rodrigues(w))[None])[0])

    best = (vol(np.zeros(3)), r0)
    for scale in (1e-2, 1e-4):  # two simplex sizes: a wide look, then a close one
        res = minimize(vol, np.zeros(3), method="Nelder-Mead",
                       options={"xatol": 1e-12, "fatol": 1e-16, "maxiter": 4000,
                                "initial_simplex": np.vstack([np.zeros(3), np.eye(3) * scale])})
        if res.fun < best[0]:
            best = (float(res.fun), r0 @ _rodrigues(res.x))
    return best


def multistart_polish(points, radius: float = 0.0, starts: int = 64, seed: int = 0):
    """Best box found from ``starts`` random rotations, each polished by Nelder-Mead on a
    rotation vector. Returns ``(volume, rotation (3, 3))``."""
    rng = np.random.default_rng(seed)
    found = [polish(points, radius, random_rotation(rng)) for _ in range(starts)]
    return min(found, key=lambda x: x[0])


def min_area_rectangle(points, samples: int = 20001) -> float:
    """Least area of a rectangle around a flat cloud ``(n, 3)``, in its plane: a dense search
    over the rectangle's angle, refined around the best one."""
    points = np.asarray(points, dtype=np.float64)
    c = points - points.mean(axis=0)
    _, _, vt = np.linalg.svd(c, full_matrices=False)
    xy = c @ vt[:2].T

    def area(angle):
        d = np.array([np.cos(angle), np.sin(angle)])
        return float(np.ptp(xy @ d) * np.ptp(xy @ np.array([-d[1], d[0]])))

    grid = np.linspace(0.0, np.pi / 2, samples)
    k = int(np.argmin([area(g) for g in grid]))
    step = grid[1] - grid[0]
    res = minimize_scalar(area, bounds=(grid[k] - step, grid[k] + step), method="bounded",
                          options={"xatol": 1e-14})
    return min(area(grid[k]), float(res.fun))


def brute_force_obb(points, radius: float = 0.0, samples: int = 360, starts: int = 32, seed: int = 0):
    """The better of `edge_pair_search` and `multistart_polish`: ``(volume, rotation)``."""
    a = edge_pair_search(points, radius, samples)
    b = multistart_polish(points, radius, starts, seed)
    return a if a[0] <= b[0] else b
