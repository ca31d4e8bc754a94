"""Bounding volumes (AABB, Sphere, OBB) as small array records, and their fitting from clouds.

Fitters only choose a centre or an orientation; extents and radii are then measured from the
points themselves, so every fitted volume contains its cloud by construction (up to rounding),
whatever the fitter's quality.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import hull as _hull
from ._validate import as_array, as_points, as_radius


@dataclass(frozen=True)
class AABB:
    """Axis-aligned box ``[lo, hi]``.

    Attributes
    ----------
    lo, hi : (3,) float64
        Corners; an empty box has ``lo = +inf`` and ``hi = -inf``.
    """

    lo: np.ndarray
    hi: np.ndarray

    def volume(self) -> float:
        """Volume (0 for an empty box)."""
        return float(np.prod(np.maximum(self.hi - self.lo, 0.0)))

    def contains(self, points, rtol: float = 0.0) -> np.ndarray:
        """``(n,) bool``: which of ``points`` ``(n, 3)`` lie in the box, widened by ``rtol`` x size."""
        p = as_array(points, "points", (None, 3))
        pad = rtol * max(float(np.max(np.abs(np.concatenate([self.lo, self.hi])))), 1.0)
        return np.all((p >= self.lo - pad) & (p <= self.hi + pad), axis=1)


@dataclass(frozen=True)
class Sphere:
    """Ball of ``radius`` around ``center`` ``(3,) float64``."""

    center: np.ndarray
    radius: float

    def volume(self) -> float:
        """Volume."""
        return 4.0 / 3.0 * np.pi * self.radius**3

    def contains(self, points, rtol: float = 0.0) -> np.ndarray:
        """``(n,) bool``: which of ``points`` ``(n, 3)`` lie in the ball, widened by ``rtol``."""
        p = as_array(points, "points", (None, 3))
        pad = rtol * max(self.radius, float(np.max(np.abs(self.center))), 1.0)
        return np.linalg.norm(p - self.center, axis=1) <= self.radius + pad


@dataclass(frozen=True)
class OBB:
    """Oriented box.

    Attributes
    ----------
    center : (3,) float64
    rotation : (3, 3) float64
        Orthonormal; its columns are the box axes.
    half_extents : (3,) float64
        Half side lengths along the axes.
    """

    center: np.ndarray
    rotation: np.ndarray
    half_extents: np.ndarray

    def volume(self) -> float:
        """Volume."""
        return float(8.0 * np.prod(self.half_extents))

    def contains(self, points, rtol: float = 0.0) -> np.ndarray:
        """``(n,) bool``: which of ``points`` ``(n, 3)`` lie in the box, widened by ``rtol``."""
        p = as_array(points, "points", (None, 3))
        local = (p - self.center) @ self.rotation
        pad = rtol * max(float(np.max(self.half_extents)), float(np.max(np.abs(self.center))), 1.0)
        return np.all(np.abs(local) <= self.half_extents + pad, axis=1)


def _require_points(points: np.ndarray, what: str) -> None:
    if len(points) == 0:
        raise ValueError(f"{what}: the cloud is empty and bounds nothing")


def fit_aabb(points: np.ndarray, radius: float = 0.0) -> AABB:
    """Exact AABB of ``hull(points) ⊕ ball(radius)``; an empty cloud gives the empty box.

    Parameters
    ----------
    points : (n, 3) float64
    radius : float
    """
    if len(points) == 0:
        return AABB(np.full(3, np.inf), np.full(3, -np.inf))
    return AABB(points.min(axis=0) - radius, points.max(axis=0) + radius)


def box_from_axes(points: np.ndarray, radius: float, rotation: np.ndarray) -> OBB:
    """The smallest box with the given axes that contains the cloud.

    Parameters
    ----------
    points : (n, 3) float64
    radius : float
    rotation : (3, 3) float64
        Orthonormal; columns are the axes.
    """
    local = points @ rotation
    lo, hi = local.min(axis=0), local.max(axis=0)
    center = rotation @ ((lo + hi) / 2.0)
    return OBB(center, rotation, (hi - lo) / 2.0 + radius)


def pca_axes(points: np.ndarray) -> np.ndarray:
    """Principal axes of a cloud, ``(3, 3) float64`` with columns as axes, right-handed."""
    _, axes, _ = _hull.affine_basis(points)
    rot = axes.T.copy()
    if np.linalg.det(rot) < 0:
        rot[:, 2] = -rot[:, 2]
    return rot


def fit_obb(points: np.ndarray, radius: float = 0.0, method: str = "optimal") -> OBB:
    """Oriented box of ``hull(points) ⊕ ball(radius)``.

    Parameters
    ----------
    points : (n, 3) float64
    radius : float
    method : {"optimal", "pca"}
        ``"pca"``: principal axes of the hull vertices. ``"optimal"``: near-minimal volume.
    """
    _require_points(points, "obb")
    verts = _hull.hull_vertices(points)
    if method == "pca":
        return box_from_axes(verts, radius, pca_axes(verts))
    if method == "optimal":
        raise NotImplementedError("optimal OBB: being written")
    raise ValueError(f"method: expected 'optimal' or 'pca', got {method!r}")


# Relative slack of the "point outside the ball" test in Welzl's algorithm (on squared radii of
# a cloud scaled to unit size): points this close to the sphere count as inside, which keeps
# rounding from re-triggering recursion; the fitted radius is re-measured afterwards, so the slack
# can only cost ~5e-13 relative radius, never containment.
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
            # Circumcentre of a triangle in 3D (RTCD §3.? / standard identity).
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
            c = pts[sub[0]] + (float(u @ u) * np.cross(v, w) + float(v @ v) * np.cross(w, u)) / (2.0 * ww)
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


def min_sphere_center(points: np.ndarray) -> np.ndarray:
    """Centre of the minimal enclosing sphere of ``points`` (Welzl's algorithm, move-to-front).

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
    offset = 0.5 * (points.min(axis=0) + points.max(axis=0))
    local = points - offset
    scale = float(np.abs(local).max())
    if scale == 0.0:
        return offset
    # Random order gives Welzl's expected linear time; a fixed seed keeps results reproducible.
    order = np.random.default_rng(0).permutation(len(local))
    pts = np.ascontiguousarray(local[order] / scale)
    center, _ = _welzl_mtf(pts, len(pts), [])
    return offset + center * scale


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
    _require_points(points, "sphere")
    if method == "exact":
        center = min_sphere_center(points)
    elif method == "ritter":
        center = _ritter_center(points)
    else:
        raise ValueError(f"method: expected 'exact' or 'ritter', got {method!r}")
    return Sphere(center, float(np.sqrt(np.max(np.sum((points - center) ** 2, axis=1)))) + radius)
