"""The single-world entry points of the per-step broad phase: one call a step (`_world`'s stages in
`broadphase`).

One step is a call with three arguments (the two pose arrays and a *context* of buffer addresses,
see `_ptr` and `context`), or with the context's own address alone when it holds the pose arrays'
addresses too (`step_bound`: arrays that stay put, as MuJoCo's): a numba call pays for every array
argument, and views built from pointers carry no reference count. The pairs come out as ``(K, 2)``
int32 rows of an output arena the owner hands out as views (`_step`).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._ptr import NO_NRT, f64_ptr, i32_ptr, i64_ptr, view_of
from .broadphase import OK, _world
from .coherence import COH_VALID
from .keys import scratch_size
from .layout import H_G, H_KS, H_NB, N_STATS, WORK

# Context: one int64 array of buffer addresses and lengths (see `_ptr`); the owner keeps the
# buffers alive and rebuilds the context when it replaces one. C_POS, C_ROT may hold the addresses of
# pose arrays bound to it (for `step_bound`, see BroadPhase.bind); C_OUT, C_NOUT, C_OFF an output
# arena of (C_NOUT, 2) int32 rows filled from C_OFF on (see `_step`). `context` leaves these five; C_CL:
# the address of the kept body-pair list (0: no frame coherence, see ``FAT_GROW``). C_LAST, C_NLAST:
# the arena row and count of the last non-empty result (-1: none to compare with), which `_step`
# reports again as `RET_SAME` when its pairs are the same; `context` leaves them too (a zeroed row,
# as the batch's, never matches: C_NLAST 0 against K > 0).
(C_I, C_NI, C_F, C_NF, C_W, C_NW, C_SAP, C_NSAP, C_BP, C_NBP, C_KEYS, C_NKEYS, C_SCR, C_NSCR, C_STATS,
 C_INFO, C_POS, C_ROT, C_OUT, C_NOUT, C_OFF, C_CL, C_LAST, C_NLAST) = range(24)
NCTX = 24

# step() return codes below zero
RET_BAD_POSE = -1
RET_OVERFLOW = -2
RET_BAD_SHAPE = -3
# step() returns RET_SAME + K when its K > 0 pairs are the rows of the last non-empty result (C_LAST)
RET_SAME = 1 << 40


def context(I, F, W, sap, bp, keys, scr, stats, info, out=None, cl=None) -> np.ndarray:
    """The context of one world's buffers (written into ``out`` when given, for a batch row).

    ``scr`` must hold at least ``scratch_size(G, keys.size)`` entries. ``cl``, int64 of ``bp``'s
    shape, turns frame coherence on (the body-pair list kept between calls, see ``FAT_GROW``; its
    state in ``W`` is cleared here).
    """
    ctx = np.zeros(NCTX, np.int64) if out is None else out
    for arr, dt in ((I, np.int64), (F, np.float64), (W, np.float64), (sap, np.int64), (bp, np.int64),
                    (keys, np.int64), (scr, np.int64), (stats, np.int64), (info, np.int64)):
        if arr.dtype != dt or not arr.flags.c_contiguous:
            raise ValueError("context: buffers must be C-contiguous arrays of the kernel's dtypes")
    if scr.size < scratch_size(int(I[H_G]), keys.size):
        raise ValueError("context: the sort scratch is shorter than scratch_size(G, keys)")
    if cl is not None and (cl.dtype != np.int64 or not cl.flags.c_contiguous or cl.shape != bp.shape):
        raise ValueError("context: the kept body-pair list must be C-contiguous int64 of bp's shape")
    ctx[:C_POS] = (I.ctypes.data, I.size, F.ctypes.data, F.size, W.ctypes.data, W.size, sap.ctypes.data,
                   sap.size, bp.ctypes.data, bp.shape[0], keys.ctypes.data, keys.size, scr.ctypes.data, scr.size,
                   stats.ctypes.data, info.ctypes.data)
    ctx[C_CL] = 0 if cl is None else cl.ctypes.data
    # the list (if any) starts empty: the next call rebuilds it
    WORK.view(I, W, "coh")[COH_VALID] = 0.0
    return ctx


@nb.njit(cache=True, inline="always")
def _buffers(ctx):
    I = view_of(i64_ptr(ctx[C_I]), ctx[C_NI])
    F = view_of(f64_ptr(ctx[C_F]), ctx[C_NF])
    W = view_of(f64_ptr(ctx[C_W]), ctx[C_NW])
    sap = view_of(i64_ptr(ctx[C_SAP]), ctx[C_NSAP])
    bp = view_of(i64_ptr(ctx[C_BP]), (ctx[C_NBP], 2))
    scr = view_of(i64_ptr(ctx[C_SCR]), ctx[C_NSCR])
    stats = view_of(i64_ptr(ctx[C_STATS]), N_STATS)
    info = view_of(i64_ptr(ctx[C_INFO]), 4)
    return I, F, W, sap, bp, scr, stats, info


def _step(body_pos, body_rot, ctx):
    """One world, one call; returns the pair count ``K``, or `RET_BAD_POSE` / `RET_OVERFLOW` /
    `RET_BAD_SHAPE`.

    The pairs are written as ``(K, 2) int32`` rows into the output arena at ``ctx[C_OFF]``, which
    then advances by ``K`` (and ``ctx[C_LAST]``, ``ctx[C_NLAST]`` record them); where the arena has
    no room left (or ``ctx[C_NOUT]`` is 0) they are written over the keys buffer's own memory
    instead (a key of row ``i`` is read before its 8 bytes are rewritten), ``ctx[C_OFF]`` stays and
    ``ctx[C_LAST]`` becomes -1 (the caller copies them into a new arena and records them there).
    K > 0 pairs equal to the ``ctx[C_NLAST]`` rows at ``ctx[C_LAST]`` are not written again:
    ``RET_SAME + K`` is returned. ``info`` = (status, body, keys needed, body pairs needed): on
    `RET_OVERFLOW` the caller grows the buffer named there and reruns.
    """
    L = view_of(i64_ptr(ctx[C_I]), ctx[C_NI])[H_NB]
    if (body_pos.shape[0] != L or body_pos.shape[1] != 3 or body_rot.shape[0] != L or body_rot.shape[1] != 3
            or body_rot.shape[2] != 3):
        return RET_BAD_SHAPE
    return _step_impl(body_pos, body_rot, ctx)


def _step_bound(addr):
    """`_step` on the pose arrays whose addresses the context holds (``C_POS``, ``C_ROT``), the context
    given by its own address ``addr``: one integer argument, the cheapest call. An array argument
    costs more in a simulation loop: numba's unboxing allocates a reference-counting record for it
    and frees it on return (a ``malloc`` and a ``free`` a call, on allocator memory the engine's step
    left cold: a visible part of a small scene's call). The owner
    keeps the context array alive and never replaces it, and checked the pose arrays' shapes and
    dtypes when it bound them."""
    ctx = view_of(i64_ptr(addr), NCTX)
    L = view_of(i64_ptr(ctx[C_I]), ctx[C_NI])[H_NB]
    body_pos = view_of(f64_ptr(ctx[C_POS]), (L, 3))
    body_rot = view_of(f64_ptr(ctx[C_ROT]), (L, 3, 3))
    return _step_impl(body_pos, body_rot, ctx)


@nb.njit(cache=True, inline="always")
def _step_impl(body_pos, body_rot, ctx):
    I, F, W, sap, bp, scr, stats, info = _buffers(ctx)
    keys = view_of(i64_ptr(ctx[C_KEYS]), ctx[C_NKEYS])
    info[0] = OK
    coherent = ctx[C_CL] != 0
    cl = view_of(i64_ptr(ctx[C_CL] if coherent else ctx[C_BP]), (ctx[C_NBP], 2))
    k = _world(body_pos, body_rot, I, F, W, sap, bp, keys, scr, stats, info, cl, coherent)
    info[2] = k
    if k < 0:
        return RET_BAD_POSE
    if k > keys.shape[0] or info[3] > 0:
        return RET_OVERFLOW
    if k == 0:
        return 0
    S = I[H_KS]
    mask = (np.int64(1) << S) - 1
    last = ctx[C_LAST]
    if k == ctx[C_NLAST] and last >= 0:
        # The same pairs as the last non-empty result (most steps of a robot in a simulation loop,
        # few of a crowd's): the caller hands out that array again, where a new view of new rows
        # costs more than this pass (tests/bench/reuse.py, its output reuse.amd-epyc.txt). Compared
        # with the rows themselves, so a caller that wrote into its result (having made it
        # writable) gets new rows.
        prev = view_of(i32_ptr(ctx[C_OUT] + 8 * last), (k, 2))
        same = True
        for i in range(k):  # no early exit: a pass over K rows, cheaper than a branch per row
            v = keys[i]
            same &= (prev[i, 0] == (v >> S)) & (prev[i, 1] == (v & mask))
        if same:
            return RET_SAME + k
    off = ctx[C_OFF]
    if off + k <= ctx[C_NOUT]:
        # Rows handed out as views of the arena are never written again (the owner starts a new
        # arena when this one is full): the caller needs no copy.
        out = view_of(i32_ptr(ctx[C_OUT] + 8 * off), (k, 2))
        ctx[C_OFF] = off + k
        ctx[C_LAST] = off
    else:
        out = view_of(i32_ptr(ctx[C_KEYS]), (k, 2))
        ctx[C_LAST] = -1
    ctx[C_NLAST] = k
    for i in range(k):
        v = keys[i]
        out[i, 0] = v >> S
        out[i, 1] = v & mask
    return k


# One signature, compiled on first use (not at import): any other argument type (float32, a
# strided view, a list) makes the dispatcher raise TypeError instead of compiling a new
# specialisation, so the caller needs no dtype or layout checks on its fast path.
STEP_SIGNATURE = "int64(float64[:, ::1], float64[:, :, ::1], int64[::1])"
_step_dispatcher = None
_bound_entry = None


def step_function():
    """The compiled `_step` (``STEP_SIGNATURE`` only; loaded from numba's cache after the first run)."""
    global _step_dispatcher
    if _step_dispatcher is None:
        _step_dispatcher = nb.njit(STEP_SIGNATURE, **NO_NRT)(_step)
    return _step_dispatcher


def step_bound():
    """A callable ``f(addr) -> K`` running `_step_bound`: the compiled function's own entry point.

    The dispatcher checks every argument's type on each call; its single argument here is
    always the address of the owner's int64 context array (``ctx.ctypes.data``), so the entry point
    behind the check is called directly (falling back to the dispatcher if this numba does not
    expose it).
    """
    global _bound_entry
    if _bound_entry is None:
        disp = nb.njit("int64(int64)", **NO_NRT)(_step_bound)
        try:
            entry = disp.overloads[disp.signatures[0]].entry_point
        except (AttributeError, IndexError, KeyError):
            entry = None
        _bound_entry = entry if callable(entry) else disp
    return _bound_entry
