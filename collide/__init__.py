"""collide: point-cloud bounding volumes and a broad phase for articulated simulation.

The flat public surface; every name here is re-exported from the module that defines it.
"""

from . import csg, hull, shapes, volumes
from .articulation import Articulation
from .broadphase import BroadPhase
from .pointcloud import PointCloud, difference, intersection, union
from .volumes import AABB, KDOP, OBB, Sphere, overlap

__all__ = [
    "AABB",
    "Articulation",
    "BroadPhase",
    "KDOP",
    "OBB",
    "PointCloud",
    "Sphere",
    "csg",
    "difference",
    "hull",
    "intersection",
    "overlap",
    "shapes",
    "union",
    "volumes",
]

__version__ = "0.1.0"
