"""Bounding volumes (AABB, Sphere, OBB) as small array records, and their fitting from clouds.

Fitters only choose a centre or an orientation; extents and radii are then measured from the
points themselves, so every fitted volume contains its cloud by construction (up to rounding),
whatever the fitter's quality.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import hull as _hull
from ._validate import as_array


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


def fit_sphere(points: np.ndarray, radius: float = 0.0, method: str = "exact") -> Sphere:
    """Enclosing sphere of ``hull(points) ⊕ ball(radius)``.

    Parameters
    ----------
    points : (n, 3) float64
    radius : float
    method : {"exact", "ritter"}
    """
    _require_points(points, "sphere")
    raise NotImplementedError("sphere fitting: being written")
