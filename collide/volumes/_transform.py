"""Bounding volumes under rigid maps, and the axis-aligned box of any of them."""

from __future__ import annotations

import numpy as np

from .._validate import as_array
from ._axes import _orthonormal
from ._kdop import KDOP, fit_kdop
from ._records import _PAD_FLOOR, _ROUNDING_PAD, AABB, OBB, Sphere, _rotation

__all__ = ["aabb_of", "transform"]

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
