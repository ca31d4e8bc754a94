"""Known-answer generators and brute-force references for tests and benchmarks.

Nothing in the library imports this package (DESIGN.md, layers). Each submodule is re-exported
here so tests write ``from collide import testing`` and ``testing.<name>``.
"""

from .surfaces import (SHAPE_KINDS, apply_affine, random_affine, random_polygon, random_rigid,
                       random_rotation, random_shape_params, random_similarity, sample_surface)
