"""Pair keys of the per-step broad phase: a geom pair as ``g1 << S | g2`` (``S`` bits hold any geom id,
`key_shift`), emitted into a buffer and sorted at the end of a world's step (`_sort_keys`: a bit set of
the key space where that is small, else the body-level and the plane keys each sorted on its own, then
merged).
"""

from __future__ import annotations

import numba as nb
from numba.cpython.unsafe.numbers import trailing_zeros
import numpy as np

from ._ptr import NO_NRT

@nb.njit(cache=True, inline="always")
def _in_sorted(keys, key):
    i = np.searchsorted(keys, key)
    return i < keys.shape[0] and keys[i] == key


@nb.njit(cache=True, inline="always")
def _pair_key(g1, g2, S):
    # The key of a geom pair, lower id first (scalars only: no reference counting when inlined).
    return (g1 << S) | g2 if g1 < g2 else (g2 << S) | g1


@nb.njit(cache=True, inline="always")
def _emit(keys, k, g1, g2, S):
    if k < keys.shape[0]:
        keys[k] = _pair_key(g1, g2, S)
    return k + 1


def key_shift(G: int) -> int:
    """Bits ``S`` of the second geom id in a pair key ``g1 << S | g2`` (every id < 2**S)."""
    return max(1, int(G - 1).bit_length())



def scratch_size(G: int, keys: int) -> int:
    """Length of the int64 scratch of `_sort_keys`, for ``G`` geoms and a keys buffer of ``keys``."""
    return keys + G + 1


@nb.njit(**NO_NRT)
def _sort_keys(keys, k, k4, S, G, scr):
    """Sort keys[:k] (pair keys ``g1 << S | g2``, ids < G): through a bit set of the key space when
    that is small and the keys out of order (`_sort_bits`); else the body-level keys ``[:k4]`` and
    the plane and explicit keys ``[k4:k]`` each on their own (`_sort_run`), then one merge.

    Apart, each part is mostly in order already: pairs are found in position order, which
    follows the ids in most models, and a plane's keys come in position order too; together they
    are not (22 humanoids: 89 body keys, then 137 floor keys smaller than all of them). ``scr``
    holds `scratch_size` int64.
    """
    n = keys.shape[0]
    words = ((G << S) + 63) >> 6  # every key < G << S
    if (words <= scr.shape[0] and words <= 2 * G + k and not (_ascending(keys, 0, k4) and _ascending(keys, k4, k))
            and _sort_bits(keys, k, words, scr)):
        return
    tmp = scr[:n]
    cnt = scr[n:n + G + 1]
    _sort_run(keys, 0, k4, S, G, tmp, cnt)
    _sort_run(keys, k4, k, S, G, tmp, cnt)
    if 0 < k4 < k and keys[k4 - 1] > keys[k4]:
        # Merge from the front with the first part moved aside: the write position never passes
        # the read position in the second part.
        for i in range(k4):
            tmp[i] = keys[i]
        i = 0
        j = k4
        o = 0
        while i < k4 and j < k:
            if keys[j] < tmp[i]:
                keys[o] = keys[j]
                j += 1
            else:
                keys[o] = tmp[i]
                i += 1
            o += 1
        while i < k4:
            keys[o] = tmp[i]
            i += 1
            o += 1


@nb.njit(cache=True, inline="always")
def _ascending(keys, lo, hi):
    # keys[lo:hi] in ascending order (no early exit: a pass without a branch)
    desc = 0
    for i in range(lo + 1, hi):
        desc += np.int64(keys[i] < keys[i - 1])
    return desc == 0


@nb.njit(**NO_NRT)
def _sort_bits(keys, k, words, bits):
    # Sort keys[:k] (each < 64 * words) through a bit set of the key space in bits[:words]: set each
    # key's bit, then read the set bits back in order; returns False, keys untouched, if a key
    # comes twice (the kernel's never do: each pair is found once). ~words + 2 k simple steps, no
    # compares between keys: where the key space is small (G << S bits: cube_3x3x3 832, stonehenge
    # 9,984), cheaper than the two counting passes (~2 G + 4 k) of a shuffled order.
    for w in range(words):
        bits[w] = 0
    dup = np.int64(0)
    for i in range(k):
        v = keys[i]
        w = v >> 6
        b = np.int64(1) << (v & 63)
        dup |= bits[w] & b
        bits[w] |= b
    if dup != 0:
        return False
    o = 0
    for w in range(words):
        b = np.uint64(bits[w])
        while b != 0:
            keys[o] = (w << 6) | np.int64(trailing_zeros(b))
            o += 1
            b &= b - np.uint64(1)
    return True


@nb.njit(**NO_NRT)
def _sort_run(keys, lo, hi, S, G, tmp, cnt):
    # Sort keys[lo:hi]: nothing if sorted; insertion sort when it is a few ascending runs (linear
    # on nearly sorted keys, no set-up), within a budget of moves; else, or past the budget, two
    # stable counting passes (second id, then first id: an LSD radix sort on G bins, ~2 G + 4 m
    # whatever the order). A sweep over many siblings shuffles the keys (cube_3x3x3: 85
    # keys in 49 runs), and a few runs can still hide long moves, where insertion sort alone was
    # quadratic.
    m = hi - lo
    if m < 2:
        return
    desc = 0
    for i in range(lo + 1, hi):
        if keys[i] < keys[i - 1]:
            desc += 1
    if desc == 0:
        return
    if 8 * desc <= m or m <= 16:
        budget = 4 * m + 64
        moves = 0
        for i in range(lo + 1, hi):
            v = keys[i]
            j = i - 1
            while j >= lo and keys[j] > v:
                keys[j + 1] = keys[j]
                j -= 1
            keys[j + 1] = v
            moves += i - 1 - j
            if moves > budget:
                break
        if moves <= budget:
            return
    mask = (np.int64(1) << S) - 1
    _counting_pass(keys, lo, tmp, 0, m, 0, mask, G, cnt)  # by the second id
    _counting_pass(tmp, 0, keys, lo, m, S, mask, G, cnt)  # then, stably, by the first


@nb.njit(cache=True, inline="always")
def _counting_pass(src, s0, dst, d0, m, shift, mask, G, cnt):
    # Stable scatter of src[s0:s0 + m] into dst[d0:d0 + m] by the id (key >> shift) & mask (< G).
    for d in range(G + 1):
        cnt[d] = 0
    for i in range(s0, s0 + m):
        cnt[((src[i] >> shift) & mask) + 1] += 1
    for d in range(G):
        cnt[d + 1] += cnt[d]
    for i in range(s0, s0 + m):
        v = src[i]
        d = (v >> shift) & mask
        dst[d0 + cnt[d]] = v
        cnt[d] += 1
