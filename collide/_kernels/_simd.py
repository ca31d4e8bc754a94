"""Lane-parallel tests written as LLVM vector IR, for the kernels' hottest loops (the kinematics'
steps, built on the same helpers: `_simd_kin`).

numba leaves vectorisation to LLVM, which turns a loop over eight lanes into vector code only
when it sees the whole pattern: a bit mask built from eight comparisons, ``m |= c << l``, comes out
as eight scalar tests, or as a vector compare followed by a shuffle-and-or reduction. Written as
one ``<8 x i1>`` comparison bitcast to ``i8``, it is the canonical form every LLVM target lowers
well (AVX-512: compares into a mask register and one ``kmov``; AVX2 and NEON: compares and a
movemask or its equivalent). The comparisons are ordered (``fcmp ole``, ``ogt``, ``olt``): the same as
numba's ``<=``, ``>``, ``<`` on floats (false on NaN), so the results are bit for bit the scalar code's.

`_py` replays a scalar helper's Python source on `_Vec` values: one source, its scalar and its
vector form, the same operations in the same order (the same bits). What breaks when misused:

- a replayed source may use arithmetic, ``abs``, `_quat.fmuladd`, ``np.sqrt``, the comparisons
  ``<=`` and ``>``, ``&`` and ``^ True`` only. A `_Mask` has no truth value of its own (every one
  is true) and a `_Vec` no ``==``: ``and``, ``or``, ``not``, ``min``, ``max``, ``==`` or an ``if``
  on a comparison give a wrong result without an error (most other operations raise when the
  kernel compiles);
- the intrinsics take raw addresses of ``(k, LANES)`` float64 blocks and check nothing: a wrong
  address or row count reads or writes the neighbouring block, or freed memory; loads and stores
  assume 8-byte alignment;
- ``LANES`` is the width of every block, defined here only: `layout`, `lanes` and `kinematics`
  take it from here.
"""

from __future__ import annotations

import types as pytypes

from llvmlite import ir
from numba.core import cgutils, types
from numba.core.dispatcher import Dispatcher
from numba.extending import intrinsic
import numpy as np

from ._quat import fmuladd

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
    of eight) ran scalar in numba, the compiler unable to tell the two blocks apart.
    """
    if not (isinstance(pq, types.Integer) and isinstance(px, types.Integer)):
        return None
    sig = types.void(pq, px)

    def codegen(context, builder, signature, args):
        aq, ax = _row_pointers(builder, args)
        # every load before the first store (the blocks may be one)
        rows = [(_load(builder, aq[i]), _load(builder, ax[i])) for i in range(6)]
        # The stores go through the same address made opaque (an empty inline asm: no instruction).
        # Seeing store(select(c, x, load p), p), LLVM's back ends emit masked stores (AVX2's
        # vmaskmovpd, slow on AMD Zen; AVX-512 and SVE have their own); opaque, the select stays
        # vminpd / vmaxpd and the store a plain one, the same bits (the twelve masked stores of
        # each merge stood out in `lanes._group`'s profile, `tests/bench/jitprof.py`).
        i64 = ir.IntType(64)
        (aw,) = _row_pointers(builder, [builder.asm(ir.FunctionType(i64, [i64]), "", "=r,0", [args[0]], False)])
        for i, (q, x) in enumerate(rows):
            take = builder.fcmp_ordered("<" if i < 3 else ">", x, q)
            builder.store(builder.select(take, x, q), aw[i], align=8)
        return context.get_dummy_value()

    return sig, codegen


# ------------------------------------------------------------------------------- kinematics
# The steps of `kinematics._kinematics_world` on (k, LANES) float64 blocks, one world a lane: the
# Python source of the scalar steps (`_quat`) replayed on LLVM vectors, so that each lane gets the
# same operations in the same order (numba compiles float arithmetic as written: no reassociation,
# no contraction into FMA; the fused multiply-adds are explicit, `_quat.fmuladd`, replayed here as
# their vector form), hence the same bits. A loop over the lanes in numba ran scalar, hardly
# faster than world by world: the compiler could not tell the blocks, all pointer-built, apart.

_V = ir.VectorType(ir.DoubleType(), LANES)


class _Vec:
    """An LLVM ``<LANES x double>`` value with Python's arithmetic operators, so that the scalar
    helpers' source (`_py`) builds vector IR when given these."""

    __slots__ = ("b", "v")

    def __init__(self, b, v):
        self.b, self.v = b, v

    def _of(self, x):
        t = self.v.type  # <LANES x double>
        return x.v if isinstance(x, _Vec) else ir.Constant(t, [float(x)] * t.count)

    def __add__(self, x):
        return _Vec(self.b, self.b.fadd(self.v, self._of(x)))

    def __radd__(self, x):
        return _Vec(self.b, self.b.fadd(self._of(x), self.v))

    def __sub__(self, x):
        return _Vec(self.b, self.b.fsub(self.v, self._of(x)))

    def __rsub__(self, x):
        return _Vec(self.b, self.b.fsub(self._of(x), self.v))

    def __mul__(self, x):
        return _Vec(self.b, self.b.fmul(self.v, self._of(x)))

    def __rmul__(self, x):
        return _Vec(self.b, self.b.fmul(self._of(x), self.v))

    def __truediv__(self, x):
        return _Vec(self.b, self.b.fdiv(self.v, self._of(x)))

    def __rtruediv__(self, x):
        return _Vec(self.b, self.b.fdiv(self._of(x), self.v))

    def __neg__(self):
        return _Vec(self.b, self.b.fneg(self.v))

    def __abs__(self):
        return _Vec(self.b, _vcall(self.b, "llvm.fabs", self.v))

    # Comparisons as numba compiles them on floats: ordered (false on NaN).
    def __le__(self, x):
        return _Mask(self.b, self.b.fcmp_ordered("<=", self.v, self._of(x)))

    def __gt__(self, x):
        return _Mask(self.b, self.b.fcmp_ordered(">", self.v, self._of(x)))


class _Mask:
    """An LLVM ``<LANES x i1>`` value (the lanes' outcomes of a comparison) with ``&`` and ``^ True``
    (logical not), so that a scalar test written with those operators builds vector IR."""

    __slots__ = ("b", "v")

    def __init__(self, b, v):
        self.b, self.v = b, v

    def __and__(self, x):
        return _Mask(self.b, self.b.and_(self.v, x.v))

    def __xor__(self, x):
        if x is not True:
            raise TypeError("_Mask ^ x: only x = True (logical not)")
        return _Mask(self.b, self.b.xor(self.v, ir.Constant(self.v.type, [1] * self.v.type.count)))

    def bits(self):
        # lane l's outcome as bit l of a uint64
        return self.b.zext(self.b.bitcast(self.v, ir.IntType(self.v.type.count)), ir.IntType(64))


def _fmuladd_vec(a, b, c):
    # `_quat.fmuladd` lane by lane: llvm.fmuladd.v8f64 (the same rounding as on scalars)
    v = next(x for x in (a, b, c) if isinstance(x, _Vec))
    t = v.v.type
    fn = cgutils.get_or_insert_function(v.b.module, ir.FunctionType(t, [t, t, t]), f"llvm.fmuladd.v{t.count}f64")
    return _Vec(v.b, v.b.call(fn, [v._of(a), v._of(b), v._of(c)]))


class _NumpyVec:
    """What `_py` gives a function in place of numpy: its ``np.sqrt`` on vectors (``llvm.sqrt``,
    correctly rounded, as numba's on scalars)."""

    @staticmethod
    def sqrt(x):
        return _Vec(x.b, _vcall(x.b, "llvm.sqrt", x.v))


class _Rows:
    """An ``(n, k)`` array's row given as vectors, read as ``A[g, k]`` (any g) by a function `_py`
    replays."""

    __slots__ = ("rows",)

    def __init__(self, rows):
        self.rows = rows

    def __getitem__(self, ix):
        return self.rows[ix[1]]


def _py(f):
    """The Python function behind the numba function ``f``, its calls to numba functions of its
    own module replaced by theirs (`_quat._rotate_about` calls `_quat._qrot`): callable on
    `_Vec` values."""
    fn = f.py_func
    env = dict(fn.__globals__)
    for k in fn.__code__.co_names:  # the names its code reads: none of these calls itself
        v = env.get(k)
        if isinstance(v, Dispatcher) and v.py_func.__module__ == fn.__module__:
            env[k] = _py(v)
        elif v is fmuladd:
            env[k] = _fmuladd_vec
        elif v is np:
            env[k] = _NumpyVec
    return pytypes.FunctionType(fn.__code__, env, fn.__name__, fn.__defaults__, fn.__closure__)


def _rows(builder, addr, n):
    # n rows (LANES,) of the float64 block at address addr (int64), as <LANES x double> pointers
    p = builder.inttoptr(addr, _V.as_pointer())
    return [builder.gep(p, [ir.Constant(ir.IntType(64), i)]) for i in range(n)]


def _get(builder, addr, n):
    return [_Vec(builder, builder.load(r, align=8)) for r in _rows(builder, addr, n)]


def _put(builder, addr, vals):
    for r, v in zip(_rows(builder, addr, len(vals)), vals):
        builder.store(v.v, r, align=8)


def _scalars(builder, addr, n):
    # the n float64 at address addr, each splat over the lanes (a static row read by every lane)
    p = builder.inttoptr(addr, ir.DoubleType().as_pointer())
    return [_splat(builder, builder.load(builder.gep(p, [ir.Constant(ir.IntType(64), i)]), align=8))
            for i in range(n)]


def _vmax(builder, a, b):
    # numba's max(a, b) on floats, lane by lane: b if b > a else a (ordered: a on NaN)
    return _Vec(builder, builder.select(builder.fcmp_ordered(">", b.v, a.v), b.v, a.v))


def _vmin(builder, a, b):
    # numba's min(a, b) on floats, lane by lane: b if b < a else a
    return _Vec(builder, builder.select(builder.fcmp_ordered("<", b.v, a.v), b.v, a.v))


def _splat(builder, x):
    i32 = ir.IntType(32)
    v = builder.insert_element(ir.Constant(_V, ir.Undefined), x, ir.Constant(i32, 0))
    return _Vec(builder, builder.shuffle_vector(v, ir.Constant(_V, ir.Undefined),
                                                ir.Constant(ir.VectorType(i32, LANES), [0] * LANES)))


def _vcall(builder, name, x):
    # the LLVM intrinsic name.v8f64 on a vector (llvm.sqrt, llvm.fabs: exact, as on scalars)
    t = x.type
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(t, [t]), f"{name}.v{t.count}f64")
    return builder.call(fn, [x])
