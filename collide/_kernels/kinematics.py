"""Batched forward kinematics of MuJoCo models (``mj_kinematics``, engine_core_smooth.c, body poses
only), and the batched broad phase fed by it straight into the lanes.

`kinematics_worlds` fills pose arrays; `step_lanes_kin` computes each group of `lanes.LANES` worlds'
poses into a small buffer of its chunk (in the chunk's lane workspace) and runs `lanes._lane_group` on
them: no pose array of the
whole batch written and read back (1024 humanoid worlds: 1.7 MB), and one parallel region per call
instead of two (a second one wakes a sleeping thread). Both compute the same poses with the same
operations (`_kinematics_world`), so the fused call gives the rows of `step_lanes` on
`kinematics_worlds`' poses, bit for bit.

Model arrays (``mujoco.MjModel``'s, as contiguous float64 / int64; ``L`` bodies, ``nj`` joints):
``qpos0 (nq,)``, ``body_parent (L,)``, ``body_pos (L, 3)``, ``body_quat (L, 4)``, ``body_jntadr (L,)``,
``body_jntnum (L,)``, ``jnt_type (nj,)``, ``jnt_qposadr (nj,)``, ``jnt_pos (nj, 3)``, ``jnt_axis (nj, 3)``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._ptr import f64_ptr, i64_ptr
from .broadphase import CI_KEYS, N_STATS, chunk_buffers, gather_batch
from .lanes import J_NR, LANES, _lane_group, lane_buffers

JNT_FREE, JNT_BALL, JNT_SLIDE, JNT_HINGE = 0, 1, 2, 3  # mjtJoint


@nb.njit(cache=True, inline="always")
def _mul_quat(a, b, out):
    w = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    x = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2]
    y = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1]
    z = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]
    out[0], out[1], out[2], out[3] = w, x, y, z


@nb.njit(cache=True, inline="always")
def _rot_vec_quat(v, q, out):
    # v + 2 q_v x (q_w v + q_v x v): mju_rotVecQuat for a unit quaternion.
    t0 = q[0] * v[0] + q[2] * v[2] - q[3] * v[1]
    t1 = q[0] * v[1] + q[3] * v[0] - q[1] * v[2]
    t2 = q[0] * v[2] + q[1] * v[1] - q[2] * v[0]
    out[0] = v[0] + 2.0 * (q[2] * t2 - q[3] * t1)
    out[1] = v[1] + 2.0 * (q[3] * t0 - q[1] * t2)
    out[2] = v[2] + 2.0 * (q[1] * t1 - q[2] * t0)


@nb.njit(cache=True, inline="always")
def _normalize4(q):
    n = np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if n < 1e-15:
        q[0], q[1], q[2], q[3] = 1.0, 0.0, 0.0, 0.0
    elif abs(n - 1.0) > 1e-15:
        q[0] /= n
        q[1] /= n
        q[2] /= n
        q[3] /= n


@nb.njit(cache=True, inline="always")
def _kinematics_world(q, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                      jnt_pos, jnt_axis, out_pos, out_rot, xquat, v):
    # Body poses out_pos (L, 3), out_rot (L, 3, 3) of one configuration q (nq,). Scratch: xquat
    # (L, 4), v (21,).
    L = out_pos.shape[0]
    pos = v[0:3]
    quat = v[3:7]
    qloc = v[7:11]
    qprev = v[11:15]
    tmp = v[15:18]
    anchor = v[18:21]
    xquat[0, 0], xquat[0, 1], xquat[0, 2], xquat[0, 3] = 1.0, 0.0, 0.0, 0.0
    for i in range(3):
        out_pos[0, i] = 0.0
        for j in range(3):
            out_rot[0, i, j] = 1.0 if i == j else 0.0
    for b in range(1, L):
        ja, jn = body_jntadr[b], body_jntnum[b]
        if jn == 1 and jnt_type[ja] == JNT_FREE:
            a = jnt_qposadr[ja]
            for i in range(3):
                pos[i] = q[a + i]
            for i in range(4):
                quat[i] = q[a + 3 + i]
            _normalize4(quat)
        else:
            p = body_parent[b]
            for i in range(3):
                pos[i] = (out_pos[p, i] + out_rot[p, i, 0] * body_pos[b, 0]
                          + out_rot[p, i, 1] * body_pos[b, 1]
                          + out_rot[p, i, 2] * body_pos[b, 2])
            _mul_quat(xquat[p], body_quat[b], quat)
            for j in range(ja, ja + jn):
                a = jnt_qposadr[j]
                t = jnt_type[j]
                _rot_vec_quat(jnt_pos[j], quat, anchor)
                for i in range(3):
                    anchor[i] += pos[i]
                if t == JNT_SLIDE:
                    _rot_vec_quat(jnt_axis[j], quat, tmp)
                    d = q[a] - qpos0[a]
                    for i in range(3):
                        pos[i] += tmp[i] * d
                else:
                    if t == JNT_BALL:
                        for i in range(4):
                            qloc[i] = q[a + i]
                        _normalize4(qloc)
                    else:
                        half = 0.5 * (q[a] - qpos0[a])
                        s = np.sin(half)
                        qloc[0] = np.cos(half)
                        qloc[1] = jnt_axis[j, 0] * s
                        qloc[2] = jnt_axis[j, 1] * s
                        qloc[3] = jnt_axis[j, 2] * s
                    for i in range(4):
                        qprev[i] = quat[i]
                    _mul_quat(qprev, qloc, quat)
                    # Off-centre rotation: keep the joint anchor fixed.
                    _rot_vec_quat(jnt_pos[j], quat, tmp)
                    for i in range(3):
                        pos[i] = anchor[i] - tmp[i]
        _normalize4(quat)
        for i in range(4):
            xquat[b, i] = quat[i]
        for i in range(3):
            out_pos[b, i] = pos[i]
        q0, q1, q2, q3 = quat[0], quat[1], quat[2], quat[3]
        out_rot[b, 0, 0] = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
        out_rot[b, 1, 1] = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
        out_rot[b, 2, 2] = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
        out_rot[b, 0, 1] = 2.0 * (q1 * q2 - q0 * q3)
        out_rot[b, 0, 2] = 2.0 * (q1 * q3 + q0 * q2)
        out_rot[b, 1, 0] = 2.0 * (q1 * q2 + q0 * q3)
        out_rot[b, 1, 2] = 2.0 * (q2 * q3 - q0 * q1)
        out_rot[b, 2, 0] = 2.0 * (q1 * q3 - q0 * q2)
        out_rot[b, 2, 1] = 2.0 * (q2 * q3 + q0 * q1)


@nb.njit(cache=True, inline="always")
def _model_views(qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr, jnt_pos,
                 jnt_axis):
    # Pointer-built views of the model arrays: views of a reference-counted array shared by the
    # threads would bump its counter atomically on every world from both cores (measured before:
    # 7.5 us per humanoid world with 2 threads, 0.9 with one).
    L = body_parent.shape[0]
    nq = qpos0.shape[0]
    nj = jnt_type.shape[0]
    return (nb.carray(f64_ptr(np.int64(qpos0.ctypes.data)), nq),
            nb.carray(i64_ptr(np.int64(body_parent.ctypes.data)), L),
            nb.carray(f64_ptr(np.int64(body_pos.ctypes.data)), (L, 3)),
            nb.carray(f64_ptr(np.int64(body_quat.ctypes.data)), (L, 4)),
            nb.carray(i64_ptr(np.int64(body_jntadr.ctypes.data)), L),
            nb.carray(i64_ptr(np.int64(body_jntnum.ctypes.data)), L),
            nb.carray(i64_ptr(np.int64(jnt_type.ctypes.data)), nj),
            nb.carray(i64_ptr(np.int64(jnt_qposadr.ctypes.data)), nj),
            nb.carray(f64_ptr(np.int64(jnt_pos.ctypes.data)), (nj, 3)),
            nb.carray(f64_ptr(np.int64(jnt_axis.ctypes.data)), (nj, 3)))


def scratch_size(L: int) -> int:
    """float64 of kinematics scratch per thread (`kinematics_worlds`' rows)."""
    return 4 * L + 21


@nb.njit(cache=True, inline="always")
def _scratch(at, L):
    # xquat (L, 4) and v (21,) at address at (pointer-built: no reference count).
    return nb.carray(f64_ptr(at), (L, 4)), nb.carray(f64_ptr(at + 32 * L), 21)


@nb.njit(cache=True, parallel=True)
def kinematics_worlds(qpos, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                      jnt_pos, jnt_axis, out_pos, out_rot, scratch):
    """Poses ``out_pos (B, L, 3)``, ``out_rot (B, L, 3, 3)`` of the configurations ``qpos (B, nq)``,
    threads over ``C = scratch.shape[0]`` chunks of worlds, ``scratch (C, scratch_size(L))``. Every
    array is C-contiguous."""
    B, L = out_pos.shape[0], out_pos.shape[1]
    nq = qpos0.shape[0]
    C = scratch.shape[0]
    (q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis) = _model_views(
        qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr, jnt_pos, jnt_axis)
    qp = nb.carray(f64_ptr(np.int64(qpos.ctypes.data)), (B, nq))
    opos = nb.carray(f64_ptr(np.int64(out_pos.ctypes.data)), (B, L, 3))
    orot = nb.carray(f64_ptr(np.int64(out_rot.ctypes.data)), (B, L, 3, 3))
    for c in nb.prange(C):
        xquat, v = _scratch(np.int64(scratch.ctypes.data) + 8 * scratch.shape[1] * c, L)
        for w in range((B * c) // C, (B * (c + 1)) // C):
            _kinematics_world(qp[w], q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis, opos[w], orot[w],
                              xquat, v)
    return 0


@nb.njit(cache=True, parallel=True)
def step_lanes_kin(qpos, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                   jnt_pos, jnt_axis, ctxs, J, LWs, ko, LBs, world_count, world_info, chunk_info, S, stats_out):
    """`lanes.step_lanes` on the poses of ``qpos (B, nq)``, each group's computed into its chunk's
    workspace just before its tests (see the module docstring): each row of ``LWs`` holds
    `lanes.kin_workspace_size` float64 from column ``ko`` on. Same result as `lanes.step_lanes` on
    `kinematics_worlds`' poses."""
    B = qpos.shape[0]
    nq = qpos0.shape[0]
    NB = body_parent.shape[0]
    C = ctxs.shape[0]
    (q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis) = _model_views(
        qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr, jnt_pos, jnt_axis)
    qp = nb.carray(f64_ptr(np.int64(qpos.ctypes.data)), (B, nq))
    Jv = nb.carray(i64_ptr(np.int64(J.ctypes.data)), J.shape[0])
    NWd = (Jv[J_NR] + 63) // 64
    for c in nb.prange(C):
        ctx, ci, I, F, W, sap, bp, scr, stats, info = chunk_buffers(ctxs, chunk_info, c)
        la, LW, LB = lane_buffers(LWs, LBs, c)
        kb = la + 8 * ko
        gpos = nb.carray(f64_ptr(kb), (LANES, NB, 3))  # the group's poses
        grot = nb.carray(f64_ptr(kb + 24 * LANES * NB), (LANES, NB, 3, 3))
        xquat, v = _scratch(kb + 96 * LANES * NB, NB)
        st = np.zeros(N_STATS, np.int64)
        off = 0
        w0 = (B * c) // C
        w1 = (B * (c + 1)) // C
        for g0 in range(w0, w1, LANES):
            nl = min(LANES, w1 - g0)
            for l in range(nl):
                _kinematics_world(qp[g0 + l], q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis, gpos[l],
                                  grot[l], xquat, v)
            off = _lane_group(gpos, grot, 0, g0, nl, I, F, W, sap, bp, scr, stats, info, Jv, LW, LB, NWd, ctx, off, st,
                              world_count, world_info, ci)
        for s in range(N_STATS):
            stats[s] = st[s]
        ci[CI_KEYS] = off
    return gather_batch(ctxs, world_count, chunk_info, S, stats_out)
