"""Benchmark: what recording a run to Rerun costs (`collide.rerun_log`), on the built-in scene.

    python tests/bench/rerun_log.py [--steps N] [--out DIR] > tests/bench/rerun_log.txt

Two ways a run is recorded, each on the built-in scene (`collide.mujoco.default_scene`, seed 0)
for N steps (default 300) of random controls, each to an ``.rrd`` file whose size is reported:

* a loop of one's own (`collide.mujoco.log_rerun`): every step ``mj_step`` then ``log.log(data)``,
  both timed (``time.perf_counter_ns``); ``log.log`` also computes our candidate pairs and
  contacts (timed inside it, reported apart), so "Rerun's part" is the call minus those;
* ``compare --rerun`` (`collide.rerun_log.record_compare`): the run's wall time against
  `collide.mujoco.compare` alone on the same model, steps and seed; the states are copied in the
  timed loop and logged after it, so compare's own figures are those of a run without a log.

Medians per step (and the 90th percentile), of the process's CPU time (``time.process_time_ns``:
every thread, so Rerun's background batching and writing count) and of wall time (which on a
shared, loaded machine adds the waits for a core); MuJoCo's ``mj_step`` in the same loop is the
yardstick. The first call (numba compiles or loads its cache) is made before the loops.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import rerun  # noqa: E402

import collide.mujoco as cm  # noqa: E402
from collide.rerun_log import record_compare  # noqa: E402
from _machine import cpu as _cpu  # noqa: E402 (tests/bench is the script's folder)


def own_loop(model, path: Path, steps: int, seed: int = 0, hold: int = 100) -> dict:
    data = mujoco.MjData(model)
    ctrls = cm._random_controls(model, steps, seed, hold)
    wall, cpu = time.perf_counter_ns, time.process_time_ns
    t_step, t_log, t_ours = [], [], []
    c_step, c_log, c_ours = [], [], []
    with cm.log_rerun(model, path) as log:
        warm = mujoco.MjData(model)
        mujoco.mj_forward(model, warm)
        log.collider.contacts(warm)  # compile / load the kernels outside the loop
        for step in range(steps):
            if step % hold == 0 and len(ctrls):
                data.ctrl[:] = ctrls[step // hold]
            t0, c0 = wall(), cpu()
            mujoco.mj_step(model, data)
            t1, c1 = wall(), cpu()
            cand = log.collider.pairs(data)  # ours, timed apart from the log call
            ours = log.collider.contacts(data)
            t2, c2 = wall(), cpu()
            log.collider.contacts(data)  # what log.log does again inside (timed once more, to subtract)
            t3, c3 = wall(), cpu()
            log.log(data, step=step, candidates=cand)
            t4, c4 = wall(), cpu()
            t_step.append((t1 - t0) * 1e-3)
            t_ours.append((t2 - t1) * 1e-3)
            t_log.append((t4 - t3 - (t3 - t2)) * 1e-3)  # Rerun's part: log.log less our contacts
            c_step.append((c1 - c0) * 1e-3)
            c_ours.append((c2 - c1) * 1e-3)
            c_log.append((c4 - c3 - (c3 - c2)) * 1e-3)
            del ours
        t_close0 = wall()
    t_close = (wall() - t_close0) * 1e-3
    return {"mj_step": (np.array(c_step), np.array(t_step)), "ours": (np.array(c_ours), np.array(t_ours)),
            "rerun": (np.array(c_log), np.array(t_log)), "close_us": t_close, "size": path.stat().st_size}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--out", default=None, help="folder for the .rrd files (default: a temporary one)")
    args = parser.parse_args()
    out = Path(args.out or tempfile.mkdtemp(prefix="collide_rerun_bench_"))
    out.mkdir(parents=True, exist_ok=True)
    model = cm.default_scene(seed=0)
    # Compile / load every kernel before anything is timed.
    cm.compare(model, steps=2, seed=0, name="warm-up")

    print(f"# Recording the built-in scene ({model.nbody} bodies, {model.ngeom} geoms) to Rerun, "
          f"{args.steps} steps of random controls, seed 0")
    print(f"# machine: {os.cpu_count()} cores, Python {sys.version.split()[0]}, {_cpu()}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start "
          f"{os.getloadavg()[0]:.1f} (machine shared with other processes)")
    print(f"# rerun-sdk {rerun.__version__}, MuJoCo {mujoco.__version__}; "
          f"command: python tests/bench/rerun_log.py --steps {args.steps}")
    print()

    r = own_loop(model, out / "own_loop.rrd", args.steps)
    print("A loop of one's own: mj_step, then log.log(data) (collide.mujoco.log_rerun), per step")
    print(f"{'':44s}{'CPU median us':>14s}{'p90':>9s}{'x mj_step':>11s}{'wall median us':>16s}{'p90':>9s}")
    med_step = float(np.median(r["mj_step"][0]))
    for label, (c, w) in (("MuJoCo mj_step", r["mj_step"]),
                          ("our candidates + contacts (Collider)", r["ours"]),
                          ("Rerun's part of log.log (the rest)", r["rerun"])):
        print(f"  {label:42s}{np.median(c):14.1f}{np.percentile(c, 90):9.1f}{np.median(c) / med_step:11.1f}"
              f"{np.median(w):16.1f}{np.percentile(w, 90):9.1f}")
    print(f"  closing the file: {r['close_us'] / 1e3:.1f} ms; file: {r['size'] / 2**20:.2f} MiB "
          f"({r['size'] / args.steps / 1024:.1f} KiB a step)")
    print()

    t0, c0 = time.perf_counter(), time.process_time()
    plain = cm.compare(model, steps=args.steps, seed=0, name="scene")
    t1, c1 = time.perf_counter(), time.process_time()
    path = out / "compare.rrd"
    result, records = record_compare(model, path, steps=args.steps, seed=0, name="scene")
    t2, c2 = time.perf_counter(), time.process_time()
    size = path.stat().st_size
    print("python -m collide compare --rerun (record_compare) against compare alone, same model, steps, seed")
    print(f"  CPU time: compare alone {c1 - c0:.2f} s, with the recording {c2 - c1:.2f} s "
          f"(+{(c2 - c1 - (c1 - c0)) / args.steps * 1e3:.2f} ms a step); wall: {t1 - t0:.2f} s, {t2 - t1:.2f} s "
          f"(+{(t2 - t1 - (t1 - t0)) / args.steps * 1e3:.2f} ms a step)")
    print(f"  file: {size / 2**20:.2f} MiB ({size / args.steps / 1024:.1f} KiB a step)")
    print(f"  compare's median time of our broad phase: {plain['time_ours_us']:.1f} us alone, "
          f"{result['time_ours_us']:.1f} us with the recording (states copied in its loop); "
          f"MuJoCo's broad phase {plain['time_mujoco_broad_us']:.1f} / {result['time_mujoco_broad_us']:.1f} us")
    print(f"  logged: {sum(x.candidates for x in records)} candidate pairs, "
          f"{sum(x.mujoco_contacts for x in records)} MuJoCo contact points, "
          f"{sum(x.our_contacts for x in records)} of ours, {records[-1].geom_bounds} geom and "
          f"{records[-1].body_bounds} body bounds a step")
    return 0


if __name__ == "__main__":
    sys.exit(main())
