"""Brute-force twins of `collide.distance`: exact signed distances without GJK or EPA.

- `polytope_signed_distance`: the signed distance of ``hull(P) ⊕ ball(rp)`` and
  ``hull(Q) ⊕ ball(rq)`` as the signed distance of the origin to the hull of the Minkowski
  difference ``{p - q}`` (every pair), from scipy's Qhull: the nearest facet plane when the
  origin is inside, the nearest facet triangle when outside; flat, collinear and single-point
  differences are handled in their own dimension. (`collide.testing.gjk_distance` is the broad
  phase's twin, a plain GJK without penetration: not an independent oracle for this.)
- `point_signed_distance`: exact signed distance of a point to a cylinder, cone or ellipsoid
  (closed forms in the axial half-plane; the ellipsoid by the monotone root of Eberly's
  "Distance from a point to an ellipse, an ellipsoid, or a hyperellipsoid", 2013).
- `support_scan`: the support point of a posed cloud by a scan of every point, the twin of
  `collide._kernels.support.support`'s hill-climb over a hull's vertex graph.
- `inner_cloud`: points on a curved primitive's surface whose hull lies within a stated
  distance ``delta`` of the primitive (a dense-sampled reference with known error: the true
  signed distance lies in ``[sd(samples) - delta_a - delta_b, sd(samples)]``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ..convex import Cone, Cylinder, Ellipsoid

__all__ = ["inner_cloud", "minkowski_difference", "origin_signed_distance", "point_signed_distance", "support_scan",
           "polytope_signed_distance"]

# Relative thickness below which a Minkowski difference is treated as flat (or a line, or a
# point): the error is at most that thickness.
FLAT_TOL = 1e-11


def support_scan(points, rotation, translation, direction) -> tuple[int, float]:
    """Support of ``rotation @ points + translation`` along ``direction``, by scanning every point.

    Parameters
    ----------
    points : (n, 3) array_like of float
    rotation : (3, 3) array_like of float
    translation : (3,) array_like of float
    direction : (3,) array_like of float

    Returns
    -------
    index : int
        The first point of largest ``direction . x`` (world frame).
    value : float
        That largest value.
    """
    w = np.asarray(points, float) @ np.asarray(rotation, float).T + np.asarray(translation, float)
    h = w @ np.asarray(direction, float)
    i = int(np.argmax(h))
    return i, float(h[i])


def minkowski_difference(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """``(n m, 3) float64``: every ``p - q`` for ``P (n, 3)``, ``Q (m, 3)`` (duplicates removed)."""
    P = np.asarray(P, float).reshape(-1, 3)
    Q = np.asarray(Q, float).reshape(-1, 3)
    return np.unique((P[:, None, :] - Q[None, :, :]).reshape(-1, 3), axis=0)


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    # Distance of point p (3,) to segments a b ((k, 3) each).
    ab = b - a
    ll = np.einsum("ij,ij->i", ab, ab)
    t = np.where(ll > 0, np.einsum("ij,ij->i", p - a, ab) / np.where(ll > 0, ll, 1.0), 0.0)
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(a + t[:, None] * ab - p, axis=1)


def _triangle_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    # Distance of point p (3,) to triangles (a, b, c) ((k, 3) each): the foot of the
    # perpendicular when it is inside, else the nearest edge.
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    ok = nn > 0
    s = np.where(ok, np.einsum("ij,ij->i", n, p - a) / np.where(ok, nn, 1.0), 0.0)
    foot = p - s[:, None] * n
    inside = ok.copy()
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(v - u, foot - u), n) >= 0
    edge = np.minimum(np.minimum(_segment_distance(p, a, b), _segment_distance(p, b, c)),
                      _segment_distance(p, c, a))
    plane = np.abs(s) * np.sqrt(nn)
    return np.where(inside, plane, edge)


def _polygon_distance(o: np.ndarray, pts: np.ndarray) -> float:
    # Distance of 2D point o to the convex hull of 2D points pts (0 inside).
    try:
        h = ConvexHull(pts)
    except (QhullError, ValueError):
        # Collinear in the plane after all: the segment between the extremes.
        d = pts[np.argmax(np.linalg.norm(pts - pts[0], axis=1))] - pts[0]
        t = (pts - pts[0]) @ d
        a3 = np.append(pts[np.argmin(t)], 0.0)[None]
        b3 = np.append(pts[np.argmax(t)], 0.0)[None]
        return float(_segment_distance(np.append(o, 0.0), a3, b3)[0])
    if np.all(h.equations[:, :2] @ o + h.equations[:, 2] <= 0):
        return 0.0
    a = np.c_[pts[h.simplices[:, 0]], np.zeros(len(h.simplices))]
    b = np.c_[pts[h.simplices[:, 1]], np.zeros(len(h.simplices))]
    return float(_segment_distance(np.append(o, 0.0), a, b).min())


def origin_signed_distance(M: np.ndarray) -> float:
    """Signed distance of the origin to ``hull(M)`` (``M (k, 3)``): positive outside, minus the
    distance to the boundary inside; a hull thinner than `FLAT_TOL` of its spread has no inside.
    Computed on ``M`` scaled by a power of two to unit size (exact): the triangle distances'
    squared cross products under- and overflowed at 1e-100 and 1e100 (helper-78, 2026-12-02)."""
    M = np.asarray(M, float).reshape(-1, 3)
    top = float(np.abs(M).max()) if M.size else 0.0
    if top > 0.0 and math.isfinite(top):
        e = math.frexp(top)[1]
        if e != 0:
            return float(np.ldexp(origin_signed_distance(np.ldexp(M, -e)), e))  # inf past the float range
    c = M.mean(axis=0)
    X = M - c
    spread = float(np.abs(X).max()) if len(M) > 1 else 0.0
    if spread == 0.0:
        return float(np.linalg.norm(c))
    _, s, vt = np.linalg.svd(X, full_matrices=False)
    s = np.concatenate([s, np.zeros(3 - len(s))])
    rank = int(np.sum(s > FLAT_TOL * s[0]))
    if rank == 3:
        try:
            h = ConvexHull(M)
        except QhullError:
            rank = 2
        else:
            off = h.equations[:, :3] @ np.zeros(3) + h.equations[:, 3]  # n . 0 + o
            if np.all(off <= 0):
                return float(off.max())  # inside: minus the nearest facet plane's distance
            tri = M[h.simplices]
            return float(_triangle_distance(np.zeros(3), tri[:, 0], tri[:, 1], tri[:, 2]).min())
    if len(vt) < 3:
        u = vt[0]
        w = np.cross(u, np.eye(3)[int(np.argmin(np.abs(u)))])
        w /= np.linalg.norm(w)
        vt = np.array([u, w, np.cross(u, w)])
    o = -c @ vt.T  # the origin in the principal frame
    local = X @ vt.T
    if rank == 2:
        return float(math.hypot(o[2], _polygon_distance(o[:2], local[:, :2])))
    if rank == 1:
        t = float(np.clip(o[0], local[:, 0].min(), local[:, 0].max()))
        return float(math.sqrt((o[0] - t) ** 2 + o[1] ** 2 + o[2] ** 2))
    return float(np.linalg.norm(c))


def polytope_signed_distance(P, Q, radius_p: float = 0.0, radius_q: float = 0.0) -> float:
    """Exact signed distance of ``hull(P) ⊕ ball(radius_p)`` and ``hull(Q) ⊕ ball(radius_q)``.

    Parameters
    ----------
    P : (n, 3) array_like of float
    Q : (m, 3) array_like of float
    radius_p, radius_q : float

    Returns
    -------
    float
        The gap when apart, minus the penetration depth when overlapping: the signed distance of
        the origin to ``hull({p - q})``, minus the radii.
    """
    return origin_signed_distance(minkowski_difference(P, Q)) - radius_p - radius_q


def _box_sd(rho: float, z: float, R: float, zlo: float, zhi: float) -> float:
    # Signed distance of (rho, z), rho >= 0, to the rectangle [0, R] x [zlo, zhi] of the
    # axial half-plane, the axis edge rho = 0 excluded from the boundary (a solid of revolution).
    dr = rho - R
    dz = max(zlo - z, z - zhi)
    if dr <= 0 and dz <= 0:
        return max(dr, dz)
    return math.hypot(max(dr, 0.0), max(dz, 0.0))


def _segment_2d(p, a, b):
    ab = (b[0] - a[0], b[1] - a[1])
    ll = ab[0] ** 2 + ab[1] ** 2
    t = 0.0 if ll == 0 else min(max(((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1]) / ll, 0.0), 1.0)
    return math.hypot(p[0] - a[0] - t * ab[0], p[1] - a[1] - t * ab[1])


def _ellipsoid_sd(r: np.ndarray, y: np.ndarray) -> float:
    # Eberly's method: the closest boundary point is x_i = r_i^2 y_i / (r_i^2 + t) for the root t
    # of F(t) = sum (r_i y_i / (r_i^2 + t))^2 - 1, unique on t > -min r_i^2, where F decreases.
    # Solved for u = t + r_m^2 > 0 (r_m the shortest radius), with r_i^2 + t = (r_i - r_m)(r_i + r_m)
    # + u: r_i^2 + t computed as such lost every digit near a near-sphere's centre, where t is
    # -r_m^2 to within the point's tiny offset (helper-52: -1.0000888 for a unit near-sphere).
    # A shortest axis i with y_i > 0 makes F >= 0 at u = r_i y_i (its term alone is 1), and F <= 0
    # at u = |r y|. A point on the plane of every shortest axis (y_i = 0 there; Eberly 2013,
    # "Distance from a point to an ellipse, an ellipsoid, or a hyperellipsoid", the case y_2 = 0):
    # F's limit at u = 0+ is G = sum over the other axes of (r_i y_i / delta_i)^2 - 1; G > 0: the
    # root is on (0, |r y|); G <= 0 (an interior point near the centre): u = 0, the other axes'
    # x_i = r_i^2 y_i / delta_i and the rest of the unit sum on a shortest axis.
    y = np.abs(y)
    if not np.all(r > 0):
        raise ValueError("needs radii > 0")
    m = int(np.argmin(r))
    delta = (r - r[m]) * (r + r[m])  # r_i^2 - r_m^2 >= 0, exact (zero) where r_i == r_m
    short = delta == 0.0
    inside = float(np.sum((y / r) ** 2)) < 1.0

    def F(u):
        return float(np.sum((r * y / (delta + u)) ** 2) - 1.0)

    if np.any(y[short] > 0):
        lo = float(np.max(r[short] * y[short]))
    else:
        o = ~short
        x = np.zeros(3)
        x[o] = r[o] ** 2 * y[o] / delta[o]
        rest = 1.0 - float(np.sum((x[o] / r[o]) ** 2))
        if rest >= 0.0:
            x[m] = r[m] * math.sqrt(rest)
            d = float(np.linalg.norm(x - y))
            return -d if inside else d
        lo = 0.0
    hi = float(np.linalg.norm(r * y))
    for _ in range(2000):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if F(mid) > 0:
            lo = mid
        else:
            hi = mid
    u = 0.5 * (lo + hi)
    x = r * r * y / (delta + u)
    d = float(np.linalg.norm(x - y))
    return -d if inside else d


def point_signed_distance(shape, point) -> float:
    """Exact signed distance of a point (shape frame) to a `Cylinder`, `Cone` or `Ellipsoid`.

    Parameters
    ----------
    shape : Cylinder, Cone or Ellipsoid
    point : (3,) array_like of float

    Returns
    -------
    float
        Distance to the solid when outside, minus the distance to its surface when inside.
    """
    p = np.asarray(point, float)
    rho = math.hypot(p[0], p[1])
    if isinstance(shape, Cylinder):
        return _box_sd(rho, p[2], shape.radius, -shape.half_height, shape.half_height)
    if isinstance(shape, Cone):
        R, H = shape.radius, shape.height
        q = (rho, p[2])
        base = _segment_2d(q, (0.0, 0.0), (R, 0.0))
        slant = _segment_2d(q, (R, 0.0), (0.0, H))
        # (the height and radius bounds are implied unless the cone is flat or a needle)
        inside = 0 <= p[2] <= H and rho <= R and rho * H + p[2] * R <= R * H
        if inside:
            return -min(base, slant)
        return min(base, slant, _segment_2d(q, (0.0, 0.0), (0.0, H)))
    if isinstance(shape, Ellipsoid):
        return _ellipsoid_sd(np.asarray(shape.radii, float), p)
    raise ValueError(f"shape: expected a Cylinder, Cone or Ellipsoid, got {type(shape).__name__}")


def inner_cloud(shape, samples: int = 1024) -> tuple[np.ndarray, float]:
    """Surface points of a curved primitive and how far their hull may be inside it.

    Parameters
    ----------
    shape : Cylinder or Cone
    samples : int
        Points around each rim circle.

    Returns
    -------
    points : (k, 3) float64
        On the true surface (shape frame): ``hull(points)`` is inside the solid.
    delta : float
        ``h_shape(u) - h_hull(u) <= delta`` for every unit ``u`` (a rim circle of radius ``r``
        against its inscribed ``samples``-gon: ``r (1 - cos(π / samples))``).
    """
    ang = 2 * np.pi * np.arange(samples) / samples
    ring = np.c_[np.cos(ang), np.sin(ang), np.zeros(samples)]
    delta = shape.radius * (1.0 - math.cos(math.pi / samples)) * (1 + 1e-9)
    if isinstance(shape, Cylinder):
        r, h = shape.radius, shape.half_height
        pts = np.concatenate([ring * r + [0, 0, -h], ring * r + [0, 0, h]])
        return pts, delta
    if isinstance(shape, Cone):
        pts = np.concatenate([ring * shape.radius, [[0.0, 0.0, shape.height]]])
        return pts, delta
    raise ValueError(f"shape: expected a Cylinder or Cone, got {type(shape).__name__}")
