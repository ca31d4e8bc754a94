"""Enclosing spheres of a cloud ``hull(points) ⊕ ball(radius)``: the exact minimal sphere
(Welzl 1991, move-to-front, on a growing working set) and Ritter's (1990).
"""

from __future__ import annotations

import numpy as np

from .. import hull as _hull
from .._validate import as_points, as_radius
from ._records import _PAD_FLOOR, _ROUNDING_PAD, Sphere, row_norms

__all__ = ["fit_sphere", "min_sphere_center"]

_require_points = _hull.require_bounded

_WELZL_SLACK = 1e-12


def _ball_of_support(support: list) -> tuple[np.ndarray, float]:
    # The smallest ball with every support point on its boundary (Welzl 1991, b_md(∅, R)),
    # for 1 to 4 points given in coordinates scaled to unit size. Degenerate supports
    # (collinear triples, coplanar quadruples), which only arise from rounding or from exactly
    # degenerate input (cocircular polygons, collinear clouds), fall back to the minimal ball
    # of the support points, found by enumeration: still a valid and minimal answer for them.
    k = len(support)
    a = support[0]
    if k == 1:
        return a.copy(), 0.0
    if k == 2:
        c = 0.5 * (a + support[1])
        return c, float(np.sum((a - c) ** 2))
    if k == 3:
        u, v = support[1] - a, support[2] - a
        w = np.cross(u, v)
        ww = float(w @ w)
        if ww > 1e-24 * float(u @ u) * float(v @ v):
            # Circumcentre of a triangle in 3D: a + (|u|^2 (v x w) + |v|^2 (w x u)) / (2 |w|^2).
            off = (float(u @ u) * np.cross(v, w) + float(v @ v) * np.cross(w, u)) / (2.0 * ww)
            return a + off, float(off @ off)
        return _min_ball_brute(support)
    m = np.array([support[1] - a, support[2] - a, support[3] - a])
    rhs = 0.5 * np.sum(m * m, axis=1)
    det = float(np.linalg.det(m))
    scale = float(np.prod(np.linalg.norm(m, axis=1)))
    if abs(det) > 1e-12 * scale:
        off = np.linalg.solve(m, rhs)
        return a + off, float(off @ off)
    return _min_ball_brute(support)


def _min_ball_brute(support: list) -> tuple[np.ndarray, float]:
    # Minimal ball of at most 4 points: the smallest ball through 2 or 3 of them that holds all.
    pts = np.array(support)
    best_c, best_r2 = None, np.inf
    n = len(pts)
    subsets = [(i, j) for i in range(n) for j in range(i + 1, n)]
    subsets += [(i, j, k) for i in range(n) for j in range(i + 1, n) for k in range(j + 1, n)]
    for sub in subsets:
        if len(sub) == 3:
            u, v = pts[sub[1]] - pts[sub[0]], pts[sub[2]] - pts[sub[0]]
            w = np.cross(u, v)
            ww = float(w @ w)
            if not ww > 1e-24 * float(u @ u) * float(v @ v):
                continue
            off = (float(u @ u) * np.cross(v, w) + float(v @ v) * np.cross(w, u)) / (2.0 * ww)
            c = pts[sub[0]] + off
        else:
            c = 0.5 * (pts[sub[0]] + pts[sub[1]])
        r2 = float(np.max(np.sum((pts - c) ** 2, axis=1)))
        if r2 < best_r2:
            best_c, best_r2 = c, r2
    return best_c, best_r2


def _welzl_mtf(pts: np.ndarray, end: int, support: list) -> tuple[np.ndarray, float]:
    # Welzl's move-to-front variant (Welzl 1991, "Smallest enclosing disks (balls and
    # ellipsoids)", §3; Gärtner 1999, "Fast and robust smallest enclosing balls"): the ball of
    # pts[:end] with ``support`` on its boundary. ``pts`` is reordered in place. The scan for
    # the next violating point is vectorised; the recursion depth is at most 4.
    center, r2 = _ball_of_support(support) if support else (pts[0] * np.nan, -1.0)
    if len(support) == 4:
        return center, r2
    i = 0
    while i < end:
        if r2 < 0.0:
            j = i
        else:
            d2 = np.sum((pts[i:end] - center) ** 2, axis=1)
            out = np.flatnonzero(d2 > r2 * (1.0 + _WELZL_SLACK) + 1e-30)
            if len(out) == 0:
                break
            j = i + int(out[0])
        p = pts[j].copy()
        center, r2 = _welzl_mtf(pts, j, support + [p])
        pts[1:j + 1] = pts[0:j].copy()
        pts[0] = p
        i = j + 1
    return center, r2


# min_sphere_center: clouds up to _SPHERE_DIRECT points go straight to Welzl; larger ones grow
# a working set by _SPHERE_ADD violators per round, for at most _SPHERE_ROUNDS rounds before
# falling back to Welzl on the whole cloud. Chosen by timing gaussian clouds of 8 to 1000 points
# against the settings 16 and 64 (2026-11-21): about as fast on large clouds, without their slow
# case near 50 points.
_SPHERE_DIRECT = 16
_SPHERE_ADD = 8
_SPHERE_ROUNDS = 64


def _welzl(pts: np.ndarray) -> tuple[np.ndarray, float]:
    # Minimal ball (centre, squared radius) of a small point set; random order gives Welzl's
    # expected linear time, a fixed seed keeps results reproducible.
    order = np.random.default_rng(0).permutation(len(pts))
    return _welzl_mtf(np.ascontiguousarray(pts[order]), len(pts), [])


def min_sphere_center(points: np.ndarray) -> np.ndarray:
    """Centre of the minimal enclosing sphere of ``points`` (exact, up to rounding).

    Welzl's algorithm (move-to-front) runs on a small working set, which grows by the points
    farthest outside its ball until the ball holds every point: the minimal ball of a subset
    that contains the whole cloud is the cloud's minimal ball (the working-set idea of
    Gärtner's pivoting, 1999). Each round costs one vectorised distance pass over the cloud,
    so large clouds never enter the Python-level recursion.

    Parameters
    ----------
    points : (n, 3) float64
        Non-empty; any configuration (duplicates, collinear, flat, far from the origin).

    Returns
    -------
    center : (3,) float64
        The points are centred on their bounding-box middle and scaled to unit size first, so
        coordinates around 1e5 lose no more precision than the input carries.
    """
    points = as_points(points)
    _require_points(points, "points")
    offset = 0.5 * (points.min(axis=0) + points.max(axis=0))
    local = points - offset
    scale = float(np.abs(local).max())
    if scale == 0.0:
        return offset
    pts = local / scale
    if len(pts) <= _SPHERE_DIRECT:
        return offset + _welzl(pts)[0] * scale
    # Start from the extremes along the coordinate axes.
    work = np.unique(np.concatenate([pts.argmin(axis=0), pts.argmax(axis=0)]))
    for _ in range(_SPHERE_ROUNDS):
        center, r2 = _welzl(pts[work])
        d2 = np.sum((pts - center) ** 2, axis=1)
        out = np.flatnonzero(d2 > r2 * (1.0 + _WELZL_SLACK) + 1e-30)
        if len(out) == 0:
            return offset + center * scale
        far = out[np.argsort(-d2[out])[:_SPHERE_ADD]]
        work = np.concatenate([work, far])
    return offset + _welzl(pts)[0] * scale


def _ritter_center(points: np.ndarray) -> np.ndarray:
    # Ritter (1990), "An efficient bounding sphere", Graphics Gems: a diameter guess from two
    # farthest-point hops, then one pass growing the sphere to each outside point.
    p0 = points[0]
    y = points[int(np.argmax(np.sum((points - p0) ** 2, axis=1)))]
    z = points[int(np.argmax(np.sum((points - y) ** 2, axis=1)))]
    center = 0.5 * (y + z)
    r = 0.5 * float(np.linalg.norm(z - y))
    i, n = 0, len(points)
    while i < n:
        d = np.linalg.norm(points[i:] - center, axis=1)
        out = np.flatnonzero(d > r)
        if len(out) == 0:
            break
        j = i + int(out[0])
        dj = float(d[out[0]])
        new_r = 0.5 * (r + dj)
        center = center + (dj - new_r) / dj * (points[j] - center)
        r = new_r
        i = j + 1
    return center


def fit_sphere(points: np.ndarray, radius: float = 0.0, method: str = "exact") -> Sphere:
    """Enclosing sphere of ``hull(points) ⊕ ball(radius)``.

    Parameters
    ----------
    points : (n, 3) float64
        Non-empty.
    radius : float
        The cloud's radius, ``>= 0``.
    method : {"exact", "ritter"}
        ``"exact"``: the minimal enclosing sphere (Welzl, move-to-front, on the centred and
        scaled points). ``"ritter"``: Ritter's (1990) fast bounding sphere, a few per cent larger.

    Returns
    -------
    Sphere
        The centre comes from the method; the radius is then measured as the largest distance
        from it to a point, plus ``radius``, so the sphere contains the cloud whatever the method.
    """
    points = as_points(points, "points")
    radius = as_radius(radius, "radius")
    _require_points(points, "sphere", radius)
    if method == "exact":
        center = min_sphere_center(points)
    elif method == "ritter":
        center = _ritter_center(points)
    else:
        raise ValueError(f"method: expected 'exact' or 'ritter', got {method!r}")
    dist = float(np.max(row_norms(points - center)))
    pad = _ROUNDING_PAD * (float(np.abs(points).max()) + radius) + _PAD_FLOOR  # see fit_obb
    return Sphere(center, dist + pad + radius)
