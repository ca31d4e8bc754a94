"""Before/after of a change to `collide.distance`, in one run: the public call on two package trees.

    python tests/bench/distance_ab.py DIR_A DIR_B [DIR_C ...] [--rounds R] [--pairs P]

``DIR_A``, ``DIR_B``, ...: folders each holding a copy of the ``collide`` package (``git archive``
of the commit before, the working tree after), each run in its own process (``PYTHONPATH`` set to
its folder, its own numba cache), in turn, ``R`` rounds. A process times one
``collide.distance(a, b, pose_a, pose_b)`` on the pairs of `distance.py` (random convex meshes of
100, 300 and 1000 vertices, ``P`` random pose pairs each; seed 0): per pair the mean CPU time of a
call (``time.process_time``, as `distance.py`) over ~20 ms, and the median over the pairs.
Printed per size: each tree's median over the rounds, its ratio to the first tree's, and the
ratios of the best rounds. The answers (distance, bracket, normal) are compared with the first
tree's bit for bit: any difference is printed. The trees are run from their own folders (the
child's working folder), so a package installed elsewhere is not imported instead.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import numpy as np

_CHILD = r"""
import json, sys, time
import numpy as np
import collide
from collide.testing.surfaces import random_rotation

def per_call(fn, budget=0.02):
    fn()
    reps = 5
    while True:
        t = time.process_time()
        for _ in range(reps):
            fn()
        dt = time.process_time() - t
        if dt > budget or reps > 1_000_000:
            return dt / reps
        reps *= 4

def mesh(rng, n):
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d * rng.uniform(0.5, 1.0, 3)

rng = np.random.default_rng(0)
res = {"file": collide.__file__}
for n in (100, 300, 1000):
    a, b = collide.PointCloud(mesh(rng, n)), collide.PointCloud(mesh(rng, n))
    times, answers = [], []
    for _ in range(int(sys.argv[1])):
        ra, rb = random_rotation(rng), random_rotation(rng)
        tb = rng.normal(size=3)
        tb *= rng.uniform(1.0, 3.0) / np.linalg.norm(tb)
        pa, pb = (ra, np.zeros(3)), (rb, tb)
        r = collide.distance(a, b, pa, pb)
        answers.append([r.distance, r.lower, r.upper, *r.normal.tolist()])
        times.append(per_call(lambda: collide.distance(a, b, pa, pb)))
    res[str(n)] = {"us": float(np.median(times)) * 1e6, "answers": answers}
print(json.dumps(res))
"""


def _run(tree: str, pairs: int) -> dict:
    env = dict(os.environ, PYTHONPATH=os.path.abspath(tree), OPENBLAS_NUM_THREADS="1")
    # cwd: the tree, so that ``python -c`` (sys.path[0] is the working folder) imports its copy.
    out = subprocess.run([sys.executable, "-c", _CHILD, str(pairs)], env=env, capture_output=True, text=True,
                         check=True, cwd=os.path.abspath(tree))
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trees", nargs="+")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--pairs", type=int, default=40)
    args = ap.parse_args(argv)
    for t in args.trees:  # compile (or load) each tree's kernels before timing anything
        print(f"{t}: {_run(t, 1)['file']}", flush=True)
    runs: dict = {t: [] for t in args.trees}
    for k in range(args.rounds):
        order = args.trees if k % 2 == 0 else args.trees[::-1]
        for t in order:
            runs[t].append(_run(t, args.pairs))
        print(f"round {k + 1}: load {os.getloadavg()[0]:.2f}", flush=True)
    first = args.trees[0]
    print(f"{'vertices':>8} " + " ".join(f"{os.path.basename(t.rstrip('/')):>14}" for t in args.trees)
          + "   ratio to the first (median; best rounds)")
    for n in ("100", "300", "1000"):
        med = {t: float(np.median([r[n]["us"] for r in runs[t]])) for t in args.trees}
        best = {t: min(r[n]["us"] for r in runs[t]) for t in args.trees}
        ratios = " ".join(f"{med[t] / med[first]:.3f} ({best[t] / best[first]:.3f})" for t in args.trees[1:])
        print(f"{n:>8} " + " ".join(f"{med[t]:>14.2f}" for t in args.trees) + "   " + ratios)
        for t in args.trees[1:]:
            a, b = np.array(runs[first][0][n]["answers"]), np.array(runs[t][0][n]["answers"])
            if not np.array_equal(a, b):
                print(f"  {t}: answers differ from {first}'s, largest {np.abs(a - b).max():.3g}")


if __name__ == "__main__":
    main()
