"""The lanes' hot tests (`lanes`): the per-world kernel's scalar tests replayed on ``<LANES x double>``
LLVM vectors (`_simd._py`), eight worlds at once, each outcome a lane bit mask.

Each is the per-world kernel's test (same operations, same order: the same bits). They take raw
addresses of ``(k, LANES)`` float64 blocks (the byte sizes below) and check nothing (see `_simd`).
"""

from __future__ import annotations

from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from ._simd import LANES, _Rows, _get, _put, _py, _scalars, _splat, _Vec, _vmax, _vmin
from .bounds import (SLACK_POS, _bounds_ok, _plane_hit_local, _pose_ok, _pose_row, aabb_slack, capsule_half, dot3,
                     plane_world)
from .layout import ROW

# Bytes of the blocks the intrinsics take by address: a pose (12, LANES), a bounds row (ROW, LANES),
# an AABB (6, LANES: lo x, y, z, hi x, y, z)
POSE_BYTES = 8 * 12 * LANES
ROW_BYTES = 8 * ROW * LANES
AABB_BYTES = 8 * 6 * LANES


@intrinsic
def bounds8(typingctx, pa, ma, pb, mb):
    """Bit l set when the bounds in lane l of the ``(ROW, LANES)`` blocks at addresses ``pa`` and
    ``pb``, inflated by ``ma``, ``mb``, overlap: `bounds._bounds_ok`'s source replayed on
    ``<LANES x double>`` vectors (`_simd._py`: the same operations in the same order, the same bits),
    its outcome one vector compare's mask. The loop over the lanes it replaced (`bounds_mask`)
    compiled to 4-wide vectors and built its mask with a shift and an or per lane (those mask
    reductions stood out in `_group`'s profile)."""
    if not (isinstance(pa, types.Integer) and isinstance(pb, types.Integer) and ma == types.float64
            and mb == types.float64):
        return None
    sig = types.uint64(pa, ma, pb, mb)

    def codegen(context, builder, signature, args):
        a, fa, b, fb = args
        ok = _py(_bounds_ok)(tuple(_get(builder, a, ROW)), _splat(builder, fa), tuple(_get(builder, b, ROW)),
                             _splat(builder, fb))
        return ok.bits()

    return sig, codegen


@intrinsic
def plane8(typingctx, psb, gp, dst):
    """dst ``(4, LANES)`` = `bounds.plane_world` of the static local plane at ``gp`` (4 float64:
    n, d) under each lane's pose in the `layout.LW_POSES` block at ``psb``: its source replayed on
    vectors (the same bits; a loop over the lanes ran scalar, four divisions a lane)."""
    if not all(isinstance(a, types.Integer) for a in (psb, gp, dst)):
        return None

    def codegen(context, builder, signature, args):
        P = _get(builder, args[0], 12)
        _put(builder, args[2], list(_py(plane_world)(*P[3:12], *P[0:3], *_scalars(builder, args[1], 4))))
        return context.get_dummy_value()

    return types.void(psb, gp, dst), codegen


def _lane_plane(builder, pa, mq):
    # the plane block (4, LANES) at pa: n0, n1, n2, d, and the limit d + mq
    n0, n1, n2, pd = _get(builder, pa, 4)
    return n0, n1, n2, pd, pd + _splat(builder, mq)


@intrinsic
def corner8(typingctx, pa, mq, box):
    """Bit l set when lane l's AABB (the ``(6, LANES)`` block at ``box``) reaches the halfspace of
    lane l's plane (block at ``pa``, inflated by ``mq``): `_corner_in` on vectors, its corner picked
    by a select per axis (numba's ``lo if n > 0 else hi``), the same outcome."""
    if not (isinstance(pa, types.Integer) and isinstance(box, types.Integer) and mq == types.float64):
        return None

    def codegen(context, builder, signature, args):
        n0, n1, n2, pd, lim = _lane_plane(builder, args[0], args[1])
        B = _get(builder, args[2], 6)
        zero = ir.Constant(ir.VectorType(ir.DoubleType(), LANES), [0.0] * LANES)
        c = [_Vec(builder, builder.select(builder.fcmp_ordered(">", n.v, zero), B[k].v, B[3 + k].v))
             for k, n in enumerate((n0, n1, n2))]
        v = _py(dot3)(n0, n1, n2, c[0], c[1], c[2])
        return (v <= lim + SLACK_POS * (abs(v) + abs(pd))).bits()

    return types.uint64(pa, mq, box), codegen


@intrinsic
def plane_hit8(typingctx, pa, mq, row):
    """Bit l set when lane l's bounds (the ``(ROW, LANES)`` block at ``row``) reach lane l's plane
    (block at ``pa``, inflated by ``mq``): `bounds._plane_hit` (`_plane_hit_local`'s source on
    vectors), the same outcome."""
    if not (isinstance(pa, types.Integer) and isinstance(row, types.Integer) and mq == types.float64):
        return None

    def codegen(context, builder, signature, args):
        n0, n1, n2, pd, lim = _lane_plane(builder, args[0], args[1])
        W = _get(builder, args[2], ROW)
        scale = abs(W[0]) + abs(W[1]) + abs(W[2]) + abs(pd)
        ok = _py(_plane_hit_local)(n0, n1, n2, lim, scale, _Rows(W), 0, _splat(builder, ir.Constant(
            ir.DoubleType(), 0.0)))
        return ok.bits()

    return types.uint64(pa, mq, row), codegen


@intrinsic
def pose_ok8(typingctx, psb):
    """Bit l set when lane l's pose in the `layout.LW_POSES` block ``(12, LANES)`` at address ``psb`` passes
    `_pose._pose_ok` (its source replayed on vectors: the same outcome)."""
    if not isinstance(psb, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        P = _get(builder, args[0], 12)
        return _py(_pose_ok)(*P[3:12], *P[0:3]).bits()

    return types.uint64(psb), codegen


@intrinsic
def place8(typingctx, psb, src, cap, m, dst, box, box2):
    """One body's (or geom's) bounds in every lane: the world rows ``(ROW, LANES)`` at address
    ``dst`` of the static local row at ``src`` (ROW float64) under the lanes' poses at ``psb`` (a
    `layout.LW_POSES` block ``(12, LANES)``), and their AABBs ``(6, LANES)`` at ``box`` and ``box2``:
    the OBB's inflated by ``m`` cut to the capsule's (static row at ``cap``: half segment, radius)
    inflated by ``m``. `bounds._pose_row`, `aabb_slack`, `capsule_half` and `dot3` replayed on
    ``<LANES x double>`` vectors (`_simd._py`), the cut as numba's ``max``/``min``: the operations
    of `bounds._world_row`, `_world_aabb` and `_cap_aabb` in one world, the same bits. The
    loops over the lanes it replaces compiled to 4-wide vectors."""
    addrs = (psb, src, cap, dst, box, box2)
    if not (all(isinstance(a, types.Integer) for a in addrs) and m == types.float64):
        return None
    sig = types.void(psb, src, cap, m, dst, box, box2)

    def codegen(context, builder, signature, args):
        pa, sa, ca, mv, da, ba, b2 = args
        P = _get(builder, pa, 12)
        R = P[3:12]
        row = _py(_pose_row)(*R, *P[0:3], tuple(_scalars(builder, sa, ROW)))
        mm = _splat(builder, mv)
        e = [row[12 + k] + mm for k in range(3)]
        tol = _py(aabb_slack)(e[0], e[1], e[2], row[0], row[1], row[2])
        C = _scalars(builder, ca, 4)
        hc = _py(capsule_half)(*R, C[0], C[1], C[2], C[3] + mm, row[0], row[1], row[2])
        lo, hi = [], []
        for i in range(3):
            h = _py(dot3)(abs(row[3 + 3 * i]), abs(row[4 + 3 * i]), abs(row[5 + 3 * i]), e[0], e[1], e[2]) + tol
            c = row[i]
            lo.append(_vmax(builder, c - h, c - hc[i]))
            hi.append(_vmin(builder, c + h, c + hc[i]))
        _put(builder, da, list(row))
        _put(builder, ba, lo + hi)
        _put(builder, b2, lo + hi)
        return context.get_dummy_value()

    return sig, codegen
