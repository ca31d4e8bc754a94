"""numba's parallel chunk size, set from inside a parallel kernel.

Each batch kernel (`broadphase.step_batch`, `lanes.step_lanes`, `kinematics.kinematics_worlds`,
`kinematics.step_lanes_kin`) cuts its worlds into more chunks than threads and wants them handed
out one at a time (chunk size 1: a thread the OS pauses does not hold up the whole call; see
`collide.BroadPhase._run_batch`). Setting it around the call from Python, ``with
numba.parallel_chunksize(1)``, costs four locked Python calls, 12-26 us a call (AMD EPYC, 2 threads);
numba's own ``numba.set_parallel_chunksize`` overload, called in a kernel, reaches the threading
layer through ctypes pointers, and a function holding one is never cached ("Cannot cache compiled
function"). `set_chunksize` calls the threading layer's symbols directly instead.
"""

from __future__ import annotations

from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic


@intrinsic
def set_chunksize(typingctx, n):
    """``numba.set_parallel_chunksize(n)``, returning the previous size (uintp).

    Calls of the threading layer's ``get_parallel_chunksize`` / ``set_parallel_chunksize``, declared
    as numba's parfor lowering declares them (``uintp get()``, ``void set(uintp)``). Only inside a
    parallel kernel (``parallel=True``): loading its cached code starts the threading layer, which
    registers the symbols; a cached plain njit function calling this could be linked before them,
    and fail. The kernel sets the size before its ``prange`` (numba's launch reads it there) and
    puts the caller's back after it.
    """
    if not isinstance(n, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        u = context.get_value_type(types.uintp)
        get = cgutils.get_or_insert_function(builder.module, ir.FunctionType(u, []), "get_parallel_chunksize")
        put = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [u]),
                                             "set_parallel_chunksize")
        old = builder.call(get, [])
        v = args[0]  # an integer of n's width (a literal's too), as uintp
        w = v.type.width
        builder.call(put, [builder.zext(v, u) if w < u.width else builder.trunc(v, u) if w > u.width else v])
        return old

    return types.uintp(n), codegen
