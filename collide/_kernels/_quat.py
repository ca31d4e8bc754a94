"""Quaternion steps of MuJoCo's kinematics (engine_util_spatial.c), on scalars.

Written once: `kinematics._kinematics_world` compiles them, and `_simd` replays their Python
source on LLVM vectors (``.py_func``), the same operations in the same order lane by lane.
"""

from __future__ import annotations

import numba as nb
import numpy as np


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
def _qmat(c0, c1, c2, c3):
    # mju_quat2Mat of a unit quaternion, row-major.
    return (c0 * c0 + c1 * c1 - c2 * c2 - c3 * c3,
            2.0 * (c1 * c2 - c0 * c3),
            2.0 * (c1 * c3 + c0 * c2),
            2.0 * (c1 * c2 + c0 * c3),
            c0 * c0 - c1 * c1 + c2 * c2 - c3 * c3,
            2.0 * (c2 * c3 - c0 * c1),
            2.0 * (c1 * c3 - c0 * c2),
            2.0 * (c2 * c3 + c0 * c1),
            c0 * c0 - c1 * c1 - c2 * c2 + c3 * c3)


@nb.njit(cache=True, inline="always")
def _frame_point(p0, p1, p2, r00, r01, r02, r10, r11, r12, r20, r21, r22, x, y, z):
    # p + R (x, y, z): a point given in a frame (position p, rotation R row-major) in the world.
    return (p0 + r00 * x + r01 * y + r02 * z,
            p1 + r10 * x + r11 * y + r12 * z,
            p2 + r20 * x + r21 * y + r22 * z)


@nb.njit(cache=True, inline="always")
def _rotate_about(p0, p1, p2, c0, c1, c2, c3, l0, l1, l2, l3, jx, jy, jz):
    # A hinge or ball joint: the frame (p, c) turned by the local rotation l about the joint's
    # anchor (jx, jy, jz in the frame), which stays where it was: returns the new (p, c).
    r0, r1, r2 = _qrot(jx, jy, jz, c0, c1, c2, c3)
    n0, n1, n2 = r0 + p0, r1 + p1, r2 + p2
    c0, c1, c2, c3 = _qmul(c0, c1, c2, c3, l0, l1, l2, l3)
    r0, r1, r2 = _qrot(jx, jy, jz, c0, c1, c2, c3)
    return n0 - r0, n1 - r1, n2 - r2, c0, c1, c2, c3


@nb.njit(cache=True, inline="always")
def _slide(p0, p1, p2, c0, c1, c2, c3, u0, u1, u2, d):
    # A slide joint: the frame's position moved by d along the axis u (in the frame).
    v0, v1, v2 = _qrot(u0, u1, u2, c0, c1, c2, c3)
    return p0 + v0 * d, p1 + v1 * d, p2 + v2 * d
