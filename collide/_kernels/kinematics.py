"""Batched forward kinematics of MuJoCo models (``mj_kinematics``, engine_core_smooth.c, body poses
only), and the batched broad phase fed by it straight into the lanes.

`kinematics_worlds` fills pose arrays, world by world (`_kinematics_world`); `step_lanes_kin`
computes each group of `lanes.LANES` worlds' poses straight into the lanes of its chunk's workspace
(`_kinematics_lanes`: the worlds in SIMD lanes, where the tests read them) and runs
`lanes._lane_group` on them: no pose array of the whole batch written and read back (1024 humanoid
worlds: 1.7 MB), and one parallel region per call instead of two (a second one wakes a sleeping
thread). Both compute the same poses with the same operations in the same order, so the fused call
gives the rows of `step_lanes` on `kinematics_worlds`' poses, bit for bit.

Model arrays (``mujoco.MjModel``'s, as contiguous float64 / int64; ``L`` bodies, ``nj`` joints):
``qpos0 (nq,)``, ``body_parent (L,)``, ``body_pos (L, 3)``, ``body_quat (L, 4)``, ``body_jntadr (L,)``,
``body_jntnum (L,)``, ``jnt_type (nj,)``, ``jnt_qposadr (nj,)``, ``jnt_pos (nj, 3)``, ``jnt_axis (nj, 3)``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._ptr import f64_ptr, i64_ptr
from .broadphase import CI_KEYS, N_STATS, chunk_buffers, gather_batch
from .lanes import J_NR, J_NV, LANES, _lane_group, lane_buffers, lane_poses

JNT_FREE, JNT_BALL, JNT_SLIDE, JNT_HINGE = 0, 1, 2, 3  # mjtJoint


@nb.njit(cache=True, inline="always")
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    # mju_mulQuat
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@nb.njit(cache=True, inline="always")
def _qrot(v0, v1, v2, q0, q1, q2, q3):
    # v + 2 q_v x (q_w v + q_v x v): mju_rotVecQuat for a unit quaternion.
    t0 = q0 * v0 + q2 * v2 - q3 * v1
    t1 = q0 * v1 + q3 * v0 - q1 * v2
    t2 = q0 * v2 + q1 * v1 - q2 * v0
    return (v0 + 2.0 * (q2 * t2 - q3 * t1),
            v1 + 2.0 * (q3 * t0 - q1 * t2),
            v2 + 2.0 * (q1 * t1 - q2 * t0))


@nb.njit(cache=True, inline="always")
def _qnorm(q0, q1, q2, q3):
    # mju_normalize4 (mjMINVAL = 1e-15). Whether |n - 1| exceeds 1e-15 comes out either way on
    # rounding alone, so a branch there mispredicts in about every other body: a select instead,
    # and a division by exactly 1.0, which changes no bit.
    n = np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    if n < 1e-15:
        return 1.0, 0.0, 0.0, 0.0
    f = n if abs(n - 1.0) > 1e-15 else 1.0
    return q0 / f, q1 / f, q2 / f, q3 / f


@nb.njit(cache=True, inline="always")
def _half_angles(q, qpos0, jnt_type, jnt_qposadr, sc):
    # sin and cos of every hinge's half angle (mju_axisAngle2Quat), before the walk down the tree:
    # a call to libm inside it spills every live value of the pose chain around the call (all
    # float registers are caller-saved); out here the calls have nothing to spill.
    for j in range(jnt_type.shape[0]):
        if jnt_type[j] == JNT_HINGE:
            a = jnt_qposadr[j]
            half = 0.5 * (q[a] - qpos0[a])
            sc[j, 0] = np.sin(half)
            sc[j, 1] = np.cos(half)


@nb.njit(cache=True, inline="always")
def _kinematics_world(q, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                      jnt_pos, jnt_axis, out_pos, out_rot, xquat, sc):
    # Body poses out_pos (L, 3), out_rot (L, 3, 3) of one configuration q (nq,). Scratch: xquat
    # (L, 4), sc (nj, 2). The running pose is held in locals, not in a scratch array: through
    # memory each step of the chain waited for the previous one's store (humanoid, 1024 worlds,
    # one thread: 1.2 -> 0.9 us a world with the half angles and the select in _qnorm, the same
    # bits).
    L = out_pos.shape[0]
    _half_angles(q, qpos0, jnt_type, jnt_qposadr, sc)
    xquat[0, 0], xquat[0, 1], xquat[0, 2], xquat[0, 3] = 1.0, 0.0, 0.0, 0.0
    for i in range(3):
        out_pos[0, i] = 0.0
        for j in range(3):
            out_rot[0, i, j] = 1.0 if i == j else 0.0
    for b in range(1, L):
        ja, jn = body_jntadr[b], body_jntnum[b]
        if jn == 1 and jnt_type[ja] == JNT_FREE:
            a = jnt_qposadr[ja]
            p0, p1, p2 = q[a], q[a + 1], q[a + 2]
            c0, c1, c2, c3 = _qnorm(q[a + 3], q[a + 4], q[a + 5], q[a + 6])
        else:
            p = body_parent[b]
            bx, by, bz = body_pos[b, 0], body_pos[b, 1], body_pos[b, 2]
            p0 = out_pos[p, 0] + out_rot[p, 0, 0] * bx + out_rot[p, 0, 1] * by + out_rot[p, 0, 2] * bz
            p1 = out_pos[p, 1] + out_rot[p, 1, 0] * bx + out_rot[p, 1, 1] * by + out_rot[p, 1, 2] * bz
            p2 = out_pos[p, 2] + out_rot[p, 2, 0] * bx + out_rot[p, 2, 1] * by + out_rot[p, 2, 2] * bz
            c0, c1, c2, c3 = _qmul(xquat[p, 0], xquat[p, 1], xquat[p, 2], xquat[p, 3],
                                   body_quat[b, 0], body_quat[b, 1], body_quat[b, 2], body_quat[b, 3])
            for j in range(ja, ja + jn):
                a = jnt_qposadr[j]
                t = jnt_type[j]
                jx, jy, jz = jnt_pos[j, 0], jnt_pos[j, 1], jnt_pos[j, 2]
                r0, r1, r2 = _qrot(jx, jy, jz, c0, c1, c2, c3)
                n0, n1, n2 = r0 + p0, r1 + p1, r2 + p2  # the joint's anchor in the world
                if t == JNT_SLIDE:
                    u0, u1, u2 = _qrot(jnt_axis[j, 0], jnt_axis[j, 1], jnt_axis[j, 2], c0, c1, c2, c3)
                    d = q[a] - qpos0[a]
                    p0 += u0 * d
                    p1 += u1 * d
                    p2 += u2 * d
                else:
                    if t == JNT_BALL:
                        l0, l1, l2, l3 = _qnorm(q[a], q[a + 1], q[a + 2], q[a + 3])
                    else:
                        s = sc[j, 0]
                        l0 = sc[j, 1]
                        l1 = jnt_axis[j, 0] * s
                        l2 = jnt_axis[j, 1] * s
                        l3 = jnt_axis[j, 2] * s
                    c0, c1, c2, c3 = _qmul(c0, c1, c2, c3, l0, l1, l2, l3)
                    # Off-centre rotation: keep the joint anchor fixed.
                    r0, r1, r2 = _qrot(jx, jy, jz, c0, c1, c2, c3)
                    p0, p1, p2 = n0 - r0, n1 - r1, n2 - r2
        c0, c1, c2, c3 = _qnorm(c0, c1, c2, c3)
        xquat[b, 0] = c0
        xquat[b, 1] = c1
        xquat[b, 2] = c2
        xquat[b, 3] = c3
        out_pos[b, 0] = p0
        out_pos[b, 1] = p1
        out_pos[b, 2] = p2
        out_rot[b, 0, 0] = c0 * c0 + c1 * c1 - c2 * c2 - c3 * c3
        out_rot[b, 1, 1] = c0 * c0 - c1 * c1 + c2 * c2 - c3 * c3
        out_rot[b, 2, 2] = c0 * c0 - c1 * c1 - c2 * c2 + c3 * c3
        out_rot[b, 0, 1] = 2.0 * (c1 * c2 - c0 * c3)
        out_rot[b, 0, 2] = 2.0 * (c1 * c3 + c0 * c2)
        out_rot[b, 1, 0] = 2.0 * (c1 * c2 + c0 * c3)
        out_rot[b, 1, 2] = 2.0 * (c2 * c3 - c0 * c1)
        out_rot[b, 2, 0] = 2.0 * (c1 * c3 - c0 * c2)
        out_rot[b, 2, 1] = 2.0 * (c2 * c3 + c0 * c1)


def lanes_scratch_size(L: int, nj: int) -> int:
    """float64 of `_kinematics_lanes`' scratch per chunk of worlds (a row of `step_lanes_kin`'s
    ``scratch``), ``L`` bodies, ``nj`` joints."""
    return LANES * (4 * L + 2 * nj + 7)


@nb.njit(cache=True, inline="always")
def _kinematics_lanes(qp, g0, nl, nv, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type,
                      jnt_qposadr, jnt_pos, jnt_axis, ps, at):
    # `_kinematics_world` of the worlds g0 .. g0 + nl - 1 of qp (B, nq), lane by lane into the lanes'
    # poses ps (L, 12, LANES) (`lanes.lane_poses`; lanes past nl repeat world g0, as lanes._group
    # does). Every world has the same tree and joints, so each branch holds for all the lanes, and
    # each step is a loop over them without one, which vectorises: the same operations in the same
    # order as `_kinematics_world` (the same bits), only the libm sin and cos stay scalar.
    # Scratch at address at (`lanes_scratch_size`): xq (L, 4, LANES), sc (nj, 2, LANES), the running
    # pose st (7, LANES).
    L = body_parent.shape[0]
    nj = jnt_type.shape[0]
    xq = nb.carray(f64_ptr(at), (L, 4, LANES))
    sc = nb.carray(f64_ptr(at + 32 * LANES * L), (nj, 2, LANES))
    st = nb.carray(f64_ptr(at + 32 * LANES * L + 16 * LANES * nj), (7, LANES))
    for j in range(nj):
        if jnt_type[j] == JNT_HINGE:
            a = jnt_qposadr[j]
            for l in range(nv):
                half = 0.5 * (qp[g0 + l if l < nl else g0, a] - qpos0[a])
                sc[j, 0, l] = np.sin(half)
                sc[j, 1, l] = np.cos(half)
    for l in range(nv):
        xq[0, 0, l], xq[0, 1, l], xq[0, 2, l], xq[0, 3, l] = 1.0, 0.0, 0.0, 0.0
        for i in range(12):
            ps[0, i, l] = 1.0 if i == 3 or i == 7 or i == 11 else 0.0
    for b in range(1, L):
        ja, jn = body_jntadr[b], body_jntnum[b]
        if jn == 1 and jnt_type[ja] == JNT_FREE:
            a = jnt_qposadr[ja]
            for l in range(nv):
                w = g0 + l if l < nl else g0
                st[0, l], st[1, l], st[2, l] = qp[w, a], qp[w, a + 1], qp[w, a + 2]
                st[3, l], st[4, l], st[5, l], st[6, l] = _qnorm(qp[w, a + 3], qp[w, a + 4], qp[w, a + 5],
                                                                qp[w, a + 6])
        else:
            p = body_parent[b]
            bx, by, bz = body_pos[b, 0], body_pos[b, 1], body_pos[b, 2]
            e0, e1, e2, e3 = body_quat[b, 0], body_quat[b, 1], body_quat[b, 2], body_quat[b, 3]
            for l in range(nv):
                st[0, l] = ps[p, 0, l] + ps[p, 3, l] * bx + ps[p, 4, l] * by + ps[p, 5, l] * bz
                st[1, l] = ps[p, 1, l] + ps[p, 6, l] * bx + ps[p, 7, l] * by + ps[p, 8, l] * bz
                st[2, l] = ps[p, 2, l] + ps[p, 9, l] * bx + ps[p, 10, l] * by + ps[p, 11, l] * bz
                st[3, l], st[4, l], st[5, l], st[6, l] = _qmul(xq[p, 0, l], xq[p, 1, l], xq[p, 2, l], xq[p, 3, l],
                                                               e0, e1, e2, e3)
            for j in range(ja, ja + jn):
                a = jnt_qposadr[j]
                t = jnt_type[j]
                jx, jy, jz = jnt_pos[j, 0], jnt_pos[j, 1], jnt_pos[j, 2]
                u0, u1, u2 = jnt_axis[j, 0], jnt_axis[j, 1], jnt_axis[j, 2]
                if t == JNT_SLIDE:
                    for l in range(nv):
                        d = qp[g0 + l if l < nl else g0, a] - qpos0[a]
                        v0, v1, v2 = _qrot(u0, u1, u2, st[3, l], st[4, l], st[5, l], st[6, l])
                        st[0, l] += v0 * d
                        st[1, l] += v1 * d
                        st[2, l] += v2 * d
                    continue
                for l in range(nv):
                    if t == JNT_BALL:
                        w = g0 + l if l < nl else g0
                        l0, l1, l2, l3 = _qnorm(qp[w, a], qp[w, a + 1], qp[w, a + 2], qp[w, a + 3])
                    else:
                        s = sc[j, 0, l]
                        l0, l1, l2, l3 = sc[j, 1, l], u0 * s, u1 * s, u2 * s
                    c0, c1, c2, c3 = st[3, l], st[4, l], st[5, l], st[6, l]
                    r0, r1, r2 = _qrot(jx, jy, jz, c0, c1, c2, c3)
                    n0, n1, n2 = r0 + st[0, l], r1 + st[1, l], r2 + st[2, l]
                    c0, c1, c2, c3 = _qmul(c0, c1, c2, c3, l0, l1, l2, l3)
                    r0, r1, r2 = _qrot(jx, jy, jz, c0, c1, c2, c3)
                    st[0, l], st[1, l], st[2, l] = n0 - r0, n1 - r1, n2 - r2
                    st[3, l], st[4, l], st[5, l], st[6, l] = c0, c1, c2, c3
        for l in range(nv):
            c0, c1, c2, c3 = _qnorm(st[3, l], st[4, l], st[5, l], st[6, l])
            xq[b, 0, l] = c0
            xq[b, 1, l] = c1
            xq[b, 2, l] = c2
            xq[b, 3, l] = c3
            ps[b, 0, l] = st[0, l]
            ps[b, 1, l] = st[1, l]
            ps[b, 2, l] = st[2, l]
            ps[b, 3, l] = c0 * c0 + c1 * c1 - c2 * c2 - c3 * c3
            ps[b, 4, l] = 2.0 * (c1 * c2 - c0 * c3)
            ps[b, 5, l] = 2.0 * (c1 * c3 + c0 * c2)
            ps[b, 6, l] = 2.0 * (c1 * c2 + c0 * c3)
            ps[b, 7, l] = c0 * c0 - c1 * c1 + c2 * c2 - c3 * c3
            ps[b, 8, l] = 2.0 * (c2 * c3 - c0 * c1)
            ps[b, 9, l] = 2.0 * (c1 * c3 - c0 * c2)
            ps[b, 10, l] = 2.0 * (c2 * c3 + c0 * c1)
            ps[b, 11, l] = c0 * c0 - c1 * c1 - c2 * c2 + c3 * c3


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


def scratch_size(L: int, nj: int) -> int:
    """float64 of kinematics scratch per chunk of worlds (a row of `kinematics_worlds`' and
    `step_lanes_kin`'s ``scratch``), ``L`` bodies, ``nj`` joints."""
    return 4 * L + 2 * nj


@nb.njit(cache=True, inline="always")
def _scratch(scratch, c, L, nj):
    # Row c of scratch: xquat (L, 4), then sc (nj, 2) (pointer-built: no reference count).
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
    for c in nb.prange(C):
        xquat, sc = _scratch(scratch, c, L, nj)
        for w in range((B * c) // C, (B * (c + 1)) // C):
            _kinematics_world(qp[w], q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis, opos[w], orot[w],
                              xquat, sc)
    return 0


@nb.njit(cache=True, parallel=True)
def step_lanes_kin(qpos, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                   jnt_pos, jnt_axis, ctxs, J, LWs, ko, LBs, scratch, world_count, world_info, chunk_info, S,
                   stats_out):
    """`lanes.step_lanes` on the poses of ``qpos (B, nq)``, each group's computed into its chunk's
    workspace just before its tests (see the module docstring): each row of ``LWs`` holds
    `lanes.kin_workspace_size` float64 from column ``ko`` on; ``scratch`` has a row of
    `lanes_scratch_size` per chunk (at least ``ctxs.shape[0]`` rows). Same result as
    `lanes.step_lanes` on `kinematics_worlds`' poses (`_kinematics_lanes`: the same bits)."""
    B = qpos.shape[0]
    nq = qpos0.shape[0]
    NB = body_parent.shape[0]
    C = ctxs.shape[0]
    (q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis) = _model_views(
        qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr, jnt_pos, jnt_axis)
    qp = nb.carray(f64_ptr(np.int64(qpos.ctypes.data)), (B, nq))
    Jv = nb.carray(i64_ptr(np.int64(J.ctypes.data)), J.shape[0])
    NWd = (Jv[J_NR] + 63) // 64
    nv = Jv[J_NV]  # LANES, unknown to the compiler (as in lanes._group)
    for c in nb.prange(C):
        ctx, ci, I, F, W, sap, bp, scr, stats, info = chunk_buffers(ctxs, chunk_info, c)
        la, LW, LB = lane_buffers(LWs, LBs, c)
        kb = la + 8 * ko
        gpos = nb.carray(f64_ptr(kb), (LANES, NB, 3))  # the group's poses
        grot = nb.carray(f64_ptr(kb + 24 * LANES * NB), (LANES, NB, 3, 3))
        ksa = np.int64(scratch.ctypes.data) + 8 * scratch.shape[1] * c
        ps = lane_poses(LW, NB)
        st = np.zeros(N_STATS, np.int64)
        off = 0
        w0 = (B * c) // C
        w1 = (B * (c + 1)) // C
        for g0 in range(w0, w1, LANES):
            nl = min(LANES, w1 - g0)
            _kinematics_lanes(qp, g0, nl, nv, q0, par, bpos, bquat, jadr, jnum, jtype, jqadr, jpos, jaxis, ps, ksa)
            off = _lane_group(gpos, grot, 0, g0, nl, I, F, W, sap, bp, scr, stats, info, Jv, LW, LB, NWd, ctx, off, st,
                              world_count, world_info, ci, True)
        for s in range(N_STATS):
            stats[s] = st[s]
        ci[CI_KEYS] = off
    return gather_batch(ctxs, world_count, chunk_info, S, stats_out)
