"""MuJoCo's model -> `Articulation`: bounding clouds, inflations, frames and the collision filter
(the rules listed in `collide.mujoco`'s docstring)."""

from __future__ import annotations

import mujoco
import numpy as np

from .. import shapes
from .._validate import as_array
from ..articulation import Articulation, not_rotations
from ..pointcloud import PointCloud
from ..volumes import aabb_corners

__all__ = ["SDF_PAD", "articulation", "exclusion_rules", "geom_clouds", "geom_frames", "geom_inflation",
           "model_excludes", "pair_inflation", "parent_excludes", "weld_groups"]

_GEOM = mujoco.mjtGeom
_DSBL = mujoco.mjtDisableBit
_ENBL = mujoco.mjtEnableBit
_OBJ_GEOM = mujoco.mjtObj.mjOBJ_GEOM

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
    bad = not_rotations(geom_rot)
    if len(bad):  # named as the model holds it (the Articulation would name its own argument)
        g = int(bad[0])
        sf = mujoco.mjtSameFrame
        # int(): ``in`` compares with the tuple's item on the left, and the enum's own __eq__
        # answers False for a numpy scalar (``sf.X == np.uint8(2)``), so ``in`` on the raw element
        # named geom_quat for every geom
        inertial = int(model.geom_sameframe[g]) in (int(sf.mjSAMEFRAME_INERTIA), int(sf.mjSAMEFRAME_INERTIAROT))
        field = "model.body_iquat" if inertial else "model.geom_quat"
        raise ValueError(f"{field}: geom {g}'s orientation is not a rotation (a quaternion of norm other than 1, "
                         "or not finite; MuJoCo uses it as it is, so its geom_xmat is no rotation either): "
                         "normalise it")
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


def _geom_name(model: mujoco.MjModel, g: int) -> str:
    name = mujoco.mj_id2name(model, _OBJ_GEOM, int(g))
    return name if name else f"geom{int(g)}"


def _contacts_disabled(model: mujoco.MjModel) -> bool:
    flags = int(model.opt.disableflags)
    return bool(flags & (_DSBL.mjDSBL_CONTACT | _DSBL.mjDSBL_CONSTRAINT)) or model.nbody < 2
