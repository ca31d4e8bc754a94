"""Primitive -> PointCloud constructors (Stürzlinger 1996, §3.1, plus the radius forms).

Every constructor returns a `PointCloud` in the shape's own frame whose set
``hull(points) ⊕ ball(radius)`` contains the true shape (conservative, up to a relative
inflation of ``TANGENT_INFLATE`` that absorbs rounding):

- exact forms: ``box`` (8 corners), ``sphere`` (1 point + radius), ``capsule`` (2 points +
  radius, MuJoCo's convention), ``mesh`` (its vertices), the free-form patches (their control
  points: the convex-hull property of Bezier, B-spline and positive-weight NURBS surfaces) and
  the sweeps of polygonal contours (``extrude``, ``cone_sweep``);
- tangent-plane forms (paper §3.1): ``cylinder``, ``cone``, ``ellipsoid``, ``torus``,
  ``superquadric`` and ``revolve`` give the vertices of a polytope circumscribed about the
  curved shape; ``planes`` trades size for tightness (more planes, a tighter cloud).

Orientation convention: a circumscribed regular k-gon has its vertices at azimuths
``(j + 1/2) 2π/k``, so its edges touch the circle at azimuths ``j 2π/k``; when ``k`` is a
multiple of 4 the tangent lines include ``x = ±r`` and ``y = ±r`` and the shape's own AABB is
exact.

Modules, each importing only those above it in this list: ``_polygons`` (shared helpers),
``_exact``, ``_tangent``, ``_plane``.
"""

from __future__ import annotations

from ._exact import bezier_patch, box, bspline_patch, capsule, cone_sweep, extrude, mesh, nurbs_patch, sphere
from ._plane import Plane, plane
from ._polygons import MAX_POINTS, TANGENT_INFLATE
from ._tangent import (cone, cylinder, ellipsoid, revolve, sphere_polytope_circumradius, superquadric,
                       superquadric_support, torus)

__all__ = [
    "MAX_POINTS", "Plane", "TANGENT_INFLATE", "bezier_patch", "box", "bspline_patch", "capsule", "cone",
    "cone_sweep", "cylinder", "ellipsoid", "extrude", "mesh", "nurbs_patch", "plane", "revolve", "sphere",
    "sphere_polytope_circumradius", "superquadric", "superquadric_support", "torus",
]
