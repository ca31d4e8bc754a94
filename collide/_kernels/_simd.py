"""Lane-parallel tests written as LLVM vector IR, for the kernels' hottest loops.

numba leaves vectorisation to LLVM, which turns a loop over eight lanes into vector code only
when it sees the whole pattern: a bit mask built from eight comparisons, ``m |= c << l``, comes out
as eight scalar tests, or as a vector compare followed by a shuffle-and-or reduction. Written as
one ``<8 x i1>`` comparison bitcast to ``i8``, it is the canonical form every LLVM target lowers
well (AVX-512: compares into a mask register and one ``kmov``; AVX2 and NEON: compares and a
movemask or its equivalent). The comparisons are ``fcmp ole``: the same as numba's ``<=`` on floats
(false on NaN), so the results are bit for bit the scalar code's.
"""

from __future__ import annotations

from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

LANES = 8


def _row_pointers(builder, addrs):
    # For each address (int64) of a (6, LANES) float64 block: pointers to its six rows as
    # <LANES x double> vectors.
    vec = ir.VectorType(ir.DoubleType(), LANES)
    i64 = ir.IntType(64)
    out = []
    for a in addrs:
        p = builder.inttoptr(a, vec.as_pointer())
        out.append([builder.gep(p, [ir.Constant(i64, i)]) for i in range(6)])
    return out


def _load(builder, p):
    return builder.load(p, align=8)


@intrinsic
def aabb_mask8(typingctx, px, py):
    """Bit l set when the AABBs of lane l overlap (closed intervals on every axis).

    ``px`` and ``py`` are addresses (int64) of two ``(6, 8)`` float64 blocks: lo x, lo y, lo z,
    hi x, hi y, hi z, each over the eight lanes.
    """
    if not (isinstance(px, types.Integer) and isinstance(py, types.Integer)):
        return None
    sig = types.uint64(px, py)

    def codegen(context, builder, signature, args):
        ax, ay = _row_pointers(builder, args)
        m = None
        for i in range(3):
            c = builder.and_(builder.fcmp_ordered("<=", _load(builder, ax[i]), _load(builder, ay[3 + i])),
                             builder.fcmp_ordered("<=", _load(builder, ay[i]), _load(builder, ax[3 + i])))
            m = c if m is None else builder.and_(m, c)
        return builder.zext(builder.bitcast(m, ir.IntType(LANES)), ir.IntType(64))

    return sig, codegen


@intrinsic
def aabb_merge8(typingctx, pq, px):
    """Grow the AABBs at ``pq`` by those at ``px``, lane by lane (a subtree's box by its child's).

    ``pq`` and ``px``: addresses (int64) of two ``(6, 8)`` float64 blocks as in `aabb_mask8`. Each
    lo becomes ``x if x < q else q`` and each hi ``x if x > q else q``: numba's ``min(q, x)`` and
    ``max(q, x)`` on floats, the same bits (signed zeros included). The loop it replaces (six rows
    of eight) ran scalar in numba, the compiler unable to tell the two blocks apart (64-link chain,
    batch on one thread: 1.75 -> 1.65 us a world).
    """
    if not (isinstance(pq, types.Integer) and isinstance(px, types.Integer)):
        return None
    sig = types.void(pq, px)

    def codegen(context, builder, signature, args):
        aq, ax = _row_pointers(builder, args)
        # every load before the first store (the blocks may be one)
        rows = [(_load(builder, aq[i]), _load(builder, ax[i])) for i in range(6)]
        for i, (q, x) in enumerate(rows):
            take = builder.fcmp_ordered("<" if i < 3 else ">", x, q)
            builder.store(builder.select(take, x, q), aq[i], align=8)
        return context.get_dummy_value()

    return sig, codegen
