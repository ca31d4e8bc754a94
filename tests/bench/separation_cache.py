"""How often the separation cache settles a pair (`collide._kernels.warm.sep_test`), per scene.

    python tests/bench/separation_cache.py [--steps N] [SCENE ...]

Each scene in ../shared/models simulated with random controls as tests/bench/contacts.py does;
before each ``Collider.contacts(data)`` the direction of every row that a candidate pair holds is
marked (scaled by ``1 + 2**-30``: GJK's normals are unit within rounding); after the call a row
still marked was read and not rewritten: its pair was settled without GJK. Printed per scene, over
the steps, the candidate pairs GJK decides (not two spheres or capsules, not a plane or two boxes)
that held a row before the call, by outcome: settled, decided again by GJK and apart (its row
rewritten), in contact (its row freed); and those without a row (which also counts the pairs that
the bounding-ball test turns away before GJK: they never take a row).
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

import collide.mujoco as cm
from collide._kernels.manifold import CONVEX, T_BOX
from collide._kernels.support import POINTS
from collide._kernels.warm import SEP_LEN, SEP_ROW, SEP_SLOTS, WARM_LEN, warm_slot

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"


def scene_counts(path: Path, steps: int, seed: int = 0, hold: int = 10) -> dict:
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    col = cm.Collider(model)
    t = col.table
    G = model.ngeom
    rows = t._wsi[-WARM_LEN - SEP_LEN:-WARM_LEN].reshape(SEP_SLOTS, SEP_ROW)
    rowsf = rows.view(np.float64)
    ctrls = cm._random_controls(model, steps, seed, hold)
    counts = dict(settled=0, gjk_apart=0, contact=0, no_row=0)

    def gjk_pair(g1, g2):
        if t.cls[g1] != CONVEX or t.cls[g2] != CONVEX:
            return False
        if model.geom_type[g1] == T_BOX and model.geom_type[g2] == T_BOX:
            return False
        return not (t.kind[g1] == POINTS and t.kind[g2] == POINTS and max(t.pts_num[g1], t.pts_num[g2]) <= 2)

    for step in range(steps):
        if step % hold == 0 and len(ctrls):
            data.ctrl[:] = ctrls[step // hold]
        mujoco.mj_step(model, data)
        pairs = [(g1, g2) for g1, g2 in col.pairs(data).tolist() if gjk_pair(g1, g2)]
        marked = {}
        for g1, g2 in pairs:
            key = g1 * G + g2 + 1
            s = warm_slot(key)
            if rows[s, 0] == key:
                rowsf[s, 1:4] *= 1.0 + 2.0 ** -30
                marked[(g1, g2)] = rowsf[s, 1:4].copy()
        col.contacts(data)
        for g1, g2 in pairs:
            key = g1 * G + g2 + 1
            s = warm_slot(key)
            if (g1, g2) not in marked:
                counts["no_row"] += 1
            elif rows[s, 0] != key:
                counts["contact"] += 1  # freed (or taken over by another pair: counted here too)
            elif np.array_equal(rowsf[s, 1:4], marked[(g1, g2)]):
                counts["settled"] += 1
            else:
                counts["gjk_apart"] += 1
    return counts


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("scenes", nargs="*")
    a = ap.parse_args(argv)
    names = a.scenes or sorted(p.name for p in MODELS.iterdir() if (p / "scene.xml").is_file())
    print(f"# separation cache outcomes, {a.steps} steps of random controls per scene; MuJoCo {mujoco.__version__}, "
          f"Python {platform.python_version()}; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"# command: python tests/bench/separation_cache.py --steps {a.steps}" + (" " + " ".join(a.scenes) if a.scenes else ""))
    print("# GJK pair-steps (a candidate pair at a step) that held a row: settled / GJK again, apart / in contact; "
          "then those without a row")
    print(f"{'scene':22s} {'settled':>8s} {'gjk apart':>10s} {'contact':>8s} {'no row':>8s}  settled share")
    for name in names:
        c = scene_counts(MODELS / name / "scene.xml", a.steps)
        held = c["settled"] + c["gjk_apart"] + c["contact"]
        share = c["settled"] / (held + c["no_row"]) if held + c["no_row"] else float("nan")
        print(f"{name:22s} {c['settled']:8d} {c['gjk_apart']:10d} {c['contact']:8d} {c['no_row']:8d}  {share:.2f}")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
