"""Benchmark: BroadPhase against MuJoCo's broad phase, python-fcl and coal, same scenes, same poses.

    python tests/bench/broadphase.py [--sizes 16,64,256,1024,4096] [--quick] > tests/bench/broadphase.txt

Scenes (issue 3):
- ``hulls N``: N free bodies, each a random convex hull of 30 points, on a jittered grid where
  each touches about 1 to 3 neighbours; a small random rigid motion per step
  (`collide.testing.free_hulls`, `hull_motion`). MuJoCo gets the same hulls as mesh geoms.
- ``chain 64``: 64 capsule links on hinges with random axes over a floor plane, simulated by
  MuJoCo under random motor controls; we replay the visited states.
- ``batch``: 1024 states of that chain in one `BroadPhase.pairs_batch` call (time per world).

Per step, on the same poses: ours = ``BroadPhase.pairs()`` on MjData's ``xpos`` and ``xmat``
bound once with `BroadPhase.bind` (the simulation-loop path: Python call included,
perf_counter_ns around it), and ``pairs(xpos, xmat)`` with the arrays passed each call ("passed"),
MuJoCo colliding each state before each of the two calls, their order alternating by state; MuJoCo
= ``mjTIMER_COL_BROAD`` after ``mj_kinematics`` + ``mj_collision`` (compiled clock callback from
`collide.mujoco.mujoco_timer`, so no Python runs in MuJoCo's interval; the header names the clock);
fcl / coal = set every object's transform from Python, update the DynamicAABBTree manager and
collect its pairs (no narrow phase), and the manager alone ("mgr": update and collide), which is
the libraries' own work. Medians over steps.
Candidates per step: ours (pairs out) against MuJoCo's broad-phase candidates, counted in a
separate run by a contact-filter callback that records and rejects every pair.
"""

from __future__ import annotations

import os

# Threads that wait passively: on a machine shared with other work, OpenMP's default spin-wait
# lets one preempted spinner stall every batched call by a scheduler time slice (measured here:
# 100+ us per world instead of ~5). Must be set before numba's OpenMP runtime starts.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
# numpy's OpenBLAS keeps worker threads that spin on the cores after a linear-algebra call. One
# interference less for the batched run's second thread (64-link chain, 2 threads, a 300 x 300 product
# before each call: 1.69 us a world with those threads, 1.45 without, 1.0-1.15 with no product; an A/B
# of the humanoid batch in mujoco_models.py showed no difference; session 16). Set before numpy loads.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import gc
import platform
import sys
import time

import mujoco
import numpy as np

from collide import Articulation, BroadPhase, PointCloud, testing
from _machine import cpu as _cpu  # noqa: E402 (tests/bench is the script's folder)

try:
    from collide.mujoco import mujoco_timer, timer_clock
except ImportError:  # pragma: no cover
    mujoco_timer = timer_clock = None

try:
    import fcl
except ImportError:  # pragma: no cover
    fcl = None
try:
    import coal
except ImportError:  # pragma: no cover
    coal = None

BROAD = int(mujoco.mjtTimer.mjTIMER_COL_BROAD)


def _quat(R: np.ndarray) -> np.ndarray:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, R.ravel())
    return q


def _median_us(ns) -> float:
    return float(np.median(ns)) / 1e3


# ------------------------------------------------------------------------------- MuJoCo scenes

def hull_model(scene) -> mujoco.MjModel:
    """The `free_hulls` scene as an MjModel: one free body per hull, a mesh geom of its points."""
    spec = mujoco.MjSpec()
    spec.option.gravity = [0, 0, 0]
    spec.memory = 1 << 28  # the default arena cannot hold a few thousand bodies' contacts
    a = scene.articulation
    for b in range(1, a.body_count):
        g = int(np.flatnonzero(a.geom_body == b)[0])
        spec.add_mesh(name=f"m{b}", uservert=a.geom_local_cloud[g].points.ravel().tolist())
        body = spec.worldbody.add_body(name=f"b{b}")
        body.add_freejoint()
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"m{b}")
    return spec.compile()


def chain_model(links: int, seed: int, radius=0.05, half_length=0.15) -> mujoco.MjModel:
    """A capsule chain on hinges with random axes, base 1 m above a floor, a motor per hinge."""
    rng = np.random.default_rng(seed)
    spec = mujoco.MjSpec()
    spec.compiler.degree = False  # joint ranges below are in radians
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1])
    parent = spec.worldbody
    for i in range(links):
        # the chain starts lying along x just above the floor, then writhes under its motors
        body = parent.add_body(name=f"l{i}", pos=[0, 0, 2 * half_length] if i else [0, 0, 0.3],
                               quat=[1, 0, 0, 0] if i else [np.sqrt(0.5), 0, np.sqrt(0.5), 0])
        axis = rng.normal(size=3) * [1, 1, 0.3]
        body.add_joint(name=f"j{i}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis / np.linalg.norm(axis),
                       damping=0.3, range=[-2.0, 2.0], limited=mujoco.mjtLimited.mjLIMITED_TRUE)
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[0, 0, 0, 0, 0, 2 * half_length],
                      size=[radius, 0, 0])
        spec.add_actuator(name=f"a{i}", target=f"j{i}", trntype=mujoco.mjtTrn.mjTRN_JOINT, gear=[8.0, 0, 0, 0, 0, 0])
        parent = body
    return spec.compile()


def articulation_of(model: mujoco.MjModel) -> Articulation:
    """Our Articulation of a capsule/plane/mesh MjModel: same bodies, geom frames and filters."""
    clouds = []
    for g in range(model.ngeom):
        t, s = model.geom_type[g], model.geom_size[g]
        if t == mujoco.mjtGeom.mjGEOM_PLANE:
            clouds.append(testing.make_plane((0, 0, 1), 0.0))
        elif t == mujoco.mjtGeom.mjGEOM_CAPSULE:
            clouds.append(PointCloud([[0, 0, -s[1]], [0, 0, s[1]]], s[0]))
        elif t == mujoco.mjtGeom.mjGEOM_MESH:
            m = model.geom_dataid[g]
            v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
            clouds.append(PointCloud(model.mesh_vert[v0:v0 + nv]))
        else:
            raise ValueError(f"geom type {t} not used by this benchmark")
    rot = np.empty((model.ngeom, 9))
    for g in range(model.ngeom):
        mujoco.mju_quat2Mat(rot[g], model.geom_quat[g])
    return Articulation(model.body_parentid, model.geom_bodyid, clouds, geom_pos=model.geom_pos,
                        geom_rot=rot.reshape(-1, 3, 3), geom_contype=model.geom_contype,
                        geom_conaffinity=model.geom_conaffinity, body_weld=model.body_weldid)


# ------------------------------------------------------------------------------- per-step runs

def run_mujoco_and_ours(model, qpos_steps, bp: BroadPhase):
    """Time MuJoCo's broad phase and ours on the same states; return the medians (ours bound, ours
    with the arrays passed, MuJoCo's) and our count."""
    d = mujoco.MjData(model)
    pos, rot = d.xpos, d.xmat.reshape(model.nbody, 3, 3)
    bp.bind(pos, rot)
    ours, passed, theirs, ours_k = [], [], [], []
    pc = time.perf_counter_ns
    gc.disable()
    try:
        with mujoco_timer():
            for s, q in enumerate(qpos_steps):
                # Each state twice, MuJoCo's kinematics and collision before each of our two calls,
                # the same Python work between them and our call, the order alternating: in a pass
                # of its own, the bound call (first, and after more Python work) read hulls 16 on
                # AMD at 9.0 us against 5.3 passed (2026-11-27).
                for bound in ((True, False) if s % 2 == 0 else (False, True)):
                    d.qpos[:] = q
                    mujoco.mj_kinematics(model, d)
                    before = d.timer[BROAD].duration
                    mujoco.mj_collision(model, d)
                    theirs.append((d.timer[BROAD].duration - before) * 1e3)  # us -> ns
                    if bound:
                        t0 = pc()
                        out = bp.pairs()
                        ours.append(pc() - t0)
                        ours_k.append(len(out))
                    else:
                        t0 = pc()
                        bp.pairs(pos, rot)
                        passed.append(pc() - t0)
    finally:
        gc.enable()
    return _median_us(ours), _median_us(passed), _median_us(theirs), float(np.mean(ours_k))


def mujoco_candidates(model, qpos_steps) -> float:
    """Mean geom pairs per step that MuJoCo's broad phase (and midphase) pass on: a contact filter
    callback records each and rejects it (so no narrow phase runs)."""
    d = mujoco.MjData(model)
    count = [0]

    def record_and_reject(m, dd, g1, g2):
        count[0] += 1
        return 1

    old = mujoco.get_mjcb_contactfilter()
    mujoco.set_mjcb_contactfilter(record_and_reject)
    try:
        for q in qpos_steps:
            d.qpos[:] = q
            mujoco.mj_kinematics(model, d)
            mujoco.mj_collision(model, d)
    finally:
        mujoco.set_mjcb_contactfilter(old)
    return count[0] / len(qpos_steps)


def _fcl_shape(cloud: PointCloud):
    if len(cloud.points) == 2 and cloud.radius > 0:
        return fcl.Capsule(cloud.radius, float(np.linalg.norm(cloud.points[1] - cloud.points[0])))
    from scipy.spatial import ConvexHull
    h = ConvexHull(cloud.points)
    return fcl.Convex(cloud.points, len(h.simplices), np.c_[np.full(len(h.simplices), 3), h.simplices].ravel())


def _coal_shape(cloud: PointCloud):
    if len(cloud.points) == 2 and cloud.radius > 0:
        return coal.Capsule(cloud.radius, float(np.linalg.norm(cloud.points[1] - cloud.points[0])))
    v = coal.StdVec_Vec3s()
    for p in cloud.points:
        v.append(np.asarray(p, float))
    return coal.Convex.convexHull(v, False, None)


def _geom_world(art, pos, rot):
    # World frames of the (non-plane) geoms: body pose times the geom's frame in its body.
    g = np.flatnonzero(~art.geom_is_plane)
    b = art.geom_body[g]
    R = rot[b] @ art.geom_rot[g]
    t = np.einsum("gij,gj->gi", rot[b], art.geom_pos[g]) + pos[b]
    return g, R, t


def run_fcl(art, poses, steps: int) -> tuple[float, float, float]:
    """python-fcl DynamicAABBTreeCollisionManager: per step set transforms, update, collect pairs.

    Returns the median per step of the whole loop body and of the manager alone (update and
    collide, after the transforms were set from Python), and the mean pair count."""
    g, R, t = _geom_world(art, *poses[0])
    # fcl/coal capsules are centred on their axis: the geom frame here is the capsule's middle.
    objs = [fcl.CollisionObject(_fcl_shape(art.geom_cloud[k]), fcl.Transform(R[i], t[i])) for i, k in enumerate(g)]
    man = fcl.DynamicAABBTreeCollisionManager()
    man.registerObjects(objs)
    man.setup()
    times, counts = [], []

    def cb(o1, o2, data):
        data.append(1)
        return False

    manager = []
    pc = time.perf_counter_ns
    for pos, rot in poses[:steps]:
        t0 = pc()
        _, R, t = _geom_world(art, pos, rot)
        for i, o in enumerate(objs):
            o.setTransform(fcl.Transform(R[i], t[i]))
        t1 = pc()
        man.update()
        found = []
        man.collide(found, cb)
        t2 = pc()
        times.append(t2 - t0)
        manager.append(t2 - t1)
        counts.append(len(found))
    return _median_us(times), _median_us(manager), float(np.mean(counts))


def run_coal(art, poses, steps: int) -> tuple[float, float, float]:
    """coal DynamicAABBTreeCollisionManager, the same loop (CollisionCallBackCollect: no narrow phase);
    returns as `run_fcl` (the manager alone: update and collide, after transforms and AABBs)."""
    g, R, t = _geom_world(art, *poses[0])
    objs = []
    for i, k in enumerate(g):
        o = coal.CollisionObject(_coal_shape(art.geom_cloud[k]))
        o.setTransform(coal.Transform3s(R[i], t[i]))
        o.computeAABB()
        objs.append(o)
    man = coal.DynamicAABBTreeCollisionManager()
    for o in objs:
        man.registerObject(o)
    man.setup()
    times, manager, counts = [], [], []
    pc = time.perf_counter_ns
    for pos, rot in poses[:steps]:
        t0 = pc()
        _, R, t = _geom_world(art, pos, rot)
        for i, o in enumerate(objs):
            o.setTransform(coal.Transform3s(R[i], t[i]))
            o.computeAABB()
        cb = coal.CollisionCallBackCollect(4 * len(objs) + 16)
        t1 = pc()
        man.update()
        man.collide(cb)
        t2 = pc()
        times.append(t2 - t0)
        manager.append(t2 - t1)
        counts.append(cb.numCollisionPairs())
    return _median_us(times), _median_us(manager), float(np.mean(counts))


# ------------------------------------------------------------------------------- scenes

def hull_states(n: int, steps: int, seed: int):
    scene = testing.free_hulls(n, seed=seed)
    model = hull_model(scene)
    pos, rot = testing.hull_motion(scene, np.random.default_rng(seed), steps, 0.01)
    qpos = np.empty((steps, model.nq))
    for s in range(steps):
        for b in range(1, n + 1):
            qpos[s, 7 * (b - 1):7 * (b - 1) + 3] = pos[s, b]
            qpos[s, 7 * (b - 1) + 3:7 * b] = _quat(rot[s, b])
    return model, qpos


def chain_states(links: int, steps: int, seed: int, every: int = 1, ctrl_seed: int | None = None):
    model = chain_model(links, seed)
    d = mujoco.MjData(model)
    rng = np.random.default_rng(seed if ctrl_seed is None else ctrl_seed)
    qpos = []
    ctrl = np.zeros(model.nu)
    for s in range(steps * every + 500):
        if s % 50 == 0:
            ctrl = rng.uniform(-1, 1, model.nu)
        d.ctrl[:] = ctrl
        mujoco.mj_step(model, d)
        if s >= 500 and (s - 500) % every == 0:
            qpos.append(d.qpos.copy())
    return model, np.array(qpos)


def poses_of(model, qpos_steps):
    d = mujoco.MjData(model)
    out = []
    for q in qpos_steps:
        d.qpos[:] = q
        mujoco.mj_kinematics(model, d)
        out.append((d.xpos.copy(), d.xmat.reshape(model.nbody, 3, 3).copy()))
    return out


def bench(name, model, qpos, fcl_steps) -> dict:
    t0 = time.perf_counter()
    art = articulation_of(model)
    bp = BroadPhase(art)
    setup = time.perf_counter() - t0  # the step kernel is loaded at the first pairs(), not here (since 2026-12-02)
    poses = poses_of(model, qpos[:3])
    bp.pairs(*poses[0])  # compile / warm
    ours, passed, theirs, ours_k = run_mujoco_and_ours(model, qpos, bp)
    row = dict(scene=name, bodies=model.nbody - 1, geoms=model.ngeom, ours=ours, passed=passed, mujoco=theirs,
               ours_k=ours_k, mj_k=mujoco_candidates(model, qpos), setup=setup, stats=bp.stats)
    fposes = poses_of(model, qpos[:fcl_steps])
    row["fcl"], row["fcl_mgr"], row["fcl_k"] = run_fcl(art, fposes, fcl_steps) if fcl else (np.nan,) * 3
    row["coal"], row["coal_mgr"], row["coal_k"] = run_coal(art, fposes, fcl_steps) if coal else (np.nan,) * 3
    return row, bp, art


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="16,64,256,1024,4096")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--worlds", type=int, default=1024)
    ap.add_argument("--quick", action="store_true", help="few steps, small sizes (a smoke run)")
    args = ap.parse_args(argv)
    if mujoco_timer is None:
        sys.exit("collide.mujoco.mujoco_timer is needed for MuJoCo's native timer")
    sizes = [int(s) for s in args.sizes.split(",")]
    steps = 30 if args.quick else args.steps
    import numba
    print(f"# collide broad phase benchmark, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"# machine: {numba.get_num_threads()} cores, Python {platform.python_version()}, {_cpu()}; "
          f"mujoco {mujoco.__version__}, numba {numba.__version__}; "
          f"OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY')}, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}")
    print("# per step, medians; ours = BroadPhase.pairs() on MjData's xpos/xmat bound once (Python call included),")
    print(f"# MuJoCo's timer on a {timer_clock()} clock;")
    print("# passed = pairs(xpos, xmat) on the same states (each state collided by MuJoCo before each of")
    print("# the two calls, their order alternating by state); MuJoCo = mjTIMER_COL_BROAD;")
    print("# fcl/coal = DynamicAABBTreeCollisionManager (transforms set from Python, update, collect pairs);")
    print("# mgr = the manager alone (update and collide, after the transforms were set): the libraries' own work;")
    print("# every ratio column = that library's time / MuJoCo's;")
    print("# candidates = pairs per step (MuJoCo: contact-filter callback, record and reject).")
    rows = []
    for n in sizes:
        # at least 60 steps: medians of 20 moved by up to 30 % between runs on a shared machine
        s = max(60, min(steps, 300 * 64 // n)) if not args.quick else steps
        model, qpos = hull_states(n, s, seed=n)
        row, _, _ = bench(f"hulls {n}", model, qpos, fcl_steps=max(5, min(s, 20)))
        rows.append(row)
        print(f"# done {row['scene']}: setup {row['setup']:.1f} s, {s} steps, stats {row['stats']}", flush=True)
    model, qpos = chain_states(64, steps, seed=1)
    row, bp, art = bench("chain 64", model, qpos, fcl_steps=min(steps, 100))
    rows.append(row)
    print(f"# done chain 64: stats {row['stats']}", flush=True)
    # Batched: B chain states (every 3rd step of a longer run), one call; time per world.
    B = 64 if args.quick else args.worlds
    _, bq = chain_states(64, B, seed=1, every=3, ctrl_seed=2)  # same chain, other controls
    d = mujoco.MjData(model)
    bpos = np.empty((B, model.nbody, 3))
    brot = np.empty((B, model.nbody, 3, 3))
    for w in range(B):
        d.qpos[:] = bq[w]
        mujoco.mj_kinematics(model, d)
        bpos[w], brot[w] = d.xpos, d.xmat.reshape(-1, 3, 3)
    got = bp.pairs_batch(bpos, brot)  # warm
    for w in range(0, B, max(1, B // 16)):
        assert np.array_equal(got[got[:, 0] == w, 1:], bp.pairs(bpos[w], brot[w]))
    reps = []
    for _ in range(21 if not args.quick else 2):  # 1-2 ms a call: 21 for a steadier median
        t0 = time.perf_counter_ns()
        got = bp.pairs_batch(bpos, brot)
        reps.append(time.perf_counter_ns() - t0)
    per_world = float(np.median(reps)) / B / 1e3
    print()
    head = (f"{'scene':<11}{'bodies':>7}{'ours us':>10}{'passed':>8}{'MuJoCo us':>11}{'ratio':>7}{'fcl us':>10}{'ratio':>7}"
            f"{'mgr us':>9}{'ratio':>7}{'coal us':>10}{'ratio':>7}{'mgr us':>9}{'ratio':>7}"
            f"{'ours cand':>11}{'MuJoCo cand':>13}{'fcl cand':>10}{'coal cand':>10}")
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['scene']:<11}{r['bodies']:>7}{r['ours']:>10.1f}{r['passed']:>8.1f}{r['mujoco']:>11.1f}"
              f"{r['ours'] / r['mujoco']:>7.2f}"
              f"{r['fcl']:>10.1f}{r['fcl'] / r['mujoco']:>7.1f}{r['fcl_mgr']:>9.1f}{r['fcl_mgr'] / r['mujoco']:>7.1f}"
              f"{r['coal']:>10.1f}{r['coal'] / r['mujoco']:>7.1f}{r['coal_mgr']:>9.1f}{r['coal_mgr'] / r['mujoco']:>7.1f}"
              f"{r['ours_k']:>11.1f}{r['mj_k']:>13.1f}{r['fcl_k']:>10.1f}{r['coal_k']:>10.1f}")
    mj_chain = rows[-1]["mujoco"]
    print(f"{'batch ' + str(B):<11}{model.nbody - 1:>7}{per_world:>10.2f}{'':>8}{mj_chain:>11.1f}"
          f"{per_world / mj_chain:>7.2f}{'':>66}{len(got) / B:>11.1f}    (time per world, {numba.get_num_threads()} threads)")
    print()
    print("# targets: ratio <= 1.0 everywhere, <= 0.5 from 1024 bodies, batch <= 0.3; ours cand < MuJoCo cand")


if __name__ == "__main__":
    main()
