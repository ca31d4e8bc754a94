"""The one representation: a point cloud plus a radius, and its operators (Stürzlinger 1996, §3).

A `PointCloud` bounds the set ``hull(points) ⊕ ball(radius)``. Transforms move the points (the
paper's §3.2: a box of a rotated box grows, the hull of moved points does not); unions append and
hull-reduce past a threshold (§3.3, 256 points in the paper); intersections use the exact
intersection of the two hulls; differences keep the first operand.
"""

from __future__ import annotations

from typing import Iterable

import numpy as np

from . import hull as _hull
from . import volumes as _volumes
from ._validate import as_affine, as_count, as_points, as_radius

__all__ = [
    "BALL_LEVEL", "PointCloud", "SIMILARITY_TOL", "difference", "intersection", "union",
]

# Ball-polytope level used when a radius must become points (general affine maps, mixed radii,
# intersections): 42 points, at most 7.1 % wider than the ball (see hull.ball_polytope).
BALL_LEVEL = 1

# A linear map whose singular values agree to this relative tolerance counts as a similarity: the
# radius is scaled by the largest singular value, a ball that contains the mapped ball (an
# ellipsoid), at most 0.1 % too wide along its shortest axis; the polytope it would otherwise
# become is up to 7.1 % too wide. At 1e-9, rotations rounded to float32 (|R^T R - I| ~ 1e-7)
# turned every sphere geom into a polytope (review of the test twins, 2026-11-21).
SIMILARITY_TOL = 1e-3


class PointCloud:
    """A convex bounding cloud: ``hull(points) ⊕ ball(radius)``.

    Parameters
    ----------
    points : (n, 3) array_like of float
        Finite points; stored as a read-only ``float64`` copy. ``n`` may be zero (the empty set).
    radius : float, default 0.0
        Non-negative radius of the ball added to the hull.

    Examples
    --------
    >>> capsule = PointCloud([[0, 0, -1], [0, 0, 1]], radius=0.5)
    >>> len(capsule)
    2
    """

    __slots__ = ("_points", "_radius")

    def __init__(self, points, radius: float = 0.0):
        pts = np.array(as_points(points, "points"), dtype=np.float64, copy=True)
        pts.setflags(write=False)
        self._points = pts
        self._radius = as_radius(radius, "radius")

    def __reduce__(self):
        # Rebuilt through __init__ (copy, pickle): the points stay a read-only copy (the default
        # protocol restored writable arrays; review, 2026-11-22).
        return (PointCloud, (self._points, self._radius))

    @classmethod
    def empty(cls) -> "PointCloud":
        """The empty cloud: no points, bounds nothing."""
        return cls(np.zeros((0, 3)))

    @property
    def points(self) -> np.ndarray:
        """(n, 3) float64, read-only."""
        return self._points

    @property
    def radius(self) -> float:
        """Radius of the ball added to the hull, ``>= 0``."""
        return self._radius

    @property
    def is_empty(self) -> bool:
        """True when the cloud has no points."""
        return len(self._points) == 0

    def __len__(self) -> int:
        return len(self._points)

    def __repr__(self) -> str:
        return f"PointCloud({len(self)} points, radius={self._radius:g})"

    def transform(self, matrix, translation=None) -> "PointCloud":
        """The cloud under an affine map (a new cloud; this one is unchanged).

        Parameters
        ----------
        matrix : (4, 4) array_like, (3, 3) array_like or tuple
            A homogeneous affine matrix; or the linear part, with ``translation``; or a
            ``(rotation (3, 3), translation (3,))`` pair.
        translation : (3,) array_like, optional
            Translation, when ``matrix`` is the linear part.

        Returns
        -------
        PointCloud
            Rigid and similarity maps (singular values within ``SIMILARITY_TOL`` = 0.1 % of each
            other: float32-rounded rotations are) keep the radius, scaled by the largest singular
            value; any other linear map first turns the radius into the vertices of a polytope
            circumscribed about the ball (hull-reduced), so the result still bounds the mapped set.
        """
        linear, t = as_affine(matrix, translation)
        if self.is_empty:
            return PointCloud.empty()
        pts, radius = self._points, self._radius
        if radius > 0.0:
            sv = np.linalg.svd(linear, compute_uv=False)
            if sv[0] - sv[-1] <= SIMILARITY_TOL * sv[0]:
                radius = radius * float(sv[0])
            else:
                pts = _hull.minkowski_ball(pts, radius, BALL_LEVEL)
                radius = 0.0
        with np.errstate(over="ignore", invalid="ignore"):
            moved = pts @ linear.T + t
            radius = float(radius)
        if not (np.all(np.isfinite(moved)) and np.isfinite(radius)):
            # The user's arrays were finite: name the map, not "points" (review, 2026-11-22).
            raise ValueError("transform: the moved cloud overflows float64 (the map's scale times the "
                             f"coordinates passes 1.8e308; largest |coordinate| {float(np.abs(pts).max()):.3g}, "
                             f"map norm {float(np.abs(linear).max()):.3g})")
        return PointCloud(moved, radius)

    def swept(self, pose0, pose1, max_angle: float = np.pi / 4) -> "PointCloud":
        """A cloud containing every position of this one while it moves from ``pose0`` to
        ``pose1`` (``(R, t)`` pairs; constant-rate turn, linear translation): see `collide.swept`."""
        from .sweep import swept  # sweep imports this module

        return swept(self, pose0, pose1, max_angle)

    def reduced(self) -> "PointCloud":
        """The same set with only the points that span the hull (robust to degenerate input)."""
        if len(self) <= 1:
            return self
        return PointCloud(_hull.hull_vertices(self._points), self._radius)

    def with_radius_as_points(self, level: int = BALL_LEVEL) -> "PointCloud":
        """A radius-0 cloud whose hull contains this cloud's set (radius turned into points)."""
        return PointCloud(_hull.minkowski_ball(self._points, self._radius, level), 0.0)

    # Bounding volumes (fitting lives in collide.volumes; these are conveniences).
    def aabb(self) -> "_volumes.AABB":
        """Axis-aligned box of the set (exact: the points' extremes plus the radius)."""
        return _volumes.fit_aabb(self._points, self._radius)

    def sphere(self, method: str = "exact") -> "_volumes.Sphere":
        """Enclosing sphere: ``"exact"`` (minimal) or ``"ritter"`` (fast, larger)."""
        return _volumes.fit_sphere(self._points, self._radius, method)

    def obb(self, method: str = "optimal") -> "_volumes.OBB":
        """Oriented box: ``"optimal"`` (within 1 % of the minimal volume), ``"exact"`` (minimal)
        or ``"pca"``."""
        return _volumes.fit_obb(self._points, self._radius, method)


def _common_radius(clouds: list[PointCloud]) -> tuple[list[np.ndarray], float]:
    # Clouds with different radii: keep the smallest radius and turn each cloud's excess into
    # points. hull(P) ⊕ B(r_i) = hull(P) ⊕ B(r_i - r) ⊕ B(r) ⊂ hull(P ⊕ (r_i - r) C) ⊕ B(r)
    # for a polytope C ⊇ B(1): conservative, and exact for the cloud(s) with the smallest radius.
    r = min(c.radius for c in clouds)
    parts = [c.points if c.radius == r else _hull.minkowski_ball(c.points, c.radius - r, BALL_LEVEL)
             for c in clouds]
    return parts, r


def union(clouds: Iterable[PointCloud], threshold: int = 256) -> PointCloud:
    """Cloud bounding the union of ``clouds`` (paper §3.3): append, reduce past ``threshold``.

    Parameters
    ----------
    clouds : iterable of PointCloud
        Empty clouds are ignored.
    threshold : int, default 256
        When the appended cloud has more points than this, it is reduced to its hull vertices.

    Returns
    -------
    PointCloud
    """
    threshold = as_count(threshold, "threshold", 1)
    if isinstance(clouds, PointCloud):
        raise ValueError("clouds: expected an iterable of PointCloud, got a single PointCloud "
                         "(write union([a, b]))")
    try:
        clouds = list(clouds)
    except TypeError:
        raise ValueError(f"clouds: expected an iterable of PointCloud, got {type(clouds).__name__}") from None
    for i, c in enumerate(clouds):
        if not isinstance(c, PointCloud):
            raise ValueError(f"clouds[{i}]: expected a PointCloud, got {type(c).__name__}")
    clouds = [c for c in clouds if not c.is_empty]
    if not clouds:
        return PointCloud.empty()
    if len(clouds) == 1:
        return clouds[0]
    parts, r = _common_radius(clouds)
    pts = np.concatenate(parts, axis=0)
    if len(pts) > threshold:
        pts = _hull.hull_vertices(pts)
    return PointCloud(pts, r)


def intersection(a: PointCloud, b: PointCloud, exact: bool = True) -> PointCloud:
    """Cloud bounding ``a ∩ b`` (paper §3.3).

    Parameters
    ----------
    a, b : PointCloud
    exact : bool, default True
        True: the vertices of ``hull(a) ∩ hull(b)`` (radii first turned into points),
        computed exactly with manifold3d. False: the 8 corners of the intersection of the two
        AABBs (fast, looser).

    Returns
    -------
    PointCloud
        Empty when the two are disjoint; a thin valid cloud when they only touch.
    """
    for name, c in (("a", a), ("b", b)):
        if not isinstance(c, PointCloud):
            raise ValueError(f"{name}: expected a PointCloud, got {type(c).__name__}")
    if not isinstance(exact, (bool, np.bool_)):
        raise ValueError(f"exact: expected True or False, got {exact!r}")
    if a.is_empty or b.is_empty:
        return PointCloud.empty()
    if not exact:
        box_a, box_b = a.aabb(), b.aabb()
        lo, hi = np.maximum(box_a.lo, box_b.lo), np.minimum(box_a.hi, box_b.hi)
        if np.any(lo > hi):
            return PointCloud.empty()
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                            for z in (lo[2], hi[2])])
        return PointCloud(corners)
    pa = _hull.minkowski_ball(a.points, a.radius, BALL_LEVEL)
    pb = _hull.minkowski_ball(b.points, b.radius, BALL_LEVEL)
    return PointCloud(_hull.intersect_hulls(pa, pb))


def difference(a: PointCloud, b: PointCloud) -> PointCloud:
    """Cloud bounding ``a \\ b``: ``a`` itself (paper §3.3; the difference is inside ``a``)."""
    for name, c in (("a", a), ("b", b)):
        if not isinstance(c, PointCloud):
            raise ValueError(f"{name}: expected a PointCloud, got {type(c).__name__}")
    return a
