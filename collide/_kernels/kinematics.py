"""Batched forward kinematics of MuJoCo models (``mj_kinematics``, engine_core_smooth.c, body poses
only), and the batched broad phase fed by it straight into the lanes.

`kinematics_worlds` fills pose arrays, world by world (`_kinematics_world`); `step_lanes_kin`
computes each group of `lanes.LANES` worlds' poses straight into the lanes of its thread's workspace
(`_kinematics_lanes`: the worlds in SIMD lanes, where the tests read them) and runs
`lanes._lane_group` on them: no pose array of the whole batch written and read back (1024 humanoid
worlds: 1.7 MB), and one parallel region per call instead of two (a second one wakes a sleeping
thread). Both compute the same poses with the same operations in the same order, so the fused call
gives the rows of `step_lanes` on `kinematics_worlds`' poses, bit for bit.

Model arrays (``mujoco.MjModel``'s, contiguous: float64, the index arrays int32 as MuJoCo keeps them;
``L`` bodies, ``nj`` joints): ``qpos0 (nq,)``, ``body_parent (L,)``, ``body_pos (L, 3)``,
``body_quat (L, 4)``, ``body_jntadr (L,)``, ``body_jntnum (L,)``, ``jnt_type (nj,)``, ``jnt_qposadr (nj,)``,
``jnt_pos (nj, 3)``, ``jnt_axis (nj, 3)``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._ptr import check_span, f64_ptr, i32_ptr, i64_ptr
from ._quat import (SINCOS_MAX, _frame_point, _qmat, _qmul, _qnorm, _rotate_about, _sincos, _slide, _turn, _unit_quat,
                    _zero3)
from ._simd import LANES
from ._simd_kin import (kin_ball8, kin_ball8_origin, kin_finish8, kin_hinge8, kin_hinge8_origin, kin_slide8, kin_start8,
                        kin_start8_unit, sincos8)
from ._threads import set_chunksize
from .batch import CI_KEYS, chunk_buffers, gather_batch, next_chunk, start_chunks
from .lanes import _lane_group, lane_buffers
from .layout import LW_GPOS, LW_GROT, LW_POSES, N_STATS, view_f3, view_f4

JNT_FREE, JNT_BALL, JNT_SLIDE, JNT_HINGE = 0, 1, 2, 3  # mjtJoint


@nb.njit(cache=True, inline="always")
def _half_angles(q, qpos0, jnt_type, jnt_qposadr, sc):
    # sin and cos of every hinge's half angle (mju_axisAngle2Quat), before the walk down the tree:
    # a call to libm inside it spilled every live value of the pose chain around the call (all
    # float registers are caller-saved). `_quat._sincos`, not libm: the lanes compute the same bits
    # eight at a time (`_simd_kin.sincos8`), which libm, called one value at a time, cannot.
    _half_angles_span(q, qpos0, jnt_type, jnt_qposadr, sc, 0, jnt_type.shape[0])


@nb.njit(cache=True, inline="always")
def _half_angles_span(q, qpos0, jnt_type, jnt_qposadr, sc, j0, j1):
    # `_half_angles` of the joints j0 .. j1 - 1 only (one tree's: `check_trees`).
    for j in range(j0, j1):
        if jnt_type[j] == JNT_HINGE:
            a = jnt_qposadr[j]
            sc[j, 0], sc[j, 1] = _sincos(0.5 * (q[a] - qpos0[a]))


@nb.njit(cache=True, inline="always")
def _kinematics_world(q, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                      jnt_pos, jnt_axis, out_pos, out_rot, xquat, sc):
    # Body poses out_pos (L, 3), out_rot (L, 3, 3) of one configuration q (nq,). Scratch: xquat
    # (L, 4), sc (nj, 2). The running pose is held in locals, not in a scratch array: through
    # memory each step of the chain waited for the previous one's store (the same bits either way).
    L = out_pos.shape[0]
    _half_angles(q, qpos0, jnt_type, jnt_qposadr, sc)
    xquat[0, 0], xquat[0, 1], xquat[0, 2], xquat[0, 3] = 1.0, 0.0, 0.0, 0.0
    for i in range(3):
        out_pos[0, i] = 0.0
        for j in range(3):
            out_rot[0, i, j] = 1.0 if i == j else 0.0
    _bodies_span(q, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr, jnt_pos,
                 jnt_axis, out_pos, out_rot, xquat, sc, 1, L)


@nb.njit(cache=True, inline="always")
def _bodies_span(q, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr, jnt_pos,
                 jnt_axis, out_pos, out_rot, xquat, sc, lo, hi):
    # The poses of bodies lo .. hi - 1 (`_kinematics_world`'s walk down the tree), their parents'
    # already in out_pos, out_rot, xquat and their joints' half angles in sc: a span of whole
    # trees (MuJoCo numbers a tree's bodies contiguously, parents first) can be posed alone.
    for b in range(lo, hi):
        ja, jn = body_jntadr[b], body_jntnum[b]
        if jn == 1 and jnt_type[ja] == JNT_FREE:
            a = jnt_qposadr[ja]
            p0, p1, p2 = q[a], q[a + 1], q[a + 2]
            c0, c1, c2, c3 = _qnorm(q[a + 3], q[a + 4], q[a + 5], q[a + 6])
        else:
            p = body_parent[b]
            p0, p1, p2 = _frame_point(out_pos[p, 0], out_pos[p, 1], out_pos[p, 2], out_rot[p, 0, 0], out_rot[p, 0, 1],
                                      out_rot[p, 0, 2], out_rot[p, 1, 0], out_rot[p, 1, 1], out_rot[p, 1, 2],
                                      out_rot[p, 2, 0], out_rot[p, 2, 1], out_rot[p, 2, 2], body_pos[b, 0],
                                      body_pos[b, 1], body_pos[b, 2])
            if _unit_quat(body_quat, b):
                c0, c1, c2, c3 = xquat[p, 0], xquat[p, 1], xquat[p, 2], xquat[p, 3]
            else:
                c0, c1, c2, c3 = _qmul(xquat[p, 0], xquat[p, 1], xquat[p, 2], xquat[p, 3],
                                       body_quat[b, 0], body_quat[b, 1], body_quat[b, 2], body_quat[b, 3])
            for j in range(ja, ja + jn):
                a = jnt_qposadr[j]
                t = jnt_type[j]
                if t == JNT_SLIDE:
                    p0, p1, p2 = _slide(p0, p1, p2, c0, c1, c2, c3, jnt_axis[j, 0], jnt_axis[j, 1], jnt_axis[j, 2],
                                        q[a] - qpos0[a])
                    continue
                if t == JNT_BALL:
                    l0, l1, l2, l3 = _qnorm(q[a], q[a + 1], q[a + 2], q[a + 3])
                else:
                    s = sc[j, 0]
                    l0, l1, l2, l3 = sc[j, 1], jnt_axis[j, 0] * s, jnt_axis[j, 1] * s, jnt_axis[j, 2] * s
                if _zero3(jnt_pos, j):
                    p0, p1, p2, c0, c1, c2, c3 = _turn(p0, p1, p2, c0, c1, c2, c3, l0, l1, l2, l3)
                else:
                    p0, p1, p2, c0, c1, c2, c3 = _rotate_about(p0, p1, p2, c0, c1, c2, c3, l0, l1, l2, l3,
                                                               jnt_pos[j, 0], jnt_pos[j, 1], jnt_pos[j, 2])
        c0, c1, c2, c3 = _qnorm(c0, c1, c2, c3)
        xquat[b, 0] = c0
        xquat[b, 1] = c1
        xquat[b, 2] = c2
        xquat[b, 3] = c3
        out_pos[b, 0] = p0
        out_pos[b, 1] = p1
        out_pos[b, 2] = p2
        m = _qmat(c0, c1, c2, c3)  # written out: a loop over a tuple indexes it at run time
        out_rot[b, 0, 0], out_rot[b, 0, 1], out_rot[b, 0, 2] = m[0], m[1], m[2]
        out_rot[b, 1, 0], out_rot[b, 1, 1], out_rot[b, 1, 2] = m[3], m[4], m[5]
        out_rot[b, 2, 0], out_rot[b, 2, 1], out_rot[b, 2, 2] = m[6], m[7], m[8]


@nb.njit(cache=True)
def lanes_scratch_size(L: int, nj: int) -> int:
    """float64 of `_kinematics_lanes`' scratch per worker (a row of `step_lanes_kin`'s
    ``scratch``), ``L`` bodies, ``nj`` joints."""
    return LANES * (4 * L + 2 * nj + 11)


@nb.njit(cache=True, inline="always")
def _kinematics_lanes(qp, g0, nl, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type,
                      jnt_qposadr, jnt_pos, jnt_axis, ps, at):
    # `_kinematics_world` of the worlds g0 .. g0 + nl - 1 of qp (B, nq), one a lane, into the lanes'
    # poses ps (L, 12, LANES) (`layout.LW_POSES`; lanes past nl repeat world g0, as lanes._group
    # does). Every world has the same tree and joints, so each branch holds for all the lanes, and
    # each step runs on all of them at once (`_simd_kin.kin_start8` ...: the scalar steps' operations,
    # the same bits); what reads qpos (free and ball joints, slides, the hinges' half angles) fills
    # its block lane by lane first. Scratch at address at (`lanes_scratch_size`): xq
    # (L, 4, LANES), sc (nj, 2, LANES), the running pose st (7, LANES), a block tmp (4, LANES).
    L = body_parent.shape[0]
    nj = jnt_type.shape[0]
    R = 8 * LANES  # bytes of a row over the lanes
    xqa = at
    sca = at + 4 * R * L
    sta = sca + 2 * R * nj
    tma = sta + 7 * R
    psa = np.int64(ps.ctypes.data)
    xq = nb.carray(f64_ptr(xqa), (L, 4, LANES))
    sc = nb.carray(f64_ptr(sca), (nj, 2, LANES))
    st = nb.carray(f64_ptr(sta), (7, LANES))
    tmp = nb.carray(f64_ptr(tma), (4, LANES))
    # The hinges' half angles, every one written (into its sine's row) before the first is read
    # back as a vector: a vector load of scalar stores still in flight waits for all of them to
    # retire (no store-to-load forwarding: that load stood out in this function's profile,
    # `tests/bench/jitprof.py`). Then sin and cos in place.
    far = False
    for j in range(nj):
        if jnt_type[j] == JNT_HINGE:
            a = jnt_qposadr[j]
            for l in range(LANES):
                x = 0.5 * (qp[g0 + l if l < nl else g0, a] - qpos0[a])
                sc[j, 0, l] = x
                far |= not abs(x) <= SINCOS_MAX
    for j in range(nj):
        if jnt_type[j] == JNT_HINGE:
            sincos8(sca + 2 * R * j, sca + 2 * R * j)
    for j in range(nj if far else 0):
        if jnt_type[j] == JNT_HINGE:
            a = jnt_qposadr[j]
            for l in range(LANES):
                x = 0.5 * (qp[g0 + l if l < nl else g0, a] - qpos0[a])
                if not abs(x) <= SINCOS_MAX:
                    sc[j, 0, l], sc[j, 1, l] = np.sin(x), np.cos(x)
    for l in range(LANES):
        xq[0, 0, l], xq[0, 1, l], xq[0, 2, l], xq[0, 3, l] = 1.0, 0.0, 0.0, 0.0
        for i in range(12):
            ps[0, i, l] = 1.0 if i == 3 or i == 7 or i == 11 else 0.0
    for b in range(1, L):
        ja, jn = body_jntadr[b], body_jntnum[b]
        if jn == 1 and jnt_type[ja] == JNT_FREE:
            a = jnt_qposadr[ja]
            for l in range(LANES):
                w = g0 + l if l < nl else g0
                st[0, l], st[1, l], st[2, l] = qp[w, a], qp[w, a + 1], qp[w, a + 2]
                st[3, l], st[4, l], st[5, l], st[6, l] = _qnorm(qp[w, a + 3], qp[w, a + 4], qp[w, a + 5],
                                                                qp[w, a + 6])
        else:
            p = body_parent[b]
            if _unit_quat(body_quat, b):
                kin_start8_unit(sta, psa + 12 * R * p, xqa + 4 * R * p, body_pos[b, 0], body_pos[b, 1], body_pos[b, 2])
            else:
                kin_start8(sta, psa + 12 * R * p, xqa + 4 * R * p, body_pos[b, 0], body_pos[b, 1], body_pos[b, 2],
                           body_quat[b, 0], body_quat[b, 1], body_quat[b, 2], body_quat[b, 3])
            for j in range(ja, ja + jn):
                a = jnt_qposadr[j]
                t = jnt_type[j]
                if t == JNT_HINGE:
                    if _zero3(jnt_pos, j):
                        kin_hinge8_origin(sta, sca + 2 * R * j, jnt_axis[j, 0], jnt_axis[j, 1], jnt_axis[j, 2])
                    else:
                        kin_hinge8(sta, sca + 2 * R * j, jnt_pos[j, 0], jnt_pos[j, 1], jnt_pos[j, 2], jnt_axis[j, 0],
                                   jnt_axis[j, 1], jnt_axis[j, 2])
                elif t == JNT_BALL:
                    for l in range(LANES):
                        w = g0 + l if l < nl else g0
                        tmp[0, l], tmp[1, l], tmp[2, l], tmp[3, l] = _qnorm(qp[w, a], qp[w, a + 1], qp[w, a + 2],
                                                                            qp[w, a + 3])
                    if _zero3(jnt_pos, j):
                        kin_ball8_origin(sta, tma)
                    else:
                        kin_ball8(sta, tma, jnt_pos[j, 0], jnt_pos[j, 1], jnt_pos[j, 2])
                else:  # slide (a free joint is a body's only joint)
                    for l in range(LANES):
                        tmp[0, l] = qp[g0 + l if l < nl else g0, a] - qpos0[a]
                    kin_slide8(sta, tma, jnt_axis[j, 0], jnt_axis[j, 1], jnt_axis[j, 2])
        kin_finish8(sta, xqa + 4 * R * b, psa + 12 * R * b)


@nb.njit(cache=True, inline="always")
def _model_views(qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr, jnt_pos,
                 jnt_axis):
    # Pointer-built views of the model arrays: views of a reference-counted array shared by the
    # threads would bump its counter atomically on every world from both cores (measured before:
    # two threads many times slower than one). The index arrays are MuJoCo's own
    # int32 (`collide.mujoco._kinematics_arrays`): no conversion per call.
    L = body_parent.shape[0]
    nq = qpos0.shape[0]
    nj = jnt_type.shape[0]
    return (nb.carray(f64_ptr(np.int64(qpos0.ctypes.data)), nq),
            nb.carray(i32_ptr(np.int64(body_parent.ctypes.data)), L),
            nb.carray(f64_ptr(np.int64(body_pos.ctypes.data)), (L, 3)),
            nb.carray(f64_ptr(np.int64(body_quat.ctypes.data)), (L, 4)),
            nb.carray(i32_ptr(np.int64(body_jntadr.ctypes.data)), L),
            nb.carray(i32_ptr(np.int64(body_jntnum.ctypes.data)), L),
            nb.carray(i32_ptr(np.int64(jnt_type.ctypes.data)), nj),
            nb.carray(i32_ptr(np.int64(jnt_qposadr.ctypes.data)), nj),
            nb.carray(f64_ptr(np.int64(jnt_pos.ctypes.data)), (nj, 3)),
            nb.carray(f64_ptr(np.int64(jnt_axis.ctypes.data)), (nj, 3)))


def scratch_size(L: int, nj: int) -> int:
    """float64 of kinematics scratch per chunk of worlds (a row of `kinematics_worlds`'
    ``scratch``), ``L`` bodies, ``nj`` joints."""
    return 4 * L + 2 * nj


@nb.njit(cache=True, inline="always")
def _scratch(scratch, c, L, nj):
    # Row c of scratch: xquat (L, 4), then sc (nj, 2) (pointer-built: no reference count).
    check_span(4 * L + 2 * nj, scratch.shape[1])
    check_span(c + 1, scratch.shape[0])
    at = np.int64(scratch.ctypes.data) + 8 * scratch.shape[1] * c
    return nb.carray(f64_ptr(at), (L, 4)), nb.carray(f64_ptr(at + 32 * L), (nj, 2))


@nb.njit(cache=True, parallel=True)
def kinematics_worlds(qpos, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                      jnt_pos, jnt_axis, out_pos, out_rot, scratch):
    """Poses ``out_pos (B, L, 3)``, ``out_rot (B, L, 3, 3)`` of the configurations ``qpos (B, nq)``,
    threads over ``C = scratch.shape[0]`` chunks of worlds, ``scratch (C, scratch_size(L, nj))``.
    Every array is C-contiguous."""
    B, L = out_pos.shape[0], out_pos.shape[1]
    nq = qpos0.shape[0]
    C = scratch.shape[0]
    nj = jnt_type.shape[0]
    (q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis) = _model_views(
        qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr, jnt_pos, jnt_axis)
    qp = nb.carray(f64_ptr(np.int64(qpos.ctypes.data)), (B, nq))
    opos = nb.carray(f64_ptr(np.int64(out_pos.ctypes.data)), (B, L, 3))
    orot = nb.carray(f64_ptr(np.int64(out_rot.ctypes.data)), (B, L, 3, 3))
    chunksize = set_chunksize(1)  # one chunk an iteration (`_threads`)
    for c in nb.prange(C):
        xquat, sc = _scratch(scratch, c, L, nj)
        for w in range((B * c) // C, (B * (c + 1)) // C):
            _kinematics_world(qp[w], q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis, opos[w], orot[w],
                              xquat, sc)
    set_chunksize(chunksize)
    return 0


@nb.njit(cache=True, parallel=True)
def step_lanes_kin(qpos, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                   jnt_pos, jnt_axis, ctxs, J, LWs, LBs, scratch, world_count, world_info, chunk_info, S,
                   stats_out):
    """`lanes.step_lanes` on the poses of ``qpos (B, nq)``, each group's computed into its worker's
    workspace just before its tests (see the module docstring), a group's poses in the workspace's
    ``gpos`` and ``grot`` (`layout.LANE_WORK`) when it holds a bad one; ``scratch`` has a row of
    `lanes_scratch_size` per worker (as many rows as ``LWs``). Same result as
    `lanes.step_lanes` on `kinematics_worlds`' poses (`_kinematics_lanes`: the same bits)."""
    B = qpos.shape[0]
    nq = qpos0.shape[0]
    NB = body_parent.shape[0]
    C = ctxs.shape[0]
    (q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis) = _model_views(
        qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr, jnt_pos, jnt_axis)
    qp = nb.carray(f64_ptr(np.int64(qpos.ctypes.data)), (B, nq))
    Jv = nb.carray(i64_ptr(np.int64(J.ctypes.data)), J.shape[0])
    nw = min(start_chunks(chunk_info, C), LWs.shape[0], LBs.shape[0], scratch.shape[0])  # a workspace a worker
    chunksize = set_chunksize(1)  # one worker a thread (`_threads`)
    for wk in nb.prange(nw):
        LW, LB = lane_buffers(LWs, LBs, wk)
        check_span(lanes_scratch_size(NB, jnt_type.shape[0]), scratch.shape[1])
        check_span(wk + 1, scratch.shape[0])
        ksa = np.int64(scratch.ctypes.data) + 8 * scratch.shape[1] * wk
        st = np.zeros(N_STATS, np.int64)
        while True:
            c = next_chunk(chunk_info, C)
            if c >= C:
                break
            ctx, ci, I, F, W, sap, bp, scr, stats, info = chunk_buffers(ctxs, chunk_info, c)
            ps = view_f3(I, LW, LW_POSES)
            gpos = view_f3(I, LW, LW_GPOS)  # the group's poses, when it holds a bad one
            grot = view_f4(I, LW, LW_GROT)
            for s in range(N_STATS):
                st[s] = 0
            off = 0
            w0 = (B * c) // C
            w1 = (B * (c + 1)) // C
            for g0 in range(w0, w1, LANES):
                nl = min(LANES, w1 - g0)
                _kinematics_lanes(qp, g0, nl, q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis, ps, ksa)
                off = _lane_group(gpos, grot, 0, g0, nl, I, F, W, sap, bp, scr, stats, info, Jv, LW, LB, ctx, off,
                                  st, world_count, world_info, ci, True)
            for s in range(N_STATS):
                stats[s] = st[s]
            ci[CI_KEYS] = off
    set_chunksize(chunksize)
    return gather_batch(ctxs, world_count, chunk_info, S, stats_out)
