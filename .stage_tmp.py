# Staged copy of _world: returns early at stage markers, for per-stage hot timings.
import inspect, re, sys, time, textwrap
import numba as nb, numpy as np
import collide._kernels.broadphase as kb
src = inspect.getsource(kb._world.py_func)
src = src.replace("@nb.njit(cache=True)\n", "")
src = src.replace("def _world(body_pos, body_rot, I, F, W, sap, bp, keys, stats, info):",
                  "def _world(body_pos, body_rot, I, F, W, sap, bp, keys, stats, info, stage):")
marks = ["    # 1. poses", "    # 2. subtree", "    # 3. candidate", "    # 4. body pairs", "    # 5a. planes", "    # 5b. explicit", "    stats[ST_OUT] = k"]
for i, m in enumerate(marks):
    assert m in src, m
    src = src.replace(m, f"    if stage == {i}:\n        return k\n" + m, 1)
ns = dict(vars(kb))
exec(src, ns)
world = nb.njit(ns["_world"])
@nb.njit
def run(n, stage, body_pos, body_rot, I, F, W, sap, bp, keys, stats, info):
    s = 0
    for _ in range(n):
        s += world(body_pos, body_rot, I, F, W, sap, bp, keys, stats, info, stage)
    return s
def tm(f, n):
    ts = []
    for _ in range(n):
        t = time.perf_counter_ns(); f(); ts.append(time.perf_counter_ns() - t)
    return np.median(ts) / 1e3
import mujoco, collide.mujoco as cm
for name in sys.argv[1:]:
    m = mujoco.MjModel.from_xml_path(f"../shared/models/{name}/scene.xml")
    d = mujoco.MjData(m); rng = np.random.default_rng(0); lo, hi = cm._control_range(m)
    for i in range(300):
        d.ctrl[:] = rng.uniform(lo, hi); mujoco.mj_step(m, d)
    xp = d.xpos.copy(); xm = d.xmat.reshape(-1, 3, 3).copy()
    b = cm.BroadPhase(m).broadphase
    b.pairs(xp, xm)
    args = (xp, xm, b._I, b._F, b._W, b._sap, b._bp, b._keys, b._stats, b._info)
    res = []
    for st in range(len(marks) + 1):
        run(1, st, *args)
        t1 = tm(lambda: run(1, st, *args), 2000); t11 = tm(lambda: run(11, st, *args), 300)
        res.append((t11 - t1) / 10)
    cum = " ".join("%.2f" % r for r in res)
    inc = " ".join("%.2f" % (res[i] - (res[i - 1] if i else 0)) for i in range(len(res)))
    full = tm(lambda: b.pairs(xp, xm), 3000)
    print(f"{name:20s} cum {cum} | stage {inc} | pairs() {full:.2f} | {b.stats}")
