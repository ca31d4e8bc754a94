"""CSG graphs, cyclic (recursive) graphs of plants, their point clouds, BVHs and ray queries.

Stürzlinger 1996, "Bounding Volume Construction using Point Clouds":
- §3.1-§3.3: a node's cloud comes from its primitives, moved by transforms, appended by unions
  (hull-reduced past ``threshold``), intersected exactly (or by boxes), and a difference keeps its
  left operand. `Node.point_cloud` does this, memoized per (node, recursion level): a shared
  subgraph's cloud is computed once in its own frame and only transformed for each instance.
- §3.5: every node of the CSG tree gets a bounding volume from its cloud; a top-down pass clips
  each child's box to its parent's (an intersection clips both operands, a difference its right
  one; an empty clip removes a difference's right subtree and empties an intersection).
  `build_bvh(..., method="box_of_box")` builds the classical hierarchy (each node's box from its
  children's transformed boxes) for comparison.
- §4: recursive graphs (a node referring back to itself through a transform: `Recursive` and
  `Ref`) unrolled to a depth; the flower experiment is `demos/flower.py`.

Ray queries (`raycast`) run in numba (`collide._kernels.ray`) with exact primitive tests and span
arithmetic (Roth 1982); the brute-force twin is `collide.testing.csg.brute_force_raycast`.

Example
-------
>>> import numpy as np
>>> from collide import csg
>>> lift = np.eye(4); lift[2, 3] = 1.0
>>> tower = csg.Recursive("t", csg.Union(csg.box([1, 1, 0.5]), csg.Transform(lift, csg.Ref("t"))), 3)
>>> tower.point_cloud().aabb().hi
array([1. , 1. , 2.5])

Modules, each importing only those above it in this list:

==============  ==========================================================================
``_graph``      the nodes and the primitive constructors
``_unrolling``  recursion states, leaf counts, point clouds, box-of-box bounds, `leaves`
``_bvh``        `build_bvh` and the `BVH` arrays
``_rays``       `raycast`, `RayHits`, `pinhole_rays`
==============  ==========================================================================
"""

from __future__ import annotations

from ._bvh import BOX_PAD, BVH, build_bvh
from ._graph import (Difference, Instances, Intersection, Leaf, Node, Recursive, Ref, Transform, Union, box,
                     capsule, cone, cylinder, ellipsoid, mesh, sphere)
from ._rays import RayHits, pinhole_rays, raycast
from ._unrolling import MAX_LEAVES, leaves, unrolled_leaf_count

__all__ = [
    "BOX_PAD", "BVH", "Difference", "Instances", "Intersection", "Leaf", "MAX_LEAVES", "Node", "RayHits",
    "Recursive", "Ref", "Transform", "Union", "box", "build_bvh", "capsule", "cone", "cylinder", "ellipsoid",
    "leaves", "mesh", "pinhole_rays", "raycast", "sphere", "unrolled_leaf_count",
]
