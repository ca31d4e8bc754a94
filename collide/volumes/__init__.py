"""Bounding volumes (AABB, Sphere, OBB, k-DOP) as small array records: fitting, transforms, overlaps.

Fitters only choose a centre or an orientation; extents and radii are then measured from the
points themselves, so every fitted volume contains its cloud by construction (up to rounding),
whatever the fitter's quality.

* `fit_aabb`: exact. `fit_sphere`: ``"exact"`` minimal sphere (Welzl 1991, move-to-front, on a
  growing working set) or ``"ritter"`` (1990). `fit_obb`: ``"exact"`` minimum volume
  (O'Rourke 1985, `_obb_exact`), ``"optimal"`` within 1 % of it (exact on small hulls,
  else subset searches and hull-face candidates polished by a compass search on rotations;
  measured in tests/bench/fitting.txt) or ``"pca"``.
* `KDOP` and `fit_kdop`: 6-, 14-, 18- and 26-DOPs (Klosowski et al. 1998).
* `transform` (rigid maps), `aabb_of`, and `overlap` for every pair of kinds (the OBB test is
  the 15-axis separating-axis test of Gottschalk 1996 / Ericson 2005 §4.4.1), conservative
  under rounding; `overlap_spheres` and `overlap_obbs` test many pairs given as arrays.

Modules, each importing only those above it in this list:

=================  ======================================================================
``_axes``          box axes of a cloud: principal axes, hull vertices, rotations, the
                   minimal rectangle (rotating calipers)
``_records``       the records `AABB`, `Sphere`, `OBB`; the shared rounding rules
``_obb_families``  O'Rourke's edge-pair families of orientations (numba)
``_obb_search``    branch and bound over those families (numba)
``_obb_exact``     the exact minimum-volume box through them
``_fit_box``       `fit_aabb`, `box_from_axes`, `fit_obb`
``_fit_sphere``    `min_sphere_center`, `fit_sphere`
``_kdop``          `KDOP`, `kdop_directions`, `fit_kdop`
``_transform``     `transform`, `aabb_of`
``_overlap``       `overlap` and its batched forms `overlap_spheres`, `overlap_obbs`
=================  ======================================================================
"""

from __future__ import annotations

from ._axes import pca_axes
from ._fit_box import MAX_COORDINATE, box_from_axes, fit_aabb, fit_obb
from ._fit_sphere import fit_sphere, min_sphere_center
from ._kdop import KDOP, KDOP_SIZES, fit_kdop, kdop_directions
from ._overlap import overlap, overlap_obbs, overlap_spheres
from ._records import AABB, OBB, OVERLAP_RTOL, ROTATION_TOL, Sphere, aabb_corners, obb_corners, row_norms
from ._transform import aabb_of, transform

__all__ = [
    "AABB",
    "KDOP",
    "KDOP_SIZES",
    "MAX_COORDINATE",
    "OBB",
    "OVERLAP_RTOL",
    "ROTATION_TOL",
    "Sphere",
    "aabb_corners",
    "aabb_of",
    "box_from_axes",
    "fit_aabb",
    "fit_kdop",
    "fit_obb",
    "fit_sphere",
    "kdop_directions",
    "min_sphere_center",
    "obb_corners",
    "overlap",
    "overlap_obbs",
    "overlap_spheres",
    "pca_axes",
    "row_norms",
    "transform",
]
