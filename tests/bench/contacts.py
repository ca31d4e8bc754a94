"""Benchmark: our whole collision (broad phase + contacts) against MuJoCo's ``mj_collision``.

    python tests/bench/contacts.py [--steps N] [--scenes NAME ...] > tests/bench/contacts.txt

Per scene in ../shared/models: the model is simulated with random controls (held 10 steps, as
`collide.mujoco.compare` does); every step, on the state MuJoCo just collided, we time
``Collider.contacts(data)`` (our broad phase and narrow phase, Python call included,
``time.perf_counter_ns`` around it) and read MuJoCo's ``mjTIMER_COL_BROAD`` and
``mjTIMER_COL_NARROW`` for the same step (`collide.mujoco.mujoco_timer`: a compiled clock
callback, no Python in MuJoCo's intervals). Medians over the steps; the ratio is ours over
MuJoCo's broad + narrow; contacts per step (mean) for both. The first call (numba compiles or
loads its cache) is made before the loop.
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
import numpy as np  # noqa: E402

import collide.mujoco as cm  # noqa: E402
from _machine import cpu as _cpu  # noqa: E402 (tests/bench is the script's folder)

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"
BROAD = int(mujoco.mjtTimer.mjTIMER_COL_BROAD)
NARROW = int(mujoco.mjtTimer.mjTIMER_COL_NARROW)


def _per_call(timer, d0: float, n0: int) -> float:
    return float(timer.duration - d0) / max(int(timer.number - n0), 1)


def bench_scene(path: Path, steps: int, seed: int = 0, hold: int = 10) -> dict:
    model = mujoco.MjModel.from_xml_path(str(path))
    t0 = time.perf_counter()
    col = cm.Collider(model)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    col.contacts(data)  # compile / load the cache, bind data
    setup = time.perf_counter() - t0
    ctrls = cm._random_controls(model, steps, seed, hold)
    tb, tn = data.timer[BROAD], data.timer[NARROW]
    ours, mjb, mjn, n_ours, n_mj = [], [], [], [], []
    perf = time.perf_counter_ns
    with cm.mujoco_timer():
        for step in range(steps):
            if step % hold == 0 and len(ctrls):
                data.ctrl[:] = ctrls[step // hold]
            b0, bn, w0, wn, time0 = tb.duration, tb.number, tn.duration, tn.number, data.time
            mujoco.mj_step(model, data)
            t0 = perf()
            c = col.contacts(data)
            t1 = perf()
            if not data.time > time0:  # reset inside mj_step: its timers restarted
                continue
            ours.append((t1 - t0) * 1e-3)
            mjb.append(_per_call(tb, b0, bn))
            mjn.append(_per_call(tn, w0, wn))
            n_ours.append(len(c))
            n_mj.append(int(data.ncon))
    ours_m, mjb_m, mjn_m = (float(np.median(x)) for x in (ours, mjb, mjn))
    mj_total = float(np.median(np.add(mjb, mjn)))
    return {"model": path.parent.name, "ngeom": model.ngeom, "steps": len(ours), "ours_us": ours_m,
            "mj_broad_us": mjb_m, "mj_narrow_us": mjn_m, "mj_us": mj_total, "ratio": ours_m / mj_total,
            "contacts_ours": float(np.mean(n_ours)), "contacts_mj": float(np.mean(n_mj)), "setup_s": setup}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--scenes", nargs="*")
    a = ap.parse_args(argv)
    if not MODELS.is_dir():
        print(f"no models at {MODELS}", file=sys.stderr)
        return 1
    scenes = sorted(p for p in MODELS.iterdir() if (p / "scene.xml").is_file()
                    and (not a.scenes or p.name in a.scenes))
    print(f"# collide vs MuJoCo {mujoco.__version__}: collision per step (broad + narrow), {a.steps} steps "
          f"of random controls per scene")
    print(f"# machine: {os.cpu_count()} cores, Python {platform.python_version()}, {_cpu()}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start "
          f"{os.getloadavg()[0]:.1f} (machine shared with other processes)")
    print(f"# command: python tests/bench/contacts.py {' '.join(sys.argv[1:])}".rstrip())
    print(f"# ours: Collider.contacts(data), Python call included; MuJoCo: mjTIMER_COL_BROAD + "
          f"mjTIMER_COL_NARROW ({cm.timer_clock()} clock); medians over the steps; contacts: mean per step")
    print()
    head = (f"{'scene':<20}{'geoms':>7}{'ours us':>10}{'MJ broad':>10}{'MJ narrow':>11}{'MJ us':>9}"
            f"{'ratio':>8}{'ours con':>10}{'MJ con':>9}{'setup s':>9}")
    print(head)
    print("-" * len(head))
    ratios = []
    for p in scenes:
        r = bench_scene(p / "scene.xml", a.steps)
        ratios.append(r["ratio"])
        print(f"{r['model']:<20}{r['ngeom']:>7}{r['ours_us']:>10.1f}{r['mj_broad_us']:>10.1f}"
              f"{r['mj_narrow_us']:>11.1f}{r['mj_us']:>9.1f}{r['ratio']:>8.2f}{r['contacts_ours']:>10.1f}"
              f"{r['contacts_mj']:>9.1f}{r['setup_s']:>9.1f}", flush=True)
    print("-" * len(head))
    print(f"median ratio over the scenes: {float(np.median(ratios)):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
