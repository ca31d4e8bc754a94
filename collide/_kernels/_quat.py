"""Quaternion steps of MuJoCo's kinematics (engine_util_spatial.c) and the sine and cosine they
need, on scalars: the one source of the world-by-world and the lanes' kinematics.

Written once: `kinematics._kinematics_world` compiles them, and `_simd` replays their Python
source on LLVM vectors (``.py_func``), the same operations in the same order lane by lane, so that
a batch's poses, and so its pairs, are one world's bit for bit. Their multiply-adds are written as
`fmuladd` (one rounding on any processor with a fused multiply-add): a fast-math flag would let
the compiler choose which product of ``a*b + c*d`` to fuse, and it chose differently in scalar and
vector code (contraction on every kernel, 2026-11-28: lanes and worlds 1e-16 apart), while an
explicit call is fused the same way in both (and took less time in `kinematics_batch`). Two
shortcuts that MuJoCo does not take, decided per joint and per body from the model (`_zero3`,
`_unit_quat`, evaluated by both kinematics alike), skip products whose outcome is known
(`_turn`).

What breaks when misused: compiled with fast-math flags, or changed without their hand-written
vector forms (`_simd_kin._qnorm_vec`, `_simd_kin._sincos` replay `_qnorm` and `_sincos`), the lanes and
the worlds differ in the last bits, and a batch's pairs may then differ from one world's at a
touching contact; a branch on a value cannot be replayed (see `_simd`). `_qrot` and `_qmat`
assume a unit quaternion: another gives a scaled matrix, not a rotation.
"""

from __future__ import annotations

from llvmlite import ir
import numba as nb
from numba.core import cgutils, types
from numba.extending import intrinsic
import numpy as np


@intrinsic
def fmuladd(typingctx, a, b, c):
    """``a * b + c`` as LLVM's ``llvm.fmuladd``: one rounding where numba compiles for a fused
    multiply-add (x86-64 with FMA3, AArch64), two elsewhere (never a slow software fma), decided
    by the target and the element type, not per expression, so scalar and vector code round alike
    (`_simd` replays it as ``llvm.fmuladd.v8f64``). A fused product is exact before its rounding, so
    an expression mixing a fused and a rounded product may leave ~1e-17 where the separate
    roundings cancelled exactly (an off-diagonal zero of `_qmat`): far inside the bounds' slack,
    and the kinematics stays within 1e-12 of ``mj_kinematics`` (a test)."""
    if not all(t == types.float64 for t in (a, b, c)):
        return None

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(d, [d, d, d]), "llvm.fmuladd.f64")
        return builder.call(fn, args)

    return types.float64(types.float64, types.float64, types.float64), codegen


@nb.njit(cache=True, inline="always")
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    # mju_mulQuat
    return (fmuladd(-a3, b3, fmuladd(-a2, b2, fmuladd(-a1, b1, a0 * b0))),
            fmuladd(-a3, b2, fmuladd(a2, b3, fmuladd(a1, b0, a0 * b1))),
            fmuladd(a3, b1, fmuladd(a2, b0, fmuladd(-a1, b3, a0 * b2))),
            fmuladd(a3, b0, fmuladd(-a2, b1, fmuladd(a1, b2, a0 * b3))))


@nb.njit(cache=True, inline="always")
def _qrot(v0, v1, v2, q0, q1, q2, q3):
    # v + 2 q_v x (q_w v + q_v x v): mju_rotVecQuat for a unit quaternion.
    t0 = fmuladd(-q3, v1, fmuladd(q2, v2, q0 * v0))
    t1 = fmuladd(-q1, v2, fmuladd(q3, v0, q0 * v1))
    t2 = fmuladd(-q2, v0, fmuladd(q1, v1, q0 * v2))
    return (fmuladd(2.0, fmuladd(-q3, t1, q2 * t2), v0),
            fmuladd(2.0, fmuladd(-q1, t2, q3 * t0), v1),
            fmuladd(2.0, fmuladd(-q2, t0, q1 * t1), v2))


@nb.njit(cache=True, inline="always")
def _qnorm(q0, q1, q2, q3):
    # mju_normalize4 (mjMINVAL = 1e-15): one division, then four products by the reciprocal, as
    # MuJoCo's (four divisions would cost the lanes' kinematics four vector divisions, among the
    # slowest instructions). Whether |n - 1| exceeds 1e-15 comes out either way on rounding
    # alone, so a branch there mispredicts in about every other body: a select instead, and a
    # product by exactly 1.0, which changes no bit. `_simd_kin._qnorm_vec` computes the same.
    n = np.sqrt(fmuladd(q3, q3, fmuladd(q2, q2, fmuladd(q1, q1, q0 * q0))))
    if n < 1e-15:
        return 1.0, 0.0, 0.0, 0.0
    f = 1.0 / n if abs(n - 1.0) > 1e-15 else 1.0
    return q0 * f, q1 * f, q2 * f, q3 * f


@nb.njit(cache=True, inline="always")
def _qmat(c0, c1, c2, c3):
    # mju_quat2Mat of a unit quaternion, row-major.
    return (fmuladd(-c3, c3, fmuladd(-c2, c2, fmuladd(c1, c1, c0 * c0))),
            2.0 * fmuladd(-c0, c3, c1 * c2),
            2.0 * fmuladd(c0, c2, c1 * c3),
            2.0 * fmuladd(c0, c3, c1 * c2),
            fmuladd(-c3, c3, fmuladd(c2, c2, fmuladd(-c1, c1, c0 * c0))),
            2.0 * fmuladd(-c0, c1, c2 * c3),
            2.0 * fmuladd(-c0, c2, c1 * c3),
            2.0 * fmuladd(c0, c1, c2 * c3),
            fmuladd(c3, c3, fmuladd(-c2, c2, fmuladd(-c1, c1, c0 * c0))))


@nb.njit(cache=True, inline="always")
def _frame_point(p0, p1, p2, r00, r01, r02, r10, r11, r12, r20, r21, r22, x, y, z):
    # p + R (x, y, z): a point given in a frame (position p, rotation R row-major) in the world.
    return (fmuladd(r02, z, fmuladd(r01, y, fmuladd(r00, x, p0))),
            fmuladd(r12, z, fmuladd(r11, y, fmuladd(r10, x, p1))),
            fmuladd(r22, z, fmuladd(r21, y, fmuladd(r20, x, p2))))


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
def _turn(p0, p1, p2, c0, c1, c2, c3, l0, l1, l2, l3):
    # `_rotate_about` with the anchor at the frame's origin (a zero jnt_pos: 264 of 462 hinges in 22
    # humanoids, all in robotis_op3 and shadow_hand): both rotations of the anchor are of a zero
    # vector, so the position stays and only the quaternion turns: for finite inputs the same values
    # (a zero's sign aside), without two of the three quaternion products. With a NaN quaternion the
    # position stays finite where the general step made it NaN; the rotation is NaN in every entry
    # either way (each entry of `_qmat` reads all four components), so the pose check refuses it.
    c0, c1, c2, c3 = _qmul(c0, c1, c2, c3, l0, l1, l2, l3)
    return p0, p1, p2, c0, c1, c2, c3


@nb.njit(cache=True, inline="always")
def _unit_quat(q, i):
    # Row i of q (n, 4) is the identity quaternion: a product by it changes no finite value (a zero's
    # sign aside; see `_turn` for NaN), so the kinematics skips it (every jointed or welded body of the
    # humanoid, 309 of the 330 bodies below the torsos' free joints in 22 humanoids).
    return q[i, 0] == 1.0 and q[i, 1] == 0.0 and q[i, 2] == 0.0 and q[i, 3] == 0.0


@nb.njit(cache=True, inline="always")
def _zero3(v, i):
    return v[i, 0] == 0.0 and v[i, 1] == 0.0 and v[i, 2] == 0.0


@nb.njit(cache=True, inline="always")
def _slide(p0, p1, p2, c0, c1, c2, c3, u0, u1, u2, d):
    # A slide joint: the frame's position moved by d along the axis u (in the frame).
    v0, v1, v2 = _qrot(u0, u1, u2, c0, c1, c2, c3)
    return fmuladd(v0, d, p0), fmuladd(v1, d, p1), fmuladd(v2, d, p2)


# sin and cos of a half angle (`kinematics._half_angles`, `_simd_kin.sincos8`): Cody-Waite reduction by
# pi/2 (Cody & Waite 1980; PIO2_1 and PIO2_2 carry 31 and 32 significant bits, so that k * PIO2_1
# and k * PIO2_2 are exact for |k| < 2**21, and |k| < 6.4e5 here), then the Taylor series on
# |r| <= pi/4, whose first omitted terms are below 1e-19 of the result: within 1 ulp of libm for
# |x| <= 100, 2 ulp up to SINCOS_MAX (a test holds them to that); sin(+-0) = +-0. Beyond
# SINCOS_MAX, and for NaN and inf, libm. One implementation for both the
# world-by-world kinematics and the lanes', so that both give the same bits; libm has no vector
# form numba can call.
PIO2_1 = 1.5707963267341256
PIO2_2 = 6.077100506303966e-11
PIO2_3 = 2.0222662487959506e-21
INV_PIO2 = 0.6366197723675814
SINCOS_MAX = 1e6
_S3, _S5, _S7, _S9, _S11, _S13, _S15, _S17 = (-1 / 6, 1 / 120, -1 / 5040, 1 / 362880, -1 / 39916800,
                                               1 / 6227020800, -1 / 1307674368000, 1 / 355687428096000)
_C2, _C4, _C6, _C8, _C10, _C12, _C14, _C16, _C18 = (-1 / 2, 1 / 24, -1 / 720, 1 / 40320, -1 / 3628800,
                                                    1 / 479001600, -1 / 87178291200, 1 / 20922789888000,
                                                    -1 / 6402373705728000)


@nb.njit(cache=True, inline="always")
def _sincos_reduced(x, k):
    # sin and cos of r = x - k pi/2, |r| <= pi/4 (k = round(x / (pi/2))).
    r = ((x - k * PIO2_1) - k * PIO2_2) - k * PIO2_3
    z = r * r
    ps = fmuladd(z, fmuladd(z, fmuladd(z, fmuladd(z, fmuladd(z, fmuladd(z, fmuladd(z, _S17, _S15), _S13), _S11),
                                                                   _S9), _S7), _S5), _S3)
    pc = fmuladd(z, fmuladd(z, fmuladd(z, fmuladd(z, fmuladd(z, fmuladd(z, fmuladd(z, fmuladd(z, _C18, _C16), _C14),
                                                                             _C12), _C10), _C8), _C6), _C4), _C2)
    s = fmuladd(r * z, ps, r)
    c = fmuladd(z, pc, 1.0)
    return s, c


@nb.njit(cache=True, inline="always")
def _sincos(x):
    """(sin x, cos x) (see ``SINCOS_MAX``)."""
    if not abs(x) <= SINCOS_MAX:
        return np.sin(x), np.cos(x)
    k = np.floor(x * INV_PIO2 + 0.5)
    s, c = _sincos_reduced(x, k)
    q = np.int64(k)
    odd = (q & 1) != 0
    fs = 1.0 - 2.0 * ((q >> 1) & 1)  # sin(r + q pi/2): s, c, -s, -c; cos: c, -s, -c, s
    fc = 1.0 - 2.0 * (((q + 1) >> 1) & 1)
    # x = -0: r + r z (...) is +0, sin(-0) is -0 (a select in the lanes)
    return x if x == 0.0 else (c if odd else s) * fs, (s if odd else c) * fc
