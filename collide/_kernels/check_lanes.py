"""Collision checks of many configurations in the batch broad phase's own pass (numba).

`check_lanes_kin` is `kinematics.step_lanes_kin` (each group of `lanes.LANES` configurations
posed in SIMD lanes of its thread's workspace, then tested by `lanes._lane_group`) with
`check.check_worlds`' decision right after each group's tests: the group's candidate pairs are
read from the chunk's keys as they were written, and each configuration's geoms are posed from
the body poses still in the lanes (`geom_pose_lane`). `check_worlds` computes every configuration's
body poses a second time (`kinematics._kinematics_world`) and reads the pairs back from the rows
the broad phase gathered; here neither: no second kinematics, no ``(K, 3)`` rows, no per-world row
index. The lanes' poses are the scalar kinematics' bit for bit (`kinematics._kinematics_lanes`),
the pairs come in the same order (a world's keys sorted, as the rows), and each pair goes through
the same `check.deepest_contact`: the answers are `check_worlds`' on `pairs_batch`'s rows.

A chunk that holds a bad pose or ran out of key room decides nothing after it (the caller, as for
the broad phase alone, `collide.broadphase._batch.Batch.run`, raises or grows the buffers and runs
the call again, every configuration decided again).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._ptr import borrow, check_span, f64_ptr, i64_ptr
from ._simd import LANES
from ._threads import set_chunksize
from .batch import CI_BAD, CI_KEYS, chunk_buffers, gather_status, next_chunk, start_chunks
from .check import decide_rows, decider_scratch, first_pass, geom_pose_lane
from .kinematics import _kinematics_lanes, _model_views, lanes_scratch_size
from .lanes import _lane_group, lane_buffers
from .layout import LW_GPOS, LW_GROT, LW_POSES, N_STATS, view_f3, view_f4
from .manifold import scratch_caps
from .step import C_KEYS, C_NKEYS

__all__ = ["check_lanes_kin", "geom_pose_lane"]  # geom_pose_lane: `check`'s, re-exported


@nb.njit(cache=True, parallel=True, nogil=True)
def check_lanes_kin(qpos, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                    jnt_pos, jnt_axis, ctxs, J, LWs, LBs, scratch, world_count, world_info, chunk_info, S, stats_out,
                    geom_body, geom_pos, geom_quat, no_function, mode, label, cls, rule, below, kind, prm, pts,
                    pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, rbound, size,
                    geom_margin, geom_gap, pair_key, pair_margin, pair_gap, override, o_margin, gtype, half, hv_adr,
                    hv_num, hv, f_adr, f_num, f_normal, f_offset, f_vadr, f_vnum, f_vidx, out_hit, out_skipped,
                    out_err):
    """`check.check_worlds` of ``qpos (B, nq)`` (``distance=False``) on the candidates of the
    lanes' broad phase, in its pass (module docstring).

    Parameters
    ----------
    qpos ... stats_out
        As `kinematics.step_lanes_kin` takes them (the model's kinematics arrays, the batch's
        buffers and lane tables).
    geom_body : (G,) int64
    geom_pos : (G, 3) float64
    geom_quat : (G, 4) float64
        Each geom's frame in its body's (`check.check_worlds`).
    no_function : (G,) bool
        Geoms that never pair with each other (MuJoCo's planes and height fields where the
        model has a height field: `collide.mujoco.BroadPhase` drops such pairs).
    mode : int
    label : (G,) int8
        The checked subset (`check.in_subset`).
    cls ... f_vidx
        `collide.contacts.GeomTable.kernel_args`.
    out_hit, out_skipped : (B,) bool
    out_err : (B,) int64
        As `check.check_worlds` writes them; written for every configuration when the call
        returns a non-empty status.

    Returns
    -------
    (1,) or (0,) int64
        `batch.gather_status`: empty when a chunk holds a bad pose or ran out of room (then the
        outputs are not all written).
    """
    B = qpos.shape[0]
    nq = qpos0.shape[0]
    NB = body_parent.shape[0]
    nj = jnt_type.shape[0]
    G = geom_body.shape[0]
    C = ctxs.shape[0]
    (q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis) = _model_views(
        qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr, jnt_pos, jnt_axis)
    qp = nb.carray(f64_ptr(np.int64(qpos.ctypes.data)), (B, nq))
    Jv = nb.carray(i64_ptr(np.int64(J.ctypes.data)), J.shape[0])
    cap, fmax = scratch_caps(pts_num, f_vnum)
    nw = min(start_chunks(chunk_info, C), LWs.shape[0], LBs.shape[0], scratch.shape[0])  # a workspace a worker
    chunksize = set_chunksize(1)  # one worker a thread (`_threads`)
    for wk in nb.prange(nw):
        LW, LB = lane_buffers(LWs, LBs, wk)
        check_span(lanes_scratch_size(NB, nj), scratch.shape[1])
        check_span(wk + 1, scratch.shape[0])
        ksa = np.int64(scratch.ctypes.data) + 8 * scratch.shape[1] * wk
        xq = nb.carray(f64_ptr(ksa), (NB, 4, LANES))  # `_kinematics_lanes`' quaternions, first in its scratch
        st = np.zeros(N_STATS, np.int64)
        xpos = np.zeros((G, 3))
        xmat = np.zeros((G, 3, 3))
        stamp = np.full(G, -1, np.int64)
        no_rows, no_body, no_rot = np.empty((0, 3), np.int32), np.empty((0, 3)), np.empty((0, 3, 3))
        dscratch, dws, d0, gws, g4, dwi = decider_scratch(cap, fmax)
        # the shared tables borrowed (`_ptr.borrow`): no counter the two threads take turns on
        cls_, rule_, below_, rbound_, size_ = borrow(cls), borrow(rule), borrow(below), borrow(rbound), borrow(size)
        gmargin, ggap, pkey = borrow(geom_margin), borrow(geom_gap), borrow(pair_key)
        pmargin, pgap, gtype_, half_ = borrow(pair_margin), borrow(pair_gap), borrow(gtype), borrow(half)
        shapes = (borrow(kind), borrow(prm), borrow(pts), borrow(pts_adr), borrow(pts_num), borrow(nbr_start),
                  borrow(nbr_start_adr), borrow(nbr_start_num), borrow(nbr), borrow(nbr_adr), borrow(nbr_num))
        faces = (borrow(hv_adr), borrow(hv_num), borrow(hv), borrow(f_adr), borrow(f_num), borrow(f_normal),
                 borrow(f_vadr), borrow(f_vnum), borrow(f_vidx))
        geom_body_, geom_pos_, geom_quat_ = borrow(geom_body), borrow(geom_pos), borrow(geom_quat)
        nf_, label_ = borrow(no_function), borrow(label)
        # `decide_rows`' tuples, of borrowed views (`ps`, `xq` and `keys` are views without a count)
        geoms = (geom_body_, geom_pos_, geom_quat_)
        tables = (cls_, rule_, below_, rbound_, size_, gmargin, ggap, pkey, pmargin, pgap, override,
                  o_margin, gtype_, half_)
        no_rows, no_body, no_rot = borrow(no_rows), borrow(no_body), borrow(no_rot)  # never read
        p0 = first_pass(cls_, shapes[0], shapes[4])
        while True:
            c = next_chunk(chunk_info, C)
            if c >= C:
                break
            ctx, ci, I, F, W, sap, bp, scr, stats, info = chunk_buffers(ctxs, chunk_info, c)
            ps = view_f3(I, LW, LW_POSES)
            gpos = view_f3(I, LW, LW_GPOS)  # the group's poses, when it holds a bad one
            grot = view_f4(I, LW, LW_GROT)
            kcap = ctx[C_NKEYS]
            keys = nb.carray(i64_ptr(ctx[C_KEYS]), kcap)
            src = (keys, S, nf_, no_rows, p0)
            pose = (ps, xq, no_body, no_rot, no_body)
            for s in range(N_STATS):
                st[s] = 0
            off = 0
            w0 = (B * c) // C
            w1 = (B * (c + 1)) // C
            for g0 in range(w0, w1, LANES):
                nl = min(LANES, w1 - g0)
                _kinematics_lanes(qp, g0, nl, q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis, ps, ksa)
                k = off
                off = _lane_group(gpos, grot, 0, g0, nl, I, F, W, sap, bp, scr, stats, info, Jv, LW, LB, ctx, off,
                                  st, world_count, world_info, ci, True)
                if ci[CI_BAD] >= 0:
                    continue  # the call raises (`batch.gather_status`): nothing to decide
                for l in range(nl):
                    w = g0 + l
                    hit, skipped, err = decide_rows(w, l, k, min(k + world_count[w], kcap), src, pose, mode,
                                                    label_, geoms, tables, shapes, faces, xpos, xmat, stamp,
                                                    dscratch, dws, d0, gws, g4, dwi)  # past kcap: runs again
                    k += world_count[w]
                    out_hit[w] = hit
                    out_skipped[w] = skipped and not hit
                    out_err[w] = err
            for s in range(N_STATS):
                stats[s] = st[s]
            ci[CI_KEYS] = off
    set_chunksize(chunksize)
    return gather_status(ctxs, chunk_info, stats_out)
