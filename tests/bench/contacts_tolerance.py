"""GJK/EPA iterations and distance error of the contacts' convex pairs, by pair kind, at several tolerances.

    python tests/bench/contacts_tolerance.py STEPS SCENE [SCENE ...]

Per scene in ../shared/models, simulated with random controls as tests/bench/contacts.py does: every
step, each broad-phase pair of two convex geoms (not two boxes) whose bounding balls come within
0.01 runs `collide._kernels.distance.pair_distance` cold at each tolerance of ``TOLS`` (0 stands
for the contacts' own, ``CONTACT_TOL`` times the two sizes; the others are absolute, as MuJoCo's
``ccd_tolerance`` is), and once at 1e-14 of the sizes (the reference). Printed per pair kind: the
pairs, the share of them penetrating, the mean iterations (GJK's plus EPA's) at each tolerance and
the largest |distance - reference|. A developer's measurement (issue 46: what a looser tolerance
for the pairs MuJoCo solves by its CCD would buy); its output went to tests/bench/contacts.txt.
"""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import numpy as np

import collide.mujoco as cm
from collide import contacts as _c
from collide._kernels import manifold as km
from collide._kernels.distance import OUT_DISTANCE, OUT_ITERATIONS, OUT_SIZE, pair_distance

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"
NAMES = {v: k for k, v in _c.GEOM_TYPES.items()}
TOLS = (0.0, 1e-8, 1e-7, 3e-7)


def _shape(t, xpos, xmat, g):
    a, n = t.pts_adr[g], t.pts_num[g]
    b, m = t.nbr_start_adr[g], t.nbr_start_num[g]
    c, e = t.nbr_adr[g], t.nbr_num[g]
    return (int(t.kind[g]), t.prm[g], t.pts[a:a + n], t.nbr_start[b:b + m], t.nbr[c:c + e], xmat[g], xpos[g])


def run(scene: str, steps: int) -> None:
    model = mujoco.MjModel.from_xml_path(str(MODELS / scene / "scene.xml"))
    col = cm.Collider(model)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    t = col.table
    ctrls = cm._random_controls(model, steps, 0, 10)
    stats: dict = {}
    out = np.empty(OUT_SIZE)
    for step in range(steps):
        if step % 10 == 0 and len(ctrls):
            data.ctrl[:] = ctrls[step // 10]
        mujoco.mj_step(model, data)
        xpos, xmat = col._poses(data)
        for g1, g2 in col.pairs(data):
            if t.cls[g1] != km.CONVEX or t.cls[g2] != km.CONVEX or (t.gtype[g1] == km.T_BOX == t.gtype[g2]):
                continue
            if np.linalg.norm(xpos[g2] - xpos[g1]) - t.rbound[g1] - t.rbound[g2] > 0.01:
                continue
            key = "-".join(sorted((NAMES[int(t.gtype[g1])], NAMES[int(t.gtype[g2])])))
            s1, s2 = _shape(t, xpos, xmat, g1), _shape(t, xpos, xmat, g2)
            size = t.size[g1] + t.size[g2]
            its, dist = [], []
            for tol in TOLS:
                pair_distance(s1, s2, tol if tol > 0 else km.CONTACT_TOL * size, np.zeros(3), -1, -1, 128, out)
                its.append(out[OUT_ITERATIONS])
                dist.append(out[OUT_DISTANCE])
            pair_distance(s1, s2, 1e-14 * size, np.zeros(3), -1, -1, 256, out)
            ref = out[OUT_DISTANCE]
            stats.setdefault(key, []).append(its + [abs(d - ref) for d in dist] + [ref < 0])
    print(f"{scene}: {steps} steps; tolerances {TOLS} (0: CONTACT_TOL x sizes)")
    print(f"  {'pair kind':<22}{'pairs':>7}{'pen':>6}   mean iterations per tolerance      largest |error| per tolerance")
    for key, st in sorted(stats.items()):
        a = np.array(st)
        k = len(TOLS)
        print(f"  {key:<22}{len(a):>7}{a[:, -1].mean():>6.2f}   " + " ".join(f"{v:6.1f}" for v in a[:, :k].mean(0))
              + "     " + " ".join(f"{v:8.1e}" for v in a[:, k:2 * k].max(0)))


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    for s in sys.argv[2:]:
        run(s, int(sys.argv[1]))
