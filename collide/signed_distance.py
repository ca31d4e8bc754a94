"""Signed distance of two convex sets with a certified bracket: `distance` and its `Distance`.

The shapes are `PointCloud` s (``hull(points) ⊕ ball(radius)``: exact for polytopes, spheres,
capsules, boxes and convex meshes) or the exact curved primitives of `collide.convex`, each
optionally posed by a ``(rotation (3, 3), translation (3,))`` pair. GJK runs on the cores, EPA
when they overlap, and the radii are added afterwards (`collide._kernels.distance`).

The result's ``lower <= true signed distance <= upper`` always holds (up to the rounding
allowance the kernel adds outwards): ``lower`` comes from a separating direction's support
values, ``upper`` from the witness points (apart) or a certified inner ball of the Minkowski
difference (overlapping). When an iteration cap stops the search early the bracket is wider,
never wrong; ``distance`` is the estimate the witnesses give, inside the bracket. A pair far
from unit size (sizes summing below 2**-100 or above 2**100) whose coordinates are far from unit
size too is queried scaled by a power of two, which is exact, so that no product of its lengths
under- or overflows: the bracket holds at every scale. (Tiny shapes far from the origin are
answered to their coordinates' rounding.)
"""

from __future__ import annotations

import math
import sys

import numpy as np
from numba import types as _nt

from . import hull as _hull
from ._fork import new_lock
from ._kernels import distance as _kd
from ._validate import as_affine, as_array, as_count, as_positive
from ._kernels.support import ELLIPSOID
from .support import SIZE_MAX, SIZE_MIN, SupportData, rolling_radius, support_data

__all__ = ["Distance", "ORTHONORMAL_TOL", "distance"]

# Largest |R^T R - I| entry a pose's rotation may have: float32-rounded rotations (~1e-7) pass, a
# scaled or sheared matrix does not (the narrow phase takes rigid poses; scale the shape instead).
ORTHONORMAL_TOL = 1e-6
_LIMIT = float(_hull.MAX_COORDINATE)


class Distance:
    """Signed distance of two convex sets, its witnesses and a certified bracket (immutable).

    Attributes
    ----------
    distance : float
        Signed distance: the gap when apart, minus the penetration depth when overlapping.
    point_a, point_b : (3,) float64
        Witness points on A and on B, world frame: ``point_b - point_a`` is ``distance * normal``
        up to rounding once converged, and never farther from it than the bracket's width.
    normal : (3,) float64
        Unit direction from A to B: translating B by ``-distance * normal`` makes the sets touch.
    lower, upper : float
        Certified bounds: ``lower <= true signed distance <= upper``.
    iterations : int
        GJK iterations plus EPA expansions.
    hints : tuple of int
        Support vertices last used on A and B (hill-climb starts for a warm query).
    """

    # The kernel's output array is the whole state: building a result is one attribute store
    # (a frozen dataclass's was a setattr per field), and each field is read from it on access.
    # The vectors are views of it. The fields are properties without setters and __slots__
    # admits no other attribute: assigning to either raises AttributeError.
    __slots__ = ("_out",)

    def __init__(self, distance: float, point_a, point_b, normal, lower: float, upper: float,
                 iterations: int, hints: tuple = (-1, -1)):
        out = np.zeros(_kd.OUT_SIZE)
        out[[_kd.OUT_DISTANCE, _kd.OUT_LOWER, _kd.OUT_UPPER, _kd.OUT_ITERATIONS, _kd.OUT_HINT_A, _kd.OUT_HINT_B]] = (
            distance, lower, upper, iterations, hints[0], hints[1])
        out[_kd.OUT_POINT_A:_kd.OUT_POINT_A + 3] = point_a
        out[_kd.OUT_POINT_B:_kd.OUT_POINT_B + 3] = point_b
        out[_kd.OUT_NORMAL:_kd.OUT_NORMAL + 3] = normal
        self._out = out

    def __reduce__(self):
        return (_from_out, (self._out.copy(),))

    def __repr__(self) -> str:
        return (f"Distance(distance={self.distance!r}, point_a={self.point_a!r}, point_b={self.point_b!r}, "
                f"normal={self.normal!r}, lower={self.lower!r}, upper={self.upper!r}, "
                f"iterations={self.iterations!r})")

    @property
    def distance(self) -> float:
        """Signed distance (float)."""
        return self._out.item(_kd.OUT_DISTANCE)

    @property
    def lower(self) -> float:
        """Certified lower bound of the signed distance (float)."""
        return self._out.item(_kd.OUT_LOWER)

    @property
    def upper(self) -> float:
        """Certified upper bound of the signed distance (float)."""
        return self._out.item(_kd.OUT_UPPER)

    @property
    def point_a(self) -> np.ndarray:
        """(3,) float64: the witness point on A, world frame."""
        return self._out[_kd.OUT_POINT_A:_kd.OUT_POINT_A + 3]

    @property
    def point_b(self) -> np.ndarray:
        """(3,) float64: the witness point on B, world frame."""
        return self._out[_kd.OUT_POINT_B:_kd.OUT_POINT_B + 3]

    @property
    def normal(self) -> np.ndarray:
        """(3,) float64: unit direction from A to B."""
        return self._out[_kd.OUT_NORMAL:_kd.OUT_NORMAL + 3]

    @property
    def iterations(self) -> int:
        """GJK iterations plus EPA expansions (int)."""
        return int(self._out.item(_kd.OUT_ITERATIONS))

    @property
    def hints(self) -> tuple:
        """(int, int): the support vertices last used on A and B."""
        return int(self._out.item(_kd.OUT_HINT_A)), int(self._out.item(_kd.OUT_HINT_B))

    @property
    def gap(self) -> float:
        """Width of the bracket, ``upper - lower``."""
        return self.upper - self.lower


_new = object.__new__


def _from_out(out: np.ndarray) -> Distance:
    # A Distance on a filled output array (a pickled one's copy).
    r = _new(Distance)
    r._out = out
    return r


# numba compiles a kernel once per combination of its arguments' types, writeable flags and
# layouts included (a full GJK + EPA each time: tests/bench/compile_log.py). `query` has one
# signature, `_SIGNATURE`: every array float64, C-contiguous, aligned and writable (the
# descriptors int64), and its dispatcher compiles nothing else (`disable_compile`). So `distance`
# hands the poses over as they come: numba's dispatch, which types every argument anyway, raises
# (TypeError, or another error of its typing) for an array of another dtype, layout or flags, or
# for anything that is not an array, before the kernel runs; `distance` then converts them into
# that form (`_canonical`, copies; a ValueError naming what is not a pose) and calls again.
# tests/test_distance_inputs.py checks that every accepted form gives the canonical answer through
# the one signature.
_EYE = np.eye(3)
_ZERO = np.zeros(3)
_COLD = np.zeros(_kd.OUT_SIZE)  # a "previous result" with a zero normal: a cold start
_COLD[[_kd.OUT_HINT_A, _kd.OUT_HINT_B]] = -1.0
_F64 = np.dtype(np.float64)
_ND = np.ndarray
_empty, _query, _OUT_SIZE = np.empty, _kd.query, _kd.OUT_SIZE  # bound once: looked up every call
_A1, _A2 = _nt.float64[::1], _nt.float64[:, ::1]
_SIGNATURE = (_nt.int64, _nt.int64, _A2, _A1, _A2, _A1) + (_nt.float64,) * 5 + (_A1, _nt.int64, _A1)
_loaded = False  # `query`'s one signature loaded and its dispatcher closed to any other (`_load_query`)
_load_lock = new_lock(sys.modules[__name__], "_load_lock")  # a free one in a forked child


def _load_query() -> None:
    # `query`'s one signature compiled, or loaded from numba's cache, then its dispatcher closed:
    # on the first call. Until then no call hands `query` anything but that form (two threads
    # making the first call at once: one loads, the other waits and finds it loaded).
    global _loaded
    with _load_lock:
        if not _loaded:
            _query.compile(_SIGNATURE)
            _query.disable_compile()
            _loaded = True


def _canonical(pose_a, pose_b, w: np.ndarray) -> tuple:
    # ``(ra, ta, rb, tb, w)`` in `query`'s one form (`_SIGNATURE`; copies), or the ValueError naming
    # the pose that is not one. Finiteness, rigidity and range stay the kernel's checks (`_raise`).
    ra, ta = (_EYE, _ZERO) if pose_a is None else _pose(pose_a, "pose_a")
    rb, tb = (_EYE, _ZERO) if pose_b is None else _pose(pose_b, "pose_b")
    if not (type(w) is _ND and w.dtype == _F64 and w.ndim == 1 and w.flags.carray):
        # an unpickled result's buffer may be read-only (a crafted one of another dtype or shape)
        w = np.array(w, dtype=np.float64, order="C").reshape(-1)
    return ra, ta, rb, tb, w


def _pose(pose, name: str) -> tuple[np.ndarray, np.ndarray]:
    # Any accepted pose as (rotation, translation) in `query`'s one form (copies), or the
    # ValueError naming what is wrong with it. Finiteness, rigidity and range are the kernel's
    # checks (`_raise`).
    if isinstance(pose, tuple) and len(pose) == 2:
        rot, pos = pose
        if (type(rot) is _ND and type(pos) is _ND and rot.shape == (3, 3) and pos.shape == (3,)
                and rot.dtype.kind in "fiub" and pos.dtype.kind in "fiub"):
            # arrays of real numbers, shaped right (a transposed rotation, float32, read-only):
            # one copy each; their finiteness is the kernel's check
            return np.array(rot, dtype=np.float64, order="C"), np.array(pos, dtype=np.float64, order="C")
        rot = as_array(rot, f"{name} rotation", (3, 3))
        pos = as_array(pos, f"{name} translation", (3,))
    else:
        rot, pos = as_affine(pose, name=name)
    return np.array(rot, dtype=np.float64, order="C"), np.array(pos, dtype=np.float64, order="C")


def _raise(err: int, name: str, rot: np.ndarray, pos: np.ndarray, size: float) -> None:
    # The ValueError of `collide._kernels.distance.query`'s code ``err`` (1-4) for a pose.
    if err == 4:
        _pose((rot, pos), name)  # names the wrong shape
        raise AssertionError("unreachable: a pose of the right shapes")
    # the values the kernel read (an ndarray subclass, a masked array among them, reaches it as is)
    rot, pos = np.array(rot, dtype=np.float64), np.array(pos, dtype=np.float64)
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


# Per shape (keyed by identity, holding the shape so that its id is not reused; shapes are
# immutable): its SupportData, which owns the arrays, the descriptor `query` reads them by, and
# the descriptor's address (what `query` takes: an int costs its dispatch less than an array).
_CACHE_SIZE = 1024
_shapes: dict = {}
# Insertions and evictions hold it (hits do not): another thread's insertion between the
# eviction's ``iter`` and ``next`` raised "dictionary changed size during iteration", and two
# threads evicting at once let the cache outgrow its bound (tests/test_distance_threads.py).
_shapes_lock = new_lock(sys.modules[__name__], "_shapes_lock")  # a free one in a forked child


def _described(shape, name: str) -> tuple:
    # (shape, (SupportData, descriptor), descriptor address, size) of a shape, cached.
    hit = _shapes.get(id(shape))
    if hit is not None and hit[0] is shape:
        return hit
    try:
        data = support_data(shape)
    except ValueError as exc:  # an empty cloud, coordinates out of range, an unknown type
        raise ValueError(f"shape {name}: {str(exc).removeprefix('shape: ')}") from None
    return _entry(shape, data, id(shape))


def _entry(shape, data: SupportData, key) -> tuple:
    # `_described`'s cache entry of a shape's support data, under ``key`` (the shape's id, or
    # its id and a scale: `_scaled`).
    desc = np.zeros(_kd.DESC_SIZE, np.int64)
    desc[_kd.DESC_KIND] = data.kind
    for n_slot, slot, arr, dtype in ((_kd.DESC_NPTS, _kd.DESC_PTS, data.points, _F64),
                                     (_kd.DESC_NSTART, _kd.DESC_START, data.nbr_start, np.int32),
                                     (_kd.DESC_NNBR, _kd.DESC_NBR, data.nbr, np.int32),
                                     (None, _kd.DESC_PRM, data.prm, _F64)):
        # `query` views each array by its address: it must be C-contiguous of this dtype, and the
        # entry below holds it (through `data`) for as long as the descriptor lives.
        want = (4,) if n_slot is None else (len(arr), 3) if slot == _kd.DESC_PTS else (len(arr),)
        if arr.dtype != dtype or not arr.flags.c_contiguous or arr.shape != want:
            raise AssertionError(f"SupportData: a {arr.dtype} array of shape {arr.shape}, not C-contiguous {dtype}")
        if n_slot is not None:
            desc[n_slot] = len(arr)
        desc[slot] = arr.ctypes.data
    entry = (shape, (data, desc), desc.ctypes.data, data.size)  # the arrays held, the address passed
    with _shapes_lock:
        while len(_shapes) >= _CACHE_SIZE:
            _shapes.pop(next(iter(_shapes)), None)  # the oldest
        _shapes[key] = entry
    return entry


# `_query_scaled`'s widening of a bound scaled down: 16 * 2**-1074 (the smallest subnormal).
_WIDEN = math.ldexp(16.0, -1074)


def _scaled(shape, entry: tuple, k: int) -> tuple:
    # `_described`'s entry of ``shape`` scaled by 2**k (exact, barring underflow), cached.
    key = (id(shape), k)
    hit = _shapes.get(key)
    if hit is not None and hit[0] is shape:
        return hit
    data = entry[1][0]
    prm = np.ldexp(data.prm, k)
    if data.kind == ELLIPSOID:  # its rolling ball stays below the curvature radius once rounded
        prm[3] = rolling_radius(prm[:3])
    scaled = SupportData(data.kind, prm, np.ldexp(data.points, k), data.nbr_start, data.nbr,
                         math.ldexp(data.size, k))
    return _entry(shape, scaled, key)


def _reach(entry: tuple) -> float:
    # The largest coordinate of a shape in its own frame plus its radius: how far it reaches from
    # its origin, per axis (for a primitive at most twice its size: a cone's apex is at its height).
    data = entry[1][0]
    if len(data.points) == 0:
        return 2.0 * data.size
    return float(np.abs(data.points).max()) + float(data.prm[3])


def _query_scaled(a, b, ea: tuple, eb: tuple, ra, ta, rb, tb, w, tolerance: float,
                  max_iterations: int) -> tuple[np.ndarray, int]:
    # `query` on a pair far from unit size: the pair and its poses' translations scaled by 2**k,
    # k chosen to bring the farthest coordinate the pair reaches to [1/2, 1), and the
    # lengths of the answer scaled back (exact, both ways, but where a length underflows: its
    # bounds are then rounded outwards). Rotations, normals and iteration counts are unchanged.
    size_a, size_b = ea[3], eb[3]
    k = 0
    if type(ta) is _ND and type(tb) is _ND and ta.shape == (3,) and tb.shape == (3,):
        # each shape's reach from the world origin, not its size: a ball of radius 1e-200 at
        # (1, 0, 0) of its own frame is a tiny shape far from the origin, left unscaled
        m = max(_reach(ea) + float(np.abs(ta).max()), _reach(eb) + float(np.abs(tb).max()))
        if math.isfinite(m) and m > 0.0 and not SIZE_MIN <= m <= SIZE_MAX:
            k = -math.frexp(m)[1]
    out = _empty(_OUT_SIZE)
    if k == 0:  # tiny shapes far from the origin, or a pose the kernel refuses
        return out, _query(ea[2], eb[2], ra, ta, rb, tb, size_a, size_b, ORTHONORMAL_TOL, _LIMIT,
                           tolerance * (size_a + size_b), w, max_iterations, out)
    sa, sb = _scaled(a, ea, k), _scaled(b, eb, k)
    # the coordinate limit scaled too where scaling down (scaling up, the pair is far inside it)
    limit = math.ldexp(_LIMIT, k) if k < 0 else _LIMIT
    err = _query(sa[2], sb[2], ra, np.ldexp(ta, k), rb, np.ldexp(tb, k), sa[3], sb[3], ORTHONORMAL_TOL,
                 limit, tolerance * (sa[3] + sb[3]), w, max_iterations, out)
    if err:
        return out, err
    for i in (_kd.OUT_POINT_A, _kd.OUT_POINT_B):
        out[i:i + 3] = np.ldexp(out[i:i + 3], -k)
    out[_kd.OUT_DISTANCE] = math.ldexp(out[_kd.OUT_DISTANCE], -k)
    for i, away in ((_kd.OUT_LOWER, -math.inf), (_kd.OUT_UPPER, math.inf)):
        v = float(out[i])
        if k < 0:
            # scaled down, a coordinate or parameter below 2**(-1022 - k) lost bits (or became 0):
            # the pair queried is the scaled one moved by less than 2**-1074 a coordinate, so its
            # distance by less than 4 * 2**-1074 (review: a 1e120 cylinder 1e-300 thick answered
            # [0, 0] for a true 2e-300); the bound is widened by that, at least to the next float
            widened = v + math.copysign(_WIDEN, away)
            v = widened if widened != v else math.nextafter(v, away)
        back = math.ldexp(v, -k)
        out[i] = back if math.ldexp(back, k) == v else math.nextafter(back, away)
    return out, 0


_TOLERANCE, _MAX_ITERATIONS = 1e-12, 128  # the defaults (known valid: not checked again)


# The largest `distance` tolerance accepted (relative to the size).
_TOLERANCE_MAX = 1e-2


def distance(a, b, pose_a=None, pose_b=None, *, warm=None, tolerance: float = _TOLERANCE,
             max_iterations: int = _MAX_ITERATIONS) -> Distance:
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
        Target bracket width, relative to the shapes' size (half their boxes' diagonals plus radii);
        at most 1e-2.
    max_iterations : int, default 128
        Cap on GJK iterations and on EPA's polytope vertices; reaching it widens the bracket.

    Returns
    -------
    Distance

    Raises
    ------
    ValueError
        For an empty cloud, a shape or pose reaching beyond `collide.hull.MAX_COORDINATE`, a
        non-finite or non-rigid pose, an unknown shape type, or bad options.

    Notes
    -----
    The bracket ``lower <= true signed distance <= upper`` always holds. How narrow it gets is limited by the
    world coordinates' precision as well as by ``tolerance``. The supports are computed in world
    coordinates, so a shape far from the origin relative to its size has the rounding of its
    position, about 1e-16 of it. Example: shapes of size 1e-6 placed 1e4 from the origin get
    brackets up to about 1e-12 wide, a few millionths of their size. Pose such shapes near the
    origin (or relative to each other) to get the full relative accuracy.

    Examples
    --------
    >>> from collide import PointCloud, distance
    >>> r = distance(PointCloud([[0, 0, 0]], 1.0), PointCloud([[3, 0, 0]], 0.5))
    >>> round(r.distance, 12), [round(float(x), 12) + 0.0 for x in r.normal]
    (1.5, [1.0, 0.0, 0.0])
    """
    ea = _shapes.get(id(a))  # `_described`'s cache hit, inline (a call less per shape)
    if ea is None or ea[0] is not a:
        ea = _described(a, "a")
    eb = _shapes.get(id(b))
    if eb is None or eb[0] is not b:
        eb = _described(b, "b")
    _, _, desc_a, size_a = ea
    _, _, desc_b, size_b = eb
    # The poses as they come ((rotation, translation) pairs unpacked): `query`'s dispatch checks
    # their form, `_canonical` converts them where it refuses one (a (4, 4) matrix at once).
    if pose_a is None:
        ra, ta = _EYE, _ZERO
    elif type(pose_a) is tuple and len(pose_a) == 2:
        ra, ta = pose_a
    else:
        ra, ta = _pose(pose_a, "pose_a")
    if pose_b is None:
        rb, tb = _EYE, _ZERO
    elif type(pose_b) is tuple and len(pose_b) == 2:
        rb, tb = pose_b
    else:
        rb, tb = _pose(pose_b, "pose_b")
    if warm is None:
        w = _COLD
    elif type(warm) is Distance:
        w = warm._out  # its normal and hints, read by the kernel
    else:
        w = np.zeros(_kd.OUT_SIZE)
        w[_kd.OUT_NORMAL:_kd.OUT_NORMAL + 3] = as_array(warm, "warm", (3,))
        w[_kd.OUT_HINT_A] = w[_kd.OUT_HINT_B] = -1.0
    if tolerance is not _TOLERANCE and not (type(tolerance) is float and 0.0 < tolerance <= _TOLERANCE_MAX):
        tolerance = as_positive(tolerance, "tolerance")
        if tolerance > _TOLERANCE_MAX:
            # a convergence tolerance, not an approximation knob: GJK's "touching" test and EPA's
            # stop read it, and at a large fraction of the size they disagree with the witnesses
            raise ValueError(f"tolerance: must be in (0, {_TOLERANCE_MAX}], got {tolerance}")
    if max_iterations is not _MAX_ITERATIONS and not (type(max_iterations) is int
                                                      and 4 <= max_iterations <= 100_000):
        max_iterations = as_count(max_iterations, "max_iterations", 4, 100_000)
    size = size_a + size_b
    if SIZE_MIN <= size <= SIZE_MAX:  # else scaled by a power of two (`collide.support.SIZE_MIN`)
        out = _empty(_OUT_SIZE)
        if not _loaded:
            _load_query()
        try:
            err = _query(desc_a, desc_b, ra, ta, rb, tb, size_a, size_b, ORTHONORMAL_TOL, _LIMIT,
                         tolerance * size, w, max_iterations, out)
        except Exception:  # noqa: BLE001 - an argument not in the kernel's one form: converted, or named
            # numba's dispatch refuses it with TypeError, or with another error of its typing of an
            # odd object (NumbaTypeError for a masked array, which is no TypeError); the kernel
            # itself raises nothing, and an error that is not the arguments' raises again below
            ra, ta, rb, tb, w = _canonical(pose_a, pose_b, w)
            err = _query(desc_a, desc_b, ra, ta, rb, tb, size_a, size_b, ORTHONORMAL_TOL, _LIMIT,
                         tolerance * size, w, max_iterations, out)
    else:
        if not _loaded:
            _load_query()
        ra, ta, rb, tb, w = _canonical(pose_a, pose_b, w)
        out, err = _query_scaled(a, b, ea, eb, ra, ta, rb, tb, w, tolerance, max_iterations)
    if err:
        if err < 10:
            _raise(err, "pose_a", ra, ta, size_a)
        _raise(err - 10, "pose_b", rb, tb, size_b)
    r = _new(Distance)
    r._out = out
    return r
