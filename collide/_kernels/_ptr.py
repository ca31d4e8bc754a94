"""Typed pointers from integer addresses, and array views on them, for numba kernels that view
preallocated buffers.

A numba call pays for every array argument (a type check, unboxing) and, inside, every view it
takes of an array with a reference-counted allocation costs an atomic increment and decrement
(threads sharing an array contend on that counter). The per-step kernels therefore take one small
int64 *context* array of addresses and build their views from these pointers (``numba.carray``, or
`view_of` in functions compiled without reference counting): such views carry no reference count.

Nothing here is checked (but for `check_span` in the checked mode), and misuse corrupts silently:

- a view, or a context holding an address, that outlives its buffer reads and writes freed
  memory: no reference keeps the buffer alive, so its owner (`collide.broadphase.BroadPhase`)
  holds every buffer for as long as a context points into it and rebuilds the context when it
  replaces one;
- the address must be that of a C-contiguous buffer of the pointer's dtype: `view_of` gives C
  strides, and `f64_ptr` on int64 data reinterprets its bits;
- a shape or an offset past the buffer's end reads or overwrites whatever follows it (numba
  checks no index by default).
"""

from __future__ import annotations

import numba as nb
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

from .._checked import CHECKED


# The per-step functions are compiled without numba's reference counting: in them an array value
# costs nothing when copied or dropped, where numba emits a call to its runtime for each (~50 a step
# in `_world` and its callees, every one on the null record of a view made from a pointer, which
# LLVM cannot see through: `_ptr.view_of`). They allocate nothing; the walk's `_traverse` does (its
# sweep's full sort), and keeps the counting (stated: a function called from one compiled without it
# is compiled without it too, unless its own decorator says otherwise). The gain, in a loop after
# mj_step, was largest on the humanoid, small on the robots.
NO_NRT = dict(cache=True, _nrt=False)


@nb.njit(cache=True, inline="always")
def check_span(end, size):
    """In the checked mode (`collide._checked`): raise IndexError unless ``0 <= end <= size``, the
    end of the views carved out of a buffer of ``size`` items against that size. Compiled away
    otherwise (``CHECKED`` is a constant frozen into the kernel)."""
    if CHECKED:
        if end < 0 or end > size:
            raise IndexError("collide (checked mode): views carved out of a buffer reach past its end")


def _pointer_cast(dtype):
    @intrinsic
    def cast(typingctx, addr):
        if not isinstance(addr, types.Integer):
            return None
        sig = types.CPointer(dtype)(addr)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(types.CPointer(dtype)))

        return sig, codegen

    return cast


f64_ptr = _pointer_cast(types.float64)
i64_ptr = _pointer_cast(types.int64)
i32_ptr = _pointer_cast(types.int32)
i8_ptr = _pointer_cast(types.int8)
bool_ptr = _pointer_cast(types.boolean)


@intrinsic
def view_of(typingctx, ptr, shape):
    """The C-contiguous array of ``shape`` (an integer or a tuple of integers) at the typed pointer
    ``ptr`` (`f64_ptr`, `i64_ptr`, `i32_ptr`): what ``numba.carray(ptr, shape)`` makes (no copy, no
    reference-counted allocation behind it), as one inline step.

    Unlike ``carray`` (a compiled function returning an array) it is allowed in functions compiled
    without numba's reference counting (``_nrt=False``), where no array value costs an increment
    and a decrement: the per-step kernel's views and their passing around made dozens of calls a
    step to numba's reference-count functions, all on null records (see `_ptr.NO_NRT`).
    """
    if not isinstance(ptr, types.CPointer):
        return None
    if isinstance(shape, types.Integer):
        ndim = 1
    elif (isinstance(shape, types.BaseTuple) and len(shape) > 0
          and all(isinstance(t, types.Integer) for t in shape)):
        ndim = len(shape)
    else:
        return None
    tup = isinstance(shape, types.BaseTuple)
    aryty = types.Array(ptr.dtype, ndim, "C")
    sig = aryty(ptr, shape)

    def codegen(context, builder, signature, args):
        intp = context.get_value_type(types.intp)
        p, sh = args
        dims = cgutils.unpack_tuple(builder, sh, ndim) if tup else [sh]
        dims = [context.cast(builder, d, t, types.intp) for d, t in zip(dims, list(shape) if tup else [shape])]
        itemsize = context.get_abi_sizeof(context.get_data_type(ptr.dtype))
        strides = []
        acc = ir.Constant(intp, itemsize)
        for d in reversed(dims):
            strides.append(acc)
            acc = builder.mul(acc, d)
        strides.reverse()
        ary = make_array(aryty)(context, builder)
        populate_array(ary, data=p, shape=dims, strides=strides, itemsize=ir.Constant(intp, itemsize), meminfo=None)
        return ary._getvalue()

    return sig, codegen


@intrinsic
def borrow(typingctx, arr):
    """The array ``arr`` again without its reference count (no meminfo): a borrowed view.

    Every array value numba copies or drops costs an atomic increment and decrement of its
    allocation's counter (calls into its runtime); per-pair code that passes tens of table views
    around (tuples, inlined helpers) pays it on each, and threads sharing the tables take turns
    on the counters' cache lines. A view of a borrowed array carries a null record, which the
    runtime skips (as `view_of`'s views do). It must not outlive ``arr``: a kernel borrows its
    own arguments, which its caller holds for the call (`collide._kernels.check.check_worlds`).
    """
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, signature, args):
        src = make_array(arr)(context, builder, value=args[0])
        out = make_array(arr)(context, builder)
        populate_array(out, data=src.data, shape=cgutils.unpack_tuple(builder, src.shape),
                       strides=cgutils.unpack_tuple(builder, src.strides), itemsize=src.itemsize, meminfo=None)
        return out._getvalue()

    return arr(arr), codegen
