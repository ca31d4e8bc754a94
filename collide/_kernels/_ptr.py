"""Typed pointers from integer addresses, for numba kernels that view preallocated buffers.

A numba call pays for every array argument (type check, unboxing, ~0.1 us each) and, inside,
every view it takes of an array with a reference-counted allocation costs an atomic increment and
decrement (threads sharing an array contend on that counter). The per-step kernels therefore take
one small int64 *context* array of addresses and build their views with ``numba.carray`` from these
pointers: such views carry no reference count at all. The owner (`collide.broadphase.BroadPhase`)
keeps every buffer alive for as long as a context points into it.
"""

from __future__ import annotations

from numba.core import types
from numba.extending import intrinsic


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
