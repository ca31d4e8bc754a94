"""Shape -> support-kernel data: the flat arrays `collide._kernels.support` reads.

A `SupportData` is computed once per shape (a `PointCloud`'s hull adjacency with scipy's Qhull,
cached per cloud) and posed per query by `SupportData.posed`, which returns the kernels' shape
tuple. Clouds with more than `CLIMB_MIN` hull vertices are searched by hill-climbing over the
hull's vertex graph (as MuJoCo and coal do for meshes); smaller ones, and flat or collinear ones
(no 3D hull), by a scan of their points.
"""

from __future__ import annotations

import math
import sys
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from . import hull as _hull
from ._fork import new_lock
from ._kernels.support import CONE, CYLINDER, ELLIPSOID, POINTS
from .convex import Cone, Cylinder, Ellipsoid
from .pointcloud import PointCloud

__all__ = ["CLIMB_MIN", "SIZE_MAX", "SIZE_MIN", "SupportData", "rolling_radius", "support_data"]

# Hull vertex count above which supports climb the vertex graph instead of scanning
# (tests/bench/distance.py measures both sides of it).
CLIMB_MIN = 32

# The sizes (`SupportData.size`) the distance kernels answer directly. GJK's and EPA's
# sub-determinants and rounding allowances are products of up to three lengths and more: far from
# unit size they under- or overflow, and brackets came out inverted or wrong (pairs scaled by
# 2**-525 and 2**275; at 1e-60 and 1e60 m a box-ellipsoid contact was 4 % off, at 1e110 m a
# penetrating pair was missed: reviews of 2026-11-30). `collide.distance` queries a pair outside
# it scaled by a power of two; `collide.contacts.GeomTable` refuses a model's geom outside it
# (one that never collides is kept, and refused where queried).
# The range keeps a wide margin to where the errors start.
SIZE_MIN, SIZE_MAX = 2.0 ** -100, 2.0 ** 100

# Below this a vector's norm (the square root of its squares) underflows: sizes take math.hypot
# there, and the norm above it, as before (the same sizes bit for bit).
_NORM_MIN = 2.0 ** -480

# Clouds whose data is kept (keyed by identity; PointCloud is immutable).
_CACHE_SIZE = 1024
_cache: OrderedDict = OrderedDict()
# Held by every change to `_cache`: a hit's ``move_to_end`` raised KeyError when another thread
# evicted the key between its ``get`` and the move (tests/test_distance_threads.py).
_cache_lock = new_lock(sys.modules[__name__], "_cache_lock")  # a free one in a forked child

_NO_ADJ = np.zeros(0, np.int32)


@dataclass(frozen=True, eq=False)
class SupportData:
    """Support-function data of one convex shape in its own frame.

    Attributes
    ----------
    kind : int
        `POINTS`, `CYLINDER`, `CONE` or `ELLIPSOID` (`collide._kernels.support`).
    prm : (4,) float64
        Primitive parameters; ``prm[3]`` is the ball radius added to the core.
    points : (n, 3) float64
        The core's support candidates (hull vertices when climbing); ``(0, 3)`` for primitives.
    nbr_start : (n + 1,) int32 or (0,) int32
        CSR offsets of the vertex adjacency; empty: supports scan ``points``.
    nbr : (m,) int32
        CSR neighbour lists.
    size : float
        Half the diagonal of the core's bounding box plus the radius: the length tolerances
        are relative to.
    """

    kind: int
    prm: np.ndarray
    points: np.ndarray
    nbr_start: np.ndarray
    nbr: np.ndarray
    size: float

    def __post_init__(self):
        # `points` read-only, always (a view; the caller's array keeps its flags): numba compiles
        # a kernel once per combination of writeable flags (`collide.signed_distance`).
        if self.points.flags.writeable:
            view = self.points.view()
            view.flags.writeable = False
            object.__setattr__(self, "points", view)

    def posed(self, rot: np.ndarray, pos: np.ndarray) -> tuple:
        """The kernels' shape tuple ``(kind, prm, pts, nbr_start, nbr, rot, pos)``.

        Parameters
        ----------
        rot : (3, 3) float64, C-contiguous
        pos : (3,) float64, C-contiguous
        """
        return (self.kind, self.prm, self.points, self.nbr_start, self.nbr, rot, pos)


def _adjacency(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    # Hull vertices and their edge graph (CSR), or None when Qhull finds no 3D hull.
    try:
        h = ConvexHull(points)
    except (QhullError, ValueError):
        return None
    verts = h.vertices
    # The extreme vertices along -x, +x, -y, +y, -z, +z first: a cold climb starts from the best
    # of them (`collide._kernels.support.SEEDS`).
    vp = points[verts]
    seeds = list(dict.fromkeys(int(f(vp[:, k])) for k in range(3) for f in (np.argmin, np.argmax)))
    order = np.concatenate([seeds, np.setdiff1d(np.arange(len(verts)), seeds)])
    verts = verts[order]
    remap = np.full(len(points), -1, np.int64)
    remap[verts] = np.arange(len(verts))
    s = remap[h.simplices]
    edges = np.concatenate([s[:, [0, 1]], s[:, [1, 2]], s[:, [2, 0]]])
    edges = np.concatenate([edges, edges[:, ::-1]])
    edges = np.unique(edges, axis=0)  # sorted by first vertex
    start = np.searchsorted(edges[:, 0], np.arange(len(verts) + 1)).astype(np.int32)
    return (np.ascontiguousarray(points[verts]), start, np.ascontiguousarray(edges[:, 1], dtype=np.int32))


def _cloud_data(cloud: PointCloud) -> SupportData:
    pts = cloud.points
    if len(pts) == 0:
        raise ValueError("shape: the cloud is empty (an empty set has no distance)")
    _hull.require_bounded(pts, "shape", cloud.radius)
    nbr_start, nbr = _NO_ADJ, _NO_ADJ
    if len(pts) > CLIMB_MIN:
        pts = _hull.hull_vertices(pts)
        if len(pts) > CLIMB_MIN:
            adj = _adjacency(pts)
            if adj is not None:
                pts, nbr_start, nbr = adj
    pts = np.ascontiguousarray(pts, dtype=np.float64)
    # (a cloud of size 1e-160 had size 0 by the norm: `collide.signed_distance` did not see how
    # small the pair was)
    extent = pts.max(axis=0) - pts.min(axis=0)
    diag = float(np.linalg.norm(extent))
    if diag < _NORM_MIN:
        diag = math.hypot(*extent.tolist())
    size = 0.5 * diag + cloud.radius
    prm = np.array([0.0, 0.0, 0.0, cloud.radius])
    return SupportData(POINTS, prm, pts, nbr_start, nbr, size)


# `rolling_radius`'s margin below the smallest radius of curvature: the rounding of ``c * c / a``
# (a few ulps) must not put the ball above it, where the core's support formula stops being one.
_ROLLING_SHRINK = 1e-9


def rolling_radius(radii) -> float:
    """The ball radius an ellipsoid's core is shrunk by: ``(1 - 1e-9) c^2 / a``.

    An ellipsoid with semi-axes ``a >= b >= c`` has no principal radius of curvature below
    ``c^2 / a`` (at the ends of its longest axis), so a ball of any radius ``rho`` up to it rolls
    freely inside it (Blaschke's rolling theorem) and the ellipsoid is ``E' ⊕ ball(rho)``, with
    ``E'`` its inner parallel body: support function ``h_E - rho``, support point ``s_E(u) - rho u``
    for a unit ``u`` (`collide._kernels.support.support`). The narrow phase then runs GJK and
    EPA on ``E'`` and adds ``rho`` as it adds a sphere's or capsule's radius: a penetration shallower
    than the two balls together leaves the cores apart, which GJK settles without EPA.

    Parameters
    ----------
    radii : (3,) array_like of float
        The semi-axes, non-negative (zero ones: a flat ellipsoid, whose ball is 0).

    Returns
    -------
    float
    """
    r = np.asarray(radii, dtype=np.float64)
    lo, hi = float(r.min()), float(r.max())
    if not hi > 0.0:  # a point (all radii zero): its own core
        return 0.0
    return (1.0 - _ROLLING_SHRINK) * lo * lo / hi


def support_data(shape) -> SupportData:
    """The support data of a `PointCloud`, `Cylinder`, `Cone` or `Ellipsoid` (cached per cloud).

    Raises
    ------
    ValueError
        For an empty cloud, coordinates (or a primitive's size) beyond
        `collide.hull.MAX_COORDINATE`, or another type.
    """
    if isinstance(shape, PointCloud):
        key = id(shape)
        with _cache_lock:
            hit = _cache.get(key)
            if hit is not None and hit[0] is shape:
                _cache.move_to_end(key)
                return hit[1]
        data = _cloud_data(shape)
        with _cache_lock:
            _cache[key] = (shape, data)  # the strong reference keeps the id from being reused
            while len(_cache) > _CACHE_SIZE:
                _cache.popitem(last=False)
        return data
    empty = np.zeros((0, 3))
    if isinstance(shape, Cylinder):
        prm = np.array([shape.radius, shape.half_height, 0.0, 0.0])
        data = SupportData(CYLINDER, prm, empty, _NO_ADJ, _NO_ADJ, math.hypot(shape.radius, shape.half_height))
    elif isinstance(shape, Cone):
        prm = np.array([shape.radius, shape.height, 0.0, 0.0])
        data = SupportData(CONE, prm, empty, _NO_ADJ, _NO_ADJ, 0.5 * math.hypot(2.0 * shape.radius, shape.height))
    elif isinstance(shape, Ellipsoid):
        prm = np.array([shape.radii[0], shape.radii[1], shape.radii[2], rolling_radius(shape.radii)])
        diag = float(np.linalg.norm(shape.radii))
        data = SupportData(ELLIPSOID, prm, empty, _NO_ADJ, _NO_ADJ,
                           diag if diag >= _NORM_MIN else math.hypot(*shape.radii.tolist()))
    else:
        raise ValueError(f"shape: expected a PointCloud, Cylinder, Cone or Ellipsoid, got {type(shape).__name__}")
    # (a cloud's coordinates are checked by `_hull.require_bounded`)
    if not data.size <= _hull.MAX_COORDINATE:
        raise ValueError(f"shape: the {type(shape).__name__.lower()}'s size {data.size:.3g} is beyond "
                         f"{_hull.MAX_COORDINATE:g} (squared distances would overflow float64)")
    return data
