"""collide: point-cloud bounding volumes and a broad phase for articulated simulation.

The flat public surface; every name here is re-exported from the module that defines it.
"""

from . import _cache, _checked

# Before any kernel is defined: numba's cache keyed on the files a kernel imports, the checked
# mode's kernels (COLLIDE_CHECKED=1: every kernel index checked, see _checked) in files of their own.
_cache.register(suffix="_checked" if _checked.CHECKED else "")
_checked.enable_boundscheck()

from . import csg, deformations, hull, shapes, volumes  # noqa: E402
from .articulation import Articulation  # noqa: E402
from .broadphase import BroadPhase  # noqa: E402
from .collider import CheckResult  # noqa: E402
from .contacts import Contacts  # noqa: E402
from .convex import Cone, Cylinder, Ellipsoid  # noqa: E402
from .deforming import deform  # noqa: E402
from .pointcloud import PointCloud, difference, intersection, union  # noqa: E402
from .signed_distance import Distance, distance  # noqa: E402
from .sweep import swept  # noqa: E402
from .volumes import AABB, KDOP, OBB, Sphere, overlap  # noqa: E402

__all__ = [
    "AABB",
    "Articulation",
    "BroadPhase",
    "CheckResult",
    "Cone",
    "Contacts",
    "Cylinder",
    "Distance",
    "Ellipsoid",
    "KDOP",
    "OBB",
    "PointCloud",
    "Sphere",
    "csg",
    "deform",
    "deformations",
    "difference",
    "distance",
    "hull",
    "intersection",
    "overlap",
    "shapes",
    "swept",
    "union",
    "volumes",
]

__version__ = "0.1.0"
