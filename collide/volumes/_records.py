"""Bounding volumes (AABB, Sphere, OBB) as small array records: fitting, transforms, overlaps.

Fitters only choose a centre or an orientation; extents and radii are then measured from the
points themselves, so every fitted volume contains its cloud by construction (up to rounding),
whatever the fitter's quality.

* `fit_aabb`: exact. `fit_sphere`: ``"exact"`` minimal sphere (Welzl 1991, move-to-front, on a
  growing working set) or ``"ritter"`` (1990). `fit_obb`: ``"exact"`` minimum volume
  (O'Rourke 1985, collide._obb_exact), ``"optimal"`` within 1 % of it (exact on small hulls,
  else subset searches and hull-face candidates polished by a compass search on rotations;
  measured in tests/bench/fitting.txt) or ``"pca"``.
* `KDOP` and `fit_kdop`: 6-, 14-, 18- and 26-DOPs (Klosowski et al. 1998).
* `transform` (rigid maps), `aabb_of`, and `overlap` for every pair of kinds (the OBB test is
  the 15-axis separating-axis test of Gottschalk 1996 / Ericson 2005 §4.4.1), conservative
  under rounding; `overlap_spheres` and `overlap_obbs` test many pairs given as arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy.spatial import ConvexHull, QhullError

from . import _obb_exact as _exact
from . import hull as _hull
from ._validate import as_array, as_points, as_radius


# ----------------------------------------------------------------------------------------------
# Records

# Relative slack of the overlap tests and of the records' checks: overlap tests compare with
# this much room (relative to the coordinates' size) so that rounding can only report an
# overlap, never hide one (DESIGN.md: a missed pair is the one unforgivable failure).
OVERLAP_RTOL = 1e-12

# Inflation of fitted OBBs and spheres, relative to the coordinates' size (8 ulps).
_ROUNDING_PAD = 8.0 * np.finfo(np.float64).eps
# ... plus this much: among subnormal coordinates (below 2.2e-308) rounding is absolute, a few
# multiples of 5e-324, and a relative pad alone lost points of a cloud scaled by 1e-310 (review,
# 2026-11-22).
_PAD_FLOOR = 64.0 * float(np.finfo(np.float64).smallest_subnormal)

# How far from orthonormal an OBB's rotation may be (max |R^T R - I|) before it is rejected.
ROTATION_TOL = 1e-6
# Up to this, a rotation is orthonormal within rounding and kept as given; beyond it (and up to
# ROTATION_TOL) an OBB replaces it by the nearest rotation, grown to contain the box as given.
_EXACT_ROTATION = 64.0 * np.finfo(np.float64).eps


# Corner signs of a box, x slowest: corner i = centre + signs[i] * half (in the box's axes).
_CORNER_SIGNS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)


def obb_corners(center: np.ndarray, rotation: np.ndarray, half_extents: np.ndarray) -> np.ndarray:
    """The 8 corners ``(8, 3)`` of the box ``center`` + ``rotation`` @ [-h, h] (columns are axes)."""
    center = as_array(center, "center", (3,))
    rotation = as_array(rotation, "rotation", (3, 3))
    half_extents = as_array(half_extents, "half_extents", (3,))
    return center + (_CORNER_SIGNS * half_extents) @ rotation.T


def aabb_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 8 corners ``(8, 3)`` of ``[lo, hi]``, each coordinate exactly ``lo`` or ``hi``."""
    return np.where(_CORNER_SIGNS < 0, lo, hi)


def _float_vec(value, name: str) -> np.ndarray:
    # Any float array, infinities allowed (the empty box); complex and non-numbers rejected.
    if np.iscomplexobj(value):
        raise ValueError(f"{name}: complex values are not coordinates")
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: cannot be read as a float64 array ({exc})") from None


def _vec3(value, name: str) -> np.ndarray:
    arr = as_array(value, name, (3,)).copy()
    arr.setflags(write=False)
    return arr


def _rotation(value, name: str) -> np.ndarray:
    rot = as_array(value, name, (3, 3)).copy()
    err = float(np.abs(rot.T @ rot - np.eye(3)).max())
    if err > ROTATION_TOL:
        raise ValueError(f"{name}: not orthonormal (max |R^T R - I| = {err:.3g})")
    if np.linalg.det(rot) < 0.0:
        raise ValueError(f"{name}: a reflection (determinant -1), expected a rotation")
    rot.setflags(write=False)
    return rot


@dataclass(frozen=True, eq=False)
class AABB:
    """Axis-aligned box ``[lo, hi]``.

    Attributes
    ----------
    lo, hi : (3,) float64
        Corners, read-only; ``lo <= hi``. The empty box has ``lo = +inf`` and ``hi = -inf``
        (see `AABB.empty`); it contains and overlaps nothing.
    """

    lo: np.ndarray
    hi: np.ndarray

    def __reduce__(self):
        # Rebuilt through __post_init__ (copy, pickle): arrays stay read-only copies.
        return (AABB, (self.lo, self.hi))

    def __post_init__(self):
        lo, hi = _float_vec(self.lo, "lo"), _float_vec(self.hi, "hi")
        empty = lo.shape == hi.shape == (3,) and np.all(lo == np.inf) and np.all(hi == -np.inf)
        if not empty:
            lo, hi = _vec3(lo, "lo"), _vec3(hi, "hi")
            if np.any(lo > hi):
                raise ValueError(f"lo: must be <= hi on every axis, got lo={lo}, hi={hi}")
        else:
            lo, hi = lo.copy(), hi.copy()
            lo.setflags(write=False)
            hi.setflags(write=False)
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)

    @classmethod
    def empty(cls) -> "AABB":
        """The empty box."""
        return cls(np.full(3, np.inf), np.full(3, -np.inf))

    @property
    def is_empty(self) -> bool:
        """True for the empty box."""
        return bool(self.lo[0] > self.hi[0])

    @property
    def center(self) -> np.ndarray:
        """(3,) float64: the middle (NaN for the empty box)."""
        return 0.5 * (self.lo + self.hi)

    @property
    def half_extents(self) -> np.ndarray:
        """(3,) float64: half side lengths."""
        return 0.5 * (self.hi - self.lo)

    def volume(self) -> float:
        """Volume (0 for an empty box)."""
        return 0.0 if self.is_empty else float(np.prod(self.hi - self.lo))

    def contains(self, points, rtol: float = 0.0) -> np.ndarray:
        """Which points lie in the box, widened by ``rtol`` times its coordinates' size.

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
        if self.is_empty:
            return np.zeros(len(p), dtype=bool)
        pad = as_radius(rtol, "rtol") * float(np.max(np.abs(np.concatenate([self.lo, self.hi]))))
        return np.all((p >= self.lo - pad) & (p <= self.hi + pad), axis=1)

    def aabb(self) -> "AABB":
        """The box itself."""
        return self

    def overlaps(self, other) -> bool:
        """Whether this box and another volume may intersect (see `overlap`)."""
        return overlap(self, other)

    def transformed(self, rotation, translation) -> "OBB":
        """The box under a rigid map: an `OBB` (see `transform`)."""
        return transform(self, rotation, translation)


@dataclass(frozen=True, eq=False)
class Sphere:
    """Ball of ``radius`` around ``center``.

    Attributes
    ----------
    center : (3,) float64
        Read-only.
    radius : float
        ``>= 0``.
    """

    center: np.ndarray
    radius: float

    def __reduce__(self):
        # Rebuilt through __post_init__ (copy, pickle): arrays stay read-only copies.
        return (Sphere, (self.center, self.radius))

    def __post_init__(self):
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        object.__setattr__(self, "radius", as_radius(self.radius, "radius"))

    def volume(self) -> float:
        """Volume."""
        return 4.0 / 3.0 * np.pi * self.radius**3

    def contains(self, points, rtol: float = 0.0) -> np.ndarray:
        """Which points lie in the ball, widened by ``rtol`` times its size.

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
        pad = as_radius(rtol, "rtol") * max(self.radius, float(np.max(np.abs(self.center))))
        return row_norms(p - self.center) <= self.radius + pad

    def aabb(self) -> AABB:
        """The exact axis-aligned box of the ball."""
        return AABB(self.center - self.radius, self.center + self.radius)

    def overlaps(self, other) -> bool:
        """Whether this ball and another volume may intersect (see `overlap`)."""
        return overlap(self, other)

    def transformed(self, rotation, translation) -> "Sphere":
        """The ball under a rigid map (see `transform`)."""
        return transform(self, rotation, translation)


@dataclass(frozen=True, eq=False)
class OBB:
    """Oriented box.

    Attributes
    ----------
    center : (3,) float64
        Read-only.
    rotation : (3, 3) float64
        Read-only, a rotation (orthonormal, determinant +1); its columns are the box axes. One
        given within `ROTATION_TOL` of orthonormal but not within rounding (a float32 rotation)
        is replaced by the nearest rotation, and ``half_extents`` grown so that the box contains
        the one given.
    half_extents : (3,) float64
        Read-only, ``>= 0``: half side lengths along the axes.
    """

    center: np.ndarray
    rotation: np.ndarray
    half_extents: np.ndarray

    def __reduce__(self):
        # Rebuilt through __post_init__ (copy, pickle): arrays stay read-only copies.
        return (OBB, (self.center, self.rotation, self.half_extents))

    def __post_init__(self):
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        rot = _rotation(self.rotation, "rotation")
        half = _vec3(self.half_extents, "half_extents")
        if np.any(half < 0.0):
            raise ValueError(f"half_extents: must be >= 0, got {half}")
        if float(np.abs(rot.T @ rot - np.eye(3)).max()) > _EXACT_ROTATION:
            # Accepted (within ROTATION_TOL: float32 rotations) but not orthonormal: the box it
            # describes, centre + R [-h, h], is held as the box with the nearest rotation that
            # contains it. Every test here reads axes as orthonormal (R^T for R^-1): with the
            # matrix as given, a box missed a point at its own corner (review, 2026-11-22).
            axes = _orthonormal(rot)
            grown = np.abs(axes.T @ rot) @ half
            half = grown + _ROUNDING_PAD * float(np.sum(grown))
            half.setflags(write=False)
            axes.setflags(write=False)
            rot = axes
        object.__setattr__(self, "rotation", rot)
        object.__setattr__(self, "half_extents", half)

    def volume(self) -> float:
        """Volume."""
        return float(8.0 * np.prod(self.half_extents))

    def corners(self) -> np.ndarray:
        """The 8 corners, ``(8, 3) float64``."""
        return obb_corners(self.center, self.rotation, self.half_extents)

    def contains(self, points, rtol: float = 0.0) -> np.ndarray:
        """Which points lie in the box, widened by ``rtol`` times its size.

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
        local = (p - self.center) @ self.rotation
        pad = as_radius(rtol, "rtol") * max(float(np.max(self.half_extents)), float(np.max(np.abs(self.center))))
        return np.all(np.abs(local) <= self.half_extents + pad, axis=1)

    def aabb(self) -> AABB:
        """The exact axis-aligned box of the oriented box: half widths ``|R| @ half_extents``."""
        half = np.abs(self.rotation) @ self.half_extents
        return AABB(self.center - half, self.center + half)

    def overlaps(self, other) -> bool:
        """Whether this box and another volume may intersect (see `overlap`)."""
        return overlap(self, other)

    def transformed(self, rotation, translation) -> "OBB":
        """The box under a rigid map (see `transform`)."""
        return transform(self, rotation, translation)


# ----------------------------------------------------------------------------------------------
# Fitting: AABB and OBB

# Largest coordinate (plus radius) the fitters accept (`hull.MAX_COORDINATE`): their squared
# distances and SVDs overflow float64 beyond about 1e154 (1e300 gave "radius: must be finite, got
# inf" and "rotation: not orthonormal", naming nothing the user passed).
MAX_COORDINATE = _hull.MAX_COORDINATE
_require_points = _hull.require_bounded


def row_norms(d: np.ndarray) -> np.ndarray:
    """Euclidean norms of the rows of ``d`` ``(n, 3)``, at every scale: the rows are divided by
    their largest magnitude first, so that no square underflows (a 1e-162 cloud's squares are
    zero in float64) or overflows."""
    d = np.asarray(d, np.float64)
    s = float(np.max(np.abs(d))) if d.size else 0.0
    if s == 0.0 or not np.isfinite(s):
        return np.sqrt(np.sum(d * d, axis=1))
    return s * np.sqrt(np.sum((d / s) ** 2, axis=1))


def fit_aabb(points: np.ndarray, radius: float = 0.0) -> AABB:
    """Exact AABB of ``hull(points) ⊕ ball(radius)``; an empty cloud gives the empty box.

    Parameters
    ----------
    points : (n, 3) float64
    radius : float
    """
    points = as_points(points, "points")
    radius = as_radius(radius, "radius")
    if len(points) == 0:
        return AABB.empty()
    with np.errstate(over="ignore"):
        lo, hi = points.min(axis=0) - radius, points.max(axis=0) + radius
        if radius > 0.0:
            # The sums are rounded to nearest, which can fall an ulp inside the ball's extreme
            # point (0.1 + 0.7 -> 0.7999999999999999): one ulp outward makes the box contain it.
            lo, hi = np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ValueError(f"aabb: coordinates plus radius overflow float64 (largest |coordinate| "
                         f"{float(np.abs(points).max()):.3g}, radius {radius:.3g})")
    return AABB(lo, hi)


def box_from_axes(points: np.ndarray, radius: float, rotation: np.ndarray) -> OBB:
    """The smallest box with the given axes that contains the cloud.

    Parameters
    ----------
    points : (n, 3) float64
    radius : float
    rotation : (3, 3) float64
        Orthonormal (within `ROTATION_TOL`: the nearest rotation is used); columns are the axes.
    """
    points = as_points(points, "points")
    radius = as_radius(radius, "radius")
    _require_points(points, "points", radius)
    rotation = _rotation(rotation, "rotation")
    if float(np.abs(rotation.T @ rotation - np.eye(3)).max()) > _EXACT_ROTATION:
        rotation = _orthonormal(rotation)  # the axes are a choice: take the nearest orthonormal ones
    local = points @ rotation
    lo, hi = local.min(axis=0), local.max(axis=0)
    center = rotation @ ((lo + hi) / 2.0)
    return OBB(center, rotation, (hi - lo) / 2.0 + radius)


def _right_handed(rot: np.ndarray) -> np.ndarray:
    rot = np.array(rot, dtype=np.float64)
    if np.linalg.det(rot) < 0.0:
        rot[:, 2] = -rot[:, 2]
    return rot


def _principal(points: np.ndarray) -> tuple[np.ndarray, int]:
    # Principal axes (rows, largest spread first) and affine rank, with the thresholds of
    # hull.affine_basis but a thin SVD: hull.affine_basis takes a full one (an (n, n) factor,
    # 8 ms at n = 1000 and out of memory at n = 1e5, measured 2026-11-21).
    centred = points - points.mean(axis=0)
    extent = float(np.abs(centred).max()) if len(points) > 1 else 0.0
    if extent == 0.0 or extent <= _hull.FLAT_TOL * float(np.abs(points.mean(axis=0)).max()):
        return np.eye(3), 0
    _, s, vt = np.linalg.svd(centred, full_matrices=len(points) < 3)
    s = np.concatenate([s, np.zeros(3 - len(s))])
    noise = 64.0 * np.finfo(np.float64).eps * float(np.abs(points).max()) * np.sqrt(len(points))
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


def _hull_points(points: np.ndarray) -> tuple[np.ndarray, "ConvexHull | None"]:
    # Hull vertices of a cloud (centred by the caller), and Qhull's hull when it was computed
    # on the full-rank cloud (its facets serve the OBB candidates). This mirrors
    # hull.hull_indices (work in the affine hull's dimension) with the thin SVD of _principal:
    # hull.affine_basis takes a full one, which costs 15 ms on 256 points and 4 s on 10k here
    # (measured 2026-11-21). If Qhull still refuses, hull.hull_vertices reduces the cloud in
    # chunks: hull(P) = hull(union of the chunks' hull vertices).
    axes, rank = _principal(points)
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


def _box_volumes(points: np.ndarray, rots: np.ndarray, radius: float) -> np.ndarray:
    # Volumes (k,) of the boxes with axes rots (k, 3, 3) around points (n, 3): one BLAS
    # product against all 3k axes, then contiguous column reductions.
    proj = points @ rots.transpose(0, 2, 1).reshape(-1, 3).T
    ext = (proj.max(axis=0) - proj.min(axis=0)).reshape(-1, 3)
    return np.prod(ext + 2.0 * radius, axis=1)


# The 26 directions of the compass (pattern) search on rotation vectors.
_COMPASS = np.array([[x, y, z] for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1)
                     if (x, y, z) != (0, 0, 0)], dtype=np.float64)
_COMPASS /= np.linalg.norm(_COMPASS, axis=1)[:, None]


@numba.njit(cache=True)
def _nb_volume(points, rot, radius, index, count):
    # Volume of the box with axes ``rot`` around points[index[:count]].
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for t in range(count):
        i = index[t]
        for a in range(3):
            p = points[i, 0] * rot[0, a] + points[i, 1] * rot[1, a] + points[i, 2] * rot[2, a]
            lo[a] = min(lo[a], p)
            hi[a] = max(hi[a], p)
    w = 2.0 * radius
    return (hi[0] - lo[0] + w) * (hi[1] - lo[1] + w) * (hi[2] - lo[2] + w)


@numba.njit(cache=True)
def _nb_polish(points, rot, radius, step, min_step, max_iter, compass):
    # Compass search on SO(3) (Kolda, Lewis & Torczon 2003, "Optimization by direct search",
    # SIAM Review 45): try the 26 body-frame rotations by angle ``step``, move to the best one
    # if it shrinks the box, else halve the step. Only points that can become extreme are
    # evaluated: turning a unit axis by angle t moves p's projection by at most t |p|, so a
    # point more than 2 t max|p| inside both extremes of every axis cannot reach one.
    n = points.shape[0]
    every = np.arange(n)
    best = _nb_volume(points, rot, radius, every, n)
    rmax = 0.0
    for i in range(n):
        rmax = max(rmax, np.sqrt(points[i, 0] ** 2 + points[i, 1] ** 2 + points[i, 2] ** 2))
    proj = np.empty((n, 3))
    near = np.empty(n, dtype=np.int64)
    cand = np.empty((3, 3))
    best_cand = np.empty((3, 3))
    k = compass.shape[0]
    for _ in range(max_iter):
        if step < min_step:
            break
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for i in range(n):
            for a in range(3):
                p = points[i, 0] * rot[0, a] + points[i, 1] * rot[1, a] + points[i, 2] * rot[2, a]
                proj[i, a] = p
                lo[a] = min(lo[a], p)
                hi[a] = max(hi[a], p)
        reach = 2.0 * step * rmax * (1.0 + 1e-9)
        count = 0
        for i in range(n):
            for a in range(3):
                if proj[i, a] >= hi[a] - reach or proj[i, a] <= lo[a] + reach:
                    near[count] = i
                    count += 1
                    break
        s, c = np.sin(step), np.cos(step)
        found = -1.0
        for j in range(k):
            # Rodrigues: R = I + s K + (1 - c) K^2 for the unit axis compass[j].
            x, y, z = compass[j, 0], compass[j, 1], compass[j, 2]
            r = np.array([[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
                          [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
                          [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]])
            for a in range(3):
                for b in range(3):
                    cand[a, b] = rot[a, 0] * r[0, b] + rot[a, 1] * r[1, b] + rot[a, 2] * r[2, b]
            v = _nb_volume(points, cand, radius, near, count)
            if v < best * (1.0 - 1e-12) and (found < 0.0 or v < found):
                found = v
                best_cand[:, :] = cand
        if found >= 0.0:
            rot = best_cand.copy()
            best = found
        else:
            step *= 0.5
    return rot, best


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
    # np.cross costs ~15 us of argument handling per call on 3-vectors.
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
# Chosen with tests/bench/fitting.py (results in fitting.txt).
_FACE_CANDIDATES = 12
_POLISH_STARTS = 3
_POLISH_STEP = 0.1
_POLISH_MIN_STEP = 1e-5
# The "optimal" OBB is the exact one for hulls of up to _EXACT_HULL vertices. Larger hulls get
# _SUBSET_ROUNDS rounds of the exact search (to a relative _SUBSET_TOL) on their vertices
# extreme along 13 directions and the _SEED_SUPPORTS most extreme along each axis of the best
# _POLISH_STARTS starting boxes (_obb_exact.exact_axes): its box where it is certified minimal
# for the whole hull, else one more start, polished first. Chosen with tests/bench/fitting.py
# (the ablation in fitting.txt).
_EXACT_HULL = 64
_SUBSET_ROUNDS = 1
_SUBSET_TOL = 1e-6
_SEED_SUPPORTS = 1


# Box evaluations the "optimal" fitter gives the exact search of a small hull (see
# _optimal_rotation); round hulls need far fewer, near-flat ones more.
_EXACT_BUDGET = 300_000


def _optimal_rotation(verts: np.ndarray, hull: "ConvexHull | None", radius: float) -> np.ndarray:
    # verts: hull vertices, centred; hull: Qhull's hull of a superset of verts in the same frame
    # (None for degenerate clouds). Returns the rotation of a box within 1 % of the minimum
    # volume on every cloud tested (the rule is in fit_obb's docstring): a minimal box often has
    # a face flush with a hull face (the face candidates), otherwise two adjacent faces flush
    # with hull edges (O'Rourke 1985), which the exact search on a subset and the polish reach.
    # The exact search within a budget of box evaluations: its branch and bound splits in
    # proportion to 1 / thickness on near-flat hulls. Out of
    # budget, its best box joins the starts below (which include the box flush with the slab's
    # face) and the polish.
    exact_rot = None
    if len(verts) <= _EXACT_HULL:
        exact_rot, certified = _exact_rotation(verts, radius, budget=_EXACT_BUDGET)
        if certified:
            return exact_rot
    axes, rank = _principal(verts)
    if rank <= 1:
        return _right_handed(axes.T)
    if rank == 2:
        # Exact minimal-area rectangle; with a radius the box has thickness 2 r and a slight
        # tilt can trade it against area, so polish then.
        rot = _right_handed(_frame_from_normal(axes[2], verts))
        if radius > 0.0:
            rot = _orthonormal(_nb_polish(np.ascontiguousarray(verts), rot, float(radius), _POLISH_STEP,
                                          _POLISH_MIN_STEP, 1000, _COMPASS)[0])
        return rot
    starts = [_right_handed(axes.T)]
    if hull is not None:
        starts.append(_surface_pca(hull.points, hull.simplices))
        normals = hull.equations[:, :3]
        tri = hull.points[hull.simplices]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        # Qhull splits a planar face into triangles with (nearly) equal normals: merge them.
        _, group = np.unique(np.round(normals, 6), axis=0, return_inverse=True)
        group = group.ravel()
        group_area = np.bincount(group, weights=area)
        group_normal = np.zeros((len(group_area), 3))
        np.add.at(group_normal, group, area[:, None] * normals)
        for g in np.argsort(-group_area)[:_FACE_CANDIDATES]:
            norm = float(np.linalg.norm(group_normal[g]))
            if norm > 0.0:
                starts.append(_right_handed(_frame_from_normal(group_normal[g] / norm, verts)))
    if exact_rot is not None:
        starts.append(exact_rot)
    vols = _box_volumes(verts, np.stack(starts), radius)
    order = np.argsort(vols, kind="stable")
    if _SUBSET_ROUNDS > 0 and exact_rot is None:
        # The exact search on the vertices extreme along 13 directions and near the faces of
        # the best starting boxes: its box is the exact one where it is certified minimal for
        # the whole hull, and otherwise one more start.
        sub_rot, certified = _exact_rotation(verts, radius, _SUBSET_ROUNDS, 0, _SUBSET_TOL,
                                             [starts[k] for k in order[:_POLISH_STARTS]])
        if certified:
            return sub_rot
        starts.append(sub_rot)
        order = np.r_[len(starts) - 1, order]
    chosen: list[np.ndarray] = []
    for k in order:
        if len(chosen) == _POLISH_STARTS:
            break
        if not any(_same_axes(starts[k], c) for c in chosen):
            chosen.append(starts[k])
    best_rot, best_vol = chosen[0], np.inf
    pts = np.ascontiguousarray(verts)
    for rot in chosen:
        rot, vol = _nb_polish(pts, np.ascontiguousarray(rot), float(radius), _POLISH_STEP,
                              _POLISH_MIN_STEP, 1000, _COMPASS)
        if vol < best_vol:
            best_rot, best_vol = rot, vol
    return _orthonormal(best_rot)


def _exact_rotation(verts: np.ndarray, radius: float, rounds: int | None = None,
                    direct: int = _exact.DIRECT, tol: float = _exact.TOL, seeds=(),
                    budget: int = -1) -> tuple[np.ndarray, bool]:
    # verts: hull vertices (centred by the caller). Rotation of the minimum-volume box of
    # hull(verts) ⊕ ball(radius) and whether it is certified (always, unless ``rounds`` limits
    # the subset rounds of _obb_exact.exact_axes). By cases of the affine rank:
    # 0: any box is a cube of side 2r. 1: the segment's axis; of every box of a segment of
    # length L, prod(L |d . u_i| + 2r) is least along it (the sum of the logs is concave and
    # increasing in each |d . u_i|, whose sum is >= 1, so its least value on the simplex, at a
    # vertex, bounds it). 2 with r = 0: volume 0 with the plane's normal as an axis, and among
    # those the least area (the minimal rectangle, as the "optimal" fitter). Otherwise the
    # exact search of _obb_exact over the hull's (or the polygon's) Gauss map.
    axes, rank = _principal(verts)
    if rank <= 1:
        return _right_handed(axes.T), True
    if rank == 2 and radius == 0.0:
        return _right_handed(_frame_from_normal(axes[2], verts)), True
    c = verts.mean(axis=0)
    scale = float(np.abs(verts - c).max())
    local = (verts - c) / scale
    # In units of the hull's size; beyond 1e15 every orientation's volume is (2r)^3 within
    # rounding (the widths change it by 3e-15 at most), and the cap keeps the cubes finite.
    r = min(radius / scale, 1e15)
    if rank == 2:
        start = _right_handed(_frame_from_normal(axes[2], verts))
        rot, _, certified = _exact.exact_axes(local, r, start, lambda sub: _exact.flat_graph(sub, axes),
                                              rounds, direct, tol, seeds, _SEED_SUPPORTS, budget)
    else:
        rot, _, certified = _exact.exact_axes(local, r, _right_handed(axes.T), _exact.solid_graph,
                                              rounds, direct, tol, seeds, _SEED_SUPPORTS, budget)
    return _orthonormal(rot), certified


def fit_obb(points: np.ndarray, radius: float = 0.0, method: str = "optimal") -> OBB:
    """Oriented box of ``hull(points) ⊕ ball(radius)``.

    Parameters
    ----------
    points : (n, 3) float64
        Non-empty.
    radius : float
        The cloud's radius, ``>= 0``.
    method : {"optimal", "exact", "pca"}
        ``"exact"``: the minimum volume, exact up to rounding (relative 1e-12), by O'Rourke's
        theorem (1985: a minimal box has two adjacent faces flush with hull edges; it holds for
        ``prod(e_i + 2 radius)`` too, see collide/_obb_exact.py) and a certified branch and
        bound over its edge-pair families, on the hull's vertices; hulls of more than 64
        vertices through subsets of them with a certificate of optimality. ``O(E^2)`` pair
        screening plus about ``E^1.5`` evaluations (``E`` hull edges) for hulls with evenly
        spread faces, ``O(n^3)`` at worst (``n`` hull vertices). Slow cases: near-flat hulls
        take time in proportion to 1 / thickness (smallest over largest principal spread), and
        highly symmetric hulls (prisms over regular polygons) approach the worst case.
        ``"optimal"`` (the
        default): the exact box where the hull has at most 64 vertices and its search ends
        within 300,000 box evaluations (near-flat hulls may not: their best box so far then
        joins the local search's starts below, with the box flush with the slab's face).
        Otherwise one round of the exact
        search on a subset of the hull's vertices (those extreme along 13 directions and near
        the faces of the best starting boxes below): its box if it is certified minimal for the
        whole hull; else it joins the starts (the PCA axes, the hull surface's principal axes
        and boxes flush with the largest hull faces, each with its minimal-area rectangle by
        rotating calipers), and the best three are polished by a compass search on rotations.
        Within 1 % of the exact box on every cloud tested (tests/test_obb_exact.py,
        tests/bench/fitting.txt). ``"pca"``: principal axes of the hull vertices. Flat clouds
        (``radius = 0``) get a zero extent and their exact minimal-area rectangle.

    Returns
    -------
    OBB
        The method only picks the axes (a right-handed rotation); the centre and half extents
        are then measured from the points, plus ``radius``, so the box always contains the
        cloud. Degenerate clouds give boxes with zero extents (plus ``radius``).
    """
    points = as_points(points, "points")
    radius = as_radius(radius, "radius")
    _require_points(points, "obb", radius)
    if method not in ("optimal", "exact", "pca"):
        raise ValueError(f"method: expected 'optimal', 'exact' or 'pca', got {method!r}")
    # Centre first: Qhull and the SVD lose precision on coordinates far from the origin.
    offset = 0.5 * (points.min(axis=0) + points.max(axis=0))
    local = points - offset
    # The axes are chosen on the cloud scaled to unit size by a power of two (exact): a 1e-160
    # cloud's squares and products underflow, and its rotations came out not orthonormal. The
    # radius scales with it (capped where it dwarfs the cloud: any axes then do).
    e = int(np.frexp(float(np.abs(local).max()))[1])
    unit = np.ldexp(local, -e)
    unit_radius = min(float(np.ldexp(radius, -e)), 1e15)
    verts, hull = _hull_points(unit)
    if method == "pca":
        rot = pca_axes(verts)
    elif method == "exact":
        rot = _exact_rotation(verts, unit_radius)[0]
    else:
        rot = _optimal_rotation(verts, hull, unit_radius)
    # Extents from every point, not only the hull vertices: _hull_points (axes only) treats
    # thickness below ~1e-12 of the spread as flat and drops it, the box must not.
    box = box_from_axes(local, radius, rot)
    # A few ulps of the coordinates' size: moving the centre back by ``offset`` and a later
    # containment test in world coordinates each round by about eps * |x| (DESIGN.md: a tiny
    # conservative inflation rather than an exact comparison that rounding can break).
    # The radius too: half extent + radius rounds by up to an ulp of the radius.
    pad = _ROUNDING_PAD * (float(np.abs(offset).max()) + float(np.abs(local).max()) + radius) + _PAD_FLOOR
    return OBB(box.center + offset, box.rotation, box.half_extents + pad)


# ----------------------------------------------------------------------------------------------
# Fitting: spheres

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
# falling back to Welzl on the whole cloud. Timed on gaussian clouds of 8 to 1000 points
# (2026-11-21): 0.45-2.2 ms per cloud, against 0.6-2.1 ms (and 2 ms at 50 points) with 16 and 64.
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


# ----------------------------------------------------------------------------------------------
# k-DOPs (discrete oriented polytopes: Klosowski et al. 1998, "Efficient collision detection
# using bounding volume hierarchies of k-DOPs"): slabs along k/2 fixed directions.

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
        return overlap(self, other)

    def transformed(self, rotation, translation) -> "KDOP":
        """The tightest k-DOP of the polytope under a rigid map (see `transform`)."""
        return transform(self, rotation, translation)


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


# ----------------------------------------------------------------------------------------------
# Rigid transforms and overlap tests.

def transform(volume, rotation, translation):
    """A volume under the rigid map ``x -> rotation @ x + translation``.

    Parameters
    ----------
    volume : AABB, Sphere, OBB or KDOP
    rotation : (3, 3) float64
        A rotation (orthonormal, determinant +1).
    translation : (3,) float64

    Returns
    -------
    Sphere, OBB or KDOP
        A sphere stays a sphere and an OBB an OBB (both exact up to a few ulps of padding, and
        grown to bound the image when ``rotation`` is within `ROTATION_TOL` of orthonormal but
        not exactly so, as float32 rotations are); an AABB becomes the OBB it is mapped to (take
        ``.aabb()`` of it for an axis-aligned bound); a k-DOP becomes the tightest k-DOP of its
        moved vertices (it grows, as any fixed-direction bound does under rotation).
    """
    rot = _rotation(rotation, "rotation")
    t = as_array(translation, "translation", (3,))
    # ``rotation`` is accepted up to ROTATION_TOL from orthonormal (float32 poses), and the volume
    # must bound the image under the map as given: a ball grows by the map's largest stretch, a box
    # by the off-diagonal part of its axes' images seen from the new (orthonormal) axes. With an
    # exact rotation both are the identity up to rounding, covered by the pad.
    if isinstance(volume, KDOP):
        # Rotated slabs are no longer the fixed directions: refit to the moved vertices (the
        # image of a convex polytope under a linear map is the hull of its vertices' images).
        return fit_kdop(volume.vertices() @ rot.T + t, 0.0, volume.k)
    if isinstance(volume, Sphere):
        center = rot @ volume.center + t
        stretch = max(1.0, float(np.linalg.norm(rot, 2)))
        pad = _ROUNDING_PAD * (volume.radius + _moved_size(rot, volume.center, t)) + _PAD_FLOOR
        return Sphere(center, volume.radius * stretch + pad)
    if isinstance(volume, AABB):
        if volume.is_empty:
            raise ValueError("volume: the empty box has no transform (it bounds nothing)")
        volume = OBB(volume.center, np.eye(3), volume.half_extents)
    if isinstance(volume, OBB):
        center = rot @ volume.center + t
        image = rot @ volume.rotation  # the box's axes under the map, nearly orthonormal
        axes = _orthonormal(image)
        half = np.abs(axes.T @ image) @ volume.half_extents
        half += _ROUNDING_PAD * (float(np.sum(volume.half_extents)) + _moved_size(rot, volume.center, t)) + _PAD_FLOOR
        return OBB(center, axes, half)
    raise ValueError(f"volume: expected an AABB, Sphere, OBB or KDOP, got {type(volume).__name__}")


def _moved_size(rot: np.ndarray, center: np.ndarray, t: np.ndarray) -> float:
    # The magnitude of the terms summed into rot @ center + t: their rounding, not the result's
    # (which may cancel to 0), sets the error of the moved centre.
    return float((np.abs(rot) @ np.abs(center) + np.abs(t)).max())


def aabb_of(volume) -> AABB:
    """The axis-aligned box of an AABB, Sphere, OBB (exact) or KDOP (its axis slabs)."""
    if isinstance(volume, (AABB, Sphere, OBB, KDOP)):
        return volume.aabb()
    raise ValueError(f"volume: expected an AABB, Sphere, OBB or KDOP, got {type(volume).__name__}")


def _slack(*arrays) -> float:
    # Absolute room for rounding: OVERLAP_RTOL times the size of the numbers compared.
    return OVERLAP_RTOL * max(1.0, *(float(np.max(np.abs(a))) for a in arrays))


def _sphere_sphere(a: Sphere, b: Sphere) -> bool:
    d = a.center - b.center
    reach = a.radius + b.radius + _slack(a.center, b.center, a.radius, b.radius)
    return bool(d @ d <= reach * reach)


def _aabb_aabb(a: AABB, b: AABB) -> bool:
    if a.is_empty or b.is_empty:
        return False
    pad = _slack(a.lo, a.hi, b.lo, b.hi)
    return bool(np.all(a.lo <= b.hi + pad) and np.all(b.lo <= a.hi + pad))


def _sphere_aabb(s: Sphere, b: AABB) -> bool:
    if b.is_empty:
        return False
    # Closest point of the box to the centre (RTCD §5.2.5); compare its distance to the radius.
    d = s.center - np.clip(s.center, b.lo, b.hi)
    reach = s.radius + _slack(s.center, s.radius, b.lo, b.hi)
    return bool(d @ d <= reach * reach)


def _sphere_obb(s: Sphere, b: OBB) -> bool:
    # The same in the box's frame (RTCD §5.2.6).
    local = (s.center - b.center) @ b.rotation
    d = local - np.clip(local, -b.half_extents, b.half_extents)
    reach = s.radius + _slack(s.center, s.radius, b.center, b.half_extents)
    return bool(d @ d <= reach * reach)


def _obb_obb(a: OBB, b: OBB) -> bool:
    # Separating-axis test on all 15 axes (Gottschalk 1996; Ericson, Real-Time Collision
    # Detection, 2005, §4.4.1): the 3 + 3 face normals and the 9 edge-edge cross products,
    # written in a's frame. An epsilon added to |R| keeps near-parallel edges, whose cross
    # product is a near-zero (meaningless) axis, from reporting a false separation.
    r = a.rotation.T @ b.rotation            # r[i, j] = a_i . b_j
    t = (b.center - a.center) @ a.rotation   # b's centre in a's frame
    eps = 1e-12
    ar = np.abs(r) + eps
    ha, hb = a.half_extents, b.half_extents
    pad = _slack(a.center, b.center, ha, hb)
    # a's axes
    if np.any(np.abs(t) > ha + ar @ hb + pad):
        return False
    # b's axes
    if np.any(np.abs(t @ r) > ar.T @ ha + hb + pad):
        return False
    # a_i x b_j, i, j in 0..2 (Ericson's nine cases, vectorised): with (i1, i2) the other two
    # indices of i and (j1, j2) those of j,
    #   |t[i2] r[i1, j] - t[i1] r[i2, j]| > ha[i1] ar[i2, j] + ha[i2] ar[i1, j]
    #                                      + hb[j1] ar[i, j2] + hb[j2] ar[i, j1]
    i1, i2 = np.array([1, 2, 0]), np.array([2, 0, 1])
    lhs = np.abs(t[i2][:, None] * r[i1, :] - t[i1][:, None] * r[i2, :])
    rhs = (ha[i1][:, None] * ar[i2, :] + ha[i2][:, None] * ar[i1, :]
           + ar[:, i2] * hb[i1][None, :] + ar[:, i1] * hb[i2][None, :])
    return not bool(np.any(lhs > rhs + pad))


def _as_obb(box: AABB) -> OBB:
    return OBB(box.center, np.eye(3), box.half_extents)


def overlap(a, b) -> bool:
    """Whether two bounding volumes may intersect (closed sets: touching counts).

    Parameters
    ----------
    a, b : AABB, Sphere, OBB or KDOP
        In any combination; the test is symmetric.

    Returns
    -------
    bool
        Exact up to rounding for spheres, AABBs and OBBs, and conservative: comparisons get a
        slack of `OVERLAP_RTOL` times the coordinates' size, so rounding can only report an
        overlap. A k-DOP is tested against another by its shared slabs, and against any other
        kind by its axis slabs (its AABB): conservative, not exact. Empty boxes overlap
        nothing.
    """
    kinds = (AABB, Sphere, OBB, KDOP)
    for name, v in (("a", a), ("b", b)):
        if not isinstance(v, kinds):
            raise ValueError(f"{name}: expected an AABB, Sphere, OBB or KDOP, got {type(v).__name__}")
    if isinstance(a, KDOP) and isinstance(b, KDOP):
        return _kdop_kdop(a, b)
    if isinstance(a, KDOP):
        a = a.aabb()
    if isinstance(b, KDOP):
        b = b.aabb()
    if isinstance(b, Sphere) and not isinstance(a, Sphere):
        a, b = b, a
    if isinstance(a, Sphere):
        if isinstance(b, Sphere):
            return _sphere_sphere(a, b)
        return _sphere_aabb(a, b) if isinstance(b, AABB) else _sphere_obb(a, b)
    if isinstance(a, AABB) and isinstance(b, AABB):
        return _aabb_aabb(a, b)
    if (isinstance(a, AABB) and a.is_empty) or (isinstance(b, AABB) and b.is_empty):
        return False
    return _obb_obb(_as_obb(a) if isinstance(a, AABB) else a, _as_obb(b) if isinstance(b, AABB) else b)


# ----------------------------------------------------------------------------------------------
# Batched forms: many pairs at once, as parallel arrays (numpy; the per-step kernels of the
# broad phase are separate, these serve setup code and as their reference).

def overlap_spheres(center_a, radius_a, center_b, radius_b) -> np.ndarray:
    """Pairwise sphere overlap, ``a[i]`` against ``b[i]`` (same rule as `overlap`).

    Parameters
    ----------
    center_a, center_b : (n, 3) float64
    radius_a, radius_b : (n,) float64
        ``>= 0``.

    Returns
    -------
    overlaps : (n,) bool
    """
    ca = as_array(center_a, "center_a", (None, 3))
    n = len(ca)
    cb = as_array(center_b, "center_b", (n, 3))
    ra = as_array(radius_a, "radius_a", (n,))
    rb = as_array(radius_b, "radius_b", (n,))
    if np.any(ra < 0) or np.any(rb < 0):
        raise ValueError("radius_a, radius_b: must be >= 0")
    size = np.maximum.reduce([np.abs(ca).max(axis=1, initial=0.0), np.abs(cb).max(axis=1, initial=0.0),
                              ra, rb, np.ones(n)])
    reach = ra + rb + OVERLAP_RTOL * size
    return np.sum((ca - cb) ** 2, axis=1) <= reach * reach


def overlap_obbs(center_a, rotation_a, half_a, center_b, rotation_b, half_b) -> np.ndarray:
    """Pairwise OBB overlap, ``a[i]`` against ``b[i]``: the 15-axis test of `overlap`, batched.

    Parameters
    ----------
    center_a, center_b : (n, 3) float64
    rotation_a, rotation_b : (n, 3, 3) float64
        Rotations; columns are the box axes (not checked for orthonormality here).
    half_a, half_b : (n, 3) float64
        Half extents, ``>= 0``.

    Returns
    -------
    overlaps : (n,) bool
        Conservative under rounding, like `overlap`.
    """
    ca = as_array(center_a, "center_a", (None, 3))
    n = len(ca)
    cb = as_array(center_b, "center_b", (n, 3))
    ra_ = as_array(rotation_a, "rotation_a", (n, 3, 3))
    rb_ = as_array(rotation_b, "rotation_b", (n, 3, 3))
    ha, hb = as_array(half_a, "half_a", (n, 3)), as_array(half_b, "half_b", (n, 3))
    if np.any(ha < 0) or np.any(hb < 0):
        raise ValueError("half_a, half_b: must be >= 0")
    r = np.einsum("nki,nkj->nij", ra_, rb_)                  # r[n, i, j] = a_i . b_j
    t = np.einsum("nk,nki->ni", cb - ca, ra_)                 # b's centre in a's frame
    ar = np.abs(r) + 1e-12                                    # Ericson's epsilon, see _obb_obb
    size = np.maximum.reduce([np.abs(ca).max(axis=1, initial=0.0), np.abs(cb).max(axis=1, initial=0.0),
                              ha.max(axis=1, initial=0.0), hb.max(axis=1, initial=0.0), np.ones(n)])
    pad = OVERLAP_RTOL * size
    sep = np.any(np.abs(t) > ha + np.einsum("nij,nj->ni", ar, hb) + pad[:, None], axis=1)
    tb = np.einsum("ni,nij->nj", t, r)                       # b's centre on b's axes
    sep |= np.any(np.abs(tb) > np.einsum("nij,ni->nj", ar, ha) + hb + pad[:, None], axis=1)
    i1, i2 = np.array([1, 2, 0]), np.array([2, 0, 1])
    lhs = np.abs(t[:, i2, None] * r[:, i1, :] - t[:, i1, None] * r[:, i2, :])
    rhs = (ha[:, i1, None] * ar[:, i2, :] + ha[:, i2, None] * ar[:, i1, :]
           + ar[:, :, i2] * hb[:, None, i1] + ar[:, :, i1] * hb[:, None, i2])
    sep |= np.any(lhs > rhs + pad[:, None, None], axis=(1, 2))
    return ~sep
