"""Benchmark: the swept broad phase against the single-step one, on the MuJoCo models.

    python tests/bench/swept.py [--steps N] [--scenes NAME ...] > tests/bench/swept.amd-epyc.txt

Per scene in ../shared/models: the model is simulated with random controls (held 10 steps, as
`collide.mujoco.compare` does); every step, on the body poses before and after it (``xpos``,
``xmat``), we time `collide.BroadPhase.pairs` at the step's end and `BroadPhase.pairs_swept` over
the step (the same instance, arrays passed in: like for like), alternating which goes first.
The calls follow a simulation loop: each step's start arrays are the previous step's end arrays
(so `pairs_swept` takes the places it kept at the last call's end and places each geom once a
step; see `collide._kernels.swept_motion._start_source`).
Medians over the steps; the ratio is swept over single. Candidates per step (mean) for both, and
the fraction of steps whose swept pairs held a pair that neither end's single step had (a pair
that could only meet in between). A second pass with every control at its range's end and a 10x
time step shows the same on fast motion. The first calls (numba compiles or loads its cache) are
made before the loop.
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


def bench_scene(path: Path, steps: int, fast: bool, seed: int = 0) -> dict:
    model = mujoco.MjModel.from_xml_path(str(path))
    if fast:
        model.opt.timestep *= 10.0
    bp = cm.BroadPhase(model).broadphase
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    lo, hi = cm._compare._control_range(model) if hasattr(cm, "_compare") else cm._control_range(model)
    rng = np.random.default_rng(seed)
    t_single, t_swept, n_single, n_swept, between, skipped = [], [], [], [], 0, 0
    p0 = data.xpos.copy()
    r0 = data.xmat.reshape(-1, 3, 3).copy()
    bp.pairs(p0, r0)
    bp.pairs_swept(p0, r0, p0, r0)
    ctrl = None
    for step in range(steps):
        if step % 10 == 0:
            ctrl = np.where(rng.random(model.nu) < 0.5, lo, hi) if fast else rng.uniform(lo, hi)
        data.ctrl[:] = ctrl
        resets = data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number
        mujoco.mj_step(model, data)
        p1 = data.xpos.copy()
        r1 = data.xmat.reshape(-1, 3, 3).copy()
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number != resets:  # MuJoCo reset the state: no step
            p0, r0 = p1, r1
            skipped += 1
            continue
        for first in ((0, 1) if step % 2 == 0 else (1, 0)):
            t = time.perf_counter_ns()
            if first == 0:
                single = bp.pairs(p1, r1)
                t_single.append(time.perf_counter_ns() - t)
            else:
                swept = bp.pairs_swept(p0, r0, p1, r1)
                t_swept.append(time.perf_counter_ns() - t)
        n_single.append(len(single))
        n_swept.append(len(swept))
        ends = {tuple(r) for r in single.tolist()} | {tuple(r) for r in bp.pairs(p0, r0).tolist()}
        s = {tuple(r) for r in swept.tolist()}
        assert ends <= s, (path.parent.name, step, sorted(ends - s)[:5])
        between += bool(s - ends)
        p0, r0 = p1, r1
    ts, tw = np.median(t_single) / 1e3, np.median(t_swept) / 1e3
    return dict(scene=path.parent.name, bodies=model.nbody, geoms=model.ngeom, single_us=ts, swept_us=tw,
                ratio=tw / ts, cand=np.mean(n_single), cand_swept=np.mean(n_swept), between=between / len(n_single),
                skipped=skipped)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--scenes", nargs="*", default=None)
    args = ap.parse_args()
    if not MODELS.is_dir():
        sys.exit(f"swept.py: no models at {MODELS} (see tests/README or the README's 'Test models')")
    scenes = args.scenes or sorted(p.name for p in MODELS.iterdir() if (p / "scene.xml").is_file())
    load = os.getloadavg()[0]
    print(f"# collide: pairs_swept (the step's motion) vs pairs (its end), {args.steps} steps of random controls "
          f"per scene; MuJoCo {mujoco.__version__}")
    print(f"# machine: {os.cpu_count()} cores, Python {platform.python_version()}, {_cpu()}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start {load:.1f}")
    print("# calls as in a simulation loop: each step's start arrays are the last step's end arrays (pairs_swept "
          "takes its kept end places)")
    print("# both through collide.BroadPhase with the pose arrays passed in (no bind); medians over the steps; "
          "between: fraction of steps with a swept pair neither end's single step had; resets: steps after which "
          "MuJoCo reset an unstable state (left out)")
    for fast in (False, True):
        print()
        print("## " + ("fast: 10x the time step, controls at their range's ends" if fast else "the model's time step"))
        print(f"{'scene':20s} {'bodies':>6s} {'geoms':>6s} {'single us':>10s} {'swept us':>9s} {'ratio':>6s} "
              f"{'cand':>7s} {'swept cand':>10s} {'between':>8s} {'resets':>6s}")
        ratios = []
        for name in scenes:
            r = bench_scene(MODELS / name / "scene.xml", args.steps, fast)
            ratios.append(r["ratio"])
            print(f"{r['scene']:20s} {r['bodies']:6d} {r['geoms']:6d} {r['single_us']:10.2f} {r['swept_us']:9.2f} "
                  f"{r['ratio']:6.2f} {r['cand']:7.1f} {r['cand_swept']:10.1f} {r['between']:8.3f} {r['skipped']:6d}",
                  flush=True)
        print(f"# ratio swept / single: median {np.median(ratios):.2f}, worst {max(ratios):.2f}, "
              f"best {min(ratios):.2f}")
    print(f"# load average at end {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
