"""Known-answer generators and brute-force references for tests and benchmarks.

Nothing in the library imports this package (DESIGN.md, layers). Each submodule is re-exported
here so tests write ``from collide import testing`` and ``testing.<name>``.
"""

from . import csg, obb
from .brute import (brute_force_bound_pairs, brute_force_pairs, filter_passing_pairs, gjk_distance,
                    hulls_intersect_lp, world_bounds, world_capsules)
from .check import all_filtered_pairs, brute_force_min_distance, random_configurations
from .csg import brute_force_raycast, random_scene
from .deform import cloud_volume, deformed_sample, sample_cloud, signed_excess, swept_sample
from .obb import brute_force_obb, edge_pair_search, multistart_polish
from .scenes import (Scene, branching_tree, chain, free_hulls, hull_motion, make_plane, many_robots,
                     random_hull, scene_motion)
from .surfaces import (SHAPE_KINDS, apply_affine, random_affine, random_polygon, random_rigid,
                       random_rotation, random_shape_params, random_similarity, sample_surface)
from .narrow import (inner_cloud, minkowski_difference, origin_signed_distance, point_signed_distance,
                     polytope_signed_distance)

__all__ = [
    "SHAPE_KINDS", "Scene", "all_filtered_pairs", "apply_affine", "branching_tree", "brute_force_bound_pairs",
    "brute_force_min_distance", "brute_force_obb",
    "brute_force_pairs", "brute_force_raycast", "chain", "cloud_volume", "csg", "deformed_sample",
    "edge_pair_search", "filter_passing_pairs", "free_hulls", "gjk_distance", "hull_motion",
    "hulls_intersect_lp", "inner_cloud", "make_plane", "many_robots", "minkowski_difference",
    "multistart_polish", "obb", "origin_signed_distance", "point_signed_distance", "polytope_signed_distance",
    "random_affine", "random_configurations", "random_hull", "random_polygon", "random_rigid", "random_rotation",
    "random_scene",
    "random_shape_params", "random_similarity", "sample_cloud", "sample_surface", "scene_motion",
    "signed_excess", "swept_sample", "world_bounds", "world_capsules",
]
