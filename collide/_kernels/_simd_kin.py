"""The batched kinematics' steps on LLVM vectors (`kinematics._kinematics_lanes`): `_quat`'s scalar
steps replayed on ``<LANES x double>`` values by `_simd._py` (the same operations in the same order:
the same bits as one world's `kinematics._kinematics_world`), one body's step in every lane at once.

The intrinsics take raw addresses of ``(k, LANES)`` float64 blocks and float64 scalars, and check
nothing (see `_simd`: a wrong address or row count reads or writes the neighbouring block).
"""

from __future__ import annotations

from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from ._quat import (INV_PIO2, SINCOS_MAX, _frame_point, _qmat, _qmul, _rotate_about, _sincos_reduced, _slide,
                    _turn)
from ._simd import _V, LANES, _fmuladd_vec, _get, _put, _py, _splat, _vcall, _Vec


def _qnorm_vec(builder, q0, q1, q2, q3):
    # _quat._qnorm lane by lane: its branch and its select as selects (the same bits).
    ss = _fmuladd_vec(q3, q3, _fmuladd_vec(q2, q2, _fmuladd_vec(q1, q1, q0 * q0)))
    n = _Vec(builder, _vcall(builder, "llvm.sqrt", ss.v))
    small = builder.fcmp_ordered("<", n.v, ir.Constant(_V, [1e-15] * LANES))
    far = builder.fcmp_ordered(">", _vcall(builder, "llvm.fabs", (n - 1.0).v), ir.Constant(_V, [1e-15] * LANES))
    f = _Vec(builder, builder.select(far, (1.0 / n).v, ir.Constant(_V, [1.0] * LANES)))
    return [_Vec(builder, builder.select(small, ir.Constant(_V, [one] * LANES), (q * f).v))
            for q, one in zip((q0, q1, q2, q3), (1.0, 0.0, 0.0, 0.0))]


def _codegen(body):
    # An intrinsic's code generation running body(builder, *args), returning nothing.
    def codegen(context, builder, signature, args):
        body(builder, *args)
        return context.get_dummy_value()

    return codegen


def _start(builder, st, psp, xqp, bx, by, bz, e0, e1, e2, e3):
    """st (7, LANES) = the body frame before its joints: the parent's pose (ps block (12, LANES) at
    psp, quaternion block (4, LANES) at xqp) composed with the body's pose in it."""
    P = _get(builder, psp, 12)
    Q = _get(builder, xqp, 4)
    p = _py(_frame_point)(*P, *(_splat(builder, x) for x in (bx, by, bz)))
    c = _py(_qmul)(*Q, *(_splat(builder, x) for x in (e0, e1, e2, e3)))
    _put(builder, st, list(p) + list(c))


def _start_unit(builder, st, psp, xqp, bx, by, bz):
    """`_start` for a body whose quaternion in its parent is the identity (`_quat._unit_quat`): the
    parent's quaternion as it is."""
    P = _get(builder, psp, 12)
    p = _py(_frame_point)(*P, *(_splat(builder, x) for x in (bx, by, bz)))
    _put(builder, st, list(p) + _get(builder, xqp, 4))


def _hinge_lq(builder, scj, u0, u1, u2):
    # the hinge's local quaternion from sin and cos of its half angle at scj (2, LANES), axis u
    s, c = _get(builder, scj, 2)
    u = [_splat(builder, x) for x in (u0, u1, u2)]
    # `_kinematics_world`: jnt_axis[j, i] * s
    return c, u[0] * s, u[1] * s, u[2] * s


def _hinge_origin(builder, st, scj, u0, u1, u2):
    """`_hinge` with the anchor at the frame's origin (`_quat._turn`)."""
    _put(builder, st, list(_py(_turn)(*_get(builder, st, 7), *_hinge_lq(builder, scj, u0, u1, u2))))


def _ball_origin(builder, st, lq):
    """`_ball` with the anchor at the frame's origin (`_quat._turn`)."""
    _put(builder, st, list(_py(_turn)(*_get(builder, st, 7), *_get(builder, lq, 4))))


def _hinge(builder, st, scj, jx, jy, jz, u0, u1, u2):
    """st turned by a hinge: sin and cos of its half angle at scj (2, LANES), axis u, anchor j."""
    S = _get(builder, st, 7)
    out = _py(_rotate_about)(*S, *_hinge_lq(builder, scj, u0, u1, u2), *(_splat(builder, x) for x in (jx, jy, jz)))
    _put(builder, st, list(out))


def _ball(builder, st, lq, jx, jy, jz):
    """st turned by a ball joint: its normalised quaternions at lq (4, LANES), anchor j."""
    out = _py(_rotate_about)(*_get(builder, st, 7), *_get(builder, lq, 4), *(_splat(builder, x) for x in (jx, jy, jz)))
    _put(builder, st, list(out))


def _slide_step(builder, st, dq, u0, u1, u2):
    """st moved by a slide joint: its displacements at dq (1, LANES), axis u."""
    S = _get(builder, st, 7)
    (d,) = _get(builder, dq, 1)
    out = _py(_slide)(*S, *(_splat(builder, x) for x in (u0, u1, u2)), d)
    _put(builder, st, list(out))


def _finish(builder, st, xqb, psb):
    """The body's quaternion (normalised, into the block at xqb) and pose (the ps block at psb:
    position, then the rotation row-major) from st."""
    S = _get(builder, st, 7)
    c = _qnorm_vec(builder, *S[3:])
    _put(builder, xqb, c)
    _put(builder, psb, S[:3] + list(_py(_qmat)(*c)))


def _sincos(builder, dst, src):
    """dst (2, LANES) = sin and cos of the row at src (`_quat._sincos`; a lane beyond SINCOS_MAX, or
    NaN, gets a value to be replaced by libm's: its quadrant taken as 0, never an out-of-range
    conversion). src may be dst's first row: it is read before anything is written."""
    (x,) = _get(builder, src, 1)
    k = _Vec(builder, _vcall(builder, "llvm.floor", (x * INV_PIO2 + 0.5).v))
    s, c = _py(_sincos_reduced)(x, k)
    ok = builder.fcmp_ordered("<=", _vcall(builder, "llvm.fabs", x.v), ir.Constant(_V, [SINCOS_MAX] * LANES))
    i64v = ir.VectorType(ir.IntType(64), LANES)

    def ones(n):
        return ir.Constant(i64v, [n] * LANES)

    q = builder.fptosi(builder.select(ok, k.v, ir.Constant(_V, [0.0] * LANES)), i64v)
    odd = builder.icmp_signed("!=", builder.and_(q, ones(1)), ones(0))
    # `_quat._sincos`: 1.0 - 2.0 * ((q >> 1) & 1), and with q + 1
    fs = 1.0 - 2.0 * _Vec(builder, builder.sitofp(builder.and_(builder.ashr(q, ones(1)), ones(1)), _V))
    fc = 1.0 - 2.0 * _Vec(builder, builder.sitofp(builder.and_(builder.ashr(builder.add(q, ones(1)), ones(1)),
                                                                ones(1)), _V))
    sin = (_Vec(builder, builder.select(odd, c.v, s.v)) * fs).v
    zero = builder.fcmp_ordered("==", x.v, ir.Constant(_V, [0.0] * LANES))
    _put(builder, dst, [_Vec(builder, builder.select(zero, x.v, sin)),
                        _Vec(builder, builder.select(odd, s.v, c.v)) * fc])


def _kin_sig(addrs, scalars):
    # The intrinsics' signature: addresses (integers), then float64 scalars; None (no match, a
    # typing error) for anything else.
    if all(isinstance(a, types.Integer) for a in addrs) and all(s == types.float64 for s in scalars):
        return types.void(*addrs, *scalars)
    return None


def _kin_intrinsic(sig, body):
    return (sig, _codegen(body)) if sig is not None else None


# Addresses first, then scalars; see the functions above.
@intrinsic
def kin_start8(typingctx, st, psp, xqp, bx, by, bz, e0, e1, e2, e3):
    return _kin_intrinsic(_kin_sig((st, psp, xqp), (bx, by, bz, e0, e1, e2, e3)), _start)


@intrinsic
def kin_start8_unit(typingctx, st, psp, xqp, bx, by, bz):
    return _kin_intrinsic(_kin_sig((st, psp, xqp), (bx, by, bz)), _start_unit)


@intrinsic
def kin_hinge8_origin(typingctx, st, scj, u0, u1, u2):
    return _kin_intrinsic(_kin_sig((st, scj), (u0, u1, u2)), _hinge_origin)


@intrinsic
def kin_ball8_origin(typingctx, st, lq):
    return _kin_intrinsic(_kin_sig((st, lq), ()), _ball_origin)


@intrinsic
def kin_hinge8(typingctx, st, scj, jx, jy, jz, u0, u1, u2):
    return _kin_intrinsic(_kin_sig((st, scj), (jx, jy, jz, u0, u1, u2)), _hinge)


@intrinsic
def kin_ball8(typingctx, st, lq, jx, jy, jz):
    return _kin_intrinsic(_kin_sig((st, lq), (jx, jy, jz)), _ball)


@intrinsic
def kin_slide8(typingctx, st, dq, u0, u1, u2):
    return _kin_intrinsic(_kin_sig((st, dq), (u0, u1, u2)), _slide_step)


@intrinsic
def kin_finish8(typingctx, st, xqb, psb):
    return _kin_intrinsic(_kin_sig((st, xqb, psb), ()), _finish)


@intrinsic
def sincos8(typingctx, dst, src):
    return _kin_intrinsic(_kin_sig((dst, src), ()), _sincos)
