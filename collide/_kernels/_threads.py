"""numba's parallel chunk size, set from inside a parallel kernel, and an atomic counter: how the
batch kernels share their chunks of worlds among the threads.

The batch kernels `batch.step_batch`, `lanes.step_lanes` and `kinematics.step_lanes_kin` cut
their worlds into more chunks than threads; a ``prange`` over one worker a thread (chunk size 1:
one iteration each) takes them from a shared counter (`fetch_add`, see
`batch.start_chunks`), so that a thread that starts late or that the OS pauses takes fewer
(see `collide.BroadPhase._run_batch`). `kinematics.kinematics_worlds` runs its chunks as a plain
``prange`` (chunk size 1), which numba's OpenMP layer splits into one fixed block a thread.
Setting the chunk size around the call from Python, ``with numba.parallel_chunksize(1)``, costs
four locked Python calls a call; numba's own ``numba.set_parallel_chunksize`` overload, called in a
kernel, reaches the threading layer through ctypes pointers, and a function holding one is never
cached ("Cannot cache compiled function"). `set_chunksize` calls the threading layer's symbols
directly instead.

What breaks when misused:

- `set_chunksize` outside a ``parallel=True`` kernel: cached code calling it may be linked before
  the threading layer has registered its symbols, and then fails to load. The size is the calling
  thread's: a kernel that does not put the previous size back leaves its own to that thread's
  later parallel loops.
- `fetch_add` on anything but a live int64 that the threads touch only through it while they
  run: a freed or foreign address is overwritten; LLVM assumes an atomic's natural alignment (8
  bytes), so a misaligned address is undefined (on x86 a split lock: slow, or trapped where
  split-lock detection is on). Its ordering is ``monotonic``: the counter alone is atomic, no other memory is
  ordered by it, so it hands out indices but cannot publish data one thread writes for another.
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


@intrinsic
def fetch_add(typingctx, addr, v):
    """Atomically add ``v`` to the int64 at address ``addr``; returns the value before (int64).

    The batch kernels hand out their chunks with it (`next_chunk`): numba's OpenMP layer splits a
    ``prange`` into one contiguous block of iterations a thread whatever the chunk size (found
    2026-11-28, timestamps per chunk: with 2 threads and 8 chunks, thread 0 always ran chunks 0-3
    and thread 1 chunks 4-7), so a thread that starts late or runs slower held up every call.
    """
    if not (isinstance(addr, types.Integer) and isinstance(v, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        a, x = args
        a = builder.sext(a, i64) if a.type.width < 64 else a
        x = builder.sext(x, i64) if x.type.width < 64 else x
        ptr = builder.inttoptr(a, i64.as_pointer())
        return builder.atomic_rmw("add", ptr, x, "monotonic")

    return types.int64(addr, v), codegen
