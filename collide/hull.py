"""Convex hulls that never fail: reduction to hull vertices, ball polytopes, exact hull ∩ hull.

Qhull (through scipy) raises on flat, collinear, single-point and duplicate input, and loses
precision far from the origin. Every routine here first finds the affine dimension of the input
(SVD of the centred points), works in that dimension, and falls back to returning its input
unchanged, which is always conservative, if Qhull still refuses.

Exact hull intersections go through manifold3d (double precision, robust booleans); this module
and ``csg`` are the only ones that import it (DESIGN.md, layers).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ._validate import as_array, as_count, as_points, as_radius

__all__ = [
    "FLAT_TOL", "MAX_BALL_LEVEL", "MAX_COORDINATE", "MIN_EXTENT", "affine_basis", "ball_polytope", "clip_hull",
    "extent", "hull_indices", "hull_vertices", "intersect_hulls", "minkowski_ball", "require_bounded",
    "require_not_tiny",
]

# Relative size of a singular value, against the largest, below which a direction is treated as
# flat. 1e-12 keeps the neglected thickness at the level of float64 rounding of the coordinates.
FLAT_TOL = 1e-12


# Largest coordinate (plus radius) the hull and fitting routines accept: their means, squared
# distances and SVDs overflow float64 beyond about 1e154 (at 1e306 the mean of a cloud overflowed
# and hull reduction collapsed it to one point, silently; found 2026-11-22).
MAX_COORDINATE = 1e150

# Smallest non-zero `extent` (the points' largest spread or the radius) the routines whose
# error terms square a length accept (the broad phase's geoms, `collide.swept`, `collide.deform`):
# squares of lengths below ~1.5e-154 underflow (a swept cloud of 1e-163 lost its deviation term,
# a deformed one its interpolation error: review, 2026-11-30). The mirror of `MAX_COORDINATE`; a
# single point of radius 0 (extent 0) stays valid.
MIN_EXTENT = 1e-150


def extent(points: np.ndarray, radius: float = 0.0) -> float:
    """A cloud's extent: the larger of its points' largest spread along an axis and its radius.

    Parameters
    ----------
    points : (n, 3) float64, non-empty
    radius : float

    Returns
    -------
    float
    """
    return max(float(np.ptp(points, axis=0).max()), radius)


def require_not_tiny(points: np.ndarray, what: str, radius: float = 0.0) -> None:
    """Raise ValueError, naming ``what``, when the `extent` of ``points`` ``(n, 3)`` (non-empty)
    and ``radius`` is non-zero and below `MIN_EXTENT`."""
    ext = extent(points, radius)
    if 0.0 < ext < MIN_EXTENT:
        raise ValueError(f"{what}: extent {ext:.3g} is below {MIN_EXTENT:g}, the smallest non-zero one "
                         "supported (squared lengths would underflow float64; scale the input)")


# Finest ball polytope: 10 * 4**level + 2 points, 163 842 at level 7 (each level four times the
# last's points and work; a level-9 request was impractical: review, 2026-11-22).
MAX_BALL_LEVEL = 7


def require_bounded(points: np.ndarray, what: str, radius: float = 0.0) -> None:
    """Raise ValueError, naming ``what``, when ``points`` ``(n, 3)`` are empty or, plus
    ``radius``, reach beyond `MAX_COORDINATE`."""
    if len(points) == 0:
        raise ValueError(f"{what}: the cloud is empty and bounds nothing")
    big = float(np.abs(points).max()) + radius
    if not big <= MAX_COORDINATE:
        raise ValueError(f"{what}: coordinates plus radius reach {big:.3g}, beyond {MAX_COORDINATE:g} "
                         "(squared distances would overflow float64)")


def affine_basis(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Centre and principal directions of a point set, and its affine dimension.

    Parameters
    ----------
    points : (n, 3) float64
        Non-empty point set.

    Returns
    -------
    center : (3,) float64
        Mean of the points.
    axes : (3, 3) float64
        Rows are the principal directions, largest spread first.
    rank : int
        0 (a single point, up to duplicates), 1 (collinear), 2 (flat) or 3.
    """
    points = as_points(points)
    require_bounded(points, "points")
    center = points.mean(axis=0)
    centred = points - center
    extent = float(np.abs(centred).max()) if len(points) > 1 else 0.0
    # A spread at the rounding level of the coordinates themselves is a single point. (It was
    # 1e-12 * |centre|, thousands of ulps: a 1e-5-wide cloud at 7e6 became one point.)
    if extent <= 64.0 * np.finfo(np.float64).eps * float(np.abs(center).max()) or extent == 0.0:
        return center, np.eye(3), 0
    # Reduced SVD: full_matrices=True would build an (n, n) matrix (out of memory at 1e5 points).
    _, s, vt = np.linalg.svd(centred, full_matrices=False)
    if len(s) < 3:  # two points: rank <= 1; complete the first direction to a basis
        u = vt[0]
        helper = np.eye(3)[int(np.argmin(np.abs(u)))]
        v = np.cross(u, helper)
        v /= np.linalg.norm(v)
        vt = np.array([u, v, np.cross(u, v)])
        s = np.concatenate([s, np.zeros(3 - len(s))])
    # Thickness below the rounding noise of the coordinates (a flat set rotated far from the
    # origin picks up ~eps * |x| of it per point) or below FLAT_TOL of the spread is flatness.
    rank = int(np.sum(s > max(FLAT_TOL * s[0], _noise(points))))
    return center, vt, rank


def _noise(points: np.ndarray) -> float:
    # Rounding noise of a spread measured on these coordinates (a singular value of the centred
    # points below it is rounding, not shape).
    return 64.0 * np.finfo(np.float64).eps * float(np.abs(points).max()) * np.sqrt(len(points))


def hull_indices(points: np.ndarray) -> np.ndarray:
    """Indices of the points that span the convex hull, robust to every degenerate input.

    Parameters
    ----------
    points : (n, 3) float64

    Returns
    -------
    index : (m,) int64
        Sorted indices into ``points``; ``hull(points[index]) == hull(points)`` up to rounding
        (a flat set keeps its polygon's vertices, a collinear set its two extremes, a single
        point one copy). If Qhull refuses even after dimension reduction, all indices of the
        unique points are returned (conservative).
    """
    points = as_points(points)
    n = len(points)
    if n <= 1:
        return np.arange(n)
    center, axes, rank = affine_basis(points)
    if rank == 0:
        return np.array([0])
    local = (points - center) @ axes.T
    # Reduction keeps every dimension above the rounding noise, not only those above FLAT_TOL of
    # the spread: a plate 1e-13 as thick as it is wide is flat for affine_basis, but keeping one
    # face's corners would lose its thickness, thousands of ulps (review, 2026-11-21). The hull is
    # taken on whitened coordinates (each principal spread scaled to one): the same vertices,
    # and Qhull sees a well-conditioned set however thin the input.
    spread = np.ptp(local, axis=0)
    keep = int(np.sum(spread > _noise(points) / np.sqrt(n)))
    rank = max(rank, keep)
    if rank == 1:
        return np.unique([int(np.argmin(local[:, 0])), int(np.argmax(local[:, 0]))])
    if n <= rank + 1:
        return np.arange(n)
    # (a spread of 0 is kept as 1: subnormal clouds have dimensions the noise estimate keeps
    # that rounded to nothing, and 0/0 made NaN coordinates for Qhull)
    local = local[:, :rank] / np.where(spread[:rank] > 0.0, spread[:rank], 1.0)
    try:
        return np.sort(ConvexHull(local).vertices)
    except (QhullError, ValueError):
        _, first = np.unique(points, axis=0, return_index=True)
        return np.sort(first)


def hull_vertices(points: np.ndarray) -> np.ndarray:
    """The points of ``points`` that span its convex hull, ``(m, 3) float64`` (see `hull_indices`)."""
    points = as_points(points)
    return points[hull_indices(points)]


@lru_cache(maxsize=8)
def _ball_polytope(level: int) -> np.ndarray:
    # Vertices of an icosahedron subdivided ``level`` times, pushed to the unit sphere: an
    # inscribed polytope. Dividing by its inradius (the smallest facet-plane distance) makes it
    # circumscribed: the unit ball touches every facet plane from inside. Level 1: 42 points,
    # circumradius 1.0705 (a ball of radius r becomes a polytope at most 7.1 % wider).
    t = (1.0 + 5.0**0.5) / 2.0
    v = np.array(
        [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], dtype=float)
    v /= np.linalg.norm(v, axis=1)[:, None]
    for _ in range(level):
        faces = ConvexHull(v).simplices
        mids = {}
        pts = list(v)
        for f in faces:
            for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
                key = (min(a, b), max(a, b))
                if key not in mids:
                    m = v[a] + v[b]
                    mids[key] = len(pts)
                    pts.append(m / np.linalg.norm(m))
        v = np.array(pts)
    hull = ConvexHull(v)
    inradius = float(np.min(-hull.equations[:, 3]))
    out = v / inradius * (1.0 + 1e-12)
    out.setflags(write=False)
    return out


def ball_polytope(level: int = 1) -> np.ndarray:
    """Vertices of a polytope that contains the unit ball.

    Parameters
    ----------
    level : int
        Icosahedron subdivision level: 0 gives 12 points (circumradius 1.258), 1 gives 42
        (1.0705), 2 gives 162 (1.018).

    Returns
    -------
    points : (m, 3) float64, read-only
    """
    return _ball_polytope(as_count(level, "level", 0, MAX_BALL_LEVEL))


def minkowski_ball(points: np.ndarray, radius: float, level: int = 1) -> np.ndarray:
    """Points whose hull contains ``hull(points) ⊕ ball(radius)``, reduced to hull vertices.

    Parameters
    ----------
    points : (n, 3) float64
    radius : float
        ``>= 0``; zero returns ``points`` unchanged.
    level : int
        Tightness of the ball polytope (see `ball_polytope`).

    Returns
    -------
    points : (m, 3) float64
    """
    points = as_points(points)
    radius = as_radius(radius)
    level = as_count(level, "level", 0, MAX_BALL_LEVEL)
    if radius == 0.0 or len(points) == 0:
        return points
    base = hull_vertices(points)
    out = (base[:, None, :] + radius * ball_polytope(level)[None, :, :]).reshape(-1, 3)
    return hull_vertices(out)


def _manifold_hull(points: np.ndarray):
    import manifold3d

    return manifold3d.Manifold.hull_points(np.ascontiguousarray(points, dtype=np.float64))


def _halfspaces(points: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    # Halfspaces ``normals @ x <= offsets`` whose intersection is hull(points), each pushed out by
    # ``tol`` (conservative). Flat, collinear and single-point sets get their affine hull as
    # pairs of opposite halfspaces plus the facets of their lower-dimensional hull.
    center, axes, rank = affine_basis(points)
    normals, offsets = [], []
    local = (points - center) @ axes[:rank].T
    if rank == 3:
        eq = ConvexHull(local).equations  # n @ (x - c) + e <= 0 inside
        normals.append(eq[:, :3] @ axes)
        offsets.append(-eq[:, 3] + normals[-1] @ center)
    elif rank == 2:
        eq = ConvexHull(local).equations
        normals.append(eq[:, :2] @ axes[:2])
        offsets.append(-eq[:, 2] + normals[-1] @ center)
    elif rank == 1:
        normals.append(np.array([axes[0], -axes[0]]))
        offsets.append(np.array([local[:, 0].max(), -local[:, 0].min()]) + normals[-1] @ center)
    flat = axes[rank:]
    if len(flat):
        # Off-plane directions: the set's thickness (at most the rounding noise) on both sides.
        off = (points - center) @ flat.T
        normals.append(np.concatenate([flat, -flat]))
        offsets.append(np.concatenate([off.max(axis=0), -off.min(axis=0)]) + normals[-1] @ center)
    return np.concatenate(normals), np.concatenate(offsets) + tol


def clip_hull(points: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Vertices of ``hull(points) ∩ {x : normals @ x <= offsets}``, by clipping one plane at a time.

    Every vertex of a convex polytope cut by a plane is either a vertex inside the plane or the
    crossing of an edge with it; crossings of *all* inside-outside pairs of vertices include
    those of the edges and lie in the cut polytope themselves, so their hull is exactly the cut
    (no edge structure needed, and flat or collinear polytopes need no special case).

    Parameters
    ----------
    points : (n, 3) float64
    normals : (h, 3) float64
    offsets : (h,) float64

    Returns
    -------
    points : (m, 3) float64
        ``(0, 3)`` when the intersection is empty.
    """
    normals = as_array(normals, "normals", (None, 3))
    offsets = as_array(offsets, "offsets", (len(normals),))
    pts = hull_vertices(points)
    for n, d in zip(normals, offsets):
        s = pts @ n - d
        inside = s <= 0.0
        if inside.all():
            continue
        if not inside.any():
            return np.zeros((0, 3))
        pin, pout, sin, sout = pts[inside], pts[~inside], s[inside], s[~inside]
        t = sin[:, None] / (sin[:, None] - sout[None, :])  # in [0, 1): sin <= 0 < sout
        cross = pin[:, None, :] + t[:, :, None] * (pout[None, :, :] - pin[:, None, :])
        pts = hull_vertices(np.concatenate([pin, cross.reshape(-1, 3)]))
    return pts


def _solid(points: np.ndarray) -> bool:
    # Full-dimensional and not thin: manifold3d's hull and boolean lose or misplace whole parts
    # of hulls thinner than about 1e-6 of their width (measured: up to 1.6x the size for 1e-8),
    # so anything thinner than 1e-4 goes to exact clipping instead.
    center, axes, rank = affine_basis(points)
    if rank < 3:
        return False
    widths = np.ptp((points - center) @ axes.T, axis=0)
    return bool(widths[2] >= 1e-4 * widths[0])


# `intersect_hulls`: the smallest extent of one set, relative to the other's, that manifold3d is
# given. Its result is off by ~1e-13 of the larger set (its own precision), which is that much
# relative to the smaller one only when the two are comparable: a ball 2**-40 the size of a box,
# straddling its face, came back without a third of its half (0.9 of its radius), and a set
# 2**-270 of the other collapsed or hung (reviews, 2026-11-30). Below this the pair is clipped
# exactly, a constant factor slower.
_MANIFOLD_MIN_RATIO = 2.0 ** -10


def intersect_hulls(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Vertices of ``hull(a) ∩ hull(b)``: manifold3d for solid hulls, exact clipping otherwise.

    Both sets are first moved to their overlap's centre (and, for manifold3d, scaled to unit
    size): far from the origin manifold3d's hulls lost volume (a 0.01-wide pair of hulls at
    6e4 intersected to nothing) and `affine_basis` took a 1e-5-wide set at 7e6 for a single
    point. Flat, collinear, single-point and thin inputs (manifold3d misplaces hulls thinner
    than about 1e-6 of their width), hulls that only touch, and any case the boolean drops as
    empty are clipped plane by plane (`clip_hull`) against halfspaces pushed out by ``1e-12``
    times the coordinate scale (conservative at rounding level), so touching sets give a thin
    valid cloud; truly disjoint hulls give ``(0, 3)``.

    Parameters
    ----------
    a, b : (n, 3), (m, 3) float64
        Non-empty point sets.

    Returns
    -------
    points : (k, 3) float64
    """
    a = as_points(a, "a")
    b = as_points(b, "b")
    if len(a) == 0 or len(b) == 0:
        raise ValueError(f"{'a' if len(a) == 0 else 'b'}: must be a non-empty point set")
    lo = np.maximum(a.min(axis=0), b.min(axis=0))
    hi = np.minimum(a.max(axis=0), b.max(axis=0))
    scale = max(float(np.abs(a).max()), float(np.abs(b).max()), float(np.ptp(a, axis=0).max()),
                float(np.ptp(b, axis=0).max()), 1e-300)
    # eps covers the rounding of the input coordinates and of the shift to the centre below.
    eps = 1e-12 * scale
    if np.any(lo > hi + 4 * eps):
        return np.zeros((0, 3))
    center = 0.5 * (np.minimum(lo, hi) + np.maximum(lo, hi))
    a = hull_vertices(a - center)
    b = hull_vertices(b - center)
    ext_a, ext_b = float(np.ptp(a, axis=0).max()), float(np.ptp(b, axis=0).max())
    size = max(ext_a, ext_b)
    # sets of very different sizes are clipped, not given to manifold3d (`_MANIFOLD_MIN_RATIO`):
    # the smaller set by the larger's halfspaces (the result then lies in the smaller, as tight)
    comparable = min(ext_a, ext_b) >= _MANIFOLD_MIN_RATIO * size
    if size > 0.0 and comparable and _solid(a) and _solid(b):
        inter = _manifold_hull(a / size) ^ _manifold_hull(b / size)
        if not inter.is_empty():
            return np.array(inter.to_mesh64().vert_properties[:, :3], dtype=np.float64) * size + center
    if not comparable and ext_b < ext_a:
        a, b = b, a
    try:
        normals, offsets = _halfspaces(b, eps)
    except (QhullError, ValueError):
        # Qhull refused b's facets: clip by b's box instead (it contains hull(b)).
        normals = np.concatenate([np.eye(3), -np.eye(3)])
        offsets = np.concatenate([b.max(axis=0), -b.min(axis=0)]) + eps
    out = clip_hull(a, normals, offsets)
    return out + center if len(out) else out
