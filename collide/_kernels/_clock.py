"""A monotonic clock in microseconds, callable from numba code without a Python call: the timer
`collide.mujoco` gives MuJoCo (``mjcb_time``) to time its broad phase against ours.

MuJoCo's timers tick only when ``mjcb_time`` is set; a Python callable there adds its own call
(32 calls a step) to every interval it measures. `now_us` is an intrinsic calling the C
library's ``clock_gettime(CLOCK_MONOTONIC)`` on a stack buffer: no allocation, no Python object,
so a ``numba.cfunc`` wrapping it caches like any kernel (a closure over a ctypes function cannot:
numba cannot pickle it, found 2026-11-22).

What breaks when misused: only differences of its values mean anything (the origin is arbitrary).
Where `AVAILABLE` is false (not Linux, or 32-bit) the clock id or the ``timespec`` layout written
here is wrong and the values are garbage: callers check it first (`collide.mujoco._native_clock`).
The call's return code is not read (``CLOCK_MONOTONIC`` does not fail on Linux).
"""

from __future__ import annotations

import sys

from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

# CLOCK_MONOTONIC's id (time.h): 1 on Linux; other systems, and 32-bit ones (whose time_t may be
# 32 bits: the two-int64 timespec below would be wrong), are not given this clock (see
# `collide.mujoco._native_clock`).
CLOCK_MONOTONIC = 1
AVAILABLE = sys.platform.startswith("linux") and sys.maxsize > 2**32


@intrinsic
def now_us(typingctx):
    """Microseconds of ``CLOCK_MONOTONIC`` (float64)."""
    sig = types.float64()

    def codegen(context, builder, signature, args):
        i32, i64 = ir.IntType(32), ir.IntType(64)
        ts_type = ir.ArrayType(i64, 2)  # struct timespec {time_t tv_sec; long tv_nsec;} on 64-bit Linux
        fnty = ir.FunctionType(i32, [i32, ts_type.as_pointer()])
        fn = builder.module.globals.get("clock_gettime")
        if fn is None:
            fn = ir.Function(builder.module, fnty, name="clock_gettime")
        ts = cgutils.alloca_once(builder, ts_type)  # in the entry block: no growth if inlined in a loop
        builder.call(fn, [ir.Constant(i32, CLOCK_MONOTONIC), ts])
        zero = ir.Constant(i32, 0)
        sec = builder.load(builder.gep(ts, [zero, zero]))
        nsec = builder.load(builder.gep(ts, [zero, ir.Constant(i32, 1)]))
        dbl = ir.DoubleType()
        return builder.fadd(builder.fmul(builder.sitofp(sec, dbl), ir.Constant(dbl, 1e6)),
                            builder.fmul(builder.sitofp(nsec, dbl), ir.Constant(dbl, 1e-3)))

    return sig, codegen
