"""The bounding-volume records AABB, Sphere and OBB: validated, read-only, picklable.

Each record holds small read-only arrays, checks them when built (a clear ValueError naming what
is wrong) and offers ``volume``, ``contains``, ``aabb``, ``overlaps`` and ``transformed``; the
last two are the package's `overlap` and `transform` (`_overlap`, `_transform`), which sit above
this module. Also here: the rounding rules every volume shares (`OVERLAP_RTOL`, the fitters'
pads, `ROTATION_TOL`) and the corner and norm helpers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validate import as_array, as_radius
from ._axes import _orthonormal

__all__ = ["AABB", "OBB", "OVERLAP_RTOL", "ROTATION_TOL", "Sphere", "aabb_corners", "obb_corners", "row_norms"]

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


def _slack(*arrays) -> float:
    # Absolute room for rounding: OVERLAP_RTOL times the size of the numbers compared.
    return OVERLAP_RTOL * max(1.0, *(float(np.max(np.abs(a))) for a in arrays))


def _overlap(a, b) -> bool:
    # The records' ``overlaps``: `collide.volumes.overlap` lives above this module (it imports
    # the records), so it is imported when first called.
    from ._overlap import overlap

    return overlap(a, b)


def _transform(volume, rotation, translation):
    # The records' ``transformed``: `collide.volumes.transform`, imported when called (see _overlap).
    from ._transform import transform

    return transform(volume, rotation, translation)


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


def row_norms(d: np.ndarray) -> np.ndarray:
    """Euclidean norms of the rows of ``d`` ``(n, 3)``, at every scale: the rows are divided by
    their largest magnitude first, so that no square underflows (a 1e-162 cloud's squares are
    zero in float64) or overflows."""
    d = np.asarray(d, np.float64)
    s = float(np.max(np.abs(d))) if d.size else 0.0
    if s == 0.0 or not np.isfinite(s):
        return np.sqrt(np.sum(d * d, axis=1))
    return s * np.sqrt(np.sum((d / s) ** 2, axis=1))


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
        return _overlap(self, other)

    def transformed(self, rotation, translation) -> "OBB":
        """The box under a rigid map: an `OBB` (see `transform`)."""
        return _transform(self, rotation, translation)


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
        return _overlap(self, other)

    def transformed(self, rotation, translation) -> "Sphere":
        """The ball under a rigid map (see `transform`)."""
        return _transform(self, rotation, translation)


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
        return _overlap(self, other)

    def transformed(self, rotation, translation) -> "OBB":
        """The box under a rigid map (see `transform`)."""
        return _transform(self, rotation, translation)


# ----------------------------------------------------------------------------------------------
