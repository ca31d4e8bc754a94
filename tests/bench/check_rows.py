"""Where check_batch's narrow phase spends its time, per candidate row (issue 43's speed work).

    python tests/bench/check_rows.py SCENE [SCENE ...]

Per scene: 1000 random configurations (seed 0), their broad phase's rows, the geom poses from
MuJoCo's ``mj_kinematics``; each row timed through `collide._kernels.check.deepest_contact`
(5 calls, one thread) and classified by the branch that decides it (a copy of its steps, here
only): ``bound0`` (a bounding test of `plane_box_contacts` leaves it out), ``plane/box`` (planes
and box-box), ``closed`` (spheres and capsules: the closed form), ``gjk-ovl`` (GJK: the cores
overlap), ``gjk-rej`` (GJK's lower bound beyond the contact distance), ``gjk-upper`` (GJK's upper
bound within the margin), ``full`` (the signed distance). ``seen``: the rows a configuration
decides before its early exit (in row order). Row types and branches are per configuration.
"""
import os
import sys
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import numpy as np, numba as nb, mujoco
from pathlib import Path
import collide.mujoco as cm
from collide import testing
from collide._kernels import check as kc
from collide._kernels.check import ACTIVE, deepest_contact
from collide._kernels._clock import now_us
from collide._kernels.manifold import (BOX_WS, CONTACT_TOL, CONVEX_PAIR, MAX_PER_PAIR, OUT_SIZE, _pair_rows, _shape,
                                       pair_margins, plane_box_contacts)
from collide._kernels.gjk import OVERLAP, SEPARATED, gjk
from collide._kernels.support import POINTS
import math

@nb.njit
def branch(g1, g2, xpos, xmat, cls, rule, below, rbound, size, geom_margin, geom_gap, pair_key, pair_margin,
                    pair_gap, override, o_margin, gtype, half, shapes, faces, scratch, out, d0, gws, g4, hints):
    # code: 0 plane/box path no contact by bound, 1 plane/box path computed, 2 closed form, 3 gjk overlap, 4 gjk sep reject, 5 gjk sep upper active, 6 full distance, 7 the axis test before GJK
    G = cls.shape[0]
    j, nent, explicit = _pair_rows(pair_key, min(g1, g2) * G + max(g1, g2))
    kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num = shapes
    margin, thr = pair_margins(g1, g2, j, explicit, geom_margin, geom_gap, pair_margin, pair_gap, override, o_margin)
    m = plane_box_contacts(g1, g2, thr, xpos, xmat, cls, rule, below, rbound, gtype, half, shapes, faces, scratch)
    if m == 0:
        return 0, 0
    if m != CONVEX_PAIR:
        return 1, 0
    s1 = _shape(g1, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, xpos, xmat)
    s2 = _shape(g2, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, xpos, xmat)
    tol = CONTACT_TOL * (size[g1] + size[g2])
    r = prm[g1, 3] + prm[g2, 3]
    if kind[g1] == POINTS and kind[g2] == POINTS and pts_num[g1] <= 2 and pts_num[g2] <= 2:
        return 2, 0
    if kc._apart_on_axis(s1, s2, xpos, g1, g2, r, thr, gws[3, 1], gws[3, 2]):
        return 7, 0
    hints[0] = -1; hints[1] = -1
    gws[:] = 0.0; g4[:] = 0.0
    st, nsx, lower, scale, iters = gjk(s1, s2, d0, hints, tol, 128, gws[0], gws[1], gws[2], g4[0], gws[3, 0], g4[1], gws[3, 1], gws[3, 2])
    if st == OVERLAP:
        return 3, iters
    if st == SEPARATED:
        if lower - r > thr:
            return 4, iters
        v = gws[3, 0]
        upper = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        if upper - r < margin and upper - r <= thr:
            return 5, iters
    return 6, iters

@nb.njit
def prof(xpos_all, xmat_all, rows, reps, cls, rule, below, kind, prm, pts, pts_adr, pts_num,
                 nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, rbound, size, geom_margin,
                 geom_gap, pair_key, pair_margin, pair_gap, override, o_margin, gtype, half, hv_adr, hv_num, hv,
                 f_adr, f_num, f_normal, f_offset, f_vadr, f_vnum, f_vidx):
    K = rows.shape[0]
    ans = np.empty(K, np.int64); code = np.empty(K, np.int64); its = np.empty(K, np.int64); t = np.empty(K)
    cap = 1
    for g in range(pts_num.shape[0]):
        cap = max(cap, pts_num[g])
    fmax = 4
    for f in range(f_vnum.shape[0]):
        fmax = max(fmax, f_vnum[f])
    cand = np.empty((cap, 3)); dep = np.empty(cap); sel = np.zeros(4, np.int64); res = np.empty((MAX_PER_PAIR, 4))
    bnrm = np.zeros(3); bws = np.empty(BOX_WS); pcand = np.empty((fmax, 3)); pdep = np.empty(fmax)
    out = np.empty(OUT_SIZE); d0 = np.zeros(3); gws = np.zeros((4, 4, 3)); g4 = np.zeros((2, 4)); hints = np.empty(2, np.int64)
    shapes = (kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num)
    faces = (hv_adr, hv_num, hv, f_adr, f_num, f_normal, f_vadr, f_vnum, f_vidx)
    scratch = (cand, dep, sel, res, bnrm, bws, pcand, pdep)
    for k in range(K):
        w = rows[k, 0]; g1 = rows[k, 1]; g2 = rows[k, 2]
        xpos = xpos_all[w]; xmat = xmat_all[w]
        t0 = now_us()
        for _ in range(reps):
            a = deepest_contact(g1, g2, xpos, xmat, cls, rule, below, rbound, size, geom_margin, geom_gap,
                                pair_key, pair_margin, pair_gap, override, o_margin, gtype, half, shapes,
                                faces, scratch, out, d0, gws, g4, hints)
        t[k] = (now_us() - t0) / reps
        ans[k] = a
        code[k], its[k] = branch(g1, g2, xpos, xmat, cls, rule, below, rbound, size, geom_margin, geom_gap,
                                pair_key, pair_margin, pair_gap, override, o_margin, gtype, half, shapes,
                                faces, scratch, out, d0, gws, g4, hints)
    return ans, code, its, t

MODELS = Path("/work/shared/models")
for name in sys.argv[1:]:
    model = mujoco.MjModel.from_xml_path(str(MODELS / name / "scene.xml"))
    data = mujoco.MjData(model)
    n = 1000
    q = testing.random_configurations(model, n, np.random.default_rng(0))
    col = cm.Collider(model)
    rows = np.ascontiguousarray(col.broadphase.pairs_batch(model, q), dtype=np.int32).reshape(-1, 3)
    G = model.ngeom
    xp = np.empty((n, G, 3)); xm = np.empty((n, G, 3, 3))
    for i in range(n):
        data.qpos[:] = q[i]; mujoco.mj_kinematics(model, data)
        xp[i] = data.geom_xpos; xm[i] = data.geom_xmat.reshape(G, 3, 3)
    ans, code, its, t = prof(xp, xm, rows, 5, *col.table._kargs)
    # rows seen with early exit (in given order)
    seen = np.zeros(len(rows), bool)
    rs = np.searchsorted(rows[:, 0], np.arange(n + 1))
    pos_hit = []
    for w in range(n):
        a = ans[rs[w]:rs[w+1]]
        k = np.flatnonzero(a == ACTIVE)
        end = rs[w] + (k[0] + 1 if len(k) else len(a))
        seen[rs[w]:end] = True
        if len(k): pos_hit.append((k[0], len(a)))
    gt = np.asarray(model.geom_type)
    tn = lambda g: mujoco.mjtGeom(gt[g]).name[6:].lower()
    print(f"== {name}: {len(rows)/n:.2f} rows/config, seen (early exit) {seen.sum()/n:.2f}/config; time all rows {t.sum()/n:.3f} us/config, seen rows {t[seen].sum()/n:.3f} us/config")
    print(f"   active rows {np.mean(ans==ACTIVE)*len(rows)/n:.2f}/config; hit configs {len(pos_hit)/n:.2f}; first active at index mean {np.mean([p for p,_ in pos_hit]) if pos_hit else 0:.2f} of {np.mean([l for _,l in pos_hit]) if pos_hit else 0:.2f}")
    names = ["bound0", "plane/box", "closed", "gjk-ovl", "gjk-rej", "gjk-upper", "full", "axis-rej"]
    for c in range(8):
        m = (code == c) & seen
        if m.any():
            print(f"   {names[c]:<10} {m.sum()/n:6.2f} rows/config  {t[m].mean():7.3f} us/row  {t[m].sum()/n:6.3f} us/config  iters {its[m].mean():.1f}")
    types = {}
    for k in np.flatnonzero(seen):
        key = tuple(sorted((tn(rows[k,1]), tn(rows[k,2])))) + (names[code[k]],)
        d = types.setdefault(key, [0, 0.0]); d[0] += 1; d[1] += t[k]
    for key, (c, s) in sorted(types.items(), key=lambda kv: -kv[1][1])[:8]:
        print(f"   {key[0]}-{key[1]} {key[2]:<10} {c/n:6.2f} rows/config {s/c:7.3f} us/row {s/n:6.3f} us/config")
