"""Before/after of a change to check_batch, in one run (the project's rule for keeping a mechanism).

    python tests/bench/check_ab.py --trees DIR_A DIR_B [DIR_C ...] [--rounds R] [--configs N]
        [--threads T] [--reps K] [--scenes NAME ...] [--distance] [--cpu]

``DIR_A``, ``DIR_B``, ...: folders each holding a copy of the ``collide`` package (before, after
one mechanism, after the next, ...). They run in turn, ``R`` rounds, each in its own process
(``PYTHONPATH`` set to its folder, its own numba cache): per scene the best of ``K`` calls of
``Collider.check_batch`` on ``N`` random configurations (seed 0), us per configuration; the table
gives each tree's median over the rounds and each tree over the one before it (and, on a
line below, the ratios of the best rounds). The answers
(``in_collision``, and ``min_distance`` with ``--distance``) are compared with the first tree's:
any difference is printed. ``--cpu``: the process's CPU time (``time.process_time``) instead of
the wall clock, for ``--threads 1`` on a machine other work keeps busy (a wait for the core is
not charged; the threads' time would be summed with more than one).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

DEFAULT = ["franka_emika_panda", "shadow_hand", "unitree_h1", "humanoid", "22_humanoids"]

_CHILD = r"""
import json, os, sys, time
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import hashlib, mujoco, numba, numpy as np
import collide, collide.mujoco as cm
from collide import testing
numba.set_num_threads(int(sys.argv[3]))
out = {"file": collide.__file__}
for name in sys.argv[5:]:
    m = mujoco.MjModel.from_xml_path(os.path.join(sys.argv[1], name, "scene.xml"))
    q = testing.random_configurations(m, int(sys.argv[2]), np.random.default_rng(0))
    col = cm.Collider(m)
    dist = sys.argv[6 - 2] == "1"
    col.check_batch(q[:8], distance=dist)
    best = np.inf
    for _ in range(int(sys.argv[4].split(",")[0])):
        t0 = time.perf_counter()
        r = col.check_batch(q, distance=dist)
        best = min(best, time.perf_counter() - t0)
    h = hashlib.sha1(r.in_collision.tobytes() + (r.min_distance.tobytes() if dist else b"")).hexdigest()[:12]
    out[name] = (best * 1e6 / len(q), h)
print(json.dumps(out))
"""


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trees", nargs="+", required=True)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--configs", type=int, default=5000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--scenes", nargs="*", default=DEFAULT)
    ap.add_argument("--distance", action="store_true")
    ap.add_argument("--cpu", action="store_true")
    a = ap.parse_args()
    models = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "shared", "models")
    print(f"# check_ab: {a.configs} configurations, {a.threads} threads, best of {a.reps}, {a.rounds} rounds "
          f"alternating; distance={a.distance}; {'CPU' if a.cpu else 'wall'} time; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"# command: python tests/bench/check_ab.py {' '.join(sys.argv[1:])}")
    print(f"# load average at start {os.getloadavg()[0]:.2f}", flush=True)
    times = {t: {s: [] for s in a.scenes} for t in a.trees}
    hashes = {t: {} for t in a.trees}
    for _ in range(a.rounds):
        for t in a.trees:
            env = dict(os.environ, PYTHONPATH=os.path.abspath(t))
            # argv: models, configs, threads, reps, then (a distance flag folded in before the scenes)
            child = _CHILD.replace("sys.argv[6 - 2]", repr("1" if a.distance else "0"))
            if a.cpu:
                child = child.replace("time.perf_counter()", "time.process_time()")
            res = subprocess.run([sys.executable, "-c", child,
                                  models, str(a.configs), str(a.threads), str(a.reps)] + a.scenes,
                                 env=env, capture_output=True, text=True, cwd="/tmp")
            if res.returncode != 0:
                print(res.stderr[-3000:], file=sys.stderr)
                return 1
            d = json.loads(res.stdout.strip().splitlines()[-1])
            assert d["file"].startswith(os.path.abspath(t)), d["file"]
            for s in a.scenes:
                times[t][s].append(d[s][0])
                hashes[t].setdefault(s, set()).add(d[s][1])
    T = a.trees
    names = [chr(ord("A") + i) for i in range(len(T))]
    for n, t in zip(names, T):
        print(f"# {n}: {t}")
    print(f"{'scene':<20}" + "".join(f"{n + ' us':>9}" for n in names)
          + "".join(f"{names[i + 1] + '/' + names[i]:>8}" for i in range(len(T) - 1)) + "   rounds")
    ratios = [[] for _ in range(len(T) - 1)]
    for s in a.scenes:
        med = [float(np.median(times[t][s])) for t in T]
        for i in range(len(T) - 1):
            ratios[i].append(med[i + 1] / med[i])
        same = "" if all(hashes[t][s] == hashes[T[0]][s] for t in T) else "  ANSWERS DIFFER"
        print(f"{s:<20}" + "".join(f"{m:>9.3f}" for m in med)
              + "".join(f"{med[i + 1] / med[i]:>8.3f}" for i in range(len(T) - 1)) + "   "
              + " | ".join(" ".join(f"{x:.2f}" for x in times[t][s]) for t in T) + same)
    print("# the same ratios of the best round: " + "; ".join(
        f"{names[i + 1]}/{names[i]} " + " ".join(f"{min(times[T[i + 1]][s]) / min(times[T[i]][s]):.3f}" for s in a.scenes)
        for i in range(len(T) - 1)))
    print("# median ratio over the scenes: "
          + ", ".join(f"{names[i + 1]}/{names[i]} {float(np.median(r)):.3f}" for i, r in enumerate(ratios))
          + f"; load average at end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
