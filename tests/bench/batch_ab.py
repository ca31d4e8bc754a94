"""A/B of package copies on `collide.mujoco.BroadPhase.pairs_batch` (a developer's tool).

    python tests/bench/batch_ab.py DIR_A DIR_B [--rounds R] [--scenes NAME ...]

Each ``DIR`` holds a copy of the ``collide`` package (``git archive <rev> collide | tar -x -C DIR``),
run in its own process with ``DIR`` first on ``sys.path`` (and so its own numba cache). Per round and
copy, in turn: for each scene, the best of 7 calls on 2,000 random configurations (seed 0), one
numba thread, CPU time (``time.process_time``: a wait for the core is not charged), us per
configuration. Printed per scene: each copy's median over the rounds, B over A of the medians and of
the best rounds, and the batch path the model takes (``lanes`` or ``worlds``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

MODELS = Path(__file__).resolve().parents[3] / "shared" / "models"
DEFAULT = ["franka_emika_panda", "shadow_hand", "unitree_h1", "humanoid", "agility_cassie", "robotis_op3"]

_CHILD = """
import json, sys, time
sys.path.insert(0, sys.argv[1])
import numba
numba.set_num_threads(1)
import mujoco, numpy as np
import collide.mujoco as cm
from collide import testing
assert cm.__file__.startswith(sys.argv[1]), (cm.__file__, sys.argv[1])  # the copy asked for, not another
out = {}
for name in sys.argv[3:]:
    m = mujoco.MjModel.from_xml_path(f"{sys.argv[2]}/{name}/scene.xml")
    bp = cm.BroadPhase(m)
    q = testing.random_configurations(m, 2000, np.random.default_rng(0))
    bp.pairs_batch(m, q)
    best = 1e9
    for _ in range(7):
        t = time.process_time()
        bp.pairs_batch(m, q)
        best = min(best, time.process_time() - t)
    out[name] = (best / 2000 * 1e6, bp.broadphase.batch_path)
print(json.dumps(out))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--scenes", nargs="*", default=DEFAULT)
    args = ap.parse_args()
    args.a, args.b = os.path.abspath(args.a), os.path.abspath(args.b)
    times = {d: {s: [] for s in args.scenes} for d in (args.a, args.b)}
    path = {}
    for _ in range(args.rounds):
        for d in (args.a, args.b):
            out = subprocess.run([sys.executable, "-c", _CHILD, d, str(MODELS), *args.scenes], capture_output=True,
                                 text=True, check=True, cwd=os.path.dirname(d)).stdout
            for s, (us, p) in json.loads(out.splitlines()[-1]).items():
                times[d][s].append(us)
                path[s] = p
    print(f"# batch_ab: A {args.a}, B {args.b}; {args.rounds} rounds; us per configuration, one thread, CPU time")
    print(f"{'scene':22s} {'A':>8s} {'B':>8s} {'B/A':>7s} {'best B/A':>9s}  path")
    for s in args.scenes:
        a, b = times[args.a][s], times[args.b][s]
        print(f"{s:22s} {statistics.median(a):8.3f} {statistics.median(b):8.3f} "
              f"{statistics.median(b) / statistics.median(a):7.3f} {min(b) / min(a):9.3f}  {path[s]}")


if __name__ == "__main__":
    main()
