"""MuJoCo adapter: ``MjModel`` -> `Articulation` with MuJoCo 4's collision filter, ``MjData`` -> poses.

The only library module that imports the ``mujoco`` package (DESIGN.md, layers). It maps every
geom type to a bounding cloud in its geom frame, and MuJoCo's rules for which geom pairs may
produce contacts to the static filter of `collide.Articulation`, so that our candidates are a
superset of the pairs MuJoCo can generate contacts for, and contain no pair its rules forbid.

MuJoCo's rules, as read in ``src/engine/engine_collision_driver.c`` (MuJoCo 3.x-4.0:
``mj_collision``, ``mj_broadphase``, ``filterBodyPair``, ``filterCollisionPair``) and checked on
this install with small MJCF models (``tests/test_mujoco.py``):

* no contacts at all with ``mjDSBL_CONTACT`` or ``mjDSBL_CONSTRAINT``, or with fewer than 2 bodies;
* dynamic pairs (not listed in ``<contact><pair>``):
  - bodies in the same weld group (``body_weldid``, bodies rigidly attached without joints,
    including every static body in group 0 of the world) never pair;
  - two bodies that dynamics never moves (``body_treeid < 0``: the world, static bodies, mocap
    bodies and bodies welded to them) never pair (observed in MuJoCo 4.0: a mocap body makes no
    contact with world geoms, static bodies or another mocap body; explicit pairs still do);
  - parent filter, unless ``mjDSBL_FILTERPARENT``: with ``w = body_weldid[b]`` and
    ``wp = body_weldid[body_parentid[w]]``, bodies ``b1, b2`` never pair when ``w1 == wp2`` or
    ``w2 == wp1``, except when either weld group is the world's (``w == 0``);
  - ``<exclude>`` body pairs never pair;
  - geoms pass when ``(contype1 & conaffinity2) or (contype2 & conaffinity1)``;
  - a contact is generated when the distance is below ``margin1 + margin2 + gap1 + gap2``
    (MuJoCo >= 3.9: geoms in the gap produce contacts flagged ``exclude``; with
    ``mjENBL_OVERRIDE`` the margin sum is ``opt.o_margin``; the gaps stay);
* the convex narrow phase (GJK/EPA) reports contacts for geoms up to ``opt.ccd_tolerance``
  apart (curved geoms always, polytopes when ``opt.ccd_iterations`` stops GJK early): every geom
  is inflated by it as well (`geom_inflation`);
* geoms the compiler snapped to their body's or inertial frame (``geom_sameframe``) are placed
  there, as ``mj_kinematics`` places them, whatever their ``geom_pos`` says (`geom_frames`);
* explicit ``<pair>``s bypass all the above filters and use their own ``margin + gap``; a dynamic
  pair with the same two geoms is dropped in favour of the explicit one;
* pairs without a collision function in ``mjCOLLISIONFUNC`` never make contacts: plane-plane,
  plane-hfield and hfield-hfield (removed from our output);
* planes are half-spaces (``z <= 0`` in the plane frame; the plane's size is visual only);
  meshes collide as the convex hull of their vertices (``mesh_vert``, already in the geom frame);
  height fields are bounded by their box ``[-x, x] x [-y, y] x [-base, top]``; SDF geoms by
  MuJoCo's own ``geom_aabb`` box, padded by `SDF_PAD` of its size (the SDF is only known to its
  plugin; MuJoCo measures that box on a mesh sampled from it, which can fall short);
* flexes, sleeping bodies and a user ``mjcb_contactfilter`` are not modelled: flex contacts are
  not geom pairs; sleeping and user filters only remove pairs, so our candidates stay a superset.

MuJoCo's ``mjTIMER_COL_BROAD`` times ``mj_broadphase`` only: body-level sweep-and-prune in a
covariance frame plus the weld, parent and bitmask filters, ending in body pairs. Geom pairs
inside multi-geom bodies are culled afterwards, in the narrow-phase timer (a BVH "midphase",
bounding spheres). Our time covers everything down to filtered geom pairs.

The package, by job, in import order (each module imports only those before it): `_model`
(``MjModel`` -> `Articulation`: clouds, inflations, frames, exclusions, weld groups), `_kinematics`
(the model's `collide.broadphase.KinematicTree`, batched kinematics), `_adapter` (`BroadPhase`:
``MjData`` -> pairs, a batch of ``qpos`` -> pairs, through `collide.BroadPhase`), `_compare`
(MuJoCo's timer on a native clock, its candidates, `compare` and its contact agreement), `_report`
(the comparison's table and figure), `_scene` (`load_model`, the built-in `default_scene`).
"""

from __future__ import annotations

from ._model import (SDF_PAD, articulation, exclusion_rules, geom_clouds, geom_frames, geom_inflation,
                     model_excludes, pair_inflation, parent_excludes, weld_groups)
from ._kinematics import kinematic_tree, kinematics_batch
from ._adapter import BroadPhase
from ._compare import (Comparison, candidate_counter, compare, contact_pairs, mujoco_deepest, mujoco_timer,
                       timer_clock)
from ._report import format_report, plot_comparison
from ._scene import default_scene, load_model
from ..collider import Collider  # contacts: collide.collider, which does not import mujoco
from ..rerun_log import log_rerun  # a Rerun recording; rerun itself imported when one is made
from . import _compare

# Private names the tests and benchmarks read here (collide.mujoco._X), the same objects.
_TIMER_BROAD = _compare._TIMER_BROAD
_control_range = _compare._control_range
_random_controls = _compare._random_controls

__all__ = [
    "BroadPhase",
    "Collider",
    "Comparison",
    "SDF_PAD",
    "articulation",
    "candidate_counter",
    "compare",
    "contact_pairs",
    "default_scene",
    "exclusion_rules",
    "format_report",
    "geom_clouds",
    "geom_frames",
    "geom_inflation",
    "kinematic_tree",
    "kinematics_batch",
    "load_model",
    "log_rerun",
    "model_excludes",
    "mujoco_deepest",
    "mujoco_timer",
    "pair_inflation",
    "parent_excludes",
    "plot_comparison",
    "timer_clock",
    "weld_groups",
]
