"""k-DOPs (discrete oriented polytopes; Klosowski et al. 1998, "Efficient collision detection
using bounding volume hierarchies of k-DOPs"): slabs along k/2 fixed directions, their record,
fitting and the slab test between two of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull

from .. import hull as _hull
from .._validate import as_array, as_points, as_radius
from ._axes import _principal
from ._records import _PAD_FLOOR, _ROUNDING_PAD, AABB, _overlap, _slack, _transform

__all__ = ["KDOP", "KDOP_SIZES", "fit_kdop", "kdop_directions"]

_require_points = _hull.require_bounded

def _kdop_directions(k: int) -> np.ndarray:
    axes = np.eye(3)
    corners = np.array([[1, 1, 1], [1, 1, -1], [1, -1, 1], [1, -1, -1]], dtype=float) / np.sqrt(3.0)
    edges = np.array([[1, 1, 0], [1, -1, 0], [1, 0, 1], [1, 0, -1], [0, 1, 1], [0, 1, -1]],
                     dtype=float) / np.sqrt(2.0)
    table = {6: [axes], 14: [axes, corners], 18: [axes, edges], 26: [axes, corners, edges]}
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)) or int(k) not in table:
        raise ValueError(f"k: expected 6, 14, 18 or 26, got {k!r}")
    k = int(k)
    out = np.concatenate(table[k])
    out.setflags(write=False)
    return out


KDOP_SIZES = (6, 14, 18, 26)


def kdop_directions(k: int) -> np.ndarray:
    """The ``k // 2`` unit slab directions of a k-DOP, ``(k // 2, 3) float64``, read-only.

    The coordinate axes come first, then (for 14 and 26) the 4 cube-corner diagonals, then
    (for 18 and 26) the 6 edge diagonals.
    """
    return _kdop_directions(k)


@dataclass(frozen=True, eq=False)
class KDOP:
    """Discrete oriented polytope: ``{x : lo <= D @ x <= hi}`` for ``D = kdop_directions(k)``.

    Attributes
    ----------
    lo, hi : (k // 2,) float64
        Read-only slab bounds along the unit directions; ``k`` is 6, 14, 18 or 26.
    """

    lo: np.ndarray
    hi: np.ndarray

    def __reduce__(self):
        # Rebuilt through __post_init__ (copy, pickle): arrays stay read-only copies.
        return (KDOP, (self.lo, self.hi))

    def __post_init__(self):
        lo = as_array(self.lo, "lo", (None,)).copy()
        hi = as_array(self.hi, "hi", (len(lo),)).copy()
        if 2 * len(lo) not in KDOP_SIZES:
            raise ValueError(f"lo: expected 3, 7, 9 or 13 slab bounds (k = 6, 14, 18, 26), "
                             f"got {len(lo)}")
        if np.any(lo > hi):
            raise ValueError(f"lo: must be <= hi on every slab, got lo={lo}, hi={hi}")
        lo.setflags(write=False)
        hi.setflags(write=False)
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)

    @property
    def k(self) -> int:
        """Number of bounding planes."""
        return 2 * len(self.lo)

    @property
    def directions(self) -> np.ndarray:
        """``(k // 2, 3) float64``: the slab directions."""
        return _kdop_directions(self.k)

    def vertices(self) -> np.ndarray:
        """Vertices of the polytope, ``(m, 3) float64`` (every feasible triple of planes)."""
        d = self.directions
        normals = np.concatenate([d, -d])
        offsets = np.concatenate([self.hi, -self.lo])
        idx = np.array([(i, j, l) for i in range(self.k) for j in range(i + 1, self.k)
                        for l in range(j + 1, self.k)])
        mats = normals[idx]
        det = np.linalg.det(mats)
        ok = np.abs(det) > 1e-9
        pts = np.linalg.solve(mats[ok], offsets[idx[ok]][..., None])[..., 0]
        scale = max(1.0, float(np.abs(offsets).max()))
        feasible = np.all(pts @ normals.T <= offsets + 1e-9 * scale, axis=1)
        return np.unique(pts[feasible], axis=0)

    def volume(self) -> float:
        """Volume (0 for a flat polytope)."""
        verts = self.vertices()
        if len(verts) < 4 or _principal(verts)[1] < 3:
            return 0.0
        return float(ConvexHull(verts).volume)

    def contains(self, points, rtol: float = 0.0) -> np.ndarray:
        """Which points lie in every slab, widened by ``rtol`` times the bounds' size.

        Parameters
        ----------
        points : (n, 3) float64
        rtol : float
            ``>= 0``: the room, relative to the volume's coordinates and size (no absolute floor:
            a 1e-9 box is widened by 1e-9 of its size, not of 1).

        Returns
        -------
        inside : (n,) bool
        """
        p = as_array(points, "points", (None, 3))
        proj = p @ self.directions.T
        pad = as_radius(rtol, "rtol") * float(np.max(np.abs(np.concatenate([self.lo, self.hi]))))
        return np.all((proj >= self.lo - pad) & (proj <= self.hi + pad), axis=1)

    def aabb(self) -> AABB:
        """An axis-aligned box containing the polytope: its first three slabs (exact when fitted)."""
        return AABB(self.lo[:3], self.hi[:3])

    def overlaps(self, other) -> bool:
        """Whether this polytope and another volume may intersect (see `overlap`)."""
        return _overlap(self, other)

    def transformed(self, rotation, translation) -> "KDOP":
        """The tightest k-DOP of the polytope under a rigid map (see `transform`)."""
        return _transform(self, rotation, translation)


def fit_kdop(points: np.ndarray, radius: float = 0.0, k: int = 26) -> KDOP:
    """Exact k-DOP of ``hull(points) ⊕ ball(radius)``.

    Parameters
    ----------
    points : (n, 3) float64
        Non-empty.
    radius : float
        The cloud's radius, ``>= 0`` (directions are unit vectors, so it adds to every slab).
    k : {6, 14, 18, 26}

    Returns
    -------
    KDOP
    """
    points = as_points(points, "points")
    radius = as_radius(radius, "radius")
    _require_points(points, "kdop", radius)
    d = _kdop_directions(k)
    proj = points @ d.T
    pad = _ROUNDING_PAD * float(np.abs(points).max()) + _PAD_FLOOR  # see fit_obb
    return KDOP(proj.min(axis=0) - radius - pad, proj.max(axis=0) + radius + pad)


def _kdop_kdop(a: KDOP, b: KDOP) -> bool:
    # Slab-interval test on the directions the two share (all of them when k is equal):
    # disjoint intervals on a shared direction separate the polytopes; overlapping intervals
    # everywhere may still leave them apart (no edge-edge axes), so the test is conservative.
    da, db = a.directions, b.directions
    match = np.abs(da @ db.T - 1.0) < 1e-12
    ia, ib = np.nonzero(match)
    pad = _slack(a.lo, a.hi, b.lo, b.hi)
    return bool(np.all(a.lo[ia] <= b.hi[ib] + pad) and np.all(b.lo[ib] <= a.hi[ia] + pad))
