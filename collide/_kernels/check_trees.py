"""The early exit of `check.check_worlds` before the broad phase: each kinematic tree on its own.

`check_worlds` decides a configuration from a broad phase's candidate rows, so every candidate of
every configuration is found before the first contact can end the search: on a scene of many
robots (22 humanoids: 353 bodies, 86,889 filtered geom pairs) the batch broad phase is most of the
call, though each configuration's first humanoid often collides with itself or the floor.

`check_trees` runs first where only ``in_collision`` is asked: for each configuration, tree by tree
(a tree: a child of the world body and its descendants, bodies numbered contiguously, parents
first, as MuJoCo orders them), the poses of that tree's bodies alone (`kinematics._bodies_span`),
then its pairs from a static list (the filtered pairs inside the tree, and those with a geom of the
world body or of a tree without joints, posed once), each culled by balls about the geoms' origins
(`check._lower_bound`'s test, squared) and decided by `check.deepest_contact`; the first active
contact decides the configuration and ends its work. A configuration it leaves undecided (no active
contact among those pairs) goes the full way, so the answer is the full path's: the static pairs
are filtered pairs of the checked subset, the poses are bit for bit those of
`kinematics._kinematics_world`, and an active contact of a filtered pair is one the conservative
broad phase hands `check_worlds` too. The cull may err without changing an answer: a pair it drops
only leaves a configuration to the full path.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._ptr import borrow
from ._threads import fetch_add, set_chunksize
from .check import ACTIVE, decider_scratch, deepest_contact, geom_pose
from .kinematics import _bodies_span, _half_angles_span
from .manifold import PLANE, SKIPPED, _finite_pose, _pair_rows, pair_margins, scratch_caps


@nb.njit(cache=True, inline="always")
def _reach(g1, g2, cls, geom_margin, geom_gap, pair_key, pair_margin, pair_gap, override, o_margin):
    # The largest contact distance (margin + gap) over the pair's collisions (`pair_margins`).
    G = cls.shape[0]
    j, nent, explicit = _pair_rows(pair_key, min(g1, g2) * G + max(g1, g2))
    out = -np.inf
    for e in range(nent):
        margin, thr = pair_margins(g1, g2, j + e, explicit, geom_margin, geom_gap, pair_margin, pair_gap, override,
                                   o_margin)
        out = max(out, thr)
    return out


# `check_trees`' worker, one call a thread (as `check._check_chunks` is `check_worlds`': numba compiled
# the deciders inlined into the parallel loop about three times as slowly, `tests/bench/compile_time.py`).
@nb.njit(cache=True, nogil=True)
def _tree_chunks(qpos, qmax, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                 jnt_pos, jnt_axis, geom_body, geom_pos, geom_quat, static_span, static_geom, tree_span, tree_geom,
                 tree_geom_start, tpairs, tpair_start, chunks, cls, rule, below, kind, prm, pts, pts_adr, pts_num,
                 nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, rbound, size, geom_margin, geom_gap,
                 pair_key, pair_margin, pair_gap, override, o_margin, gtype, half, hv_adr, hv_num, hv, f_adr, f_num,
                 f_normal, f_vadr, f_vnum, f_vidx, out_hit, B, L, G, nj, T, cap, fmax, addr):
    bpos = np.zeros((L, 3))
    brot = np.zeros((L, 3, 3))
    bquat = np.zeros((L, 4))
    bquat[0, 0] = 1.0  # the world body, as `_kinematics_world` poses it
    for i in range(3):
        brot[0, i, i] = 1.0
    sc = np.empty((max(nj, 1), 2))
    for s in range(static_span.shape[0]):  # no joint: q and sc are not read
        _bodies_span(qpos[0], qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type,
                     jnt_qposadr, jnt_pos, jnt_axis, bpos, brot, bquat, sc, static_span[s, 0], static_span[s, 1])
    xpos = np.zeros((G, 3))
    xmat = np.zeros((G, 3, 3))
    scratch, dws, d0, gws, g4, dwi = decider_scratch(cap, fmax)
    # the shared tables borrowed (`borrow`, as check_worlds does)
    cls_, rule_, below_, rbound_, size_ = borrow(cls), borrow(rule), borrow(below), borrow(rbound), borrow(size)
    gmargin, ggap, pkey = borrow(geom_margin), borrow(geom_gap), borrow(pair_key)
    pmargin, pgap, gtype_, half_ = borrow(pair_margin), borrow(pair_gap), borrow(gtype), borrow(half)
    shapes = (borrow(kind), borrow(prm), borrow(pts), borrow(pts_adr), borrow(pts_num), borrow(nbr_start),
              borrow(nbr_start_adr), borrow(nbr_start_num), borrow(nbr), borrow(nbr_adr), borrow(nbr_num))
    faces = (borrow(hv_adr), borrow(hv_num), borrow(hv), borrow(f_adr), borrow(f_num), borrow(f_normal),
             borrow(f_vadr), borrow(f_vnum), borrow(f_vidx))
    geom_body_, geom_pos_, geom_quat_ = borrow(geom_body), borrow(geom_pos), borrow(geom_quat)
    span_, tpairs_, tstart = borrow(tree_span), borrow(tpairs), borrow(tpair_start)
    sgeom, tgeom, tgeom_start = borrow(static_geom), borrow(tree_geom), borrow(tree_geom_start)
    qpos_, qpos0_, parent_, bpos0, bquat0 = borrow(qpos), borrow(qpos0), borrow(body_parent), borrow(body_pos), \
        borrow(body_quat)
    jntadr, jntnum, jtype, jqadr = borrow(body_jntadr), borrow(body_jntnum), borrow(jnt_type), \
        borrow(jnt_qposadr)
    jpos, jaxis = borrow(jnt_pos), borrow(jnt_axis)
    # the static geoms' poses (no joint above them) once, and each pair's reach for the cull:
    # the ball test |c1 - c2| > r1 + r2 + thr squared (no root), a plane's n . (c - p) > r + thr
    for i in range(sgeom.shape[0]):
        geom_pose(sgeom[i], bpos, brot, bquat, geom_body_, geom_pos_, geom_quat_, xpos, xmat)
    P = tpairs_.shape[0]
    reach = np.empty(P)
    for r in range(P):
        g1 = tpairs_[r, 0]
        g2 = tpairs_[r, 1]
        thr = _reach(g1, g2, cls_, gmargin, ggap, pkey, pmargin, pgap, override, o_margin)
        if cls_[g1] == PLANE or cls_[g2] == PLANE:
            reach[r] = thr + rbound_[g2 if cls_[g1] == PLANE else g1]
        else:
            e = rbound_[g1] + rbound_[g2] + thr
            reach[r] = e * e if e >= 0.0 else -1.0
    while True:
        c = fetch_add(addr, 1)
        if c >= chunks:
            break
        for w in range((B * c) // chunks, (B * (c + 1)) // chunks):
            q = qpos_[w]
            hit = False
            small = True
            for i in range(q.shape[0]):
                small &= abs(q[i]) <= qmax
            for t in range(T if small else 0):
                _half_angles_span(q, qpos0_, jtype, jqadr, sc, span_[t, 2], span_[t, 3])
                _bodies_span(q, qpos0_, parent_, bpos0, bquat0, jntadr, jntnum, jtype, jqadr, jpos, jaxis, bpos,
                             brot, bquat, sc, span_[t, 0], span_[t, 1])
                ok = True
                for i in range(tgeom_start[t], tgeom_start[t + 1]):
                    g = tgeom[i]
                    geom_pose(g, bpos, brot, bquat, geom_body_, geom_pos_, geom_quat_, xpos, xmat)
                    ok &= _finite_pose(xpos, xmat, g)
                if not ok:
                    break  # the full path names the configuration
                for r in range(tstart[t], tstart[t + 1]):
                    g1 = tpairs_[r, 0]
                    g2 = tpairs_[r, 1]
                    if cls_[g1] == PLANE or cls_[g2] == PLANE:
                        gp = g1 if cls_[g1] == PLANE else g2
                        gc = g2 if cls_[g1] == PLANE else g1
                        if (xmat[gp, 0, 2] * (xpos[gc, 0] - xpos[gp, 0]) + xmat[gp, 1, 2] * (xpos[gc, 1] - xpos[gp, 1])
                                + xmat[gp, 2, 2] * (xpos[gc, 2] - xpos[gp, 2]) > reach[r]):
                            continue
                    else:
                        d0_ = xpos[g2, 0] - xpos[g1, 0]
                        d1_ = xpos[g2, 1] - xpos[g1, 1]
                        d2_ = xpos[g2, 2] - xpos[g1, 2]
                        if d0_ * d0_ + d1_ * d1_ + d2_ * d2_ > reach[r]:
                            continue
                    if cls_[g1] == SKIPPED or cls_[g2] == SKIPPED:
                        continue  # left to the full path
                    a = deepest_contact(g1, g2, xpos, xmat, cls_, rule_, below_, rbound_, size_, gmargin, ggap,
                                        pkey, pmargin, pgap, override, o_margin, gtype_, half_, shapes, faces,
                                        scratch, dws, d0, gws, g4, dwi)
                    if a == ACTIVE:
                        hit = True
                        break
                if hit:
                    break
            out_hit[w] = hit
    return 0


@nb.njit(cache=True, parallel=True, nogil=True)
def check_trees(qpos, qmax, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                jnt_pos, jnt_axis, geom_body, geom_pos, geom_quat, static_span, static_geom, tree_span, tree_geom,
                tree_geom_start, tpairs, tpair_start, chunks, workers,
                counter, cls, rule, below, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num,
                nbr, nbr_adr, nbr_num, rbound, size, geom_margin, geom_gap, pair_key, pair_margin, pair_gap, override,
                o_margin, gtype, half, hv_adr, hv_num, hv, f_adr, f_num, f_normal, f_offset, f_vadr, f_vnum, f_vidx,
                out_hit):
    """Configurations decided in collision tree by tree, before any broad phase (module docstring).

    Parameters
    ----------
    qpos : (B, nq) float64
        Finite (the caller checks).
    qmax : float
        A configuration with a coordinate beyond it in magnitude is left undecided (the full
        path then reports what it reports: its poses could overflow).
    qpos0 ... geom_quat
        As `check.check_worlds` takes them.
    static_span : (S, 2) int64
        The bodies ``[static_span[s, 0], static_span[s, 1])`` of each tree without joints (fixed
        and mocap bodies: the same poses in every configuration), posed once per worker.
    static_geom : (Gs,) int32
        The geoms of ``tpairs`` on those bodies or the world body (posed once per worker).
    tree_span : (T, 4) int64
        Each tree with joints: its bodies ``[tree_span[t, 0], tree_span[t, 1])`` and joints
        ``[tree_span[t, 2], tree_span[t, 3])``, trees in body order.
    tree_geom : (Gt,) int32
    tree_geom_start : (T + 1,) int64
        Tree ``t``'s geoms in ``tpairs``: ``tree_geom[tree_geom_start[t]:tree_geom_start[t + 1]]``.
    tpairs : (P, 2) int32
        Filtered geom pairs of the checked subset, ``g1 < g2``, each inside one tree of
        ``tree_span`` or between such a tree and a geom of the world body or of a tree without
        joints, grouped by tree.
    tpair_start : (T + 1,) int64
        Tree ``t``'s pairs are ``tpairs[tpair_start[t]:tpair_start[t + 1]]``.
    chunks, workers, counter
        As `check.check_worlds` takes them.
    cls ... f_vidx
        `collide.contacts.GeomTable.kernel_args`.
    out_hit : (B,) bool
        Receives True where an active contact was found (the configuration is in collision),
        False where the full path must decide.

    Returns
    -------
    int
        0.
    """
    B = qpos.shape[0]
    L = body_parent.shape[0]
    G = geom_body.shape[0]
    nj = jnt_type.shape[0]
    T = tree_span.shape[0]
    cap, fmax = scratch_caps(pts_num, f_vnum)
    addr = counter.ctypes.data
    chunksize = set_chunksize(1)  # one iteration a worker (`_threads`)
    for wk in nb.prange(workers):
        _tree_chunks(qpos, qmax, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type,
                     jnt_qposadr, jnt_pos, jnt_axis, geom_body, geom_pos, geom_quat, static_span, static_geom,
                     tree_span, tree_geom, tree_geom_start, tpairs, tpair_start, chunks, cls, rule, below, kind, prm,
                     pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, rbound,
                     size, geom_margin, geom_gap, pair_key, pair_margin, pair_gap, override, o_margin, gtype, half,
                     hv_adr, hv_num, hv, f_adr, f_num, f_normal, f_vadr, f_vnum, f_vidx, out_hit, B, L, G, nj, T, cap,
                     fmax, addr)
    set_chunksize(chunksize)
    return 0


__all__ = ["check_trees"]
