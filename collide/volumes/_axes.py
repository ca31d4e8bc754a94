"""Box axes of a cloud: principal axes, hull vertices, rotations and the minimal rectangle.

The building blocks the OBB fitters choose axes with (`_fit_box`): none of them decides an
extent, so none can make a box miss a point.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from .. import hull as _hull
from .._validate import as_points

__all__ = ["pca_axes"]

_require_points = _hull.require_bounded

def _right_handed(rot: np.ndarray) -> np.ndarray:
    rot = np.array(rot, dtype=np.float64)
    if np.linalg.det(rot) < 0.0:
        rot[:, 2] = -rot[:, 2]
    return rot


def _principal(points: np.ndarray, rounding: float = 0.0) -> tuple[np.ndarray, int]:
    # Principal axes (rows, largest spread first) and affine rank, with the thresholds of
    # hull.affine_basis but a thin SVD: hull.affine_basis takes a full one (an (n, n) factor:
    # quadratic in time and memory, out of memory at n = 1e5). ``rounding``: the magnitude of
    # the coordinates the points were rounded at before the caller moved them (fit_obb's cloud
    # far from the origin, centred): spread at that noise level is rounding, not shape (20
    # collinear points 1e6 from the origin came out a needle 1e-9 thick, and the exact box's
    # search, in proportion to 1 / thickness, did not end: helper-78, 2026-12-02).
    centred = points - points.mean(axis=0)
    extent = float(np.abs(centred).max()) if len(points) > 1 else 0.0
    if extent == 0.0 or extent <= _hull.FLAT_TOL * float(np.abs(points.mean(axis=0)).max()):
        return np.eye(3), 0
    _, s, vt = np.linalg.svd(centred, full_matrices=len(points) < 3)
    s = np.concatenate([s, np.zeros(3 - len(s))])
    noise = 64.0 * np.finfo(np.float64).eps * max(float(np.abs(points).max()), rounding) * np.sqrt(len(points))
    return vt, int(np.sum(s > max(_hull.FLAT_TOL * s[0], noise)))


def pca_axes(points: np.ndarray) -> np.ndarray:
    """Principal axes of a cloud, ``(3, 3) float64`` with columns as axes, right-handed.

    Parameters
    ----------
    points : (n, 3) float64
        Non-empty.
    """
    points = as_points(points, "points")
    _require_points(points, "points")
    return _right_handed(_principal(points)[0].T)


# Chunk size of the fallback reduction in _hull_points.
_CHUNK = 256


def _hull_points(points: np.ndarray, rounding: float = 0.0) -> tuple[np.ndarray, "ConvexHull | None"]:
    # Hull vertices of a cloud (centred by the caller), and Qhull's hull when it was computed
    # on the full-rank cloud (its facets serve the OBB candidates). This mirrors
    # hull.hull_indices (work in the affine hull's dimension) with the thin SVD of _principal:
    # hull.affine_basis takes a full one, quadratic in the number of points. If Qhull still
    # refuses, hull.hull_vertices reduces the cloud in chunks: hull(P) = hull(union of the
    # chunks' hull vertices). ``rounding``: as `_principal`'s.
    axes, rank = _principal(points, rounding)
    if rank == 0:
        return points[:1], None
    if rank == 1:
        proj = points @ axes[0]
        return points[np.unique([int(np.argmin(proj)), int(np.argmax(proj))])], None
    if len(points) <= rank + 1:
        return points, None
    try:
        if rank == 3:
            hull = ConvexHull(points)
            return points[np.sort(hull.vertices)], hull
        flat = ConvexHull((points - points.mean(axis=0)) @ axes[:2].T)
        return points[np.sort(flat.vertices)], None
    except (QhullError, ValueError):
        pass
    while len(points) > _CHUNK:
        parts = [_hull.hull_vertices(points[i:i + _CHUNK]) for i in range(0, len(points), _CHUNK)]
        reduced = np.concatenate(parts, axis=0)
        if len(reduced) == len(points):
            return points, None
        points = reduced
    return _hull.hull_vertices(points), None


def _rodrigues(vecs: np.ndarray) -> np.ndarray:
    # Rotation matrices (k, 3, 3) of rotation vectors (k, 3) (axis * angle).
    theta = np.linalg.norm(vecs, axis=1)
    safe = np.where(theta > 0.0, theta, 1.0)
    k = vecs / safe[:, None]
    kx = np.zeros((len(vecs), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx = kx - kx.transpose(0, 2, 1)
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    return np.eye(3)[None] + s * kx + (1.0 - c) * (kx @ kx)


def _orthonormal(rot: np.ndarray) -> np.ndarray:
    # Nearest rotation (polar factor through SVD), right-handed: removes the drift that a
    # product of many small rotations accumulates.
    u, _, vt = np.linalg.svd(rot)
    out = u @ vt
    if np.linalg.det(out) < 0.0:
        out = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    return out


@numba.njit(cache=True)
def _nb_min_rect(points, u, v):
    # Unit direction (2,) in the (u, v) plane of one side of the minimal-area rectangle of the
    # points projected on that plane. One side of a minimal rectangle is flush with an edge of
    # the 2D hull (Freeman & Shapira 1975), so the hull (Andrew's monotone chain) is built and
    # every edge direction tried (rotating calipers, O(h^2) here: hulls are small).
    n = points.shape[0]
    xy = np.empty((n, 2))
    for i in range(n):
        xy[i, 0] = points[i, 0] * u[0] + points[i, 1] * u[1] + points[i, 2] * u[2]
        xy[i, 1] = points[i, 0] * v[0] + points[i, 1] * v[1] + points[i, 2] * v[2]
    by_y = np.argsort(xy[:, 1], kind="mergesort")
    order = by_y[np.argsort(xy[by_y, 0], kind="mergesort")]
    hull = np.empty(2 * n + 1, dtype=np.int64)
    h = 0
    for rep in range(2):
        start = h
        for t in range(n):
            i = order[t] if rep == 0 else order[n - 1 - t]
            while h >= start + 2:
                o, a = hull[h - 2], hull[h - 1]
                cr = ((xy[a, 0] - xy[o, 0]) * (xy[i, 1] - xy[o, 1])
                      - (xy[a, 1] - xy[o, 1]) * (xy[i, 0] - xy[o, 0]))
                if cr > 0.0:
                    break
                h -= 1
            hull[h] = i
            h += 1
        h -= 1  # the last point of each chain starts the other one
    best_dir = np.array([1.0, 0.0])
    best_area = np.inf
    for e in range(max(h, 1)):
        a, b = hull[e], hull[(e + 1) % max(h, 1)]
        dx, dy = xy[b, 0] - xy[a, 0], xy[b, 1] - xy[a, 1]
        ln = np.sqrt(dx * dx + dy * dy)
        if ln == 0.0:
            continue
        dx, dy = dx / ln, dy / ln
        lo0, hi0, lo1, hi1 = np.inf, -np.inf, np.inf, -np.inf
        for t in range(h):
            q = hull[t]
            p0 = xy[q, 0] * dx + xy[q, 1] * dy
            p1 = -xy[q, 0] * dy + xy[q, 1] * dx
            lo0, hi0 = min(lo0, p0), max(hi0, p0)
            lo1, hi1 = min(lo1, p1), max(hi1, p1)
        area = (hi0 - lo0) * (hi1 - lo1)
        if area < best_area:
            best_area = area
            best_dir[0], best_dir[1] = dx, dy
    return best_dir


def _frame_from_normal(normal: np.ndarray, points: np.ndarray) -> np.ndarray:
    # Right-handed rotation whose third column is ``normal`` and whose first two columns are
    # the sides of the minimal-area rectangle of the points projected on the normal's plane.
    helper = np.zeros(3)
    helper[int(np.argmin(np.abs(normal)))] = 1.0
    u = _cross(normal, helper)
    u /= np.linalg.norm(u)
    v = _cross(normal, u)
    d = _nb_min_rect(points, u, v)
    a = d[0] * u + d[1] * v
    return np.column_stack([a, _cross(normal, a), normal])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    # np.cross's argument handling outweighs its arithmetic many times over on 3-vectors.
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _surface_pca(points: np.ndarray, simplices: np.ndarray) -> np.ndarray:
    # Principal axes of the hull's surface (area-weighted triangle second moments; Gottschalk,
    # Lin & Manocha 1996, "OBBTree", §4): unlike the vertices' PCA, not biased by sampling.
    p, q, r = points[simplices[:, 0]], points[simplices[:, 1]], points[simplices[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(q - p, r - p), axis=1)
    total = float(area.sum())
    if total <= 0.0:
        return pca_axes(points)
    m = (p + q + r) / 3.0
    mean = (area @ m) / total
    second = (9.0 * (m * area[:, None]).T @ m + (p * area[:, None]).T @ p
              + (q * area[:, None]).T @ q + (r * area[:, None]).T @ r)
    cov = second / (12.0 * total) - np.outer(mean, mean)
    _, vecs = np.linalg.eigh(cov)
    return _right_handed(vecs[:, ::-1])


def _same_axes(a: np.ndarray, b: np.ndarray) -> bool:
    # Two rotations give the same box axes (up to order and sign).
    return bool(np.all(np.abs(a.T @ b).max(axis=1) > 1.0 - 1e-9))


# Hull face normals (largest merged face areas first) tried as a box axis, best distinct
# starts polished, and the polish's first and last step (radians), for the "optimal" OBB.
