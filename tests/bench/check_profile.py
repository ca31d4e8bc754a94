"""Where check_batch's time goes, per scene (issue 43's speed work): the parts of one call timed apart.

    python tests/bench/check_profile.py [--configs N] [--threads T] [--reps R] [--scenes NAME ...]

Per scene (random configurations inside the joint limits, seed 0), us per configuration, best of R:

* call: ``Collider.check_batch(qpos)``;
* broad: the batch broad phase alone (``BroadPhase.pairs_batch``, kinematics inside it);
* kin+: ``check_worlds`` with no candidate rows (its own kinematics, the workers' scratch, the chunks);
* kernel: ``check_worlds`` with the broad phase's rows (kin+ and the narrow phase);
* glue: call less broad less kernel (Python: checks, row_start, arrays);
* rows: candidate rows per configuration, hit: the fraction in collision, path: the batch broad
  phase's (`BroadPhase.batch_path`), and the most frequent geom type pairs among the rows.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import mujoco  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402

import collide.mujoco as cm  # noqa: E402
from collide import testing  # noqa: E402
from collide._kernels import check as _kc  # noqa: E402
from check_batch import _best  # noqa: E402 (tests/bench is the script's folder)

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"
DEFAULT = ["franka_emika_panda", "shadow_hand", "unitree_h1", "humanoid", "22_humanoids"]



def _kernel(col, q, rows, distance=False):
    kin = col._setup_check()
    B = len(q)
    row_start = np.searchsorted(rows[:, 0], np.arange(B + 1, dtype=np.int32)).astype(np.int64)
    workers = max(1, numba.get_num_threads())
    chunks = min(B, 16 * workers)
    hit = np.zeros(B, bool)
    sk = np.zeros(B, bool)
    err = np.zeros(B, np.int64)
    dp = np.zeros((0, 2), np.int32)
    return lambda: _kc.check_worlds(q, *kin, rows, row_start, col._subset_mode, col._subset_label, dp, np.inf,
                                    False, chunks, min(workers, chunks), np.zeros(1, np.int64), *col.table._kargs,
                                    hit, np.empty(0), np.empty((0, 2), np.int32), sk, err)


def scene(name, n, reps):
    model = mujoco.MjModel.from_xml_path(str(MODELS / name / "scene.xml"))
    q = testing.random_configurations(model, n, np.random.default_rng(0))
    col = cm.Collider(model)
    res = col.check_batch(q)
    call = _best(lambda: col.check_batch(q), reps)
    broad = _best(lambda: col.broadphase.pairs_batch(model, q), reps)
    rows = np.ascontiguousarray(col.broadphase.pairs_batch(model, q), dtype=np.int32).reshape(-1, 3)
    k_none = _kernel(col, q, np.zeros((0, 3), np.int32))
    k_none()
    kin = _best(k_none, reps)
    k_full = _kernel(col, q, rows)
    kern = _best(k_full, reps)
    # the candidate rows' geom types, per configuration (a sample)
    types = {}
    gtype = np.asarray(model.geom_type)
    nsee = min(n, 500)
    for _, a, b in rows[rows[:, 0] < nsee]:
        k = tuple(sorted((mujoco.mjtGeom(gtype[a]).name[6:].lower(), mujoco.mjtGeom(gtype[b]).name[6:].lower())))
        types[k] = types.get(k, 0) + 1
    per = 1e6 / n
    top = sorted(types.items(), key=lambda kv: -kv[1])[:5]
    return (f"{name:<20}{call * per:>8.2f}{broad * per:>8.2f}{kin * per:>8.2f}{kern * per:>8.2f}"
            f"{(call - broad - kern) * per:>8.2f}{len(rows) / n:>7.1f}{res.in_collision.mean():>6.2f}  "
            f"{col.broadphase.broadphase.batch_path:<7}"
            + " ".join(f"{a}-{b}:{c / nsee:.2f}" for (a, b), c in top))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--configs", type=int, default=5000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--scenes", nargs="*", default=DEFAULT)
    a = ap.parse_args()
    numba.set_num_threads(a.threads)
    print(f"# load {os.getloadavg()[0]:.2f}, {a.configs} configs, {a.threads} threads, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"{'scene':<20}{'call':>8}{'broad':>8}{'kin+':>8}{'kernel':>8}{'glue':>8}{'rows':>7}{'hit':>6}  path    "
          "row types per configuration")
    for s in a.scenes:
        print(scene(s, a.configs, a.reps), flush=True)
    print(f"# load {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    sys.exit(main())
