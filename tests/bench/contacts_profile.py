"""Profile of ``Collider.contacts``: where a step's time goes (broad phase, Python call, kernel by pair kind).

    python tests/bench/contacts_profile.py [--steps N] [--every K] --scenes NAME ...

Per scene in ../shared/models, simulated with random controls as tests/bench/contacts.py does; at
each step (after ``mj_step``) the medians over the steps of:

* ``first``: the first ``Collider.contacts(data)`` after the step (what contacts.py times);
* ``call``: the same call repeated on that state (caches warm);
* ``replayed``: after the run, each step's poses copied into one MjData and a Collider of its own
  called on them, no ``mj_step`` between (caches warm, the poses moving as in the run, so the
  warm starts work as there): ``first - replayed`` is what the step's eviction of our code and
  tables costs, ``replayed - call`` what the same state again gains from the warm starts;
* ``broad``: ``Collider.pairs(data)`` (the broad phase, its Python call included);
* ``contacts_of``: `collide.contacts.contacts_of` on those pairs (our Python wrapper and the kernel);
* ``kernel``: `collide._kernels.manifold.collide_bound` alone (its entry point), on a copy of the table;
* ``fixed``: the kernel on no pairs (numba's dispatch and the tables' views, the per-call floor);

and, every ``--every`` steps, the kernel on the step's pairs of one kind of geom pair at a time,
minus ``fixed``: time per step and per pair of that kind. Repeated calls are timed as the
minimum of 3 (warm caches): they split a step's time, ``first`` is the step's real cost.
"""

from __future__ import annotations

import argparse
import copy
import os
import platform
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import collide.mujoco as cm  # noqa: E402
from collide import contacts as _c  # noqa: E402
from collide._kernels import manifold as _km  # noqa: E402
from _machine import cpu as _cpu  # noqa: E402 (tests/bench is the script's folder)

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"
NAMES = {v: k for k, v in _c.GEOM_TYPES.items()}


def _best(f, reps: int = 3) -> float:
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter_ns()
        f()
        ts.append(time.perf_counter_ns() - t0)
    return min(ts) * 1e-3


def profile(path: Path, steps: int, every: int, seed: int = 0, hold: int = 10) -> tuple[dict, dict]:
    model = mujoco.MjModel.from_xml_path(str(path))
    col = cm.Collider(model)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    col.contacts(data)
    table = col.table
    own = copy.copy(table)  # `kernel`'s: a scratch, warm-start cache and arena of its own
    own._new_out(_km.MAX_PER_PAIR * own.pair_mult << 16)  # room for any step's contacts
    skip = np.empty(1 << 16, np.bool_)
    ctrls = cm._random_controls(model, steps, seed, hold)
    split = {k: [] for k in ("first", "call", "replayed", "broad", "contacts_of", "kernel", "fixed")}
    fields = ("xpos", "xquat", "xmat", "geom_xpos", "geom_xmat")  # what the two phases read
    kept = []
    kinds: dict = {}
    for step in range(steps):
        if step % hold == 0 and len(ctrls):
            data.ctrl[:] = ctrls[step // hold]
        mujoco.mj_step(model, data)
        t0 = time.perf_counter_ns()
        col.contacts(data)
        split["first"].append((time.perf_counter_ns() - t0) * 1e-3)
        split["call"].append(_best(lambda: col.contacts(data)))
        kept.append([getattr(data, f).copy() for f in fields])
        split["broad"].append(_best(lambda: col.pairs(data)))
        pairs = col.pairs(data)
        xpos, xmat = col._poses(data)
        split["contacts_of"].append(_best(lambda: _c.contacts_of(table, pairs, xpos, xmat)))

        def kernel(p):
            # the profile's own copy of the table (its arena's rows are never handed out): its
            # first free row reset at each call
            own._out[6][_km.A_NEXT] = 0
            return _c._bound(p, xpos, xmat, skip, own._ctx_addr, own._out[7])

        split["kernel"].append(_best(lambda: kernel(pairs)))
        fixed = _best(lambda: kernel(pairs[:0]))
        split["fixed"].append(fixed)
        if step % every:
            continue
        types = table.gtype[pairs]
        label = np.array(["-".join(sorted((NAMES[int(a)], NAMES[int(b)]))) for a, b in types]) if len(pairs) else []
        for key in set(label):
            sub = np.ascontiguousarray(pairs[label == key])
            kinds.setdefault(key, []).append((_best(lambda: kernel(sub)) - fixed, len(sub)))
    replay = mujoco.MjData(model)
    mujoco.mj_forward(model, replay)
    again = cm.Collider(model)
    again.contacts(replay)
    for poses in kept:
        for f, v in zip(fields, poses):
            getattr(replay, f)[:] = v
        t0 = time.perf_counter_ns()
        again.contacts(replay)
        split["replayed"].append((time.perf_counter_ns() - t0) * 1e-3)
    return split, kinds


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--every", type=int, default=10)
    ap.add_argument("--scenes", nargs="+", required=True)
    a = ap.parse_args(argv)
    print(f"# Collider.contacts profile, MuJoCo {mujoco.__version__}, {a.steps} steps of random controls per scene")
    print(f"# machine: {os.cpu_count()} cores, Python {platform.python_version()}, {_cpu()}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start "
          f"{os.getloadavg()[0]:.1f} (machine shared with other processes)")
    print(f"# command: python tests/bench/contacts_profile.py {' '.join(sys.argv[1:])}".rstrip())
    for name in a.scenes:
        split, kinds = profile(MODELS / name / "scene.xml", a.steps, a.every)
        print(f"\n{name}: medians over the steps, us")
        print("  " + "  ".join(f"{k} {np.median(v):.1f}" for k, v in split.items()))
        print(f"  {'pair kind':<24}{'pairs/step':>11}{'us/step':>9}{'us/pair':>9}")
        rows = sorted(kinds.items(), key=lambda kv: -np.mean([t for t, _ in kv[1]]))
        for key, v in rows:
            t = float(np.mean([x for x, _ in v]))
            n = float(np.mean([x for _, x in v]))
            print(f"  {key:<24}{n:>11.1f}{t:>9.1f}{t / n:>9.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
