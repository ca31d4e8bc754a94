"""Exact curved convex primitives for the narrow phase: cylinder, cone, ellipsoid.

The broad phase bounds these shapes with circumscribed polytopes (`collide.shapes`, the paper's
tangent planes); the narrow phase must use the true surface (issue 46, part 3), which each class
here gives through an analytic support function (`collide._kernels.support`). Their axis is the
local ``z`` axis, as in MuJoCo; `cloud` returns the bounding `PointCloud` for the broad phase.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import shapes as _shapes
from ._validate import as_array, as_radius
from .pointcloud import PointCloud

__all__ = ["Cone", "Cylinder", "Ellipsoid"]


@dataclass(frozen=True)
class Cylinder:
    """A solid cylinder along ``z``: ``x² + y² <= radius²``, ``|z| <= half_height`` (MuJoCo's
    ``size = [radius, half_height]``).

    Parameters
    ----------
    radius, half_height : float
        ``>= 0`` (zero radius: a segment; zero half height: a disk).
    """

    radius: float
    half_height: float

    def __post_init__(self):
        object.__setattr__(self, "radius", as_radius(self.radius, "radius"))
        object.__setattr__(self, "half_height", as_radius(self.half_height, "half_height"))

    def cloud(self, planes: int = 16) -> PointCloud:
        """The circumscribed `PointCloud` (`collide.shapes.cylinder`), for the broad phase."""
        return _shapes.cylinder(self.radius, self.half_height, planes)


@dataclass(frozen=True)
class Cone:
    """A solid cone: base disk of ``radius`` at ``z = 0``, apex at ``(0, 0, height)`` (the
    convention of `collide.shapes.cone`).

    Parameters
    ----------
    radius, height : float
        ``>= 0``.
    """

    radius: float
    height: float

    def __post_init__(self):
        object.__setattr__(self, "radius", as_radius(self.radius, "radius"))
        object.__setattr__(self, "height", as_radius(self.height, "height"))

    def cloud(self, planes: int = 16) -> PointCloud:
        """The circumscribed `PointCloud` (`collide.shapes.cone`), for the broad phase."""
        return _shapes.cone(self.radius, self.height, planes)


@dataclass(frozen=True, eq=False)
class Ellipsoid:
    """A solid axis-aligned ellipsoid ``(x/rx)² + (y/ry)² + (z/rz)² <= 1``.

    Parameters
    ----------
    radii : (3,) array_like of float
        ``>= 0`` each; stored as a read-only ``(3,) float64`` array.
    """

    radii: np.ndarray

    def __post_init__(self):
        r = np.array(as_array(self.radii, "radii", (3,)), dtype=np.float64)
        if np.any(r < 0.0):
            raise ValueError(f"radii: must be >= 0, got {r.tolist()}")
        r.setflags(write=False)
        object.__setattr__(self, "radii", r)

    def __eq__(self, other) -> bool:
        if not isinstance(other, Ellipsoid):
            return NotImplemented
        return bool(np.array_equal(self.radii, other.radii))

    def __hash__(self) -> int:
        return hash(tuple(self.radii.tolist()))

    def cloud(self, planes: int = 16) -> PointCloud:
        """The circumscribed `PointCloud` (`collide.shapes.ellipsoid`), for the broad phase."""
        return _shapes.ellipsoid(self.radii, planes)
