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
"""

from __future__ import annotations

import ctypes
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numba
import numpy as np

from .. import shapes
from .._kernels import _clock
from .._kernels.broadphase import RET_SAME as _RET_SAME
from .._validate import as_array, as_count
from ..articulation import Articulation
from ..broadphase import BroadPhase as _BroadPhase
from ..broadphase import KinematicTree
from ..pointcloud import PointCloud
from ..volumes import aabb_corners

_GEOM = mujoco.mjtGeom
_DSBL = mujoco.mjtDisableBit
_ENBL = mujoco.mjtEnableBit
_TIMER_BROAD = int(mujoco.mjtTimer.mjTIMER_COL_BROAD)

__all__ = [
    "BroadPhase",
    "Collider",
    "articulation",
    "candidate_counter",
    "compare",
    "contact_pairs",
    "mujoco_deepest",
    "default_scene",
    "exclusion_rules",
    "format_report",
    "geom_clouds",
    "geom_frames",
    "geom_inflation",
    "kinematic_tree",
    "kinematics_batch",
    "log_rerun",
    "model_excludes",
    "mujoco_timer",
    "pair_inflation",
    "parent_excludes",
    "plot_comparison",
    "weld_groups",
]


# ----------------------------------------------------------------------------------------------
# Model -> Articulation
# ----------------------------------------------------------------------------------------------

# Relative padding of an SDF geom's box (MuJoCo's geom_aabb, measured on a sampled mesh).
SDF_PAD = 0.02


def geom_clouds(model: mujoco.MjModel) -> list:
    """Bounding cloud of every geom, in its geom frame.

    Parameters
    ----------
    model : mujoco.MjModel

    Returns
    -------
    clouds : list of PointCloud or shapes.Plane, length ``model.ngeom``
        Primitives through `collide.shapes` (sphere and capsule exact; cylinder and ellipsoid
        as circumscribed polytopes); meshes as their vertices (MuJoCo collides with their convex
        hull); planes as ``shapes.plane()`` (the half-space ``z <= 0`` of the geom frame);
        height fields as their box; SDF geoms as MuJoCo's ``geom_aabb`` box, padded.
    """
    clouds = []
    for g in range(model.ngeom):
        try:
            clouds.append(_geom_cloud(model, g))
        except ValueError as exc:  # name the geom (a size edited into the model after compiling)
            raise ValueError(f"geom {g} ({_geom_name(model, g)}): {exc}") from None
    return clouds


def _geom_cloud(model: mujoco.MjModel, g: int):
    """One geom's cloud or plane, in its geom frame (see `geom_clouds`)."""
    t, size = int(model.geom_type[g]), model.geom_size[g]
    if t == _GEOM.mjGEOM_SPHERE:
        return shapes.sphere(float(size[0]))
    elif t == _GEOM.mjGEOM_CAPSULE:
        return shapes.capsule(float(size[0]), float(size[1]))
    elif t == _GEOM.mjGEOM_CYLINDER:
        return shapes.cylinder(float(size[0]), float(size[1]))
    elif t == _GEOM.mjGEOM_ELLIPSOID:
        return shapes.ellipsoid(size[:3].astype(np.float64))
    elif t == _GEOM.mjGEOM_BOX:
        return shapes.box(size[:3].astype(np.float64))
    elif t == _GEOM.mjGEOM_MESH:
        mid = int(model.geom_dataid[g])
        adr, num = int(model.mesh_vertadr[mid]), int(model.mesh_vertnum[mid])
        # mesh_vert is float32 in the mesh frame, which the compiler made the geom frame
        # (it recentres the mesh and folds the offset into geom_pos/geom_quat).
        return shapes.mesh(model.mesh_vert[adr:adr + num].astype(np.float64))
    elif t == _GEOM.mjGEOM_PLANE:
        return shapes.plane()
    elif t == _GEOM.mjGEOM_HFIELD:
        sx, sy, top, base = model.hfield_size[int(model.geom_dataid[g])]
        return PointCloud(aabb_corners(np.array([-sx, -sy, -base]), np.array([sx, sy, top])))
    elif t == _GEOM.mjGEOM_SDF:
        # MuJoCo's box comes from a mesh sampled from the SDF, which can fall short of the
        # true surface (mujoco.sdf.torus 0.35/0.15: half extent 0.49995, not 0.5): pad it.
        c, h = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        pad = SDF_PAD * float(np.max(h))
        return PointCloud(aabb_corners(c - h - pad, c + h + pad))
    else:
        raise ValueError(f"unsupported geom type {t}")


def geom_inflation(model: mujoco.MjModel) -> np.ndarray:
    """``(G,) float64``: how far each geom's bound is inflated: ``margin + gap + opt.ccd_tolerance``,
    the margin and gap of a box ``sqrt(3)`` times (`_box_factor`).

    MuJoCo generates a contact below ``margin1 + margin2 + gap1 + gap2`` (``getMargin`` +
    ``getGap`` in engine_collision_driver.c); with ``mjENBL_OVERRIDE`` the margin sum becomes
    ``opt.o_margin``, so each geom takes half of it. Its convex-convex narrow phase (``mjc_ccd`` in
    engine_collision_gjk.c) also reports contacts for geoms a little apart: it runs EPA once GJK's
    distance estimate is within ``opt.ccd_tolerance``, and that estimate (the norm of a point of
    the Minkowski difference) is never below the true distance, so a reported pair is at most the
    tolerance apart. Measured on this install: true gaps up to 0.77 x ``ccd_tolerance`` with an ellipsoid or
    a cylinder at the default 35 iterations (3000 random poses per pair of types, tolerance 1e-3
    to 5e-2), and up to 0.78 x for boxes, meshes and height fields when ``opt.ccd_iterations``
    stops GJK early (4 iterations: review, 2026-11-22). Every geom adds the whole tolerance
    (1e-6 by default), so a pair carries twice the bound.
    """
    if model.opt.enableflags & _ENBL.mjENBL_OVERRIDE:
        margin = np.full(model.ngeom, 0.5 * float(as_array(model.opt.o_margin, "model.opt.o_margin", ())))
    else:
        margin = as_array(model.geom_margin, "model.geom_margin", (None,))
    grow = np.maximum(margin + as_array(model.geom_gap, "model.geom_gap", (None,)), 0.0)
    return grow * _box_factor(np.asarray(model.geom_type) == _GEOM.mjGEOM_BOX) + _ccd_slack(model)


def _box_factor(box: np.ndarray) -> np.ndarray:
    # MuJoCo's box-box collider (mjc_BoxBox) makes a contact when the boxes' separation along
    # every separating axis it tests is below the margin: its ``dist`` is the largest such
    # separation, not the Euclidean distance, which may be larger (0.536 apart with margin 0.5:
    # a contact at dist 0.467; adversarial review, 2026-11-28). Such boxes meet once one of them
    # is grown by the margin along its own face normals, and that box lies within the box grown
    # by sqrt(3) times the margin as a ball: a box's margin counts sqrt(3) times (1 elsewhere).
    return np.where(box, np.sqrt(3.0) * (1.0 + 1e-12), 1.0)


def pair_inflation(model: mujoco.MjModel) -> np.ndarray:
    """``(P,) float64``: contact distance of each explicit ``<pair>``: ``margin + gap``, plus
    ``opt.ccd_tolerance`` for each of its two geoms (see `geom_inflation`)."""
    if model.opt.enableflags & _ENBL.mjENBL_OVERRIDE:
        margin = np.full(model.npair, float(as_array(model.opt.o_margin, "model.opt.o_margin", ())))
    else:
        margin = as_array(model.pair_margin, "model.pair_margin", (None,))
    grow = np.maximum(margin + as_array(model.pair_gap, "model.pair_gap", (None,)), 0.0)
    box = np.asarray(model.geom_type) == _GEOM.mjGEOM_BOX
    both = box[np.asarray(model.pair_geom1, int)] & box[np.asarray(model.pair_geom2, int)]
    return grow * _box_factor(both) + 2.0 * _ccd_slack(model)  # box-box pairs: see _box_factor


def _ccd_slack(model: mujoco.MjModel) -> float:
    tol = float(model.opt.ccd_tolerance)
    if not np.isfinite(tol):
        raise ValueError(f"model.opt.ccd_tolerance: must be finite, got {tol}")
    return max(tol, 0.0)



def geom_frames(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """Each geom's pose in its body's frame as MuJoCo's kinematics places it.

    The compiler marks a geom whose frame coincides with its body's or inertial frame, up to
    its tolerance, in ``geom_sameframe``, and ``mj_kinematics`` then copies that frame
    (``mj_local2Global``): ``geom_pos`` / ``geom_quat`` are ignored for it (a plane at
    ``pos="0 0 -5e-7"`` sits at the body origin). Same for the rotation alone (``BODYROT``,
    ``INERTIAROT``).

    Returns
    -------
    pos : (G, 3) float64
    rot : (G, 3, 3) float64
    """
    pos = np.array(model.geom_pos, dtype=np.float64).reshape(-1, 3)
    quat = np.array(model.geom_quat, dtype=np.float64).reshape(-1, 4)
    sf = np.asarray(model.geom_sameframe)
    bid = np.asarray(model.geom_bodyid)
    same = mujoco.mjtSameFrame
    ident = np.array([1.0, 0.0, 0.0, 0.0])
    body = sf == same.mjSAMEFRAME_BODY
    pos[body] = 0.0
    quat[body | (sf == same.mjSAMEFRAME_BODYROT)] = ident
    inertia = sf == same.mjSAMEFRAME_INERTIA
    pos[inertia] = np.asarray(model.body_ipos)[bid[inertia]]
    irot = inertia | (sf == same.mjSAMEFRAME_INERTIAROT)
    quat[irot] = np.asarray(model.body_iquat)[bid[irot]]
    return pos, _quat_to_mat(quat)


def _model_mismatch(model: mujoco.MjModel, other: mujoco.MjModel) -> str | None:
    # What differs between two models as far as our bounds and filters go (None: nothing): a
    # BroadPhase of one model must not silently answer for another of the same sizes.
    if model is other:
        return None
    for attr in ("nbody", "ngeom", "npair", "nexclude"):
        if getattr(model, attr) != getattr(other, attr):
            return f"{attr} {getattr(other, attr)} != {getattr(model, attr)}"
    for attr in ("body_parentid", "body_weldid", "geom_bodyid", "geom_type", "geom_dataid", "geom_size",
                 "geom_pos", "geom_quat", "geom_contype", "geom_conaffinity", "geom_margin", "geom_gap",
                 "pair_geom1", "pair_geom2", "pair_margin", "pair_gap", "exclude_signature"):
        if not np.array_equal(getattr(model, attr), getattr(other, attr)):
            return f"{attr} differs"
    for attr in ("disableflags", "enableflags", "o_margin", "ccd_tolerance"):
        if getattr(model.opt, attr) != getattr(other.opt, attr):
            return f"opt.{attr} differs"
    if model.nmeshvert != other.nmeshvert or not np.array_equal(model.mesh_vert, other.mesh_vert):
        return "mesh_vert differs"
    return None


def parent_excludes(model: mujoco.MjModel) -> np.ndarray:
    """``(E, 2) int64`` body pairs removed by MuJoCo's parent filter (``filterBodyPair``).

    Bodies ``b1, b2`` never pair when the weld group of one is the weld group of the parent of
    the other's weld root, unless either group is the world's (0). Only bodies that carry geoms
    are listed. Empty with ``mjDSBL_FILTERPARENT``.
    """
    if model.opt.disableflags & _DSBL.mjDSBL_FILTERPARENT:
        return np.zeros((0, 2), dtype=np.int64)
    weld = np.asarray(model.body_weldid)
    parent = np.asarray(model.body_parentid)
    has_geom = np.asarray(model.body_geomnum) > 0
    members: dict[int, np.ndarray] = {}
    for w in np.unique(weld[has_geom]):
        members[int(w)] = np.flatnonzero(has_geom & (weld == w))
    rows = []
    for w, group in members.items():
        if w == 0:
            continue
        wp = int(weld[parent[w]])
        if wp == 0 or wp not in members:
            continue
        a, b = np.meshgrid(members[wp], group, indexing="ij")
        rows.append(np.stack([a.ravel(), b.ravel()], axis=1))
    if not rows:
        return np.zeros((0, 2), dtype=np.int64)
    out = np.sort(np.concatenate(rows), axis=1)
    return np.unique(out, axis=0)


def model_excludes(model: mujoco.MjModel) -> np.ndarray:
    """``(E, 2) int64``: the model's ``<exclude>`` body pairs (decoded from exclude_signature)."""
    sig = np.asarray(model.exclude_signature, dtype=np.int64)
    return np.stack([sig >> 16, sig & 0xFFFF], axis=1).reshape(-1, 2)


def _quat_to_mat(quat: np.ndarray) -> np.ndarray:
    out = np.empty((len(quat), 9))
    for i, q in enumerate(quat):
        mujoco.mju_quat2Mat(out[i], q)
    return out.reshape(-1, 3, 3)


def articulation(model: mujoco.MjModel) -> Articulation:
    """The `Articulation` of a MuJoCo model: its bodies, geoms and collision filter.

    Parameters
    ----------
    model : mujoco.MjModel

    Returns
    -------
    Articulation
        Bodies as in the model (body 0 is the world), geoms placed as `geom_frames` says,
        clouds from `geom_clouds`, contype/conaffinity, inflation from `geom_inflation`,
        exclusions from ``<exclude>`` and `parent_excludes`, weld groups from `weld_groups`,
        explicit pairs with `pair_inflation`. MuJoCo's parent filter (on
        weld groups, not bodies) goes through `exclusion_rules`.
    """
    if not isinstance(model, mujoco.MjModel):
        raise ValueError(f"model: expected a mujoco.MjModel, got {type(model).__name__}")
    weld = weld_groups(model)
    filter_parent, excludes = exclusion_rules(model, weld)
    pairs = np.stack([model.pair_geom1, model.pair_geom2], axis=1).astype(np.int64).reshape(-1, 2)
    geom_pos, geom_rot = geom_frames(model)
    return Articulation(
        body_parent=np.asarray(model.body_parentid, dtype=np.int64),
        geom_body=np.asarray(model.geom_bodyid, dtype=np.int64),
        geom_cloud=geom_clouds(model),
        geom_pos=geom_pos,
        geom_rot=geom_rot,
        geom_contype=np.asarray(model.geom_contype, dtype=np.int64),
        geom_conaffinity=np.asarray(model.geom_conaffinity, dtype=np.int64),
        geom_margin=geom_inflation(model),
        exclude=excludes,
        pairs=pairs,
        filter_parent=filter_parent,
        # MuJoCo's pair margin + gap is the contact distance; the articulation inflates each of
        # the two geoms by pair_margin, so each takes half.
        pair_margin=0.5 * pair_inflation(model),
        body_weld=weld,
    )


def exclusion_rules(model: mujoco.MjModel, weld: np.ndarray) -> tuple[bool, np.ndarray]:
    """MuJoCo's body-pair exclusions as `Articulation`'s ``filter_parent`` plus explicit pairs.

    MuJoCo's set is ``<exclude>`` plus `parent_excludes`. The articulation's own parent rule
    (a body never pairs with its parent unless the parent is body 0) lets the broad phase skip
    those tests while descending the tree, so it is used whenever every pair it removes is in
    MuJoCo's set (or already in one weld group of ``weld``); MuJoCo's remaining pairs are
    passed explicitly. Otherwise (say a static body, weld group 0, as a parent) the rule is off
    and MuJoCo's whole set is explicit.

    Returns
    -------
    filter_parent : bool
    exclude : (E, 2) int64
        Body pairs, lower id first.
    """
    mj = np.concatenate([model_excludes(model), parent_excludes(model)]).astype(np.int64)
    mj = np.unique(np.sort(mj.reshape(-1, 2), axis=1), axis=0)
    L = model.nbody
    mj_keys = set((mj[:, 0] * L + mj[:, 1]).tolist())
    parent = np.asarray(model.body_parentid, dtype=np.int64)
    has_geom = np.asarray(model.body_geomnum) > 0
    child = np.flatnonzero((np.arange(L) > 0) & (parent > 0))
    rule = np.sort(np.stack([parent[child], child], axis=1), axis=1)
    rule_keys = set((rule[:, 0] * L + rule[:, 1]).tolist())
    for a, b in rule:
        matters = has_geom[a] and has_geom[b] and weld[a] != weld[b]
        if matters and int(a * L + b) not in mj_keys:
            return False, mj
    rest = [k for k in sorted(mj_keys) if k not in rule_keys]
    return True, np.array([[k // L, k % L] for k in rest], dtype=np.int64).reshape(-1, 2)


def weld_groups(model: mujoco.MjModel) -> np.ndarray:
    """``(L,) int64`` groups of bodies that never pair: ``body_weldid``, with every body that
    dynamics never moves (``body_treeid < 0``: world, static, mocap) merged into group 0."""
    weld = np.asarray(model.body_weldid, dtype=np.int64).copy()
    tree = getattr(model, "body_treeid", None)
    if tree is not None:
        weld[np.asarray(tree) < 0] = 0
    return weld


# ----------------------------------------------------------------------------------------------
# Batched forward kinematics (mj_kinematics, engine_core_smooth.c, for body poses only)
# ----------------------------------------------------------------------------------------------

def kinematic_tree(model: mujoco.MjModel) -> KinematicTree:
    """The bodies and joints ``mj_kinematics`` reads, as a `collide.broadphase.KinematicTree`.

    Its float arrays are views of the model's own (a body's pose or ``qpos0`` changed in place
    reaches the next call, as it reaches ``mj_kinematics``; `BroadPhase.pairs_batch` keeps the
    tree per ``MjModel``); its index arrays are checked copies.
    """
    return KinematicTree(model.qpos0, model.body_parentid, model.body_pos, model.body_quat, model.body_jntadr,
                         model.body_jntnum, model.jnt_type, model.jnt_qposadr, np.reshape(model.jnt_pos, (-1, 3)),
                         np.reshape(model.jnt_axis, (-1, 3)))


def kinematics_batch(model: mujoco.MjModel, qpos) -> tuple[np.ndarray, np.ndarray]:
    """Body poses of many configurations, as ``mj_kinematics`` computes them, in one numba call.

    Parameters
    ----------
    model : mujoco.MjModel
    qpos : (B, nq) array_like of float
        One configuration per world. Mocap bodies stay at their model poses.

    Returns
    -------
    body_pos : (B, nbody, 3) float64
    body_rot : (B, nbody, 3, 3) float64
        Equal to ``data.xpos`` / ``data.xmat`` after ``mj_kinematics`` up to rounding (the same
        formulas, engine_core_smooth.c; tested against MuJoCo on every test scene).
    """
    return kinematic_tree(model).poses(qpos)


def _contacts_disabled(model: mujoco.MjModel) -> bool:
    flags = int(model.opt.disableflags)
    return bool(flags & (_DSBL.mjDSBL_CONTACT | _DSBL.mjDSBL_CONSTRAINT)) or model.nbody < 2


_NOT_BOUND = object()


class BroadPhase:
    """Our broad phase on a MuJoCo model: ``MjData`` in, candidate geom pairs out.

    Parameters
    ----------
    model : mujoco.MjModel
        Read once, here: geometry, filter rules and flags (``mjDSBL_CONTACT``,
        ``mjDSBL_CONSTRAINT``, ``mjDSBL_FILTERPARENT``, ``mjENBL_OVERRIDE``). Build a new
        BroadPhase after changing them (reading ``model.opt`` through the bindings is slow per call).
    coherent : bool, default True
        Keep the body pairs of fat boxes between steps (`collide.BroadPhase`'s ``coherent``):
        the same pairs, less time in a simulation loop; no effect on a model of at most 64
        positions (no tree is walked there).

    Attributes
    ----------
    articulation : Articulation
    broadphase : collide.BroadPhase

    Notes
    -----
    As `collide.BroadPhase`: calls from several threads are safe and take turns (one lock per
    instance); ``copy.copy`` gives another thread an instance of its own.
    """

    def __init__(self, model: mujoco.MjModel, coherent: bool = True):
        self.model = model
        self.articulation = articulation(model)
        self.broadphase = _BroadPhase(self.articulation, coherent)
        self._empty2 = np.zeros((0, 2), dtype=np.int32)
        self._empty2.flags.writeable = False
        self._empty3 = np.zeros((0, 3), dtype=np.int32)
        self._disabled = _contacts_disabled(model)
        self._views_of = _NOT_BOUND  # the MjData whose arrays are bound (none yet; None is not an MjData)
        self._views = None
        self._tree = (None, None)  # (MjModel, its kinematic_tree): pairs_batch's, see there
        # MuJoCo has no collision function for plane-hfield and hfield-hfield (mjCOLLISIONFUNC
        # is NULL there): such pairs never make contacts and are removed after the kernel.
        types = np.asarray(model.geom_type)
        self._no_function = None
        self._null = (None, None)  # _drop_null's last input and output (pairs()), one tuple: one store
        if np.any(types == _GEOM.mjGEOM_HFIELD):
            self._no_function = (types == _GEOM.mjGEOM_HFIELD) | (types == _GEOM.mjGEOM_PLANE)

    def __repr__(self) -> str:
        return (f"collide.mujoco.BroadPhase({self.model.nbody} bodies, {self.model.ngeom} geoms"
                f"{'' if self.broadphase.coherent else ', coherent=False'})")

    def __reduce__(self):
        # Rebuilt from the model (see collide.BroadPhase.__reduce__): the kernel's context holds
        # raw addresses of this object's buffers and of the last MjData's arrays.
        return (BroadPhase, (self.model, self.broadphase.coherent))

    def _drop_null(self, pairs: np.ndarray, first: int) -> np.ndarray:
        if self._no_function is None or len(pairs) == 0:
            return pairs
        held, out = self._null
        if first == 0 and pairs is held:  # pairs() handed out its last result again
            return out
        nf = self._no_function
        out = pairs[~(nf[pairs[:, first]] & nf[pairs[:, first + 1]])]
        if first == 0:  # pairs(): read-only, and the same array again while its input is
            out.flags.writeable = False
            self._null = (pairs, out)  # another thread sees both or neither
        return out

    @property
    def stats(self):
        """Counters of the last call (see `collide.BroadPhase.stats`)."""
        return self.broadphase.stats

    def pairs(self, data: mujoco.MjData) -> np.ndarray:
        """Candidate geom pairs at the poses of ``data`` (after ``mj_kinematics`` or a step).

        Parameters
        ----------
        data : mujoco.MjData
            Its ``xpos`` ``(nbody, 3)`` and ``xmat`` ``(nbody, 9)`` are read.

        Returns
        -------
        pairs : (K, 2) int32, read-only
            Geom ids, lower first, rows sorted and unique; rows never written again, and the last
            non-empty call's array again when its pairs are the same, as in
            `collide.BroadPhase.pairs`.
        """
        bp = self.broadphase
        lock = bp._lock  # one call at a time per instance (collide.BroadPhase.pairs)
        lock.acquire()
        try:
            if data is not self._views_of or bp._bound is not self._views:
                self._check_data(data)  # once per MjData (here, where its arrays are bound), not per step
                if self._disabled:
                    return self._empty2
                # The bindings build new numpy views at every attribute access (a cost per call), and
                # an MjData's arrays never move: bind the last MjData's views to the kernel's context
                # (held there, so they stay valid), and each step is a call with one argument. Bound
                # again if someone bound other arrays to self.broadphase in between.
                bp._bind(data.xpos, data.xmat.reshape(-1, 3, 3))
                self._views_of = data
                self._views = bp._bound
            # BroadPhase.pairs() on the bound arrays, written out: one Python call less on the fast path.
            # Through bind + pairs (public) instead, the small models' calls were measurably slower
            # (tests/bench/ab.py; issue 42's note has the figures): this stays, and its bookkeeping
            # must follow BroadPhase.pairs'.
            k = bp._step_bound(bp._ctx_addr)
            if k < 0:  # a bad pose raises; full buffers are grown and the step rerun
                try:
                    k = bp._rerun(*bp._bound, k)
                except ValueError as exc:
                    if not np.any(bp._bound[1]):
                        raise ValueError("data: body poses are all zero; run mujoco.mj_kinematics, "
                                         "mj_forward or mj_step on it first") from exc
                    raise
            if k >= _RET_SAME:  # the pairs of the last non-empty result: its array again
                out = bp._last
            elif k == 0:
                return self._empty2
            else:
                o = bp._arena_used  # BroadPhase._take, written out
                e = o + k
                if e <= bp._arena_rows:
                    bp._arena_used = e
                    out = bp._last = bp._arena[o:e]
                else:
                    out = bp._take(k)
            return out if self._no_function is None else self._drop_null(out, 0)
        finally:
            lock.release()

    def world_bounds(self, data: mujoco.MjData, of: str = "geoms", inflate: bool = True):
        """World bounds of every geom (or body) at the poses of ``data``.

        `collide.BroadPhase.world_bounds` on ``data.xpos`` and ``data.xmat``; rows by MuJoCo geom
        (or body) id. Inflated geoms are grown by `geom_inflation` (margin + gap +
        ``opt.ccd_tolerance``, times ``1 + MARGIN_SLACK``: `Articulation.geom_bound_margin`); an
        explicit ``<pair>`` is tested with its own inflation instead.

        Returns
        -------
        collide.broadphase.WorldBounds
        """
        self._check_data(data)
        try:
            return self.broadphase.world_bounds(data.xpos, data.xmat.reshape(-1, 3, 3), of, inflate)
        except ValueError as exc:
            # a pose error (the arguments are checked first) on an MjData never moved
            if str(exc).startswith("body ") and not np.any(data.xmat):
                raise ValueError("data: body poses are all zero; run mujoco.mj_kinematics, mj_forward or mj_step "
                                 "on it first") from exc
            raise

    def _check_data(self, data) -> None:
        # An MjData of this model (checked where pairs() binds its arrays, and by world_bounds).
        if not isinstance(data, mujoco.MjData):
            raise ValueError(f"data: expected a mujoco.MjData, got {type(data).__name__}")
        if data.xpos.shape[0] != self.model.nbody:
            raise ValueError(f"data: made for a model with {data.xpos.shape[0]} bodies, this broad phase's "
                             f"has {self.model.nbody}")
        diff = _model_mismatch(self.model, getattr(data, "model", self.model))
        if diff is not None:
            raise ValueError(f"data: made for another model than this broad phase's ({diff}); "
                             "build a BroadPhase of that model")

    def pairs_batch(self, model: mujoco.MjModel, qpos) -> np.ndarray:
        """Candidate pairs of many configurations: kinematics per world, one batched call.

        Parameters
        ----------
        model : mujoco.MjModel
            The model this broad phase was built from.
        qpos : (B, nq) array_like of float
            One configuration per world (mocap bodies stay at their model poses).

        Returns
        -------
        pairs : (K, 3) int32
            ``(world, geom1, geom2)`` rows, sorted: those of `kinematics_batch` followed by
            `collide.BroadPhase.pairs_batch`, from one call,
            `collide.BroadPhase.pairs_batch_joints` on the model's `kinematic_tree` (on a model
            the lanes run, each thread computes a group's poses in its own workspace just before
            testing them, none of the batch's poses written out). A subclass that overrides the
            `kinematics_batch` method gets the two calls.
        """
        if not isinstance(model, mujoco.MjModel):
            raise ValueError(f"model: expected a mujoco.MjModel, got {type(model).__name__}")
        diff = _model_mismatch(self.model, model)
        if diff is not None:
            raise ValueError(f"model: not the model this BroadPhase was built from ({diff})")
        if self._disabled:
            as_array(qpos, "qpos", (None, model.nq))  # a bad qpos is refused all the same
            return self._empty3
        if type(self).kinematics_batch is not BroadPhase.kinematics_batch:  # kinematics of one's own
            out = self.broadphase.pairs_batch(*self.kinematics_batch(model, as_array(qpos, "qpos", (None, model.nq))))
        else:
            # The model's tree (`kinematic_tree`: views of its float arrays), made once per MjModel
            # and held with it (an id could be reused): the model's buffers never move, so the views
            # see every change made to them in place, as mj_kinematics would. Made afresh at every
            # call (ten binding accesses and the tree's checks) it would cost a good part of a small
            # batch's call.
            held, tree = self._tree
            if model is not held:
                tree = kinematic_tree(model)
                self._tree = (model, tree)  # one store: another thread sees both or neither
            out = self.broadphase.pairs_batch_joints(tree, qpos)
        return out if self._no_function is None else self._drop_null(out, 1)

    def kinematics_batch(self, model: mujoco.MjModel, qpos: np.ndarray):
        """Body poses of each configuration (see the module function `kinematics_batch`)."""
        return kinematics_batch(model, qpos)


# ----------------------------------------------------------------------------------------------
# Measuring MuJoCo: its timer, its broad-phase candidates, its contacts
# ----------------------------------------------------------------------------------------------

def _native_clock():
    # MuJoCo's timers tick only when mjcb_time is set. A Python callable would add its own call
    # overhead to every interval (a sizeable part of a small model's broad phase), so on Linux we hand it a
    # numba C callback reading clock_gettime(CLOCK_MONOTONIC) (`_kernels._clock`); elsewhere, or if
    # that fails, the portable clock, with a warning: the benchmarks' MuJoCo figures then carry it.
    if _clock.AVAILABLE:
        try:
            @numba.cfunc("float64()", cache=True)
            def now_us():
                return _clock.now_us()

            return ctypes.cast(now_us.address, ctypes.CFUNCTYPE(ctypes.c_double)), now_us
        except Exception as exc:  # pragma: no cover - any failure: the portable clock
            warnings.warn(f"collide.mujoco: no native clock for MuJoCo's timers ({type(exc).__name__}: {exc}); "
                          "timing with a Python callback, which adds its call's overhead to each interval")
    return lambda: time.perf_counter() * 1e6


def timer_clock() -> str:
    """``"native"`` or ``"python"``: the clock `mujoco_timer` hands MuJoCo (for benchmark headers)."""
    global _CLOCK
    if _CLOCK is None:
        _CLOCK = _native_clock()
    return "native" if isinstance(_CLOCK, tuple) else "python"


_CLOCK = None


class mujoco_timer:
    """Context manager: MuJoCo's timers tick (``mjcb_time`` set, in microseconds) inside it."""

    def __enter__(self):
        global _CLOCK
        if _CLOCK is None:
            _CLOCK = _native_clock()
        self._old = mujoco.get_mjcb_time()
        fn = _CLOCK[0] if isinstance(_CLOCK, tuple) else _CLOCK
        mujoco.set_mjcb_time(fn)
        return self

    def __exit__(self, *exc):
        mujoco.set_mjcb_time(self._old)
        return False


class candidate_counter:
    """Context manager counting MuJoCo's broad-phase candidates without changing its result.

    A ``mjcb_contactfilter`` replaces MuJoCo's contype/conaffinity test for every geom pair its
    broad phase and midphase pass on (``filterCollisionPair``); ours counts the call and returns
    the bitmask verdict MuJoCo would have reached, so the simulation is unchanged.

    Attributes
    ----------
    count : int
        Calls since the last `reset`.
    """

    def __init__(self, model: mujoco.MjModel):
        self._contype = [int(v) for v in model.geom_contype]
        self._conaff = [int(v) for v in model.geom_conaffinity]
        self.count = 0

    def reset(self) -> None:
        self.count = 0

    def _filter(self, m, d, g1, g2):
        self.count += 1
        ct, ca = self._contype, self._conaff
        return int(not ((ct[g1] & ca[g2]) or (ct[g2] & ca[g1])))

    def __enter__(self):
        self._old = mujoco.get_mjcb_contactfilter()
        mujoco.set_mjcb_contactfilter(self._filter)
        return self

    def __exit__(self, *exc):
        mujoco.set_mjcb_contactfilter(self._old)
        return False


def contact_pairs(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """MuJoCo's current contacts as geom pairs: ``(K, 2) int32``, lower id first, sorted, unique.

    Contacts involving a flex (geom id -1) are left out: they are not geom pairs.
    """
    if data.ncon == 0:
        return np.zeros((0, 2), dtype=np.int32)
    g = np.sort(np.asarray(data.contact.geom[:data.ncon], dtype=np.int32), axis=1)
    g = g[g[:, 0] >= 0]
    return np.unique(g, axis=0)


def _geom_name(model: mujoco.MjModel, g: int) -> str:
    name = mujoco.mj_id2name(model, _OBJ_GEOM, int(g))
    return name if name else f"geom{int(g)}"


_OBJ_GEOM = mujoco.mjtObj.mjOBJ_GEOM
_UNSTABLE = [int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                              mujoco.mjtWarning.mjWARN_BADQACC)]


def _unstable_warnings(data: mujoco.MjData) -> tuple:
    return tuple(data.warning[w].number for w in _UNSTABLE)


def _control_range(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    lo = np.full(model.nu, -1.0)
    hi = np.full(model.nu, 1.0)
    limited = np.asarray(model.actuator_ctrllimited, dtype=bool)
    rng = np.asarray(model.actuator_ctrlrange)
    lo[limited], hi[limited] = rng[limited, 0], rng[limited, 1]
    return lo, hi


@dataclass
class Comparison:
    """Per-step record of a comparison run (see `compare`)."""

    model_name: str
    seed: int
    contact_pairs: list = field(default_factory=list)
    candidates: list = field(default_factory=list)
    mujoco_candidates: list = field(default_factory=list)
    time_ours_us: list = field(default_factory=list)
    time_mujoco_broad_us: list = field(default_factory=list)
    missed: list = field(default_factory=list)


def _random_controls(model: mujoco.MjModel, steps: int, seed: int, hold: int) -> np.ndarray:
    # The controls of `compare`, one row per change (every ``hold`` steps), drawn before the runs
    # so that a second run replays the first.
    rng = np.random.default_rng(seed)
    lo, hi = _control_range(model)
    n = -(-steps // hold) if model.nu else 0
    return np.array([np.where(rng.random(model.nu) < 0.5, lo, hi) for _ in range(n)]).reshape(n, model.nu)


def compare(model: mujoco.MjModel, steps: int = 1000, seed: int = 0, name: str = "model",
            broadphase: BroadPhase | None = None, on_step=None, hold: int = 100, contacts: bool = True) -> dict:
    """Simulate ``model`` with random controls; every step, compare MuJoCo's contacts with ours.

    Controls are random and piecewise constant: every ``hold`` steps each actuator is set to
    one end of its control range (or of [-1, 1]), chosen at random. Held extremes drive joints
    to their limits, where self-contacts and floor contacts happen (per-step uniform noise
    averages out: a position-controlled arm such as kuka_iiwa_14 then never touches anything
    in 2000 steps). Each step: ``mj_step``; then, on the state MuJoCo just collided
    (``xpos``/``xmat`` and ``contact`` are left from the same ``mj_forward``, before
    integration), our candidates from `BroadPhase.pairs`, timed. MuJoCo's broad-phase
    candidates are counted in a second run with the same controls, through a contact-filter
    callback that returns MuJoCo's own verdict (in the timed run, its Python calls inside
    ``mj_step`` would evict our code and data from the caches before each of our calls).

    Parameters
    ----------
    model : mujoco.MjModel
    steps : int
        Number of simulation steps, ``>= 1``.
    seed : int
        Seed of the random controls.
    name : str
        Model name for the report.
    broadphase : BroadPhase, optional
        Reused when given (built from ``model`` otherwise).
    on_step : callable, optional
        ``on_step(step, data, candidates)`` after each step (the demo uses it to render).
    hold : int
        Steps between control changes, ``>= 1``.
    contacts : bool, default True
        Also compare contacts: `Collider.contacts` on the states of the counting run (below)
        against MuJoCo's, each geom pair's deepest contact.

    Returns
    -------
    dict
        JSON-ready: ``steps``, ``recall`` (share of MuJoCo contact pairs, over all steps, among
        our candidates; 1.0 when there were none), ``missed`` (list of ``{step, geom1, geom2,
        name1, name2}``), ``contact_pairs_per_step``, ``candidates_per_step``,
        ``mujoco_candidates_per_step`` (lists of ints, one per step; MuJoCo's are the geom
        pairs its broad phase and midphase pass to the contact filter, plus its explicit pairs), ``time_ours_us`` and
        ``time_mujoco_broad_us`` (medians), their ``ratio``, the per-step times
        (``time_ours_us_per_step``, ``time_mujoco_broad_us_per_step``), ``model``, ``seed``,
        ``unstable_resets`` (times MuJoCo reset an unstable simulation; such a step's MuJoCo
        time is that of the broad phase after the reset),
        ``mujoco_count_replayed`` (True when the counting run reproduced every step's contacts),
        ``contact_pairs_total`` (MuJoCo contact pairs summed over the steps),
        ``flex_contacts_total`` (MuJoCo contacts involving a flex, summed over the steps: not geom
        pairs, so left out of the comparison), ``nbody`` and ``ngeom``; ``contacts`` (None without
        ``contacts``): geom pairs in contact by MuJoCo (``mujoco_pairs``), by us (``our_pairs``),
        by both (``matched``), MuJoCo's pairs we made no contact for (``missed``) and ours it
        made none for (``extra``), lists of ``{step, geom1, geom2, name1, name2, dist}``, and how
        many of each lie within MuJoCo's ``ccd_tolerance`` of touching (``missed_near_touching``,
        ``extra_near_touching``, ``tolerance``: its GJK/EPA answers within it); contact
        counts (``mujoco_contacts``, ``our_contacts``); over the matched pairs' deepest contacts,
        the largest and median ``dist`` difference (``dist_error_max``, ``dist_error_median``; the
        pair with the largest, ``dist_error_worst``, with both answers) and
        angle between the normals (``normal_error_max_rad``, ``normal_error_median_rad``: large
        where the normal is not unique, a face on a face).
    """
    steps = as_count(steps, "steps", 1)
    seed = as_count(seed, "seed", 0)
    hold = as_count(hold, "hold", 1)
    bp = broadphase if broadphase is not None else BroadPhase(model)
    if not isinstance(bp, BroadPhase):
        raise ValueError(f"broadphase: expected a collide.mujoco.BroadPhase, got {type(bp).__name__}")
    diff = _model_mismatch(bp.model, model)
    if diff is not None:
        raise ValueError(f"broadphase: built from another model ({diff})")
    rec = Comparison(name, seed)
    perf = time.perf_counter_ns
    # Inside the loop only raw copies are kept: numpy's set routines (np.unique with an axis,
    # np.isin) between two calls made our next call much slower (evicting its code and data),
    # so the recall bookkeeping runs after the loop.
    raw_contacts, raw_candidates = [], []
    ctrls = _random_controls(model, steps, seed, hold)
    # Run 1, timed: MuJoCo's broad-phase timer and our call on the state it just collided.
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    bp.pairs(data)  # compile / warm up (and bind data) outside the timed loop
    timer = data.timer[_TIMER_BROAD]
    resets = 0
    with mujoco_timer():
        for step in range(steps):
            if step % hold == 0 and len(ctrls):
                data.ctrl[:] = ctrls[step // hold]
            dur0, num0, time0, warn0 = timer.duration, timer.number, data.time, _unstable_warnings(data)
            mujoco.mj_step(model, data)
            t0 = perf()
            cand = bp.pairs(data)
            t1 = perf()
            rec.time_ours_us.append((t1 - t0) * 1e-3)
            # An unstable simulation is reset inside mj_step (mj_resetData, then the forward pass
            # again): its time starts over and its timers and warnings restart from zero, so the
            # timer then holds only the intervals after the reset (found 2026-11-22: negative
            # times, and 1 reset reported for 3). A reset shows as time not advancing, or as a
            # new instability warning (the first step's reset).
            if not data.time > time0 or _unstable_warnings(data) != warn0:
                resets += 1
                dur0 = num0 = 0
            rec.time_mujoco_broad_us.append(float(timer.duration - dur0) / max(int(timer.number - num0), 1))
            raw_contacts.append(np.array(data.contact.geom[:data.ncon], dtype=np.int64))
            raw_candidates.append(cand)
            if on_step is not None:
                on_step(step, data, cand)
    # Run 2, the same controls again: MuJoCo's candidates, counted by a contact-filter callback.
    # Not in run 1: the callback runs Python for every candidate inside mj_step, between MuJoCo's
    # timed broad phase and our call, and evicts our kernel's code and data from the caches
    # (hundreds of calls a step on 22_humanoids, our call markedly slower). The callback returns MuJoCo's own
    # verdict, so both runs simulate the same states; `replayed` says whether every step's
    # contacts came out the same.
    replayed = True
    # Explicit pairs never reach the contact filter: MuJoCo tests each of them every step.
    npair = int(model.npair)
    data2 = mujoco.MjData(model)
    mujoco.mj_forward(model, data2)  # as run 1 did
    # Our contacts on the same states (`Collider`), against MuJoCo's: each geom pair's deepest.
    agreement = _ContactAgreement(model) if contacts else None
    with candidate_counter(model) as counter:
        for step in range(steps):
            if step % hold == 0 and len(ctrls):
                data2.ctrl[:] = ctrls[step // hold]
            counter.reset()
            mujoco.mj_step(model, data2)
            rec.mujoco_candidates.append(counter.count + npair)
            if replayed and not np.array_equal(data2.contact.geom[:data2.ncon], raw_contacts[step]):
                replayed = False
            if agreement is not None:
                agreement.add(step, data2)
    ng = np.int64(model.ngeom)
    flex_contacts = 0
    for step, (geoms, cand) in enumerate(zip(raw_contacts, raw_candidates)):
        rec.candidates.append(len(cand))
        geoms = np.sort(geoms, axis=1)
        flex_contacts += int(np.count_nonzero(geoms[:, 0] < 0))
        geoms = geoms[geoms[:, 0] >= 0]  # flex contacts are not geom pairs
        key_c = np.unique(geoms[:, 0] * ng + geoms[:, 1])
        rec.contact_pairs.append(len(key_c))
        if len(key_c):
            key_o = cand[:, 0].astype(np.int64) * ng + cand[:, 1]
            for key in key_c[~np.isin(key_c, key_o)]:
                g1, g2 = divmod(int(key), int(ng))
                rec.missed.append({"step": step, "geom1": g1, "geom2": g2,
                                   "name1": _geom_name(model, g1), "name2": _geom_name(model, g2)})
    total = int(np.sum(rec.contact_pairs))
    t_ours = float(np.median(rec.time_ours_us))
    t_mj = float(np.median(rec.time_mujoco_broad_us))
    return {
        "model": rec.model_name,
        "seed": seed,
        "steps": steps,
        "recall": 1.0 if total == 0 else (total - len(rec.missed)) / total,
        "missed": rec.missed,
        "contact_pairs_total": total,
        "flex_contacts_total": flex_contacts,
        "contact_pairs_per_step": rec.contact_pairs,
        "candidates_per_step": rec.candidates,
        "mujoco_candidates_per_step": rec.mujoco_candidates,
        "time_ours_us": t_ours,
        "time_mujoco_broad_us": t_mj,
        "ratio": t_ours / t_mj if t_mj > 0 else float("inf"),
        "time_ours_us_per_step": rec.time_ours_us,
        "time_mujoco_broad_us_per_step": rec.time_mujoco_broad_us,
        "nbody": int(model.nbody),
        "ngeom": int(model.ngeom),
        "unstable_resets": resets,
        "mujoco_count_replayed": replayed,
        "contacts": agreement.summary() if agreement is not None else None,
    }


def mujoco_deepest(data: mujoco.MjData) -> dict:
    """MuJoCo's deepest contact of each geom pair in ``data.contact`` (flex contacts left out).

    Returns
    -------
    dict
        ``{(g1, g2): (dist, normal, includemargin)}``, ``g1 < g2``, ``normal`` ``(3,) float64``
        from ``g1`` to ``g2`` (``contact.frame[:3]``, turned for that order).
    """
    out: dict = {}
    for i in range(data.ncon):
        c = data.contact[i]
        a, b = int(c.geom[0]), int(c.geom[1])
        if a < 0 or b < 0:
            continue
        n = np.array(c.frame[:3])
        if a > b:
            a, b, n = b, a, -n
        old = out.get((a, b))
        if old is None or c.dist < old[0]:
            out[(a, b)] = (float(c.dist), n, float(c.includemargin))
    return out


class _ContactAgreement:
    # `compare`'s contact check: per step, MuJoCo's deepest contact of each geom pair (flex
    # contacts left out) against ours (`Collider.contacts` on the same MjData).
    def __init__(self, model: mujoco.MjModel):
        self.model = model
        self.collider = Collider(model)
        # MuJoCo's GJK/EPA answers within opt.ccd_tolerance: a pair that near touching may have
        # a contact in one answer and not in the other.
        self.tolerance = max(float(model.opt.ccd_tolerance), 0.0)
        self.mujoco_pairs = self.ours_pairs = self.matched = 0
        self.missed: list = []
        self.extra: list = []
        self.dist_err: list = []
        self.normal_err: list = []
        self.contacts_mujoco = self.contacts_ours = 0
        self.worst_err, self.worst = -1.0, None  # the matched pair whose dist differs most

    def add(self, step: int, data: mujoco.MjData) -> None:
        theirs = mujoco_deepest(data)
        self.contacts_mujoco += int(np.count_nonzero(np.all(data.contact.geom[:data.ncon] >= 0, axis=1)))
        ours = self.collider.contacts(data)
        self.contacts_ours += len(ours)
        best = ours.deepest()
        self.mujoco_pairs += len(theirs)
        self.ours_pairs += len(best)
        for key, (dist, n, _) in theirs.items():
            i = best.get(key)
            if i is None:
                self.missed.append(self._entry(step, key, dist))
                continue
            self.matched += 1
            self.dist_err.append(abs(float(ours.dist[i]) - dist))
            if self.dist_err[-1] >= self.worst_err:
                self.worst_err = self.dist_err[-1]
                self.worst = dict(self._entry(step, key, dist), ours=float(ours.dist[i]))
            self.normal_err.append(float(np.arccos(np.clip(np.dot(ours.normal[i], n), -1.0, 1.0))))
        for key, i in best.items():
            if key not in theirs:
                self.extra.append(self._entry(step, key, float(ours.dist[i])))

    def _entry(self, step: int, key: tuple, dist: float) -> dict:
        g1, g2 = key
        return {"step": step, "geom1": g1, "geom2": g2, "name1": _geom_name(self.model, g1),
                "name2": _geom_name(self.model, g2), "dist": dist}

    def summary(self) -> dict:
        d, n = np.asarray(self.dist_err), np.asarray(self.normal_err)
        return {
            "mujoco_pairs": self.mujoco_pairs, "our_pairs": self.ours_pairs, "matched": self.matched,
            "missed": self.missed, "extra": self.extra,
            "missed_near_touching": sum(e["dist"] > -self.tolerance for e in self.missed),
            "extra_near_touching": sum(e["dist"] < self.tolerance for e in self.extra),
            "tolerance": self.tolerance,
            "mujoco_contacts": self.contacts_mujoco, "our_contacts": self.contacts_ours,
            "dist_error_max": float(d.max()) if len(d) else 0.0,
            "dist_error_median": float(np.median(d)) if len(d) else 0.0,
            "dist_error_worst": self.worst,
            "normal_error_max_rad": float(n.max()) if len(n) else 0.0,
            "normal_error_median_rad": float(np.median(n)) if len(n) else 0.0,
        }


def format_report(result: dict) -> str:
    """The comparison as a printable table (see `compare` for the figures)."""
    c = np.asarray(result["contact_pairs_per_step"])
    o = np.asarray(result["candidates_per_step"])
    mj = np.asarray(result["mujoco_candidates_per_step"])
    lines = [
        f"collide vs MuJoCo {mujoco.__version__}: {result['model']} "
        f"({result['nbody']} bodies, {result['ngeom']} geoms), {result['steps']} steps, "
        f"seed {result['seed']}",
        "",
        f"{'per step':<34}{'mean':>10}{'median':>10}{'max':>10}",
        f"{'MuJoCo contact pairs':<34}{c.mean():>10.1f}{np.median(c):>10.0f}{c.max():>10d}",
        f"{'our candidates':<34}{o.mean():>10.1f}{np.median(o):>10.0f}{o.max():>10d}",
        f"{'MuJoCo broad-phase candidates':<34}{mj.mean():>10.1f}{np.median(mj):>10.0f}"
        f"{mj.max():>10d}",
        "",
        f"recall: {100.0 * result['recall']:.2f} % of {result['contact_pairs_total']} MuJoCo "
        f"contact pairs were among our candidates ({len(result['missed'])} missed)",
    ]
    for miss in result["missed"][:20]:
        lines.append(f"  MISSED step {miss['step']}: {miss['name1']} ({miss['geom1']}) - "
                     f"{miss['name2']} ({miss['geom2']})")
    if len(result["missed"]) > 20:
        lines.append(f"  ... {len(result['missed']) - 20} more")
    lines += [
        "",
        f"median time per step: ours {result['time_ours_us']:.1f} us (Python call included), "
        f"MuJoCo broad phase {result['time_mujoco_broad_us']:.1f} us "
        f"(mjTIMER_COL_BROAD), "
        + (f"ratio {result['ratio']:.2f}x" if np.isfinite(result["ratio"]) else "ratio n/a (MuJoCo's timer read 0)"),
    ]
    ct = result.get("contacts")
    if ct:
        lines += [
            "",
            f"contacts: {ct['matched']} of {ct['mujoco_pairs']} geom pairs MuJoCo made contacts for had ours "
            f"({len(ct['missed'])} missed, {ct['missed_near_touching']} of them within MuJoCo's ccd_tolerance "
            f"{ct['tolerance']:g} of touching; {len(ct['extra'])} of ours beyond MuJoCo's, "
            f"{ct['extra_near_touching']} within it); "
            f"{ct['our_contacts']} contact points against MuJoCo's {ct['mujoco_contacts']}",
            f"  deepest contact of each pair: dist differs by {ct['dist_error_median']:.2g} (median), "
            f"{ct['dist_error_max']:.2g} (max); normals by {ct['normal_error_median_rad']:.2g} rad (median), "
            f"{ct['normal_error_max_rad']:.2g} rad (max)",
        ]
        w = ct.get("dist_error_worst")
        if w:
            lines.append(f"  largest dist difference: step {w['step']}, {w['name1']} ({w['geom1']}) - {w['name2']} "
                         f"({w['geom2']}): MuJoCo {w['dist']:.6g}, ours {w['ours']:.6g}")
        for kind in ("missed", "extra"):
            for e in ct[kind][:5]:
                lines.append(f"  {kind.upper()} step {e['step']}: {e['name1']} ({e['geom1']}) - {e['name2']} "
                             f"({e['geom2']}), dist {e['dist']:.3g}")
    if result.get("mujoco_count_replayed") is False:
        lines.append("note: the run counting MuJoCo's candidates did not reproduce the timed run's contacts")
    if result.get("flex_contacts_total"):
        lines.append(f"note: {result['flex_contacts_total']} MuJoCo contacts involving a flex were left out "
                     "(collide bounds geoms; flex contacts are not geom pairs)")
    if result.get("unstable_resets"):
        lines.append(f"note: MuJoCo reset an unstable simulation {result['unstable_resets']} time(s)")
    return "\n".join(lines)


def plot_comparison(result: dict, path) -> None:
    """Write a figure of the per-step figures of `compare` (needs matplotlib).

    Top: MuJoCo contact pairs, our candidates and MuJoCo's broad-phase candidates per step;
    bottom: our time and MuJoCo's broad-phase time per step.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import LogLocator, NullFormatter, ScalarFormatter

    steps = np.arange(result["steps"])
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    ax1.plot(steps, result["mujoco_candidates_per_step"], lw=0.8,
             label="MuJoCo broad-phase candidates")
    ax1.plot(steps, result["candidates_per_step"], lw=0.8, label="our candidates")
    ax1.plot(steps, result["contact_pairs_per_step"], lw=0.8, label="MuJoCo contact pairs")
    ax1.set_ylabel("geom pairs per step")
    ax1.set_title(f"{result['model']}: recall {100 * result['recall']:.2f} %, "
                  f"{len(result['missed'])} missed", pad=20)  # room for the legend above
    # Outside the axes: the lines fill the panel (MuJoCo's candidates run along its top).
    ax1.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=3, fontsize="small", frameon=False)
    ax2.plot(steps, result["time_mujoco_broad_us_per_step"], lw=0.6,
             label=f"MuJoCo broad phase (median {result['time_mujoco_broad_us']:.1f} us)")
    ax2.plot(steps, result["time_ours_us_per_step"], lw=0.6,
             label=f"ours, Python call included (median {result['time_ours_us']:.1f} us)")
    ax2.set_yscale("log")
    # 2, 5, 10, 20, 50 rather than 2 x 10^0 ... and crowded minor labels
    ax2.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax2.yaxis.set_major_formatter(ScalarFormatter())
    ax2.yaxis.set_minor_formatter(NullFormatter())
    ax2.set_xlabel("step")
    ax2.set_ylabel("time per step (us)")
    ax2.legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2, fontsize="small", frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ----------------------------------------------------------------------------------------------
# The built-in scene
# ----------------------------------------------------------------------------------------------

def _add_limb(parent, name: str, pos, axes, segments) -> None:
    # A chain of capsules, each hinged to the previous one, each hinge with a motor added later.
    body = parent
    for k, (direction, length) in enumerate(segments):
        start = pos if k == 0 else np.asarray(segments[k - 1][0]) * segments[k - 1][1]
        child = body.add_body(name=f"{name}{k}", pos=list(start))
        for a, axis in enumerate(axes):
            child.add_joint(name=f"{name}{k}_j{a}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis,
                            range=[-1.2, 1.2], damping=0.5)
        end = np.asarray(direction) * length
        child.add_geom(name=f"{name}{k}", type=_GEOM.mjGEOM_CAPSULE, size=[0.045, 0, 0],
                       fromto=[0, 0, 0, *end], density=800)
        body = child


def load_model(path) -> tuple[mujoco.MjModel, str]:
    """A model from an MJCF file, and a short name for reports (the folder of a ``scene.xml``).

    Raises
    ------
    ValueError
        No such file, or MuJoCo cannot load it (its message included).
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"no such model file: {path}")
    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise ValueError(f"MuJoCo cannot load {path}: {exc}") from None
    return model, (path.parent.name if path.stem == "scene" else path.stem)


def default_scene(seed: int = 0, objects: int = 40) -> mujoco.MjModel:
    """The built-in comparison scene, made with ``mujoco.MjSpec``: no files needed.

    An articulated figure (a capsule torso on a free joint, head, two arms and two legs of
    hinged capsules with motors) falls onto a pile of random convex meshes and primitives
    (boxes, spheres, capsules, cylinders, ellipsoids) dropped on a floor.

    Parameters
    ----------
    seed : int
        Seed of the pile's shapes and positions.
    objects : int
        Number of loose objects in the pile.

    Returns
    -------
    mujoco.MjModel
    """
    seed = as_count(seed, "seed", 0)
    objects = as_count(objects, "objects", 0)
    rng = np.random.default_rng(seed)
    spec = mujoco.MjSpec()
    spec.modelname = "collide_default_scene"
    spec.option.timestep = 0.004
    spec.worldbody.add_geom(name="floor", type=_GEOM.mjGEOM_PLANE, size=[3, 3, 0.1],
                            rgba=[0.55, 0.6, 0.65, 1.0])
    spec.worldbody.add_light(pos=[0, -1, 3], dir=[0, 0.3, -1], diffuse=[0.8, 0.8, 0.8])
    side = int(np.ceil(np.sqrt(max(objects, 1) / 2.0)))
    kinds = ["mesh", "mesh", "box", "sphere", "capsule", "cylinder", "ellipsoid"]
    for i in range(objects):
        layer, cell = divmod(i, side * side)
        x, y = (np.array(divmod(cell, side)) - (side - 1) / 2.0) * 0.22
        pos = [x + rng.uniform(-0.03, 0.03), y + rng.uniform(-0.03, 0.03), 0.1 + 0.22 * layer]
        quat = rng.normal(size=4)
        body = spec.worldbody.add_body(name=f"obj{i}", pos=pos, quat=quat / np.linalg.norm(quat))
        body.add_freejoint()
        kind = kinds[i % len(kinds)]
        s = rng.uniform(0.035, 0.08, size=3)
        if kind == "mesh":
            pts = rng.normal(size=(int(rng.integers(8, 24)), 3)) * s
            spec.add_mesh(name=f"hull{i}", uservert=pts.ravel().tolist())
            body.add_geom(name=f"obj{i}", type=_GEOM.mjGEOM_MESH, meshname=f"hull{i}")
        else:
            gtype = {"box": _GEOM.mjGEOM_BOX, "sphere": _GEOM.mjGEOM_SPHERE,
                     "capsule": _GEOM.mjGEOM_CAPSULE, "cylinder": _GEOM.mjGEOM_CYLINDER,
                     "ellipsoid": _GEOM.mjGEOM_ELLIPSOID}[kind]
            body.add_geom(name=f"obj{i}", type=gtype, size=s.tolist())
    torso = spec.worldbody.add_body(name="torso", pos=[0, 0, 0.45 + 0.22 * (objects // (side * side) + 1)])
    torso.add_freejoint()
    torso.add_geom(name="torso", type=_GEOM.mjGEOM_CAPSULE, size=[0.07, 0, 0],
                   fromto=[0, -0.08, 0, 0, 0.08, 0], density=600)
    torso.add_geom(name="head", type=_GEOM.mjGEOM_SPHERE, size=[0.08, 0, 0], pos=[0, 0, 0.17])
    torso.add_geom(name="pelvis", type=_GEOM.mjGEOM_CAPSULE, size=[0.06, 0, 0],
                   fromto=[0, -0.06, -0.22, 0, 0.06, -0.22], density=600)
    xy = [[1, 0, 0], [0, 1, 0]]
    for sign, side_name in ((1, "left"), (-1, "right")):
        _add_limb(torso, f"{side_name}_arm", [0, sign * 0.13, 0.02], xy,
                  [([0, sign * 0.6, -0.8], 0.18), ([0, sign * 0.3, -0.95], 0.16)])
        _add_limb(torso, f"{side_name}_leg", [0, sign * 0.07, -0.25], [[0, 1, 0]],
                  [([0, 0, -1.0], 0.22), ([0, 0, -1.0], 0.2)])
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_HINGE:
            act = spec.add_actuator(name=f"motor_{joint.name}", target=joint.name,
                                    trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.gear[0] = 6.0
            act.ctrllimited = 1
            act.ctrlrange = [-1.0, 1.0]
    return spec.compile()


from ..collider import Collider  # noqa: E402  (contacts: collide.collider, which does not import mujoco)
from ..rerun_log import log_rerun  # noqa: E402  (a Rerun recording; rerun itself imported when one is made)
