"""Culling of the per-step broad phase: which body pairs' AABBs may overlap.

The walk (`walk._traverse`) finds every body pair once at its lowest common ancestor with the tests
here: a body against its own subtree (`_body_walk`), pairs of child subtrees (`_subtree_pair`), and
the rows of small branching subtrees' static bit masks (`_row_hits`). A subtree whose AABB misses is
skipped whole. `_sweep` makes the subtree AABBs in one reverse pass; `_filter` is the static filter
of the pairs found (the kernel form of `collide.broadphase.tables.StaticFilter.bodies`); `_scan` and
`_scan_masks` test a kept list or the static masks of a small model.

Where a loop tests pairs one after another, the pair is written and the count advanced by the
outcome, without a branch on it: in a simulation loop the outcome of each test is data that the
branch predictor, retrained by the engine's own code between steps, cannot foresee, and each
misprediction flushes the pipeline.
"""

from __future__ import annotations

import numba as nb
from numba.cpython.unsafe.numbers import leading_zeros, trailing_zeros
import numpy as np

from ._ptr import NO_NRT, f64_ptr, view_of
from .layout import ST_BODY_AABB, ST_SUBTREE

@nb.njit(cache=True, inline="always")
def _row_hits(bt_at, stride, base, a, keep):
    # The bits i of keep (the pair of column a and column base + i) whose boxes meet, the boxes the
    # columns of the (6, stride) array at address bt_at (lo x, y, z, hi x, y, z). Only the span of
    # keep's bits is tested (pairs are stored once, a < q: a row tests its later partners only),
    # a column at a time; the span's columns are the array's (its last bit is a partner). Scalars
    # in (a pointer view inside): no reference counting in `_traverse`.
    bt = view_of(f64_ptr(bt_at), (6, stride))
    l0 = bt[0, a]
    l1 = bt[1, a]
    l2 = bt[2, a]
    h0 = bt[3, a]
    h1 = bt[4, a]
    h2 = bt[5, a]
    hits = np.uint64(0)
    i = np.int64(trailing_zeros(keep))
    stop = 64 - np.int64(leading_zeros(keep))
    while i < stop:
        c = base + i
        hits |= np.uint64((bt[0, c] <= h0) & (bt[1, c] <= h1) & (bt[2, c] <= h2) & (l0 <= bt[3, c])
                          & (l1 <= bt[4, c]) & (l2 <= bt[5, c])) << np.uint64(i)
        i += 1
    return hits & keep


@nb.njit(cache=True, inline="always")
def _push(bp, nb_, x, y):
    if nb_ < bp.shape[0]:
        bp[nb_, 0] = x
        bp[nb_, 1] = y
    return nb_ + 1


@nb.njit(cache=True, inline="always")
def _body_walk(a, q, stop, skip_child, end, baabb, saabb, has_bounds, bp, nb_, stats):
    # Body a against every body of the positions [q, stop) (whole subtrees), skipping a subtree
    # whose AABB misses a's whole (q = end[q]); with skip_child, the bodies at the top of those
    # subtrees (a's direct children under the parent rule) cull but are not paired. The AABB
    # tests are written out (see _aabb_hit).
    nxt = q  # the next top-level subtree
    while q < stop:
        top = q == nxt
        if top:
            nxt = end[q]
        stats[ST_SUBTREE] += 1
        if ((baabb[a, 0] <= saabb[q, 3]) & (saabb[q, 0] <= baabb[a, 3]) & (baabb[a, 1] <= saabb[q, 4])
                & (saabb[q, 1] <= baabb[a, 4]) & (baabb[a, 2] <= saabb[q, 5]) & (saabb[q, 2] <= baabb[a, 5])):
            if has_bounds[q] and not (top and skip_child):
                hit = end[q] == q + 1  # a leaf's subtree AABB is its body AABB: just tested
                if not hit:
                    stats[ST_BODY_AABB] += 1
                    hit = (baabb[a, 0] <= baabb[q, 3] and baabb[q, 0] <= baabb[a, 3]
                           and baabb[a, 1] <= baabb[q, 4] and baabb[q, 1] <= baabb[a, 4]
                           and baabb[a, 2] <= baabb[q, 5] and baabb[q, 2] <= baabb[a, 5])
                if hit:
                    if nb_ < bp.shape[0]:
                        bp[nb_, 0] = a
                        bp[nb_, 1] = q
                    nb_ += 1
            q += 1
        else:
            q = end[q]
    return nb_


MASK_MAX = 64  # up to this many positions, the body pairs come from static bit masks (`_scan_masks`), no tree


@nb.njit(**NO_NRT)
def _subtree_pair(A, B, end, baabb, saabb, has_bounds, bp, nb_, stats):
    """Every body of subtree A against every body of subtree B (disjoint subtrees whose AABBs
    meet): down A, skipping a subtree whose AABB misses B's whole, each body with bounds walks B
    (`_body_walk`)."""
    ea = end[A]
    eb = end[B]
    a = A
    while a < ea:
        stats[ST_SUBTREE] += 1
        if ((saabb[a, 0] <= saabb[B, 3]) & (saabb[B, 0] <= saabb[a, 3]) & (saabb[a, 1] <= saabb[B, 4])
                & (saabb[B, 1] <= saabb[a, 4]) & (saabb[a, 2] <= saabb[B, 5]) & (saabb[B, 2] <= saabb[a, 5])):
            if has_bounds[a]:
                nb_ = _body_walk(a, B, eb, False, end, baabb, saabb, has_bounds, bp, nb_, stats)
            a += 1
        else:
            a = end[a]
    return nb_


# ------------------------------------------------------------------------------- one world

@nb.njit(**NO_NRT)
def _sweep(saabb, parent_pos, L):
    """Subtree AABBs: one reverse sweep over the positions, children before parents, each row of
    ``saabb`` started as its body's AABB and merged into its parent's row."""
    for x in range(L - 1, 0, -1):
        a0, a1, a2, a3, a4, a5 = saabb[x, 0], saabb[x, 1], saabb[x, 2], saabb[x, 3], saabb[x, 4], saabb[x, 5]
        q = parent_pos[x]
        a0 = min(saabb[q, 0], a0)
        a1 = min(saabb[q, 1], a1)
        a2 = min(saabb[q, 2], a2)
        a3 = max(saabb[q, 3], a3)
        a4 = max(saabb[q, 4], a4)
        a5 = max(saabb[q, 5], a5)
        saabb[q, 0] = a0
        saabb[q, 1] = a1
        saabb[q, 2] = a2
        saabb[q, 3] = a3
        saabb[q, 4] = a4
        saabb[q, 5] = a5


@nb.njit(**NO_NRT)
def _filter(bp, nbp, contype, conaffinity, weld, parent_pos, filter_parent, ex_start, ex_other, single):
    """The static filter over the traversal's ``bp[:nbp]``, compacting ``bp`` in place; returns
    the count kept. Each kept pair is written lower position first, its second as ``~y`` when
    loose (a multi-geom body whose bounds are mostly empty space, ``single < 0``)."""
    m = 0
    for t in range(nbp):
        x = bp[t, 0]
        y = bp[t, 1]
        if y < 0:
            y = ~y  # a flat root's pair: the static filter passed at set-up
        else:
            if (contype[x] & conaffinity[y]) == 0 and (contype[y] & conaffinity[x]) == 0:
                continue
            if weld[x] == weld[y]:
                continue
            if filter_parent and ((parent_pos[x] == y and y != 0) or (parent_pos[y] == x and x != 0)):
                continue
            excluded = False
            for e in range(ex_start[x], ex_start[x + 1]):
                if ex_other[e] == y:
                    excluded = True
            if excluded:
                continue
        # A multi-geom body whose bounds are mostly empty space (walls around an arena, the world's
        # scattered static geoms: single < 0, see BroadPhase) passes every body-level test; its
        # pairs go straight to its geoms' AABBs.
        # Lower position first: the OBB test is not bitwise symmetric in its two boxes, and the
        # batch's lanes test each pair in this order (a sweep may hand it reversed).
        x, y = min(x, y), max(x, y)
        bp[m, 0] = x
        bp[m, 1] = ~y if (single[x] < 0 or single[y] < 0) else y
        m += 1
    return m


@nb.njit(cache=True, inline="always")
def _scan(cl, n, baabb, bp):
    # The pairs of the kept list cl[:n] whose exact AABBs overlap, into bp (written, counted by the
    # outcome: no branch on it).
    m = 0
    for t in range(n):
        x = cl[t, 0]
        yy = cl[t, 1]
        y = yy ^ (yy >> 63)  # ~y -> y
        bp[m, 0] = x
        bp[m, 1] = yy
        m += np.int64((baabb[x, 0] <= baabb[y, 3]) & (baabb[y, 0] <= baabb[x, 3]) & (baabb[x, 1] <= baabb[y, 4])
                      & (baabb[y, 1] <= baabb[x, 4]) & (baabb[x, 2] <= baabb[y, 5]) & (baabb[y, 2] <= baabb[x, 5]))
    return m


@nb.njit(cache=True, inline="always")
def _scan_masks(smask, L, baabb_t, single, bp):
    # Up to MASK_MAX positions, the body pairs passing the static filter whose AABBs meet (the tree
    # walk and the filter of a small model, `_world`): bit y of smask[x] (`pack`) is the pair (x, y),
    # x < y; each row's box is tested against its partners' columns of the (6, L) boxes baabb_t
    # (`_row_hits`, as the flat roots' rows in `_traverse`), the pairs that meet go into bp in
    # (x, y) order (counted past its end, not written), y marked ~y when loose (a multi-geom
    # body's, ``single < 0``, as `_filter` writes it).
    bt_at = np.int64(baabb_t.ctypes.data)
    cap = bp.shape[0]
    m = 0
    for x in range(L):
        keep = np.uint64(smask[x])
        if keep == 0:
            continue
        hits = _row_hits(bt_at, L, 0, x, keep)
        lx = -np.int64(single[x] < 0)
        while hits != 0:
            y = np.int64(trailing_zeros(hits))
            hits &= hits - np.uint64(1)
            if m < cap:
                bp[m, 0] = x
                bp[m, 1] = y ^ (lx | -np.int64(single[y] < 0))  # ~y when loose
            m += 1
    return m


def sap_state(children: np.ndarray) -> np.ndarray:
    """The traversal's int64 state for ``L`` positions (``children``: ``L - 1`` ids): the children
    lists in their initial sweep order, then ``L`` of scratch (the planes' candidate positions,
    `broadphase._plane_pairs`)."""
    return np.concatenate([children, np.zeros(len(children) + 1, np.int64)]).astype(np.int64)
