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
in `layout` (`INT`, `FLT`, `WORK`); one step is a call with three arguments (the two pose
arrays and a *context* of buffer addresses, see `_ptr` and `context`), or with the context's own
address alone when it holds the pose arrays' addresses too (`step_bound`: arrays that stay put, as
MuJoCo's): a numba call pays for every array argument, and views built from pointers carry no
reference count. Each stage takes the views it needs by slot (`layout.view_i1` ...: no copy).
The stages' parts live by concept: `bounds` (rows and their tests), `culling` (the walk, the sweep,
the filter) and `keys` (pair keys and their sort); this module holds the stages and the entry points.

One step, for one world (`_world`):
1. validate each body's pose (finite, proper orthonormal rotation: one combined test) and move
   its local bounds to the world (one rotation per body; no point is touched); the geoms of bodies
   with several geoms follow on first use (a single-geom body's bounds *are* its geom's, inflated);
2. subtree AABBs by one reverse sweep over the positions (each body's AABB of its world OBB and
   capsule, merged into its parent's): the tree is a one-level bounding hierarchy, never boxes of boxes;
3. every body pair exactly once, at its lowest common ancestor ``n``: body ``n`` against its own
   subtree (one walk over its descendants; under the parent rule a direct child's subtree AABB
   culls but the child is not paired), and each pair of ``n``'s child
   subtrees: all pairs for a few children, sweep-and-prune on one axis from ``SAP_MIN``, a hash
   grid from ``GRID_MIN`` children when their widths along the sweep axis sum to more than
   ``GRID_SWEEP`` times its extent (a filled volume, as free bodies in a box: far fewer tests than
   the sweep; bodies spread over a floor sweep faster); a subtree whose AABB misses is skipped whole
   (``q = end[q]``). A small branching subtree (a robot, a hand: ``flat_root``) instead tests
   its statically passing body pairs, bit masks made at set-up, a vectorised row at a time.
   Up to ``MASK_MAX`` (64) positions (a robot, a hand, a small scene) there is no tree at all:
   every body pair that passes the static filter is a bit of a mask made at set-up, and each
   body's row of AABB tests runs over the boxes' columns, a vector compare per 8 partners
   (`_scan_masks`; in a simulation loop it took less time than the walk on the small MuJoCo
   models, about the same on wonik_allegro).
   Tests whose outcome is data keep no branch on it where they can (the pair is written, the
   count advanced by the outcome): in a simulation loop the engine retrains the branch predictor
   between steps, and every misprediction flushes the pipeline. Surviving body pairs go to a
   buffer: no deep call chain on the hot path (in the walk, compiled with numba's reference
   counting, each call with array arguments pays it, even inlined: the hottest tests are written
   out);
4. body pair -> static filter -> sphere and OBB separating-axis tests (15 axes, Ericson 2005,
   *Real-Time Collision Detection* §4.4.1), 64 body pairs at a time with every axis evaluated
   (`pair_bits`: four pairs a vector, the rows gathered where they lie) ->
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

from ._ptr import NO_NRT, check_span, f64_ptr, i32_ptr, i64_ptr, view_of
from ._threads import fetch_add, set_chunksize
# The stages' parts live by concept (bounds, culling, keys); the names other modules, the Python side
# and the tests read here are re-exported.
from .bounds import (BIG, EPS_PAR, MAX_POSITION, ORTHO_TOL, PAIR_LANES, SLACK_POS, SLACK_REL,  # noqa: F401
                     _aabb_hit, _bounds_ok, _cap_aabb, _explicit_hit, _geom_rows, _pairs_mask, _place, _plane_hit,
                     _plane_hit_local, _plane_world, _pose_ok, _pose_row, _row_of, _sphere_hit, _world_aabb,
                     _world_row, aabb_slack, bounds_mask, capsule_half, dot3, pair_bits, plane_world)
from .culling import (FLAT_MAX, GRID_MIN, GRID_SWEEP, MASK_MAX, SAP_MIN, _filter, _scan,  # noqa: F401
                      _scan_masks, _sweep, _traverse, sap_state)
from .keys import _emit, _in_sorted, _pair_key, _sort_keys, key_shift, scratch_size  # noqa: F401
from .layout import (F_BCAP, F_BLOCAL, F_GCAP, F_GLOCAL, F_GMARGIN, F_GPLANE, F_PAIR_M, FLT, I_CHILD_START, I_CHILDREN,
                    I_CONAFFINITY, I_CONTYPE, I_END, I_EX_OTHER, I_EX_START, I_FLAT_MASK, I_FLAT_N, I_FLAT_ROOT,
                    I_GEOM_BID, I_GEOM_CONAFFINITY, I_GEOM_CONTYPE, I_GSTART, I_HAS_BOUNDS, I_NCHILD, I_ORDER,
                    I_PAIR_G, I_PAIR_KEYS, I_PAIRFLAG, I_PARENT_POS, I_PGEOMS, I_PLANE_OK, I_PLANES, I_POS_OF,
                    I_SINGLE, I_SMASK, I_WELD, INT, N_COH, N_STATS, ROW, ST_BODY_AABB, ST_BODY_OBB, ST_BODY_SPHERE,
                    ST_GEOM_AABB, ST_GEOM_OBB, ST_GEOM_SPHERE, ST_OUT, ST_PLANE, ST_REUSED, ST_SUBTREE, W_BAABB,
                    W_BAABB_T, W_BW, W_COH, W_FAT_B, W_FAT_S, W_FAT_T, W_GAABB, W_GSTAMP, W_GW, W_PLW, W_SAABB, W_TMP,
                    WORK, view_f1, view_f2, view_i1, view_i2)

# Status codes written to info[0]
OK = 0
BAD_NONFINITE = 1
BAD_ROTATION = 2
BAD_RANGE = 3

# Frame coherence (`_world`, single-world calls only): the body pairs whose *fat* boxes (each body's
# AABB grown by FAT_GROW of its largest extent on every side) overlap and pass the static filter are
# kept between calls; while every body's AABB stays inside its fat box, a call tests that list's
# exact AABBs instead of walking the tree: two AABBs inside two fat boxes can only meet if the fat
# boxes do (the broad phase of Bullet's and Box2D's dynamic trees: fat AABBs; Catto, "Dynamic
# AABB Trees", GDC 2019). The answer is the walk's, bit for bit. State, float64, in the
# workspace's ``coh`` field (`layout.W_COH`): the list is valid, its length, a decayed count of
# recent rebuilds (x COH_DECAY a call, +1 a rebuild), calls left on the exact walk, and the length
# of the next such spell.
FAT_GROW = 0.2
COH_VALID, COH_N, COH_SCORE, COH_SKIP, COH_BACKOFF = range(5)
assert COH_BACKOFF < N_COH
COH_DECAY = 0.875
# Above this decayed count (rebuilds in more than about a third of the calls, 8 x the rate in a
# steady state: bodies leave their fat boxes all the time, as 22 falling humanoids do), rebuilding
# costs more than the list saves: the exact walk runs for COH_BACKOFF calls (8, doubled each time
# up to COH_BACKOFF_MAX, halved by each call that reuses the list) before the list is tried again.
# The threshold weighs the two kinds of model, measured in alternating passes: set higher, the
# humanoid under the benchmark's extreme controls paid for rebuilds that did not pay off; at 2.5
# it stayed near the walk alone, while wonik_allegro and shadow_hand kept most of their gain.
COH_SCORE_MAX = 2.5
COH_BACKOFF_MIN = 8.0
COH_BACKOFF_MAX = 1024.0

# Header of I: counts. Positions (``H_L``) are the bodies in depth-first order plus, when the world
# has several solid geoms, one leaf per world geom (``H_V`` of them, at positions 1..V; see
# BroadPhase): bodies (``H_NB``) index the pose arrays, positions everything else. ``H_FLAT``: 1 when
# some subtree is flat (``flat_root``), so that the step writes ``baabb_t`` (see `_place`; it does
# too up to MASK_MAX positions).
H_L, H_G, H_GS, H_Q, H_E, H_P, H_FP, H_KS, H_NB, H_V, H_FLAT = range(11)
HEADER = 11


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


@nb.njit(cache=True, inline="always")
def _fat_views(I, W):
    # The frame-coherence part of W: fat_b (L, 6), fat_s (L, 6), fat_t (6, L), state (N_COH).
    return view_f2(I, W, W_FAT_B), view_f2(I, W, W_FAT_S), view_f2(I, W, W_FAT_T), view_f1(I, W, W_COH)


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
def _walk(I, W, sap, bp, stats, boxes, sboxes, cols, exact):
    # The tree walk over the given boxes (the exact AABBs, or the fat ones; ``cols``: their columns),
    # then the static filter: the body pairs into bp, their count; when bp is too short, minus the
    # count needed.
    L = I[H_L]
    nbp = _traverse(L, view_i1(I, I, I_END), view_i1(I, I, I_NCHILD), view_i1(I, I, I_CHILD_START),
                    view_i1(I, I, I_CHILDREN), view_i1(I, I, I_HAS_BOUNDS), boxes, sboxes, view_f2(I, W, W_BW), sap, bp,
                    stats, I[H_FP] != 0, cols, view_i1(I, I, I_FLAT_ROOT), view_i1(I, I, I_FLAT_N),
                    view_i1(I, I, I_FLAT_MASK), exact)
    if nbp > bp.shape[0]:
        return -nbp
    return _filter(bp, nbp, view_i1(I, I, I_CONTYPE), view_i1(I, I, I_CONAFFINITY), view_i1(I, I, I_WELD),
                   view_i1(I, I, I_PARENT_POS), I[H_FP] != 0, view_i1(I, I, I_EX_START), view_i1(I, I, I_EX_OTHER),
                   view_i1(I, I, I_SINGLE))


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
        fat_b, fat_s, fat_t, cs = _fat_views(I, W)
        if cs[COH_SKIP] > 0.0:
            cs[COH_SKIP] -= 1.0
        else:
            out = False
            for x in range(L):  # branch-free: vectorised
                out |= ((baabb[x, 0] < fat_b[x, 0]) | (baabb[x, 1] < fat_b[x, 1]) | (baabb[x, 2] < fat_b[x, 2])
                        | (baabb[x, 3] > fat_b[x, 3]) | (baabb[x, 4] > fat_b[x, 4]) | (baabb[x, 5] > fat_b[x, 5]))
            if cs[COH_VALID] != 0.0 and not out:
                stats[ST_REUSED] = 1
                cs[COH_SCORE] *= COH_DECAY
                cs[COH_BACKOFF] *= 0.5
                n = np.int64(cs[COH_N])
                stats[ST_BODY_AABB] += n
                return _scan(cl, n, baabb, bp)
            score = cs[COH_SCORE] * COH_DECAY + 1.0
            cs[COH_VALID] = 0.0  # until rebuilt (an overflow below returns first)
            if score > COH_SCORE_MAX:
                back = min(max(2.0 * cs[COH_BACKOFF], COH_BACKOFF_MIN), COH_BACKOFF_MAX)
                cs[COH_SKIP] = back - 1.0  # this call is the spell's first
                cs[COH_BACKOFF] = back
                cs[COH_SCORE] = 0.0
            else:
                cs[COH_SCORE] = score
                # Rebuild: fat boxes (a body without bounds keeps its empty box), their subtree
                # boxes, the walk over them, the filter; the list kept, then tested as above.
                for x in range(L):
                    g = max(FAT_GROW * max(baabb[x, 3] - baabb[x, 0], baabb[x, 4] - baabb[x, 1],
                                           baabb[x, 5] - baabb[x, 2]), 0.0)
                    for i in range(3):
                        fat_b[x, i] = baabb[x, i] - g
                        fat_b[x, 3 + i] = baabb[x, 3 + i] + g
                    for i in range(6):
                        fat_s[x, i] = fat_b[x, i]
                if I[H_FLAT] != 0:
                    for i in range(6):
                        for x in range(L):
                            fat_t[i, x] = fat_b[x, i]
                _sweep(fat_s, view_i1(I, I, I_PARENT_POS), L)
                n = _walk(I, W, sap, bp, stats, fat_b, fat_s, fat_t, False)
                if n < 0:
                    info[3] = -n
                    cs[COH_SCORE] = score - 1.0  # the caller grows bp and reruns: one rebuild
                    return -1
                for t in range(n):
                    cl[t, 0] = bp[t, 0]
                    cl[t, 1] = bp[t, 1]
                cs[COH_N] = n
                cs[COH_VALID] = 1.0
                stats[ST_BODY_AABB] += n
                return _scan(cl, n, baabb, bp)
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
    m = _walk(I, W, sap, bp, stats, baabb, saabb, view_f2(I, W, W_BAABB_T), True)  # 3. down the tree, 4a. filter
    if m < 0:
        info[3] = -m
        return -1
    return m


@nb.njit(cache=True, inline="always")
def _geom_pairs(body_pos, body_rot, I, F, W, bp, m, keys, stats, stamp):
    # Stage 4b: the body pairs bp[:m] -> sphere and OBB tests of the body bounds, 64 pairs at a
    # time, four a vector (`pair_bits`), into a bit mask (a loose pair, ~y, passes) -> the geom
    # pairs of each pair that hit, tested on the geoms' own bounds (AABB, sphere, then `_bounds_ok`)
    # unless both bodies hold one geom. Keys into keys[:k] (counted beyond); returns k.
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
    bw_at = np.int64(bw.ctypes.data)
    bp_at = np.int64(bp.ctypes.data)
    for c0 in range(0, m, 64):
        cnt = min(64, m - c0)
        force = np.uint64(0)
        for i in range(cnt):
            force |= np.uint64(bp[c0 + i, 1] < 0) << np.uint64(i)
        hits = force
        for j in range(0, cnt, PAIR_LANES):
            hits |= pair_bits(bw_at, bp_at, c0 + j, min(PAIR_LANES, cnt - j)) << np.uint64(j)
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
                        stats[ST_GEOM_SPHERE] += 1
                        if not _sphere_hit(A, a, ma, B, b, mb):
                            continue
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
        # costs a misprediction per test in a simulation loop (see _subtree_pair).
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


# ------------------------------------------------------------------------------- entry points

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
# A batch chunk's summary (`step_batch`'s chunk_info rows): its key count, its first bad world (-1:
# none), the body-pair capacity a world lacked (0: none).
CI_KEYS, CI_BAD, CI_NEED = range(3)
N_CI = 3

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
    kw = _world(pos_w, rot_w, I, F, W, sap, bp, keys, scr, stats, info, bp, False)
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
    for c in range(C):
        if chunk_info[c, CI_BAD] >= 0 or chunk_info[c, CI_NEED] > 0 or chunk_info[c, CI_KEYS] > ctxs[c, C_NKEYS]:
            return np.empty((0, 3), np.int32)
    mask = (np.int64(1) << S) - 1
    K = 0
    for c in range(C):
        K += chunk_info[c, CI_KEYS]
    for s in range(N_STATS):
        stats[s] = 0
    for c in range(C):
        cs = view_of(i64_ptr(ctxs[c, C_STATS]), N_STATS)
        for s in range(N_STATS):
            stats[s] += cs[s]
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
