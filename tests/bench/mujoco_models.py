"""Benchmark: our broad phase against MuJoCo's on every scene in ../shared/models.

    python tests/bench/mujoco_models.py [--steps N] [--worlds B] > tests/bench/mujoco_models.txt

Per scene: the model is simulated with random controls (`collide.mujoco.compare`); every step,
on the state MuJoCo just collided, we time ``BroadPhase.pairs(data)`` (Python call included,
``time.perf_counter_ns`` around the call) and read MuJoCo's ``mjTIMER_COL_BROAD`` for the same
step (a compiled clock callback, `collide.mujoco.timer_clock`, named in the header: no Python in
MuJoCo's interval). Medians over the steps, their ratio, and candidates per step: ours against
MuJoCo's broad-phase candidates, as the issues define them: the geom pairs its broad phase and
midphase pass to its contact filter, counted by a contact-filter callback that keeps MuJoCo's own
verdict, in a second run replaying the same controls (in the timed run the callback's Python calls
inside ``mj_step`` would evict our code and data before each of our calls). MuJoCo then drops part
of them with its own bounding-sphere test (``mj_filterSphere``) before any collision function: fewer
reach its narrow phase than this count.
Recall is checked on the way (every MuJoCo contact pair must be
among ours).

The floor: the same loop again (same controls) with a `BroadPhase` whose ``pairs(data)`` keeps the
Python wrapper and a compiled call made as ours is made (the compiled function's entry point, past
numba's dispatcher: `collide._kernels.step.step_bound`) and returns the last result's array
as ours does on a step whose pairs did not change, but does no work (`_Floor`). After
``mj_step`` that costs 0.6-4 us on the AMD machine's models under 30 bodies and 5-7 us on 22
humanoids (2026-11-28 runs; code and data the engine's step evicted): no kernel behind a Python
call takes less there, so where the floor ratio nears 1 the target of 1.0x
MuJoCo's broad phase is out of reach for any such kernel.

Batched: ``BroadPhase.pairs_batch(model, qpos)`` on B humanoid configurations taken from a
simulated trajectory: time per world of the whole call (our numba forward kinematics included),
of the kinematics, and of the broad-phase kernel alone (poses already computed), with 1 numba
thread and with the default count, against MuJoCo's single-world broad-phase time on the same
configurations (and the whole call against MuJoCo's ``mj_kinematics`` plus broad phase); in rounds,
each a MuJoCo pass over the configurations then our calls, and each ratio taken within its round,
so that a drift of the machine's speed moves both sides of it (MuJoCo's ``mj_kinematics`` alone is
timed once, before the rounds). On a model of
few body pairs the whole call computes each group of worlds' poses in the lane kernel
(`collide._kernels.kinematics`), so it may take less than the two parts timed apart.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

# Spinning OpenMP waiters stall threaded calls on a machine shared with other work (see
# collide.BroadPhase.pairs_batch); must be set before numba starts its OpenMP runtime.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
# numpy's OpenBLAS keeps worker threads that spin after a linear-algebra call: one interference
# less for the batched run's second thread (see tests/bench/broadphase.py). Set before numpy loads.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import mujoco  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402

import collide.mujoco as cm  # noqa: E402
from _machine import cpu as _cpu  # noqa: E402 (tests/bench is the script's folder)

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"


@numba.njit("int64(int64)", cache=True)
def _no_op(addr):
    # The floor's compiled call: takes the context address as the kernel does, does nothing.
    return (addr & 0) + 1


# Called as `pairs(data)` calls the kernel: through the compiled function's entry point, not the
# dispatcher (`collide._kernels.step.step_bound`). Through the dispatcher the floor read
# 1.4 us more on humanoid and 8 us more on 22 humanoids after mj_step (a no-op timed both ways in
# the loop, AMD EPYC, 2026-11-28): more than our call pays.
_no_op_entry = _no_op.overloads[_no_op.signatures[0]].entry_point


class _Floor(cm.BroadPhase):
    """`collide.mujoco.BroadPhase` whose ``pairs(data)`` does everything but the work: the same Python
    wrapper (its attribute reads and tests), one compiled call on the context address through the
    compiled function's entry point (as ours), and the last result's array returned again, as ours
    does when the pairs did not change (most steps; a new view of new rows costs more). What any
    numba kernel behind a Python call pays after ``mj_step``, cold caches included: timed in the
    same loop as ours (`collide.mujoco.compare`, same controls), the floor of our per-step time on
    this machine."""

    def pairs(self, data):
        bp = self.broadphase
        if data is not self._views_of or bp._bound is not self._views:
            self._check_data(data)
            bp.bind(data.xpos, data.xmat.reshape(-1, 3, 3))
            self._views_of = data
            self._views = bp._bound
            bp._arena_w[:1] = (0, 1)  # a valid pair (never read: no benchmark model has a heightfield)
            bp._last = bp._arena[:1]
        k = _no_op_entry(bp._ctx_addr)
        if k < 0:
            raise RuntimeError("unreachable")
        if k == 0:
            return self._empty2
        out = bp._last
        return out if self._no_function is None else self._drop_null(out, 0)


def bench_scene(path: Path, steps: int) -> dict:
    model = mujoco.MjModel.from_xml_path(str(path))
    t0 = time.perf_counter()
    bp = cm.BroadPhase(model)
    setup = time.perf_counter() - t0
    result = cm.compare(model, steps=steps, seed=0, name=path.parent.name, broadphase=bp)
    result["setup_s"] = setup
    # The floor, in a loop of its own over the same controls (its recall is meaningless: it
    # proposes nothing); its ratio against MuJoCo's timer in that loop.
    floor = cm.compare(model, steps=steps, seed=0, name=path.parent.name, broadphase=_Floor(model))
    result["floor_us"] = floor["time_ours_us"]
    result["floor_ratio"] = floor["ratio"]
    return result


def _loop_us(f, *args, n: int = 20000, passes: int = 7) -> float:
    # Median over passes of the time per call of f(*args) in a Python loop, in us.
    per = []
    for _ in range(passes):
        t0 = time.perf_counter_ns()
        for _ in range(n):
            f(*args)
        per.append((time.perf_counter_ns() - t0) / n)
    return float(np.median(per)) * 1e-3


def bench_batch(path: Path, worlds: int, rounds: int = 11) -> dict:
    model = mujoco.MjModel.from_xml_path(str(path))
    bp = cm.BroadPhase(model)
    # Configurations from a simulated trajectory with random controls (one per step).
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    lo, hi = cm._control_range(model)
    qpos = np.empty((worlds, model.nq))
    for i in range(worlds):
        data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, data)
        qpos[i] = data.qpos

    def mujoco_pass() -> float:
        # MuJoCo's single-world broad phase on the same configurations: the median per world.
        times = []
        with cm.mujoco_timer():
            timer = data.timer[cm._TIMER_BROAD]
            for i in range(worlds):
                data.qpos[:] = qpos[i]
                d0, n0 = timer.duration, timer.number
                mujoco.mj_fwdPosition(model, data)
                times.append((timer.duration - d0) / max(timer.number - n0, 1))
        return float(np.median(times))

    # And mj_kinematics alone, what our kinematics computes (MuJoCo's kinematics timer also covers
    # mj_comPos, mj_camlight, mj_flex and mj_tendon: review, 2026-11-22). No timer of its own: on
    # each configuration a hot Python loop of calls, less the same loop on an empty model (the
    # binding's own cost); the median over the configurations (the cost depends on the state:
    # humanoid 0.55 us at qpos0, 1.1 us after 1024 steps).
    empty = mujoco.MjModel.from_xml_string("<mujoco/>")
    binding = _loop_us(mujoco.mj_kinematics, empty, mujoco.MjData(empty))
    mj_kin = []
    for i in range(worlds):
        data.qpos[:] = qpos[i]
        mj_kin.append(_loop_us(mujoco.mj_kinematics, model, data, n=100, passes=3) - binding)
    bp.pairs_batch(model, qpos[:8])  # compile / warm up
    pos, rot = bp.kinematics_batch(model, qpos)
    bp.broadphase.pairs_batch(pos, rot)
    # Rounds interleave MuJoCo's pass and our calls, so that both see the same phases of a shared
    # machine (its speed drifts by up to 2x over minutes); each ratio is taken within a round, one
    # round per thread count. The first call after MuJoCo's pass (~30 ms on one core) is timed
    # apart ("after idle"): its caches are cold, and with 2 threads it wakes the sleeping second
    # one (OMP_WAIT_POLICY=PASSIVE); the others follow it back to back, as batches in a loop do.
    default = numba.get_num_threads()
    counts = sorted({1, default})
    mj_rounds = []
    per = {n: {"full_us": [], "kernel_us": [], "kinematics_us": [], "ratio": [], "ratio_alone": [], "idle_us": []}
           for n in counts}
    for _ in range(rounds):
        for threads in counts:
            mj = mujoco_pass()
            mj_rounds.append(mj)
            numba.set_num_threads(threads)
            t0 = time.perf_counter_ns()
            bp.pairs_batch(model, qpos)
            per[threads]["idle_us"].append((time.perf_counter_ns() - t0) * 1e-3 / worlds)
            t0 = time.perf_counter_ns()
            out = bp.pairs_batch(model, qpos)
            full = (time.perf_counter_ns() - t0) * 1e-3 / worlds
            t0 = time.perf_counter_ns()
            pos, rot = bp.kinematics_batch(model, qpos)
            kin = (time.perf_counter_ns() - t0) * 1e-3 / worlds
            t0 = time.perf_counter_ns()
            bp.broadphase.pairs_batch(pos, rot)
            kern = (time.perf_counter_ns() - t0) * 1e-3 / worlds
            r = per[threads]
            r["full_us"].append(full)
            r["kinematics_us"].append(kin)
            r["kernel_us"].append(kern)
            r["ratio"].append(full / mj)
            r["ratio_alone"].append(kern / mj)
        numba.set_num_threads(default)
    rows = {n: {k: float(np.median(v)) for k, v in r.items()} for n, r in per.items()}
    return {"worlds": worlds, "pairs": len(out), "threads": rows, "rounds": rounds,
            "mujoco_us": float(np.median(mj_rounds)), "mujoco_us_range": (min(mj_rounds), max(mj_rounds)),
            "mujoco_kinematics_us": float(np.median(mj_kin))}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--worlds", type=int, default=1024)
    parser.add_argument("--scenes", nargs="*", help="only these scene folders (default: all)")
    args = parser.parse_args(argv)
    if not MODELS.is_dir():
        print(f"no models at {MODELS}", file=sys.stderr)
        return 1
    scenes = sorted(p for p in MODELS.iterdir() if (p / "scene.xml").is_file()
                    and (not args.scenes or p.name in args.scenes))
    print(f"# collide vs MuJoCo {mujoco.__version__}, broad phase per step, {args.steps} steps of "
          f"random controls per scene")
    print(f"# machine: {numba.config.NUMBA_NUM_THREADS} cores, Python "
          f"{platform.python_version()}, {_cpu()}; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; "
          f"load average at start {os.getloadavg()[0]:.1f} (machine shared with other processes); "
          f"OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY')}, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}")
    print("# ours: BroadPhase.pairs(data), Python call included; MuJoCo: mjTIMER_COL_BROAD "
          f"(body-level SAP + filters, ends in body pairs; {cm.timer_clock()} clock); medians over the steps")
    print("# candidates: geom pairs per step (mean); MuJoCo's = pairs its broad phase and midphase "
          "pass to its contact filter (before its own bounding-sphere test), counted in a second run "
          "with the same controls")
    print("# floor: the same loop with pairs(data)'s Python wrapper around a compiled call that does "
          "nothing, returning the last result's array again (tests/bench/mujoco_models.py, _Floor): "
          "what any numba kernel behind a Python call pays after mj_step on this machine; floor ratio: "
          "over MuJoCo's timer in that loop")
    print()
    head = (f"{'scene':<20}{'bodies':>7}{'geoms':>7}{'contacts':>10}{'ours cand':>10}"
            f"{'MJ cand':>9}{'cand ratio':>11}{'ours us':>9}{'MJ us':>8}{'time ratio':>11}"
            f"{'floor us':>9}{'floor ratio':>12}{'recall':>8}{'setup s':>9}")
    print(head)
    print("-" * len(head))
    rows = []
    for path in scenes:
        r = bench_scene(path / "scene.xml", args.steps)
        c = np.mean(r["contact_pairs_per_step"])
        o = np.mean(r["candidates_per_step"])
        mj = np.mean(r["mujoco_candidates_per_step"])
        rows.append(r)
        print(f"{r['model']:<20}{r['nbody']:>7}{r['ngeom']:>7}{c:>10.1f}{o:>10.1f}{mj:>9.1f}"
              f"{o / mj:>11.2f}{r['time_ours_us']:>9.1f}{r['time_mujoco_broad_us']:>8.1f}"
              f"{r['ratio']:>11.2f}{r['floor_us']:>9.1f}{r['floor_ratio']:>12.2f}"
              f"{100 * r['recall']:>7.1f}%{r['setup_s']:>9.2f}", flush=True)
        if not r["mujoco_count_replayed"]:
            print(f"# {r['model']}: the counting run did not replay the timed run's contacts", flush=True)
    print()
    humanoid = MODELS / "humanoid" / "scene.xml"
    if humanoid.is_file() and args.worlds > 0:
        b = bench_batch(humanoid, args.worlds)
        lo_mj, hi_mj = b["mujoco_us_range"]
        print(f"# batched: humanoid, {b['worlds']} worlds in one pairs_batch call, {b['pairs']} pairs out; "
              f"per world, medians over {b['rounds']} rounds per thread count, each a MuJoCo pass over the "
              f"configurations then our calls; MuJoCo single world {b['mujoco_us']:.2f} us (mjTIMER_COL_BROAD in "
              f"mj_fwdPosition, same configurations; per round {lo_mj:.2f}-{hi_mj:.2f})")
        print(f"{'numba threads':<16}{'pairs_batch(model, qpos)':>26}{'ratio':>7}{'kinematics':>12}"
              f"{'broad phase alone':>19}{'ratio (alone)':>15}{'after idle':>12}")
        for threads, t in b["threads"].items():
            print(f"{threads:<16}{t['full_us']:>23.2f} us{t['ratio']:>7.2f}"
                  f"{t['kinematics_us']:>9.2f} us{t['kernel_us']:>16.2f} us{t['ratio_alone']:>15.2f}"
                  f"{t['idle_us']:>9.2f} us")
        print("# ratio: the whole call (issue 4's .pairs_batch: our kinematics included) over MuJoCo's "
              "broad phase alone, the median of the rounds' ratios; ratio (alone): our broad phase alone, "
              "like for like; after idle: the whole call, the first after MuJoCo's pass (not in the ratios)")
        mk = b["mujoco_kinematics_us"]
        whole = ", ".join(f"{t['full_us'] / (mk + b['mujoco_us']):.2f} on {n} thread{'s' if n > 1 else ''}"
                          for n, t in b["threads"].items())
        print(f"# MuJoCo's mj_kinematics alone {mk:.2f} us (timed once, before the rounds: the median over the "
              f"configurations, each a hot Python loop less the binding's cost on an empty model): the whole call "
              f"over MuJoCo's kinematics + broad phase ({mk + b['mujoco_us']:.2f} us), {whole}")
    return 0 if all(not r["missed"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
