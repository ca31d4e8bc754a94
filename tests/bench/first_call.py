"""Is the first call's cost after ``mj_step`` our tables' cache misses? (a developer's tool)

    python tests/bench/first_call.py NAME [STEPS]

The scene is simulated as tests/bench/contacts.py does, on two MjData stepped alike: each step,
``first`` is ``Collider.contacts`` right after ``mj_step`` (the benchmark's figure), ``call``
the same call again (caches warm, the same state: every warm start hits); on the twin, ``touched``
is the call after ``mj_step`` and a read of every table and workspace of ours (the narrow
phase's packed tables and scratch, the broad phase's buffers), a Collider of its own. When
``touched`` stays near ``first``, what the step evicted is not those arrays (the kernels' code,
the interpreter's state). Medians over the steps, us; the arrays' size read, KB.
(`tests/bench/contacts_profile.py`'s ``replayed`` separates the warm starts' part.)
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import mujoco
import numpy as np

import collide.mujoco as cm

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"


def main(name: str, steps: int = 300) -> None:
    model = mujoco.MjModel.from_xml_path(str(MODELS / name / "scene.xml"))
    da, db = mujoco.MjData(model), mujoco.MjData(model)
    mujoco.mj_forward(model, da)
    mujoco.mj_forward(model, db)
    ca, cb = cm.Collider(model), cm.Collider(model)
    ca.contacts(da)
    cb.contacts(db)
    ctrls = cm._random_controls(model, steps, 0, 10)
    bp = cb.broadphase.broadphase
    arrs = [a.view(np.uint8) for a in (*cb.table._tables, cb.table._wsi, cb.table._wsf, bp._I, bp._F, bp._W)]
    ns = time.perf_counter_ns
    r: dict = {"first": [], "touched": [], "call": []}
    for s in range(steps):
        if s % 10 == 0 and len(ctrls):
            da.ctrl[:] = ctrls[s // 10]
        mujoco.mj_copyData(db, model, da)
        mujoco.mj_step(model, da)
        t0 = ns()
        ca.contacts(da)
        r["first"].append(ns() - t0)
        t0 = ns()
        ca.contacts(da)
        r["call"].append(ns() - t0)
        mujoco.mj_step(model, db)
        for a in arrs:
            a[::64].sum()  # a byte of every cache line
        t0 = ns()
        cb.contacts(db)
        r["touched"].append(ns() - t0)
    print(f"{name:<14}" + "  ".join(f"{k} {np.median(v) * 1e-3:.1f}" for k, v in r.items())
          + f"  (read KB {sum(a.nbytes for a in arrs) // 1024})")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 300)
