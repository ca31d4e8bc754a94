"""Shares of one check_batch call per configuration (issue 43's speed work), CPU time, one thread.

    python tests/bench/check_shares.py [--configs N] [--reps R] [--scenes NAME ...]

Per scene (random configurations inside the joint limits, seed 0), us per configuration, the best
of R calls in CPU time (``time.process_time``: a wait for a core is not charged; run it on one
numba thread), each part timed alone:

* call: ``Collider.check_batch(qpos)`` (the whole path: the early exit by trees where the model
  takes it, then the full path on the undecided configurations);
* trees: the early exit by trees alone (``Collider._early_trees``; 0 where the model has none);
* broad: the batch broad phase on the configurations the full path gets (``pairs_batch``);
* kin: ``check_worlds``' own kinematics, ``_kinematics_world`` of every configuration with a
  candidate in the subset (the poses the broad phase computed already: the duplicate), in a
  one-thread loop here;
* fixed: ``check_worlds`` with no candidate rows (workers' scratch, chunks, dispatch);
* decide: ``check_worlds`` with the rows, less kin and fixed (geom poses and deepest_contact);
* glue: call less trees, broad and ``check_worlds`` (Python: checks, row sorting, arrays, dispatch).

The last columns are those shares of ``call`` in per cent.
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
import numba as nb  # noqa: E402
import numpy as np  # noqa: E402

import collide.mujoco as cm  # noqa: E402
from collide import testing  # noqa: E402
from collide._kernels import check as _kc  # noqa: E402
from collide._kernels.kinematics import _kinematics_world  # noqa: E402

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"
DEFAULT = ["franka_emika_panda", "shadow_hand", "unitree_h1", "humanoid", "22_humanoids"]


def _cpu_best(f, reps: int) -> float:
    best = np.inf
    for _ in range(reps):
        t0 = time.process_time()
        f()
        best = min(best, time.process_time() - t0)
    return best


@nb.njit(cache=True)
def _kin_posed(qpos, posed, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
               jnt_pos, jnt_axis):
    # check_worlds' kinematics alone: _kinematics_world of the configurations marked posed.
    L = body_parent.shape[0]
    bpos = np.empty((L, 3))
    brot = np.empty((L, 3, 3))
    bquat = np.empty((L, 4))
    sc = np.empty((max(jnt_type.shape[0], 1), 2))
    acc = 0.0
    for w in range(qpos.shape[0]):
        if posed[w]:
            _kinematics_world(qpos[w], qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type,
                              jnt_qposadr, jnt_pos, jnt_axis, bpos, brot, bquat, sc)
            acc += bpos[L - 1, 0]
    return acc


def _check_worlds(col, q, rows):
    kin = col._setup_check()
    B = len(q)
    row_start = np.searchsorted(rows[:, 0], np.arange(B + 1, dtype=np.int32)).astype(np.int64)
    hit = np.zeros(B, bool)
    sk = np.zeros(B, bool)
    err = np.zeros(B, np.int64)
    dp = np.zeros((0, 2), np.int32)
    return lambda: _kc.check_worlds(q, *kin, rows, row_start, col._subset_mode, col._subset_label, dp, np.inf,
                                    False, 1, 1, np.zeros(1, np.int64), *col.table._kargs,
                                    hit, np.empty(0), np.empty((0, 2), np.int32), sk, err)


def scene(name: str, n: int, reps: int) -> str:
    model = mujoco.MjModel.from_xml_path(str(MODELS / name / "scene.xml"))
    q = testing.random_configurations(model, n, np.random.default_rng(0))
    col = cm.Collider(model)
    col.check_batch(q)
    call = _cpu_best(lambda: col.check_batch(q), reps)
    kin_arrays = col._setup_check()
    trees = 0.0
    qf = q
    if col._trees():
        hit = np.zeros(n, bool)
        workers = max(1, numba.get_num_threads())
        trees = _cpu_best(lambda: col._early_trees(q, np.zeros(n, bool), kin_arrays, col.table._kargs, workers), reps)
        rest = col._early_trees(q, hit, kin_arrays, col.table._kargs, workers)
        qf = np.ascontiguousarray(q[rest])
    nf = len(qf)
    if nf:
        broad = _cpu_best(lambda: col.broadphase.pairs_batch(model, qf), reps)
        rows = np.ascontiguousarray(col.broadphase.pairs_batch(model, qf), dtype=np.int32).reshape(-1, 3)
        lab, mode = col._subset_label, col._subset_mode
        posed = np.zeros(nf, bool)
        sel = np.ones(len(rows), bool)
        if mode == _kc.SUBSET_ONE:
            sel = ((lab[rows[:, 1]] & 1) != 0) & ((lab[rows[:, 2]] & 1) != 0)
        posed[rows[sel, 0]] = True
        kin_fn = lambda: _kin_posed(qf, posed, *kin_arrays[:10])  # noqa: E731
        kin_fn()
        kin = _cpu_best(kin_fn, reps)
        k_none = _check_worlds(col, qf, np.zeros((0, 3), np.int32))
        k_none()
        fixed = _cpu_best(k_none, reps)
        kernel = _cpu_best(_check_worlds(col, qf, rows), reps)
        nrows = len(rows) / nf
    else:
        broad = kin = fixed = kernel = nrows = 0.0
    decide = kernel - kin - fixed
    glue = call - trees - broad - kernel
    per = 1e6 / n
    parts = [trees, broad, kin, fixed, decide, glue]
    return (f"{name:<20}{call * per:>8.3f}" + "".join(f"{x * per:>8.3f}" for x in parts)
            + "".join(f"{100 * x / call:>6.1f}" for x in parts) + f"{nf / n:>6.2f}{nrows:>7.1f}")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--configs", type=int, default=3000)
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--scenes", nargs="*", default=DEFAULT)
    a = ap.parse_args()
    numba.set_num_threads(1)
    print(f"# check_shares: {a.configs} configurations, 1 thread, CPU time, best of {a.reps}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load {os.getloadavg()[0]:.2f}")
    print(f"# command: python tests/bench/check_shares.py {' '.join(sys.argv[1:])}")
    print(f"{'scene':<20}{'call':>8}{'trees':>8}{'broad':>8}{'kin':>8}{'fixed':>8}{'decide':>8}{'glue':>8}"
          f"{'%tree':>6}{'%brd':>6}{'%kin':>6}{'%fix':>6}{'%dec':>6}{'%glue':>6}{'full':>6}{'rows':>7}")
    for s in a.scenes:
        print(scene(s, a.configs, a.reps), flush=True)
    print(f"# load {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
