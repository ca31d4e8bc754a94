"""Signed distance of two convex sets with a certified bracket: `distance` and its `Distance`.

The shapes are `PointCloud` s (``hull(points) ⊕ ball(radius)``: exact for polytopes, spheres,
capsules, boxes and convex meshes) or the exact curved primitives of `collide.convex`, each
optionally posed by a ``(rotation (3, 3), translation (3,))`` pair. GJK runs on the cores, EPA
when they overlap, and the radii are added afterwards (`collide._kernels.distance`).

The result's ``lower <= true signed distance <= upper`` always holds (up to the rounding
allowance the kernel adds outwards): ``lower`` comes from a separating direction's support
values, ``upper`` from the witness points (apart) or a certified inner ball of the Minkowski
difference (overlapping). When an iteration cap stops the search early the bracket is wider,
never wrong; ``distance`` is the estimate the witnesses give, inside the bracket.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import hull as _hull
from ._kernels import distance as _kd
from ._validate import as_affine, as_array, as_count, as_positive
from .support import support_data

__all__ = ["Distance", "ORTHONORMAL_TOL", "distance"]

# Largest |R^T R - I| entry a pose's rotation may have: float32-rounded rotations (~1e-7) pass, a
# scaled or sheared matrix does not (the narrow phase takes rigid poses; scale the shape instead).
ORTHONORMAL_TOL = 1e-6


@dataclass(frozen=True, eq=False)
class Distance:
    """Signed distance of two convex sets, its witnesses and a certified bracket.

    Attributes
    ----------
    distance : float
        Signed distance: the gap when apart, minus the penetration depth when overlapping.
    point_a, point_b : (3,) float64
        Witness points on A and on B, world frame: ``point_b - point_a == distance * normal``.
    normal : (3,) float64
        Unit direction from A to B: translating B by ``-distance * normal`` makes the sets touch.
    lower, upper : float
        Certified bounds: ``lower <= true signed distance <= upper``.
    iterations : int
        GJK iterations plus EPA expansions.
    hints : tuple of int
        Support vertices last used on A and B (hill-climb starts for a warm query).
    """

    distance: float
    point_a: np.ndarray
    point_b: np.ndarray
    normal: np.ndarray
    lower: float
    upper: float
    iterations: int
    hints: tuple = field(default=(-1, -1), repr=False)

    @property
    def gap(self) -> float:
        """Width of the bracket, ``upper - lower``."""
        return self.upper - self.lower


# numba compiles `checked_distance` once per combination of its arrays' writeable flags (a full
# GJK + EPA each time): the poses and the warm direction reach it writable, always (these two
# are read by the kernel only), and `SupportData.points` read-only, always.
_EYE = np.eye(3)
_ZERO = np.zeros(3)


def _pose(pose, name: str) -> tuple[np.ndarray, np.ndarray]:
    # (rotation, translation) as C-contiguous float64 arrays; checked by the kernel (`_raise`).
    if pose is None:
        return _EYE, _ZERO
    if type(pose) is tuple and len(pose) == 2:
        r, t = pose
        if (type(r) is np.ndarray and type(t) is np.ndarray and r.dtype == np.float64
                and t.dtype == np.float64 and r.shape == (3, 3) and t.shape == (3,)
                and r.flags.c_contiguous and t.flags.c_contiguous and r.flags.writeable
                and t.flags.writeable):
            return r, t  # the common case, without copies
    rot, pos = as_affine(pose, name=name)
    return np.array(rot, dtype=np.float64, order="C"), np.array(pos, dtype=np.float64, order="C")


def _raise(err: int, name: str, rot: np.ndarray, pos: np.ndarray, size: float) -> None:
    # The ValueError of `collide._kernels.distance.pose_error`'s code ``err`` for a pose.
    if err == 1:
        raise ValueError(f"{name}: non-finite value (NaN or inf) in the rotation or translation")
    if err == 2:
        dev = float(np.abs(rot.T @ rot - np.eye(3)).max())
        raise ValueError(f"{name}: the rotation is not orthonormal with determinant +1 "
                         f"(|R^T R - I| = {dev:.3g}, det = {float(np.linalg.det(rot)):.3g}; "
                         f"allowed {ORTHONORMAL_TOL:g})")
    reach = float(np.abs(pos).max()) + size
    raise ValueError(f"{name}: the translation puts the shape at {reach:.3g}, beyond "
                     f"{_hull.MAX_COORDINATE:g} (squared distances would overflow float64)")


_new = object.__new__
_OUT_A, _OUT_N = _kd.OUT_POINT_A, _kd.OUT_NORMAL + 3


def distance(a, b, pose_a=None, pose_b=None, *, warm=None, tolerance: float = 1e-12,
             max_iterations: int = 128) -> Distance:
    """Signed distance of two convex shapes, with witness points and a certified bracket.

    Parameters
    ----------
    a, b : PointCloud, Cylinder, Cone or Ellipsoid
        The shapes, each in its own frame. A cloud is ``hull(points) ⊕ ball(radius)``; its
        hull adjacency is computed once and cached.
    pose_a, pose_b : tuple or (4, 4) array_like, optional
        ``(rotation (3, 3), translation (3,))`` or a homogeneous rigid matrix: world =
        ``rotation @ local + translation``. None: the identity.
    warm : Distance or (3,) array_like, optional
        A previous result for the same pair (its normal seeds the first search direction and its
        support vertices the hill-climbs), or a direction from A to B.
    tolerance : float, default 1e-12
        Target bracket width, relative to the shapes' size (half their boxes' diagonals plus radii).
    max_iterations : int, default 128
        Cap on GJK iterations and on EPA's polytope vertices; reaching it widens the bracket.

    Returns
    -------
    Distance

    Raises
    ------
    ValueError
        For an empty cloud, a non-finite or non-rigid pose, an unknown shape type, or bad options.

    Examples
    --------
    >>> from collide import PointCloud, distance
    >>> r = distance(PointCloud([[0, 0, 0]], 1.0), PointCloud([[3, 0, 0]], 0.5))
    >>> round(r.distance, 12), [round(float(x), 12) + 0.0 for x in r.normal]
    (1.5, [1.0, 0.0, 0.0])
    """
    da = support_data(a)
    db = support_data(b)
    ra, ta = _pose(pose_a, "pose_a")
    rb, tb = _pose(pose_b, "pose_b")
    hint_a = hint_b = -1  # cold: the hill-climbs start from the best extreme vertex
    if warm is None:
        d0 = _ZERO
    elif isinstance(warm, Distance):
        d0 = warm.normal if warm.normal.flags.writeable else np.array(warm.normal)
        hint_a, hint_b = warm.hints
    else:
        d0 = np.array(as_array(warm, "warm", (3,)))  # a writable copy (one signature)
    if not (type(tolerance) is float and 0.0 < tolerance < 1.0):
        tolerance = as_positive(tolerance, "tolerance")
    if not (type(max_iterations) is int and 4 <= max_iterations <= 100_000):
        max_iterations = as_count(max_iterations, "max_iterations", 4, 100_000)
    out = np.empty(_kd.OUT_SIZE)
    err = _kd.checked_distance(da.posed(ra, ta), db.posed(rb, tb), da.size, db.size, ORTHONORMAL_TOL,
                               _hull.MAX_COORDINATE, tolerance * (da.size + db.size), d0, hint_a, hint_b,
                               max_iterations, out)
    if err:
        if err < 10:
            _raise(err, "pose_a", ra, ta, da.size)
        _raise(err - 10, "pose_b", rb, tb, db.size)
    vec = out[_OUT_A:_OUT_N].copy()  # one copy; the fields are its views
    dist, lower, upper, _, _, _, _, _, _, _, _, _, _, iters, ha, hb = out.tolist()
    # Built without the frozen dataclass's __init__ (a setattr per field): the same fields.
    r = _new(Distance)
    r.__dict__.update(distance=dist, point_a=vec[0:3], point_b=vec[3:6], normal=vec[6:9], lower=lower,
                      upper=upper, iterations=int(iters), hints=(int(ha), int(hb)))
    return r
