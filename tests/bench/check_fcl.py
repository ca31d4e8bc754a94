"""python-fcl's and coal's collision managers on a MuJoCo scene, for `check_batch.py` (issue 43).

What a Python user of those libraries writes to ask "is this configuration in collision": one
collision object per geom that can collide (contype or conaffinity nonzero), in a
``DynamicAABBTreeCollisionManager``; per configuration, each object's transform set from MuJoCo's
geom poses (``mj_kinematics`` first, not timed: the libraries have no kinematics), the manager
updated, then ``collide`` with a callback that narrow-tests the pair (``collide`` of the two
objects, one contact) and stops at the first contact of a pair MuJoCo's filters keep (parent/weld,
contype/conaffinity, ``<exclude>``; `collide.collider.filtered_pairs`). python-fcl's callback gets
wrappers that do not say which objects they are, so its filter reads the contact's geometries,
after the narrow test. coal 3.0.3's callback class cannot be subclassed from Python and its
objects and geometries cannot be told apart in a callback: its figure is the manager's
``CollisionCallBackCollect`` (every candidate narrow-tested, no filter, no early exit), a cost
of the same work, its answer not MuJoCo's (parent and child geoms overlap). Timed per query:
the transforms, the update and the collide call. Shapes: sphere, capsule, box, cylinder,
ellipsoid as themselves, a plane as a large box under it (`PLANE_HALF`), a mesh as its convex hull (MuJoCo collides a
mesh's hull); MuJoCo's margins are not applied (both libraries test penetration).
"""

from __future__ import annotations

import time

import mujoco
import numpy as np
from scipy.spatial import ConvexHull

GT = mujoco.mjtGeom
# A plane as a box under it (python-fcl's dynamic AABB tree crashes on a half-space's unbounded
# box): half-extent and half-depth, its top face on the plane.
PLANE_HALF, PLANE_DEPTH = 1e3, 1.0


def _hull(model, g):
    m = int(model.geom_dataid[g])
    a, n = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
    v = np.asarray(model.mesh_vert[a:a + n], np.float64)
    h = ConvexHull(v)
    return v, h.simplices.astype(np.int64)


def _fcl_shape(fcl, model, g):
    t, s = int(model.geom_type[g]), model.geom_size[g]
    if t == GT.mjGEOM_SPHERE:
        return fcl.Sphere(s[0])
    if t == GT.mjGEOM_CAPSULE:
        return fcl.Capsule(s[0], 2 * s[1])
    if t == GT.mjGEOM_BOX:
        return fcl.Box(2 * s[0], 2 * s[1], 2 * s[2])
    if t == GT.mjGEOM_CYLINDER:
        return fcl.Cylinder(s[0], 2 * s[1])
    if t == GT.mjGEOM_ELLIPSOID:
        return fcl.Ellipsoid(s[0], s[1], s[2])
    if t == GT.mjGEOM_PLANE:
        return fcl.Box(2 * PLANE_HALF, 2 * PLANE_HALF, 2 * PLANE_DEPTH)
    if t == GT.mjGEOM_MESH:
        v, f = _hull(model, g)
        faces = np.hstack([np.full((len(f), 1), 3), f]).ravel()
        return fcl.Convex(v, len(f), faces)
    return None


def _coal_shape(coal, model, g):
    t, s = int(model.geom_type[g]), model.geom_size[g]
    if t == GT.mjGEOM_SPHERE:
        return coal.Sphere(s[0])
    if t == GT.mjGEOM_CAPSULE:
        return coal.Capsule(s[0], 2 * s[1])
    if t == GT.mjGEOM_BOX:
        return coal.Box(2 * s[0], 2 * s[1], 2 * s[2])
    if t == GT.mjGEOM_CYLINDER:
        return coal.Cylinder(s[0], 2 * s[1])
    if t == GT.mjGEOM_ELLIPSOID:
        return coal.Ellipsoid(s[0], s[1], s[2])
    if t == GT.mjGEOM_PLANE:
        return coal.Box(2 * PLANE_HALF, 2 * PLANE_HALF, 2 * PLANE_DEPTH)
    if t == GT.mjGEOM_MESH:
        v, f = _hull(model, g)
        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(len(f), len(v))
        bvh.addVertices(v)
        bvh.addTriangles(f)
        bvh.endModel()
        bvh.buildConvexHull(True, "Qt")
        return bvh.convex
    return None


def _geoms(model):
    return [g for g in range(model.ngeom) if model.geom_contype[g] or model.geom_conaffinity[g]]


def _run(model, q, objs, geoms, set_tf, manager, collide_all):
    # per configuration: poses (untimed), then transforms + update + collide (timed)
    data = mujoco.MjData(model)
    planes = np.flatnonzero(model.geom_type == GT.mjGEOM_PLANE)
    hit = np.zeros(len(q), bool)
    total = 0.0
    for i, x in enumerate(q):
        data.qpos[:] = x
        mujoco.mj_kinematics(model, data)
        pos, mat = data.geom_xpos.copy(), data.geom_xmat.reshape(-1, 3, 3)
        pos[planes] -= PLANE_DEPTH * mat[planes, :, 2]
        t0 = time.perf_counter()
        for o, g in zip(objs, geoms):
            set_tf(o, mat[g], pos[g])
        manager.update()
        hit[i] = collide_all()
        total += time.perf_counter() - t0
    return total / len(q), hit


def bench_fcl(model, q, allowed: set):
    """python-fcl: (us per query, in collision per configuration), or (None, reason)."""
    try:
        import fcl
    except ImportError as exc:
        return None, f"python-fcl not importable ({exc})"
    geoms = _geoms(model)
    objs, keep, shapes = [], [], {}
    for g in geoms:
        s = _fcl_shape(fcl, model, g)
        if s is None:
            return None, f"geom type {int(model.geom_type[g])} has no fcl shape here"
        objs.append(fcl.CollisionObject(s, fcl.Transform()))
        keep.append(g)
        shapes[id(s)] = g
    man = fcl.DynamicAABBTreeCollisionManager()
    man.registerObjects(objs)
    man.setup()
    req = fcl.CollisionRequest(num_max_contacts=1)
    state = {"hit": False}

    def callback(o1, o2, _):
        # python-fcl hands the callback new wrappers of the two objects, which do not say which
        # objects they are: the filters read the contact's geometries, after the narrow test
        res = fcl.CollisionResult()
        if fcl.collide(o1, o2, req, res) and res.contacts:
            c = res.contacts[0]
            a, b = shapes[id(c.o1)], shapes[id(c.o2)]
            if (min(a, b), max(a, b)) in allowed:
                state["hit"] = True
                return True
        return False

    def collide_all():
        state["hit"] = False
        man.collide(None, callback)
        return state["hit"]

    def set_tf(o, r, p):
        o.setTransform(fcl.Transform(r, p))

    return _run(model, q, objs, keep, set_tf, man, collide_all)


def bench_coal(model, q, allowed: set):
    """coal: (us per query, in collision per configuration), or (None, reason)."""
    try:
        import coal
    except ImportError as exc:
        return None, f"coal not importable ({exc})"
    geoms = _geoms(model)
    objs, keep = [], []
    for g in geoms:
        s = _coal_shape(coal, model, g)
        if s is None:
            return None, f"geom type {int(model.geom_type[g])} has no coal shape here"
        objs.append(coal.CollisionObject(s, coal.Transform3s()))
        keep.append(g)
    man = coal.DynamicAABBTreeCollisionManager()
    for o in objs:
        man.registerObject(o)
    man.setup()
    # coal 3's Python callbacks cannot be subclassed ("This class cannot be instantiated from
    # Python"), its objects come back as new wrappers and its geometries compare by value: no
    # filter can be applied. CollisionCallBackCollect narrow-tests every candidate of the manager;
    # its answer ("some pair collides", filtered or not) is not MuJoCo's question.
    cb = coal.CollisionCallBackCollect(8 * len(objs) + 8)

    def collide_all():
        cb.init()
        man.collide(cb)
        return cb.numCollisionPairs() > 0

    def set_tf(o, r, p):
        o.setTransform(coal.Transform3s(r, p))

    return _run(model, q, objs, keep, set_tf, man, collide_all)


__all__ = ["bench_coal", "bench_fcl"]
