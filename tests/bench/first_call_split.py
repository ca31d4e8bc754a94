"""The first call after ``mj_step``, split: broad and narrow phase, after MuJoCo's code or a data-only sweep (a developer's tool).

    python tests/bench/first_call_split.py NAME [STEPS]

The scene is simulated as tests/bench/contacts.py does. Each step, after ``mj_step``: ``broad_first``
is ``Collider.pairs(data)``, ``narrow_after_broad`` `collide.contacts.contacts_of` on its pairs right
after it (the narrow phase's share of the benchmark's first call); then both again on the same state
(``*_again``: every cache warm); then both after a sweep over 8 MB of other data (``thrash_*``: our
data evicted, our code kept in the instruction caches); then both after ``mj_forward`` (``mjfwd_*``:
MuJoCo's code run, the state unchanged). Where ``thrash`` stays near ``again`` and ``mjfwd`` near
``first``, what a step costs the first call is the code (instruction caches, branch predictors),
not our tables. Medians over the steps, us; one call each (not a best of several).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import mujoco
import numpy as np

import collide.mujoco as cm
from collide import contacts as _c

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"
KEYS = ("broad_first", "narrow_after_broad", "broad_again", "narrow_again", "thrash_broad", "thrash_narrow",
        "mjfwd_broad", "mjfwd_narrow")


def main(name: str, steps: int = 300) -> None:
    model = mujoco.MjModel.from_xml_path(str(MODELS / name / "scene.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    col = cm.Collider(model)
    col.contacts(data)
    table = col.table
    ctrls = cm._random_controls(model, steps, 0, 10)
    big = np.ones(1 << 20)  # 8 MB
    res: dict = {k: [] for k in KEYS}
    ns = time.perf_counter_ns

    def both(prefix: str) -> None:
        t0 = ns()
        pairs = col.pairs(data)
        t1 = ns()
        xpos, xmat = col._poses(data)
        t2 = ns()
        _c.contacts_of(table, pairs, xpos, xmat)
        t3 = ns()
        res[prefix[0]].append((t1 - t0) * 1e-3)
        res[prefix[1]].append((t3 - t2) * 1e-3)

    for step in range(steps):
        if step % 10 == 0 and len(ctrls):
            data.ctrl[:] = ctrls[step // 10]
        mujoco.mj_step(model, data)
        both(KEYS[0:2])
        both(KEYS[2:4])
        big += 1.0
        both(KEYS[4:6])
        mujoco.mj_forward(model, data)
        both(KEYS[6:8])
    print(f"{name}: medians over {steps} steps, us:  " + "  ".join(f"{k} {np.median(v):.1f}" for k, v in res.items()))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 300)
