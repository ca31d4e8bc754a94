"""Benchmark: collision checks of many configurations (issue 43) against MuJoCo's own way.

    python tests/bench/check_batch.py [--configs N] [--threads T] [--reps R] [--scenes NAME ...]
        > tests/bench/check_batch.txt

Per scene in ../shared/models, ``N`` random configurations inside the joint limits
(`collide.testing.random_configurations`, seed 0), in the same run:

* ours: ``Collider.check_batch(qpos)`` (one call, ``T`` numba threads), its wall time per
  configuration (the best of ``R`` calls), and with ``distance=True`` (one call); its narrow
  phase's share (ours less the same call on a one-geom subset, where no pair is left to decide);
  the batch broad phase alone (``BroadPhase.pairs_batch``, a part of ours) and the batch kinematics alone
  (``kinematics_batch``, for scale);
* MuJoCo's loop, what a Python user pays today: ``data.qpos[:] = q; mj_kinematics; mj_collision``
  per configuration, its wall time per configuration;
* MuJoCo's C floor: ``mjTIMER_COL_BROAD`` + ``mjTIMER_COL_NARROW`` of those same ``mj_collision``
  calls (`collide.mujoco.mujoco_timer`), per configuration.

Ratios are ours over MuJoCo's (the loop's, and the C floor's). ``agree`` counts configurations
where ``in_collision`` equals MuJoCo's answer (an active contact). Memory: bytes per configuration
held by a call (qpos copy, results, and the broad phase's candidate rows: 12 bytes a row, held for
one block of `collide.collider.BLOCK` configurations at a time).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import mujoco  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402

import collide.mujoco as cm  # noqa: E402
from collide import testing  # noqa: E402
from _machine import cpu as _cpu  # noqa: E402 (tests/bench is the script's folder)
import check_fcl  # noqa: E402
from collide.collider import filtered_pairs  # noqa: E402

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"
BROAD = int(mujoco.mjtTimer.mjTIMER_COL_BROAD)
NARROW = int(mujoco.mjtTimer.mjTIMER_COL_NARROW)
DEFAULT_SCENES = ["franka_emika_panda", "shadow_hand", "unitree_h1", "humanoid", "22_humanoids"]


def _best(f, reps: int) -> float:
    best = np.inf
    for _ in range(reps):
        t0 = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t0)
    return best


def bench_scene(name: str, n: int, reps: int, n_fcl: int) -> dict:
    model = mujoco.MjModel.from_xml_path(str(MODELS / name / "scene.xml"))
    data = mujoco.MjData(model)
    q = testing.random_configurations(model, n, np.random.default_rng(0))
    col = cm.Collider(model)
    col.check_batch(q[:4], distance=True)  # compile or load the kernels, make the filtered pairs
    ours = _best(lambda: col.check_batch(q), reps)
    res = col.check_batch(q)
    t0 = time.perf_counter()
    col.check_batch(q, distance=True)
    ours_dist = time.perf_counter() - t0
    # no pair passes a one-geom subset: the broad phase, kinematics and poses without the narrow phase
    bare = cm.Collider(model, geoms=[model.ngeom - 1])
    bare.check_batch(q[:4])
    no_narrow = _best(lambda: bare.check_batch(q), reps)
    broad = _best(lambda: col.broadphase.pairs_batch(model, q), reps)
    rows = len(col.broadphase.pairs_batch(model, q))
    kin = _best(lambda: cm.kinematics_batch(model, q), reps)
    mj = np.zeros(n, bool)
    tb, tn = data.timer[BROAD], data.timer[NARROW]
    with cm.mujoco_timer():
        b0, bn, w0, wn = tb.duration, tb.number, tn.duration, tn.number
        t0 = time.perf_counter()
        for i in range(n):
            data.qpos[:] = q[i]
            mujoco.mj_kinematics(model, data)
            mujoco.mj_collision(model, data)
        loop = time.perf_counter() - t0
        floor_b = (tb.duration - b0) / max(tb.number - bn, 1)
        floor_n = (tn.duration - w0) / max(tn.number - wn, 1)
    for i in range(n):  # the answers, outside the timed loop
        data.qpos[:] = q[i]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        mj[i] = bool(np.any(data.contact.exclude[:data.ncon] == 0))
    per = 1e6 / n
    floor = floor_b + floor_n
    allowed = set(map(tuple, filtered_pairs(col.broadphase.articulation).tolist()))
    libs = {}
    for lib, fn in (("fcl", check_fcl.bench_fcl), ("coal", check_fcl.bench_coal)):
        t, h = fn(model, q[:n_fcl], allowed)
        libs[lib] = (t * 1e6, int(np.sum(h == res.in_collision[:n_fcl]))) if t is not None else (None, h)
    mem = 8 * model.nq + 2 + 12 * rows / n  # qpos copy, in_collision + skipped, candidate rows
    return {"scene": name, "nq": model.nq, "ngeom": model.ngeom, "ours": ours * per, "ours_dist": ours_dist * per,
            "broad": broad * per, "kin": kin * per, "narrow": (ours - no_narrow) * per, "loop": loop * per, "floor_b": floor_b, "floor_n": floor_n,
            "r_loop": ours * per / (loop * per), "r_floor": ours * per / floor, "hit": float(res.in_collision.mean()),
            "agree": int(np.sum(res.in_collision == mj)), "n": n, "rows": rows / n, "mem": mem, "libs": libs}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--configs", type=int, default=2000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--scenes", nargs="*", default=DEFAULT_SCENES)
    ap.add_argument("--fcl-configs", type=int, default=300, help="configurations for python-fcl and coal")
    a = ap.parse_args(argv)
    if not MODELS.is_dir():
        print(f"no models at {MODELS}", file=sys.stderr)
        return 1
    numba.set_num_threads(a.threads)
    print(f"# collide Collider.check_batch vs MuJoCo {mujoco.__version__}: {a.configs} random configurations "
          f"per scene (inside joint limits, seed 0), {numba.get_num_threads()} numba threads")
    print(f"# machine: {os.cpu_count()} cores, Python {platform.python_version()}, {_cpu()}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start "
          f"{os.getloadavg()[0]:.1f} (machine shared with other processes)")
    print(f"# command: python tests/bench/check_batch.py {' '.join(sys.argv[1:])}".rstrip())
    print("# us per configuration. ours: check_batch(qpos) (best of reps), +dist: distance=True (one call); "
          "narrow: ours less the same call\n#   with no pair to decide (a one-geom subset: broad phase, kinematics, poses); broad: pairs_batch alone, "
          "kin: kinematics_batch alone (both inside ours, for scale)")
    print(f"# MJ loop: data.qpos[:] = q; mj_kinematics; mj_collision from Python; MJ C floor: "
          f"mjTIMER_COL_BROAD + mjTIMER_COL_NARROW ({cm.timer_clock()} clock); x loop, x floor: ours / MuJoCo's")
    print(f"# fcl: python-fcl's DynamicAABBTreeCollisionManager, us per query (transforms + update + collide, MuJoCo's "
          f"filters in its callback, first contact ends it; tests/bench/check_fcl.py) on the first {a.fcl_configs} "
          "configurations; x fcl: ours / it; fcl agr: its in_collision equal to ours")
    print("# coal*: coal's DynamicAABBTreeCollisionManager, us per query, CollisionCallBackCollect: no filter can be "
          "applied from Python in coal 3.0.3 (check_fcl.py), so its answer is not MuJoCo's; a cost of the same work")
    print("# hit: fraction in collision; agree: configurations where in_collision equals MuJoCo's active contact; "
          "rows: candidate pairs per configuration; mem: bytes per configuration held by a call")
    print()
    head = (f"{'scene':<20}{'ours':>8}{'+dist':>9}{'narrow':>8}{'broad':>8}{'kin':>7}{'MJ loop':>9}{'MJ broad':>9}"
            f"{'MJ narr':>9}{'x loop':>8}{'x floor':>8}{'hit':>6}{'agree':>12}{'rows':>7}{'mem':>7}{'fcl':>9}{'x fcl':>7}"
            f"{'fcl agr':>8}{'coal*':>8}{'x coal':>7}")
    print(head)
    print("-" * len(head))
    notes = []
    for s in a.scenes:
        r = bench_scene(s, a.configs, a.reps, min(a.fcl_configs, a.configs))
        lib = ""
        for k in ("fcl", "coal"):
            t, v = r["libs"][k]
            if t is None:
                notes.append(f"# {s}: {k} not measured: {v}")
                lib += f"{'n/a':>9}{'':>7}{'':>8}" if k == "fcl" else f"{'n/a':>8}{'':>7}"
            elif k == "fcl":
                lib += f"{t:>9.1f}{r['ours'] / t:>7.3f}{v:>4d}/{min(a.fcl_configs, a.configs):<3d}"
            else:
                lib += f"{t:>8.1f}{r['ours'] / t:>7.3f}"
        print(f"{r['scene']:<20}{r['ours']:>8.2f}{r['ours_dist']:>9.1f}{r['narrow']:>8.2f}{r['broad']:>8.2f}{r['kin']:>7.2f}"
              f"{r['loop']:>9.2f}{r['floor_b']:>9.2f}{r['floor_n']:>9.2f}{r['r_loop']:>8.3f}{r['r_floor']:>8.2f}"
              f"{r['hit']:>6.2f}{r['agree']:>7d}/{r['n']:<4d}{r['rows']:>7.1f}{r['mem']:>7.0f}" + lib, flush=True)
    print("-" * len(head))
    for line in notes:
        print(line)
    print(f"# load average at end {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
