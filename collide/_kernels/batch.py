"""The batch driver of the per-step broad phase, world by world: worlds split into chunks that
numba's threads take one at a time, each chunk with its own buffers (a context row, `step.context`),
each world through `broadphase._world`; `gather_batch` turns the chunks' keys into rows
``(world, g1, g2)`` in the same call (`gather_status` only checks the chunks, for a kernel that
used the keys in its pass). The lanes (`lanes.step_lanes`) and the fused kinematics
(`kinematics.step_lanes_kin`) use the same chunks.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._ptr import check_span, f64_ptr, i64_ptr, view_of
from ._threads import fetch_add, set_chunksize
from .broadphase import OK, _world
from .layout import N_STATS
from .step import C_KEYS, C_NKEYS, C_STATS, NCTX, _buffers

# A batch chunk's summary (`step_batch`'s chunk_info rows): its key count, its first bad world (-1:
# none), the body-pair capacity a world lacked (0: none).
CI_KEYS, CI_BAD, CI_NEED = range(3)
N_CI = 3


@nb.njit(cache=True, inline="always")
def _batch_world(w, pos_w, rot_w, I, F, W, sap, bp, kp, cap, off, scr, stats, info, world_info, world_count, st,
                 so, ci):
    # World w of a batch (poses pos_w, rot_w) through `_world`, its sorted keys at offset off of
    # the chunk's keys (at address kp, capacity cap), its count and stats (into st[so:]) recorded,
    # its status in world_info[w] when bad and in its chunk's summary ci (CI_BAD, CI_NEED); returns
    # the next offset. Beyond capacity it keeps counting (on a zero-length tail) so the caller
    # learns the size.
    start = off if off < cap else cap
    keys = view_of(i64_ptr(kp + 8 * start), cap - start)
    info[0] = OK
    # No coherence between a batch's worlds: a False known only at run time, as `_step`'s flag is.
    # A literal False would make numba compile `_world` a second time, for ``Literal[bool](False)``.
    no_coherence = info[0] != OK
    kw = _world(pos_w, rot_w, I, F, W, sap, bp, keys, scr, stats, info, bp, no_coherence)
    world_count[w] = kw
    if kw < 0:
        for i in range(4):
            world_info[w, i] = info[i]
        if ci[CI_BAD] < 0:
            ci[CI_BAD] = w
    if info[3] > ci[CI_NEED]:
        ci[CI_NEED] = info[3]
    for s in range(N_STATS):
        st[so + s] += stats[s]
    return off + kw if kw > 0 else off


@nb.njit(cache=True, inline="always")
def start_chunks(chunk_info, C):
    """Before a batch kernel's parallel loop: clear the chunk counter (the row after the ``C``
    chunks' rows of ``chunk_info``, whose second entry the caller sets to the number of workers,
    one a thread) and return the number of workers.

    Each worker then takes chunks by `next_chunk` until none is left: a thread that starts late
    (woken from sleep) or runs slower (a busier core) takes fewer of them, where a fixed share
    held up the whole call (timed per chunk: every call ended long after the faster thread was
    done; see `_threads.fetch_add`). The count comes from the caller: numba's
    ``get_num_threads`` in a kernel keeps it from being cached."""
    if chunk_info.shape[0] <= C or chunk_info.shape[1] < 2:
        # without the row, the counter would be written past the array's end
        raise ValueError("chunk_info: needs a row after the chunks' (counter, workers)")
    chunk_info[C, 0] = 0
    return max(1, min(chunk_info[C, 1], C))


@nb.njit(cache=True, inline="always")
def next_chunk(chunk_info, C):
    """The next chunk not yet taken (``>= C`` once all are): see `start_chunks`."""
    return fetch_add(np.int64(chunk_info.ctypes.data) + 8 * N_CI * C, 1)


@nb.njit(cache=True, inline="always")
def chunk_buffers(ctxs, chunk_info, c):
    """Chunk c of a batch kernel: its context row, its `chunk_info` row (cleared) and its buffers
    (`_buffers`), all pointer-built."""
    check_span(NCTX * (c + 1), ctxs.size)
    check_span(N_CI * (c + 1), chunk_info.size)
    ctx = view_of(i64_ptr(np.int64(ctxs.ctypes.data) + 8 * NCTX * c), NCTX)
    ci = view_of(i64_ptr(np.int64(chunk_info.ctypes.data) + 8 * N_CI * c), N_CI)
    ci[CI_BAD] = -1
    ci[CI_NEED] = 0
    I, F, W, sap, bp, scr, stats, info = _buffers(ctx)
    return ctx, ci, I, F, W, sap, bp, scr, stats, info


@nb.njit(cache=True, parallel=True)
def step_batch(body_pos, body_rot, ctxs, world_count, world_info, chunk_info, S, stats_out):
    """Worlds split into ``C = ctxs.shape[0]`` contiguous chunks taken by numba's threads one at a
    time (`start_chunks`: ``chunk_info`` has a row more, the counter and the worker count the
    caller sets), each chunk with its own buffers (a context row; the static ``I`` and ``F`` are
    shared, read only).
    World ``w``'s sorted keys follow the previous worlds of its chunk in the chunk's keys;
    ``world_count[w]`` is its pair count (-1 with ``world_info[w]`` = (status, body, ...) on a bad
    pose; ``world_info`` is written for bad worlds only). ``chunk_info[c]`` (int64, 3) sums up chunk
    c (`CI_KEYS`: its key count, which may exceed the keys' capacity; `CI_BAD`: its first bad world
    or -1; `CI_NEED`: the body-pair capacity a world lacked, or 0), and `gather_batch` reads them
    here, in the same call, then returns its rows (``stats_out``: the chunks' stats summed): the
    caller has nothing left to do on the arrays of B rows (see `gather_batch`). ``body_pos`` and
    ``body_rot`` must be C-contiguous.

    Every view here is pointer-built (no reference count): views of a shared reference-counted
    array would bump its counter atomically on every world, from both cores (measured: two
    threads slower than one).
    """
    B = body_pos.shape[0]
    L = body_pos.shape[1]
    C = ctxs.shape[0]
    pos_all = view_of(f64_ptr(np.int64(body_pos.ctypes.data)), (B, L, 3))
    rot_all = view_of(f64_ptr(np.int64(body_rot.ctypes.data)), (B, L, 3, 3))
    nw = start_chunks(chunk_info, C)
    chunksize = set_chunksize(1)  # one worker a thread (`_threads`)
    for _ in nb.prange(nw):
        st = np.zeros(2 * N_STATS, np.int64)
        while True:
            c = next_chunk(chunk_info, C)
            if c >= C:
                break
            ctx, ci, I, F, W, sap, bp, scr, stats, info = chunk_buffers(ctxs, chunk_info, c)
            cap = ctx[C_NKEYS]
            for s in range(N_STATS):
                st[N_STATS + s] = 0
            off = 0
            for w in range((B * c) // C, (B * (c + 1)) // C):
                off = _batch_world(w, pos_all[w], rot_all[w], I, F, W, sap, bp, ctx[C_KEYS], cap, off, scr, stats,
                                   info, world_info, world_count, st, N_STATS, ci)
            for s in range(N_STATS):
                stats[s] = st[N_STATS + s]
            ci[CI_KEYS] = off
    set_chunksize(chunksize)
    return gather_batch(ctxs, world_count, chunk_info, S, stats_out)


@nb.njit(cache=True)
def gather_batch(ctxs, world_count, chunk_info, S, stats):
    """At the end of a batch kernel (`step_batch`, `lanes.step_lanes`, `kinematics.step_lanes_kin`), in
    its call: rows ``(world, g1, g2)`` int32 from the chunks' keys, world by world, and ``stats``
    (N_STATS,) = the chunks' stats summed; ``(0, 3)`` rows when a chunk holds a bad world or ran out
    of room (the caller reads ``chunk_info`` then).

    In the parallel kernels' own call rather than the caller's: the first numpy operation after a
    batch is slow, the Python and numpy code having left the caches. One thread: a parallel region
    of its own costs more than it saves, its waiting thread having gone to sleep."""
    B = world_count.shape[0]
    C = ctxs.shape[0]
    if not _chunks_ok(ctxs, chunk_info):
        return np.empty((0, 3), np.int32)
    mask = (np.int64(1) << S) - 1
    K = 0
    for c in range(C):
        K += chunk_info[c, CI_KEYS]
    _sum_stats(ctxs, stats)
    out = np.empty((K, 3), np.int32)
    r = 0
    for c in range(C):
        keys = view_of(i64_ptr(ctxs[c, C_KEYS]), ctxs[c, C_NKEYS])
        i = 0
        for w in range((B * c) // C, (B * (c + 1)) // C):
            for _ in range(world_count[w]):
                out[r, 0] = w
                out[r, 1] = keys[i] >> S
                out[r, 2] = keys[i] & mask
                r += 1
                i += 1
    return out


@nb.njit(cache=True)
def gather_status(ctxs, chunk_info, stats):
    """`gather_batch` for a batch kernel that consumed its keys in its pass (`check_lanes.check_lanes_kin`):
    ``stats`` (N_STATS,) = the chunks' stats summed, and ``(1,)`` int64, or ``(0,)`` when a chunk
    holds a bad world or ran out of room (the caller reads ``chunk_info`` then, as after
    `gather_batch`'s empty rows)."""
    if not _chunks_ok(ctxs, chunk_info):
        return np.zeros(0, np.int64)
    _sum_stats(ctxs, stats)
    return np.ones(1, np.int64)


@nb.njit(cache=True, inline="always")
def _chunks_ok(ctxs, chunk_info):
    # No chunk holds a bad world or ran out of room (`gather_batch`, `gather_status`).
    for c in range(ctxs.shape[0]):
        if chunk_info[c, CI_BAD] >= 0 or chunk_info[c, CI_NEED] > 0 or chunk_info[c, CI_KEYS] > ctxs[c, C_NKEYS]:
            return False
    return True


@nb.njit(cache=True, inline="always")
def _sum_stats(ctxs, stats):
    # stats (N_STATS,) = the chunks' stats summed (`gather_batch`, `gather_status`).
    for s in range(N_STATS):
        stats[s] = 0
    for c in range(ctxs.shape[0]):
        cs = view_of(i64_ptr(ctxs[c, C_STATS]), N_STATS)
        for s in range(N_STATS):
            stats[s] += cs[s]
