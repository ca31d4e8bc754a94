"""The walk of the per-step broad phase: every body pair whose AABBs may overlap, found once at its
lowest common ancestor (`_traverse`), then the static filter (`_walk`).

At each position ``n``: a flat root's statically passing pairs from bit masks (`culling._row_hits`),
body ``n`` against its descendants, then pairs of ``n``'s child subtrees: all pairs for a few
children, sweep-and-prune on one axis from ``SAP_MIN`` (any number of children). The tests among
subtrees are `culling`'s. `_traverse` stays one function, its parts written out: split into inlined
helpers, each helper's array arguments cost reference-count calls per node in this
reference-counted function (measured: a long chain's walk slower, beyond run-to-run noise).
"""

from __future__ import annotations

import numba as nb
from numba.cpython.unsafe.numbers import trailing_zeros
import numpy as np

from .culling import _body_walk, _filter, _push, _row_hits, _subtree_pair
from .layout import (H_FP, H_L, I_CHILD_START, I_CHILDREN, I_CONAFFINITY, I_CONTYPE, I_END, I_EX_OTHER, I_EX_START,
                     I_FLAT_MASK, I_FLAT_N, I_FLAT_ROOT, I_HAS_BOUNDS, I_NCHILD, I_PARENT_POS, I_SINGLE, I_WELD,
                     ST_BODY_AABB, ST_SUBTREE, view_i1)

SAP_MIN = 8  # a node with more children than this sorts them (sweep-and-prune)


@nb.njit(cache=True, _nrt=True)  # allocates: counted (see NO_NRT; a callee takes its caller's flag)
def _traverse(L, end, nchild, child_start, children, has_bounds, baabb, saabb, sap, bp, stats, filter_parent,
              baabb_t, flat_root, flat_n, flat_mask):
    """Candidate body pairs (world AABBs overlap) into ``bp``; returns their count (may exceed cap).

    ``sap`` (`sap_state`): the sweep orders of the children lists (then scratch, not used here).
    ``baabb``, ``saabb``, ``baabb_t``: the exact boxes, or the fat ones (`coherence`).
    """
    nb_ = 0
    cap = bp.shape[0]
    skip_to = 0  # the end of the last flat subtree
    bt_at = np.int64(baabb_t.ctypes.data)
    bt_n = baabb_t.shape[1]
    for n in range(L):
        if n < skip_to:
            continue
        if flat_root[n]:
            # A small subtree (a robot, a hand): its body pairs that pass the static filter, as a
            # bit mask per body made at set-up (bit i of flat_mask[a]: the pair (a, n + i)). Each
            # row of AABB tests, a against every body of the subtree, runs over baabb's columns
            # (baabb_t) into a bit mask; the static one keeps the pairs to push. No walk, no
            # sibling pairs, no call.
            for a in range(n, end[n]):
                keep = np.uint64(flat_mask[a])
                if keep == 0:
                    continue
                hits = _row_hits(bt_at, bt_n, n, a, keep)
                while hits != 0:
                    if nb_ < cap:
                        bp[nb_, 0] = a
                        bp[nb_, 1] = ~(n + np.int64(trailing_zeros(hits)))  # ~q: the static filter passed
                    nb_ += 1
                    hits &= hits - np.uint64(1)
            stats[ST_BODY_AABB] += flat_n[n]
            skip_to = end[n]
            continue
        # body n against its descendants; n + 1 is its first child, each sibling follows the
        # previous one's range
        if has_bounds[n] and end[n] > n + 1:
            # One walk over the descendants [n + 1, end[n]) (every child's subtree in turn),
            # skipping a missed subtree whole. Under the parent rule a direct child is a parent
            # pair, never reported: its subtree AABB still culls, its body is not paired.
            skip = filter_parent and n != 0
            nb_ = _body_walk(n, n + 1, end[n], skip, end, baabb, saabb, has_bounds, bp, nb_, stats)
        kc = nchild[n]
        if kc < 2:
            continue
        off = child_start[n]
        if kc <= SAP_MIN:
            for i in range(kc):
                ci = children[off + i]
                for j in range(i + 1, kc):
                    cj = children[off + j]
                    stats[ST_SUBTREE] += 1
                    if ((saabb[ci, 0] <= saabb[cj, 3]) & (saabb[cj, 0] <= saabb[ci, 3]) & (saabb[ci, 1] <= saabb[cj, 4])
                            & (saabb[cj, 1] <= saabb[ci, 4]) & (saabb[ci, 2] <= saabb[cj, 5])
                            & (saabb[cj, 2] <= saabb[ci, 5])):
                        if end[ci] == ci + 1 and end[cj] == cj + 1:  # two bodies: no call
                            if has_bounds[ci] and has_bounds[cj]:
                                nb_ = _push(bp, nb_, ci, cj)
                        else:
                            nb_ = _subtree_pair(ci, cj, end, baabb, saabb, has_bounds, bp, nb_, stats)
            continue
        # Sweep and prune on the axis of the node's largest extent. The order persists between
        # calls (sap holds it), so insertion sort is ~linear under small motion; a big reshuffle
        # (a new world in a batch, an axis change) falls back to a full sort.
        ax = 0
        best = -1.0
        for d in range(3):
            e = saabb[n, 3 + d] - saabb[n, d]
            if e > best:
                best = e
                ax = d
        swaps = 0
        limit = 16 * kc + 64
        for i in range(1, kc):
            c = sap[off + i]
            v = saabb[c, ax]
            j = i - 1
            while j >= 0 and saabb[sap[off + j], ax] > v:
                sap[off + j + 1] = sap[off + j]
                j -= 1
                swaps += 1
            sap[off + j + 1] = c
            if swaps > limit:
                break
        if swaps > limit:
            lo = np.empty(kc)
            for i in range(kc):
                lo[i] = saabb[children[off + i], ax]
            idx = np.argsort(lo)
            for i in range(kc):
                sap[off + i] = children[off + idx[i]]
        cap = bp.shape[0]
        for i in range(kc):
            ci = sap[off + i]
            hi = saabb[ci, 3 + ax]
            leaf_i = end[ci] == ci + 1
            # ci's box in locals: the stores into bp below would otherwise reload it every time
            lo0 = saabb[ci, 0]
            lo1 = saabb[ci, 1]
            lo2 = saabb[ci, 2]
            hi0 = saabb[ci, 3]
            hi1 = saabb[ci, 4]
            hi2 = saabb[ci, 5]
            ntest = 0
            for j in range(i + 1, kc):
                cj = sap[off + j]
                if saabb[cj, ax] > hi:
                    break
                ntest += 1
                hit = ((lo0 <= saabb[cj, 3]) & (saabb[cj, 0] <= hi0) & (lo1 <= saabb[cj, 4])
                       & (saabb[cj, 1] <= hi1) & (lo2 <= saabb[cj, 5]) & (saabb[cj, 2] <= hi2))
                if leaf_i and end[cj] == cj + 1:
                    # Two bodies, the common case of a wide node: no branch on the outcome (see
                    # `culling`); a body without bounds has an empty AABB, never a hit.
                    if nb_ < cap:
                        bp[nb_, 0] = ci
                        bp[nb_, 1] = cj
                    nb_ += np.int64(hit)
                elif hit:
                    nb_ = _subtree_pair(ci, cj, end, baabb, saabb, has_bounds, bp, nb_, stats)
            stats[ST_SUBTREE] += ntest
    return nb_


@nb.njit(cache=True, inline="always")
def _walk(I, W, sap, bp, stats, boxes, sboxes, cols):
    # The tree walk over the given boxes (the exact AABBs, or the fat ones; ``cols``: their columns),
    # then the static filter: the body pairs into bp, their count; when bp is too short, minus the
    # count needed.
    L = I[H_L]
    nbp = _traverse(L, view_i1(I, I, I_END), view_i1(I, I, I_NCHILD), view_i1(I, I, I_CHILD_START),
                    view_i1(I, I, I_CHILDREN), view_i1(I, I, I_HAS_BOUNDS), boxes, sboxes, sap, bp, stats,
                    I[H_FP] != 0, cols, view_i1(I, I, I_FLAT_ROOT), view_i1(I, I, I_FLAT_N), view_i1(I, I, I_FLAT_MASK))
    if nbp > bp.shape[0]:
        return -nbp
    return _filter(bp, nbp, view_i1(I, I, I_CONTYPE), view_i1(I, I, I_CONAFFINITY), view_i1(I, I, I_WELD),
                   view_i1(I, I, I_PARENT_POS), I[H_FP] != 0, view_i1(I, I, I_EX_START), view_i1(I, I, I_EX_OTHER),
                   view_i1(I, I, I_SINGLE))
