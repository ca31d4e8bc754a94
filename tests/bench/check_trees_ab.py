"""A/B of check_batch's early exit by trees (`collide._kernels.check_trees`) in one process.

    python tests/bench/check_trees_ab.py [--configs N] [--threads T] [--rounds R] [--scenes NAME ...]

Per scene two Colliders of the same package: A with the early exit off (``TREE_SHARE = -1`` when
its static arguments are made), B as shipped; rounds alternate A and B, each the best of 3 calls
of ``check_batch`` on ``N`` random configurations (seed 0), us per configuration; the medians and
B/A are printed, and whether the answers are identical. No second compile is needed (the other
A/B, check_ab.py, compiles each package copy afresh).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import mujoco
import numba
import numpy as np

import collide.mujoco as cm
from collide import collider as ccol
from collide import testing

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"
DEFAULT = ["franka_emika_panda", "shadow_hand", "unitree_h1", "humanoid", "22_humanoids"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--configs", type=int, default=3000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--scenes", nargs="*", default=DEFAULT)
    a = ap.parse_args(argv)
    numba.set_num_threads(a.threads)
    print(f"# check_trees_ab: {a.configs} configurations, {a.threads} threads, best of 3, {a.rounds} rounds "
          f"alternating; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start "
          f"{os.getloadavg()[0]:.2f}")
    print(f"# command: python tests/bench/check_trees_ab.py {' '.join(sys.argv[1:])}".rstrip())
    print(f"{'scene':<20}{'A us':>9}{'B us':>9}{'B/A':>8}  same  rounds (A B)")
    for name in a.scenes:
        m = mujoco.MjModel.from_xml_path(str(MODELS / name / "scene.xml"))
        q = testing.random_configurations(m, a.configs, np.random.default_rng(0))
        share = ccol.TREE_SHARE
        ccol.TREE_SHARE = -1.0
        ca = cm.Collider(m)
        ra = ca.check_batch(q)  # its static arguments made now, without the early exit
        ccol.TREE_SHARE = share
        cb = cm.Collider(m)
        rb = cb.check_batch(q)
        same = np.array_equal(ra.in_collision, rb.in_collision) and np.array_equal(ra.skipped, rb.skipped)
        ta, tb = [], []
        for _ in range(a.rounds):
            for col, out in ((ca, ta), (cb, tb)):
                best = np.inf
                for _ in range(3):
                    t0 = time.perf_counter()
                    col.check_batch(q)
                    best = min(best, time.perf_counter() - t0)
                out.append(best * 1e6 / a.configs)
        ma, mb = float(np.median(ta)), float(np.median(tb))
        rounds = " ".join(f"{x:.2f}/{y:.2f}" for x, y in zip(ta, tb))
        print(f"{name:<20}{ma:>9.3f}{mb:>9.3f}{mb / ma:>8.3f}  {str(same):<5} {rounds}", flush=True)
    print(f"# load average at end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
