"""numba kernels of the per-step broad phase: flat arrays in, sorted geom-pair keys out.

Layout (built by `collide.broadphase.BroadPhase` from an `Articulation`, see `pack`): bodies are
addressed by depth-first *position* ``p`` (every subtree is the range ``[p, end[p])``), geoms by
their ids. When the world has several solid geoms, each is a leaf of its own at positions 1..V
(posed by body 0, with the world's rules), so static scenery is culled geom by geom at the root.
A bounds record ("row", `layout.ROW`) is 19 float64: OBB centre (3), OBB rotation (9, row-major,
columns are the box axes), OBB half extents (3), sphere centre (3), sphere radius (1). Each row also
has a capsule (half segment (3), radius (1)) centred on its OBB centre: a body's or geom's world
AABB is its OBB's cut to its capsule's (`_cap_aabb`).

The static model travels as two flat arrays (``I`` int64 with a header of counts and the field
table, ``F`` float64) and the workspace as one (``W`` float64), every field of each declared once
in `layout` (`INT`, `FLT`, `WORK`); one step is one call of `step`'s entry points (a batch:
`batch`, `lanes`). Each stage takes the views it needs by slot (`layout.view_i1` ...: no copy).
The stages' parts live by concept: `bounds` (rows and their tests), `walk` (the walk down the
tree), `culling` (the tests among subtrees, the sweep, the filter), `coherence` (the
body pairs kept between calls) and `keys` (pair keys and their sort); this module holds the stages.

One step, for one world (`_world`):
1. validate each body's pose (finite, proper orthonormal rotation: one combined test) and move
   its local bounds to the world (one rotation per body; no point is touched); the geoms of bodies
   with several geoms follow on first use (a single-geom body's bounds *are* its geom's, inflated);
2. subtree AABBs by one reverse sweep over the positions (each body's AABB of its world OBB and
   capsule, merged into its parent's): the tree is a one-level bounding hierarchy, never boxes of boxes;
3. every body pair exactly once, at its lowest common ancestor ``n``: body ``n`` against its own
   subtree (one walk over its descendants; under the parent rule a direct child's subtree AABB
   culls but the child is not paired), and each pair of ``n``'s child subtrees: all pairs for a
   few children, sweep-and-prune on one axis from ``SAP_MIN``; a subtree whose AABB misses is
   skipped whole (``q = end[q]``). A small branching subtree (a robot, a hand: ``flat_root``)
   instead tests its statically passing body pairs, bit masks made at set-up, a row at a time.
   Up to ``MASK_MAX`` (64) positions (a robot, a hand, a small scene) there is no tree at all:
   every body pair that passes the static filter is a bit of a mask made at set-up, and each
   body's row of AABB tests runs over the boxes' columns into a bit mask (`_scan_masks`; in a
   simulation loop it took less time than the walk on the small MuJoCo models, about the same on
   wonik_allegro).
   Tests whose outcome is data keep no branch on it where they can (the pair is written, the
   count advanced by the outcome): in a simulation loop the engine retrains the branch predictor
   between steps, and every misprediction flushes the pipeline. Surviving body pairs go to a
   buffer: no deep call chain on the hot path (in the walk, compiled with numba's reference
   counting, each call with array arguments pays it, even inlined: the hottest tests are written
   out);
4. body pair -> static filter -> sphere and OBB separating-axis tests (15 axes, Ericson 2005,
   *Real-Time Collision Detection* §4.4.1), 64 body pairs at a time with every axis evaluated
   (`_pairs_mask`) ->
   geom pairs, the same tests one by one on the geoms' bounds;
Steps 2-3 and the static filter are skipped while the body pairs kept from earlier calls stand:
with frame coherence (single-world calls), each body's AABB is checked against its fat box and,
when every one is inside, only the kept pairs' AABBs are tested (``FAT_GROW``; above ``MASK_MAX``
positions only: below, the masks' scan costs less than keeping the list);
5. planes (halfspaces) down the tree, the static filter of every (plane, body) pair precomputed,
   a multi-geom body's geoms tested by their spheres and boxes in the body's frame, then by their
   world AABBs' corners; explicit pairs last (spheres and OBBs only); keys ``g1 << S | g2`` sorted
   (``S`` bits hold any geom id: decoding is a shift and a mask, not an integer division per pair):
   through a bit set of the key space where that is small, else the body-level and the plane keys
   each on its own, then merged (`_sort_keys`).
"""

from __future__ import annotations

import numba as nb
from numba.cpython.unsafe.numbers import trailing_zeros
import numpy as np

from ._ptr import NO_NRT, f64_ptr, view_of
from .bounds import (BIG, MAX_POSITION, SLACK_POS, _aabb_hit, _bounds_ok, _explicit_hit, _geom_rows, _pairs_mask,
                     _place, _plane_hit, _plane_hit_local, _plane_world, _pose_ok, _row_of, dot3)
from .coherence import NO_LIST, _kept_pairs
from .culling import MASK_MAX, _scan_masks, _sweep
from .keys import _emit, _in_sorted, _pair_key, _sort_keys, key_shift
from .layout import (F_BCAP, F_BLOCAL, F_GCAP, F_GLOCAL, F_GMARGIN, F_GPLANE, F_PAIR_M, FLT, H_E, H_FLAT, H_FP, H_G,
                     H_GS, H_KS, H_L, H_NB, H_P, H_Q, H_V, HEADER, I_GEOM_BID, I_GEOM_CONAFFINITY, I_GEOM_CONTYPE,
                     I_GSTART, I_HAS_BOUNDS, I_ORDER, I_PAIR_G, I_PAIR_KEYS, I_PAIRFLAG, I_PGEOMS, I_PLANE_OK,
                     I_PLANES, I_POS_OF, I_PARENT_POS, I_SINGLE, I_SMASK, INT, N_STATS, ST_BODY_AABB, ST_BODY_OBB,
                     ST_BODY_SPHERE, ST_GEOM_AABB, ST_GEOM_OBB, ST_GEOM_SPHERE, ST_OUT, ST_PLANE, W_BAABB, W_BAABB_T,
                     W_BW, W_GAABB, W_GSTAMP, W_GW, W_PLW, W_SAABB, W_TMP, WORK, view_f1, view_f2,
                     view_i1, view_i2)
from .walk import _walk


# Status codes written to info[0]
OK = 0
BAD_NONFINITE = 1
BAD_ROTATION = 2
BAD_RANGE = 3


def pack(dims: dict, n_virtual: int = 0, filter_parent: bool = False, **fields) -> tuple[np.ndarray, np.ndarray]:
    """The static model as ``I`` (int64: the counts, the field table, then `layout.INT`'s fields)
    and ``F`` (float64, `layout.FLT`'s fields), every field by name with its declared shape.

    Excluded body pairs travel as lists of partners per position (``ex_other[ex_start[x]:
    ex_start[x + 1]]``, both directions): a body has none or a few, so a scan of its own list beats
    a binary search of all. ``flat_root`` (L) marks the subtrees whose body pairs are tested from the
    static masks ``flat_mask`` (L), ``flat_n[x]`` pairs in the root x's (see `_traverse`). ``smask``
    (L + 1): where L <= MASK_MAX, bit y of ``smask[x]`` is the body pair (x, y), x < y, when it
    passes the static filter (`_scan_masks`), and ``smask[L]`` the count of those pairs; zeros
    otherwise.
    """
    head = np.zeros(HEADER, np.int64)
    head[[H_L, H_G, H_GS, H_Q, H_E, H_P, H_FP, H_KS, H_NB, H_V, H_FLAT]] = (
        dims["L"], dims["G"], dims["Gs"], dims["Q"], dims["E"], dims["P"], int(filter_parent), key_shift(dims["G"]),
        dims["NB"], n_virtual, int(np.any(fields["flat_root"])))
    I = INT.pack(dims, head, **{f[0]: fields[f[0]] for f in INT.fields})
    F = FLT.pack(dims, **{f[0]: fields[f[0]] for f in FLT.fields})
    return I, F


def model_dims(I: np.ndarray) -> dict:
    """The counts of the layouts of `layout.MODEL` (``I``, ``F``, ``W``, the lanes' ``LW``) from
    ``I``'s header."""
    return {"L": int(I[H_L]), "G": int(I[H_G]), "Gs": int(I[H_GS]), "Q": int(I[H_Q]), "E": int(I[H_E]),
            "P": int(I[H_P]), "NB": int(I[H_NB])}



def workspace_size(I: np.ndarray) -> int:
    """Length of the float64 workspace ``W`` of one world of the model ``I``."""
    return WORK.size(model_dims(I))


@nb.njit(**NO_NRT)
def _world(body_pos, body_rot, I, F, W, sap, bp, keys, scr, stats, info, cl, coherent):
    """One world: validate poses, world bounds, tree culling, filters; returns the pair count.

    ``scr`` is int64 scratch for the output sort (`scratch_size`). On a bad pose, ``info[0]`` gets
    the status code, ``info[1]`` the body id, and -1 is returned.
    Body pairs beyond ``bp``'s capacity set ``info[3]`` to the count needed (the caller grows
    ``bp`` and reruns); keys beyond ``keys.shape[0]`` are counted but not written (likewise).
    With ``coherent``, the body-pair list is kept between calls in ``cl`` (``bp``'s shape; see
    ``FAT_GROW``): a caller that replaces ``cl`` clears ``W``'s ``COH_VALID``
    (`layout.W_COH`). A batch's worlds are unrelated: no coherence there.
    """
    # Geom rows of multi-geom bodies are computed on first use in this call (`_geom_rows`): most
    # bodies never reach the geom level.
    gstamp = view_f1(I, W, W_GSTAMP)
    gstamp[I[H_L]] += 1.0
    stamp = gstamp[I[H_L]]
    for s in range(N_STATS):
        stats[s] = 0
    info[3] = 0
    if not _poses_ok(body_pos, body_rot, I[H_NB], info):  # 1. poses
        return -1
    _place_bodies(body_pos, body_rot, I, F, W)  # 1. world bounds of the positions
    m = _body_pairs(I, W, sap, bp, stats, info, cl, coherent)  # 2-4a. body pairs, filtered
    if m < 0:
        return 0  # bp too short: info[3] says how long it must be
    k = _geom_pairs(body_pos, body_rot, I, F, W, bp, m, keys, stats, stamp)  # 4b. body -> geom pairs
    k4 = min(k, keys.shape[0])  # the body-level keys end here (see _sort_keys)
    k = _plane_pairs(body_pos, body_rot, I, F, W, sap, keys, k, stats, stamp)  # 5a. planes
    k = _explicit_pairs(body_pos, body_rot, I, F, W, keys, k, stats)  # 5b. explicit pairs
    stats[ST_OUT] = k
    if k <= keys.shape[0]:
        _sort_keys(keys, k, k4, I[H_KS], I[H_G], scr)
    return k


@nb.njit(cache=True, inline="always")
def _poses_ok(body_pos, body_rot, NB, info):
    # Stage 1a: every pose checked first, in one loop without a branch over flat views of the
    # (C-contiguous) pose arrays, which the compiler vectorises (gathers). Only a failing call looks
    # at the bodies one by one, by id, so that the first offender is named (info[0], info[1]).
    rf = view_of(f64_ptr(np.int64(body_rot.ctypes.data)), 9 * NB)
    pf = view_of(f64_ptr(np.int64(body_pos.ctypes.data)), 3 * NB)
    bad = False
    for b in range(NB):
        o = 9 * b
        q = 3 * b
        bad |= not _pose_ok(rf[o], rf[o + 1], rf[o + 2], rf[o + 3], rf[o + 4], rf[o + 5], rf[o + 6], rf[o + 7],
                            rf[o + 8], pf[q], pf[q + 1], pf[q + 2])
    for b in range(NB if bad else 0):
        ok = _pose_ok(body_rot[b, 0, 0], body_rot[b, 0, 1], body_rot[b, 0, 2], body_rot[b, 1, 0], body_rot[b, 1, 1],
                      body_rot[b, 1, 2], body_rot[b, 2, 0], body_rot[b, 2, 1], body_rot[b, 2, 2], body_pos[b, 0],
                      body_pos[b, 1], body_pos[b, 2])
        if not ok:
            info[0] = BAD_ROTATION
            for i in range(3):
                if abs(body_pos[b, i]) > MAX_POSITION:
                    info[0] = BAD_RANGE
            for i in range(3):
                if not np.isfinite(body_pos[b, i]):
                    info[0] = BAD_NONFINITE
                for j in range(3):
                    if not np.isfinite(body_rot[b, i, j]):
                        info[0] = BAD_NONFINITE
            info[1] = b
            return False
    return True


@nb.njit(cache=True, inline="always")
def _place_bodies(body_pos, body_rot, I, F, W):
    # Stage 1b: the world row and AABB of every position (a position without bounds gets an empty
    # box); the columns of baabb where flat roots or the static masks read them.
    L = I[H_L]
    pos_of = view_i1(I, I, I_POS_OF)
    has_bounds = view_i1(I, I, I_HAS_BOUNDS)
    blocal = view_f2(I, F, F_BLOCAL)
    bcap = view_f2(I, F, F_BCAP)
    bw = view_f2(I, W, W_BW)
    baabb = view_f2(I, W, W_BAABB)
    saabb = view_f2(I, W, W_SAABB)
    baabb_t = view_f2(I, W, W_BAABB_T)
    by_masks = L <= MASK_MAX
    cols = I[H_FLAT] != 0 or by_masks  # baabb_t written (saabb only where the tree is walked)
    for b in range(I[H_NB]):
        x = pos_of[b]
        if has_bounds[x]:
            _place(body_rot, body_pos, b, blocal, bcap, x, bw, baabb, saabb, baabb_t, cols, not by_masks)
        else:
            for i in range(3):
                baabb[x, i] = BIG
                baabb[x, 3 + i] = -BIG
                baabb_t[i, x] = BIG
                baabb_t[3 + i, x] = -BIG
                saabb[x, i] = BIG
                saabb[x, 3 + i] = -BIG
    for x in range(1, I[H_V] + 1):  # the world's geoms as leaves of their own
        _place(body_rot, body_pos, 0, blocal, bcap, x, bw, baabb, saabb, baabb_t, cols, not by_masks)



@nb.njit(cache=True, inline="always")
def _body_pairs(I, W, sap, bp, stats, info, cl, coherent):
    # Stages 2-4a: the body pairs whose AABBs overlap and that pass the static filter, into bp[:m]
    # (lower position first; a loose pair, see _filter, as ~y); returns m, or -1 when bp is too
    # short (info[3]: the count needed). From the list kept by earlier calls while every body stays
    # inside its fat box (see FAT_GROW), from the static masks up to MASK_MAX positions, else down
    # the tree.
    L = I[H_L]
    baabb = view_f2(I, W, W_BAABB)
    by_masks = L <= MASK_MAX
    if coherent and not by_masks:  # (up to MASK_MAX positions the masks' scan costs less than the list's upkeep)
        m = _kept_pairs(I, W, sap, bp, stats, info, cl, baabb)
        if m != NO_LIST:
            return m
    if by_masks:
        # at most MASK_MAX positions: every pair passing the static filter, a row at a time over
        # baabb's columns (`_scan_masks`); no tree.
        smask = view_i1(I, I, I_SMASK)
        stats[ST_BODY_AABB] += smask[L]
        m = _scan_masks(smask, L, view_f2(I, W, W_BAABB_T), view_i1(I, I, I_SINGLE), bp)
        if m > bp.shape[0]:
            info[3] = m
            return -1
        return m
    saabb = view_f2(I, W, W_SAABB)
    _sweep(saabb, view_i1(I, I, I_PARENT_POS), L)  # 2. subtree AABBs
    m = _walk(I, W, sap, bp, stats, baabb, saabb, view_f2(I, W, W_BAABB_T))  # 3. down the tree, 4a. filter
    if m < 0:
        info[3] = -m
        return -1
    return m


@nb.njit(cache=True, inline="always")
def _geom_pairs(body_pos, body_rot, I, F, W, bp, m, keys, stats, stamp):
    # Stage 4b: the body pairs bp[:m] -> sphere and OBB tests of the body bounds, 64 pairs at a
    # time into a bit mask (`_pairs_mask`; a loose pair, ~y, passes) -> the geom
    # pairs of each pair that hit, tested on the geoms' own bounds (AABB, then `_bounds_ok`: sphere
    # and OBB) unless both bodies hold one geom. Keys into keys[:k] (counted beyond); returns k.
    S = I[H_KS]
    single = view_i1(I, I, I_SINGLE)
    pairflag = view_i1(I, I, I_PAIRFLAG)
    gstart = view_i1(I, I, I_GSTART)
    pgeoms = view_i1(I, I, I_PGEOMS)
    gct = view_i1(I, I, I_GEOM_CONTYPE)
    gca = view_i1(I, I, I_GEOM_CONAFFINITY)
    pair_keys = view_i1(I, I, I_PAIR_KEYS)
    order = view_i1(I, I, I_ORDER)
    glocal = view_f2(I, F, F_GLOCAL)
    gcap = view_f2(I, F, F_GCAP)
    gmargin = view_f1(I, F, F_GMARGIN)
    bw = view_f2(I, W, W_BW)
    gw = view_f2(I, W, W_GW)
    baabb = view_f2(I, W, W_BAABB)
    gaabb = view_f2(I, W, W_GAABB)
    gstamp = view_f1(I, W, W_GSTAMP)
    check_pairs = pair_keys.shape[0] > 0
    k = 0
    for c0 in range(0, m, 64):
        cnt = min(64, m - c0)
        force = np.uint64(0)
        for i in range(cnt):
            force |= np.uint64(bp[c0 + i, 1] < 0) << np.uint64(i)
        hits = force | _pairs_mask(bw, bp, c0, cnt)
        nl = 0
        f = force
        while f != 0:
            nl += 1
            f &= f - np.uint64(1)
        stats[ST_BODY_SPHERE] += cnt - nl
        stats[ST_BODY_OBB] += cnt - nl
        while hits != 0:
            t = c0 + np.int64(trailing_zeros(hits))
            hits &= hits - np.uint64(1)
            x = bp[t, 0]
            y = bp[t, 1]
            y = y ^ (y >> 63)
            sx = single[x] > 0
            sy = single[y] > 0
            if sx and sy and not (check_pairs and (pairflag[x] | pairflag[y]) != 0):
                # Two single-geom bodies: their geoms' masks are the bodies' (the static filter
                # passed), their rows the bodies' (tested above): the pair is the geoms'.
                k = _emit(keys, k, pgeoms[gstart[x]], pgeoms[gstart[y]], S)
                continue
            if not sx:
                _geom_rows(x, order, gstart, pgeoms, glocal, gcap, gmargin, body_pos, body_rot, gw, gaabb, gstamp,
                           stamp)
            if not sy:
                _geom_rows(y, order, gstart, pgeoms, glocal, gcap, gmargin, body_pos, body_rot, gw, gaabb, gstamp,
                           stamp)
            cp = check_pairs and pairflag[x] != 0 and pairflag[y] != 0
            for ii in range(gstart[x], gstart[x + 1]):
                g1 = pgeoms[ii]
                for jj in range(gstart[y], gstart[y + 1]):
                    g2 = pgeoms[jj]
                    if (gct[g1] & gca[g2]) == 0 and (gct[g2] & gca[g1]) == 0:
                        continue
                    if cp:
                        key = _pair_key(g1, g2, S)
                        if _in_sorted(pair_keys, key):
                            continue
                    if not (sx and sy):
                        # A single-geom body's row is its geom's, already inflated.
                        A = bw if sx else gw
                        a = x if sx else g1
                        ma = 0.0 if sx else gmargin[g1]
                        B = bw if sy else gw
                        b = y if sy else g2
                        mb = 0.0 if sy else gmargin[g2]
                        # AABBs first: exact for the axis-aligned boxes multi-geom bodies are often
                        # made of (walls, a bin), whose spheres reach far
                        stats[ST_GEOM_AABB] += 1
                        if not _aabb_hit(baabb if sx else gaabb, a, baabb if sy else gaabb, b):
                            continue
                        stats[ST_GEOM_SPHERE] += 1  # `_bounds_ok` tests the spheres first
                        stats[ST_GEOM_OBB] += 1
                        if not _bounds_ok(_row_of(A, a), ma, _row_of(B, b), mb):
                            continue
                    k = _emit(keys, k, g1, g2, S)
    return k


@nb.njit(cache=True, inline="always")
def _plane_pairs(body_pos, body_rot, I, F, W, sap, keys, k, stats, stamp):
    # Stage 5a: each plane against each position's AABB (flat and branch-free over the positions:
    # the AABB's corner deepest along -n, and the static filter's flag), then the candidates' own
    # bounds, and a multi-geom body's geoms in its frame. Keys from keys[k]; returns the new k.
    L = I[H_L]
    S = I[H_KS]
    planes = view_i1(I, I, I_PLANES)
    plane_ok = view_i2(I, I, I_PLANE_OK)
    geom_bid = view_i1(I, I, I_GEOM_BID)
    single = view_i1(I, I, I_SINGLE)
    pairflag = view_i1(I, I, I_PAIRFLAG)
    gstart = view_i1(I, I, I_GSTART)
    pgeoms = view_i1(I, I, I_PGEOMS)
    gct = view_i1(I, I, I_GEOM_CONTYPE)
    gca = view_i1(I, I, I_GEOM_CONAFFINITY)
    pair_keys = view_i1(I, I, I_PAIR_KEYS)
    order = view_i1(I, I, I_ORDER)
    glocal = view_f2(I, F, F_GLOCAL)
    gcap = view_f2(I, F, F_GCAP)
    gplane = view_f2(I, F, F_GPLANE)
    gmargin = view_f1(I, F, F_GMARGIN)
    bw = view_f2(I, W, W_BW)
    gw = view_f2(I, W, W_GW)
    baabb = view_f2(I, W, W_BAABB)
    gaabb = view_f2(I, W, W_GAABB)
    gstamp = view_f1(I, W, W_GSTAMP)
    plw = view_f2(I, W, W_PLW)
    check_pairs = pair_keys.shape[0] > 0
    lst = sap[L - 1:]  # scratch (sap_state)
    for i in range(planes.shape[0]):
        _plane_world(planes[i], body_pos, body_rot, geom_bid, gplane, plw, i)
        qg = planes[i]
        mq = gmargin[qg]
        # The AABB corner deepest along -n against the halfspace.
        n0 = plw[i, 0]
        n1 = plw[i, 1]
        n2 = plw[i, 2]
        pd = plw[i, 3]
        lim = pd + mq
        k0 = 0 if n0 > 0 else 3
        k1 = 1 if n1 > 0 else 4
        k2 = 2 if n2 > 0 else 5
        # Flat and branch-free over the bodies: a walk down the tree branching on each outcome
        # costs a misprediction per test in a simulation loop (see `culling`).
        m = 0
        for x in range(L):
            lst[m] = x
            v = dot3(n0, n1, n2, baabb[x, k0], baabb[x, k1], baabb[x, k2])
            m += np.int64((v <= lim + SLACK_POS * (abs(v) + abs(pd))) & (plane_ok[i, x] != 0))
        stats[ST_PLANE] += L + m
        for t in range(m):
            x = lst[t]
            hit = _plane_hit(plw, i, mq, bw, x, 0.0)
            if single[x] > 0 and not (check_pairs and pairflag[x] != 0):
                # One geom, its masks in plane_ok already: its key is written and counted by the
                # outcome, no branch on it (a body lying on the floor, a chain, a pile).
                g = pgeoms[gstart[x]]
                if k < keys.shape[0]:
                    keys[k] = _pair_key(g, qg, S)
                k += np.int64(hit)
            elif hit:
                multi = single[x] <= 0
                if multi:
                    # the plane in the body's frame, for its geoms' sphere and OBB tests
                    b = order[x]
                    ln0 = dot3(body_rot[b, 0, 0], body_rot[b, 1, 0], body_rot[b, 2, 0], n0, n1, n2)
                    ln1 = dot3(body_rot[b, 0, 1], body_rot[b, 1, 1], body_rot[b, 2, 1], n0, n1, n2)
                    ln2 = dot3(body_rot[b, 0, 2], body_rot[b, 1, 2], body_rot[b, 2, 2], n0, n1, n2)
                    llim = lim - dot3(n0, n1, n2, body_pos[b, 0], body_pos[b, 1], body_pos[b, 2])
                    lscale = abs(body_pos[b, 0]) + abs(body_pos[b, 1]) + abs(body_pos[b, 2]) + abs(pd)
                for ii in range(gstart[x], gstart[x + 1]):
                    g = pgeoms[ii]
                    if (gct[g] & gca[qg]) == 0 and (gct[qg] & gca[g]) == 0:
                        continue
                    if check_pairs:
                        key = _pair_key(g, qg, S)
                        if _in_sorted(pair_keys, key):
                            continue
                    if multi:
                        stats[ST_PLANE] += 1
                        # the geom's sphere and OBB in the body's frame, then its world AABB's
                        # corner, as the body's above: the geoms' world rows are made (`_geom_rows`)
                        # only when one of them passes
                        if not _plane_hit_local(ln0, ln1, ln2, llim, lscale + abs(glocal[g, 0])
                                                + abs(glocal[g, 1]) + abs(glocal[g, 2]), glocal, g, gmargin[g]):
                            continue
                        _geom_rows(x, order, gstart, pgeoms, glocal, gcap, gmargin, body_pos, body_rot, gw, gaabb,
                                   gstamp, stamp)
                        v = dot3(n0, n1, n2, gaabb[g, k0], gaabb[g, k1], gaabb[g, k2])
                        if not (v <= lim + SLACK_POS * (abs(v) + abs(pd))):
                            continue
                    k = _emit(keys, k, g, qg, S)
    return k


@nb.njit(cache=True, inline="always")
def _explicit_pairs(body_pos, body_rot, I, F, W, keys, k, stats):
    # Stage 5b: explicit pairs, only the bounds test, with the pair's own inflation if given.
    pair_g = view_i2(I, I, I_PAIR_G)
    pair_m = view_f1(I, F, F_PAIR_M)
    gmargin = view_f1(I, F, F_GMARGIN)
    gplane = view_f2(I, F, F_GPLANE)
    geom_bid = view_i1(I, I, I_GEOM_BID)
    glocal = view_f2(I, F, F_GLOCAL)
    tmp = view_f2(I, W, W_TMP)
    S = I[H_KS]
    for i in range(pair_g.shape[0]):
        if _explicit_hit(i, pair_g, pair_m, gmargin, gplane, geom_bid, glocal, body_pos, body_rot, tmp, stats):
            k = _emit(keys, k, pair_g[i, 0], pair_g[i, 1], S)
    return k

