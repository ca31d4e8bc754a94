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
from llvmlite import ir
from numba.core import types
from numba.cpython.unsafe.numbers import leading_zeros, trailing_zeros
from numba.extending import intrinsic
import numpy as np

from ._ptr import check_span, f64_ptr, i32_ptr, i64_ptr, view_of
from ._quat import fmuladd
from ._simd import LANES as LANES8, _py, box_row8, gather_rows
from ._threads import fetch_add, set_chunksize
from .layout import (F_BCAP, F_BLOCAL, F_GCAP, F_GLOCAL, F_GMARGIN, F_GPLANE, F_PAIR_M, FLT, I_CHILD_START, I_CHILDREN,
                     I_CONAFFINITY, I_CONTYPE, I_END, I_EX_OTHER, I_EX_START, I_FLAT_MASK, I_FLAT_N, I_FLAT_ROOT,
                     I_GEOM_BID, I_GEOM_CONAFFINITY, I_GEOM_CONTYPE, I_GSTART, I_HAS_BOUNDS, I_NCHILD, I_ORDER,
                     I_PAIR_G, I_PAIR_KEYS, I_PAIRFLAG, I_PARENT_POS, I_PGEOMS, I_PLANE_OK, I_PLANES, I_POS_OF,
                     I_SINGLE, I_SMASK, I_WELD, INT, N_COH, ROW, W_BAABB, W_BAABB_T, W_BW, W_COH, W_FAT_B, W_FAT_S,
                     W_FAT_T, W_GAABB, W_GSTAMP, W_GW, W_PLW, W_SAABB, W_TMP, WORK, view_f1, view_f2, view_i1, view_i2)

# The per-step functions are compiled without numba's reference counting: in them an array value
# costs nothing when copied or dropped, where numba emits a call to its runtime for each (~50 a step
# in `_world` and its callees, every one on the null record of a view made from a pointer, which
# LLVM cannot see through: `_ptr.view_of`). They allocate nothing; the walk's `_traverse` and
# `_grid_pairs` do, and keep the counting (stated: a function called from one compiled without it
# is compiled without it too, unless its own decorator says otherwise). The gain, in a loop after
# mj_step, was largest on the humanoid, small on the robots.
NO_NRT = dict(cache=True, _nrt=False)

BIG = 1e300  # empty AABB: lo = BIG, hi = -BIG (finite, so n . lo never meets inf - inf)
ORTHO_TOL = 1e-6  # max |R^T R - I| accepted for a body rotation (articulation.POSE_ORTHO_TOL: bounds carry the slack)
# Conservative slack: rounding must never separate touching bounds. AbsR gets EPS_PAR (Ericson's
# guard against near-parallel edge pairs, whose cross product is ~0); every comparison gets
# SLACK_REL of the sizes involved plus SLACK_POS of the coordinates' magnitude (a difference of
# world centres far from the origin carries ~1e-16 of their size as rounding).
EPS_PAR = 1e-12
SLACK_REL = 1e-12
SLACK_POS = 1e-13
SAP_MIN = 8  # a node with more children than this sorts them (sweep-and-prune) ...
GRID_MIN = 64  # ... or, with more than this, hashes them into a uniform grid
GRID_SWEEP = 8.0  # ... when the children's widths along the sweep axis sum to more than this x its extent
# Forward neighbour cells (lexicographically after (0, 0, 0)): each pair of adjacent cells once.
_FWD = np.array([(dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)
                 if (dx, dy, dz) > (0, 0, 0)], np.int64)

# Status codes written to info[0]
OK = 0
BAD_NONFINITE = 1
BAD_ROTATION = 2
BAD_RANGE = 3
# Body positions are refused beyond this (= `collide.hull.MAX_COORDINATE`, the geoms' own limit;
# a test keeps the two equal):
# near the float range, sums of coordinates overflow to inf and an inf times a zero normal
# component is NaN, which no test passes (a ball touching a plane at 1e308 was lost; review,
# 2026-11-22).
MAX_POSITION = 1e150

# stats slots
(ST_SUBTREE, ST_BODY_AABB, ST_BODY_SPHERE, ST_BODY_OBB, ST_GEOM_SPHERE, ST_GEOM_OBB, ST_PLANE, ST_OUT,
 ST_GEOM_AABB, ST_REUSED) = range(10)
N_STATS = 10

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


def key_shift(G: int) -> int:
    """Bits ``S`` of the second geom id in a pair key ``g1 << S | g2`` (every id < 2**S)."""
    return max(1, int(G - 1).bit_length())


def workspace_size(I: np.ndarray) -> int:
    """Length of the float64 workspace ``W`` of one world of the model ``I``."""
    return WORK.size(model_dims(I))


@nb.njit(cache=True, inline="always")
def _fat_views(I, W):
    # The frame-coherence part of W: fat_b (L, 6), fat_s (L, 6), fat_t (6, L), state (N_COH).
    return view_f2(I, W, W_FAT_B), view_f2(I, W, W_FAT_S), view_f2(I, W, W_FAT_T), view_f1(I, W, W_COH)


# ------------------------------------------------------------------------------- small tests
# The bounds' dot products are fused multiply-adds (`_quat.fmuladd`: one rounding each on FMA
# hardware, fewer instructions and a shorter chain), written through `dot3` and `dot3_add` in both
# kernels so that the lanes round as one world does. A fused sum is nearer the exact one than the
# separately rounded sum it replaced: the tests' slack (SLACK_REL, SLACK_POS, EPS_PAR) covers both.

@nb.njit(cache=True, inline="always")
def dot3(a0, a1, a2, b0, b1, b2):
    """``a0 b0 + a1 b1 + a2 b2``, summed left to right, the two sums fused."""
    return fmuladd(a2, b2, fmuladd(a1, b1, a0 * b0))


@nb.njit(cache=True, inline="always")
def dot3_add(c, a0, a1, a2, b0, b1, b2):
    """``c + a0 b0 + a1 b1 + a2 b2``, summed left to right, the three sums fused."""
    return fmuladd(a2, b2, fmuladd(a1, b1, fmuladd(a0, b0, c)))


@nb.njit(cache=True, inline="always")
def _pose_row(r00, r01, r02, r10, r11, r12, r20, r21, r22, p0, p1, p2, src):
    """The world bounds row (a 19-tuple, `ROW`) of the local row ``src`` (a 19-tuple) under the pose
    ``x = R y + p``: centre ``R c + p``, axes block ``R A`` (row i: sum_k R[i, k] A[k]), the same
    half extents, sphere centre ``R s + p`` and radius. ``lanes.place8`` replays this source on
    vectors over the lanes (the same operations in the same order: the same bits; a loop over the
    lanes calling this ran the 64-link chain's batch slower than loops per entry, which compiled
    to 4-wide vectors)."""
    (c0, c1, c2, a00, a01, a02, a10, a11, a12, a20, a21, a22, e0, e1, e2, s0, s1, s2, rad) = src
    return (dot3_add(p0, r00, r01, r02, c0, c1, c2),
            dot3_add(p1, r10, r11, r12, c0, c1, c2),
            dot3_add(p2, r20, r21, r22, c0, c1, c2),
            dot3(r00, r01, r02, a00, a10, a20),
            dot3(r00, r01, r02, a01, a11, a21),
            dot3(r00, r01, r02, a02, a12, a22),
            dot3(r10, r11, r12, a00, a10, a20),
            dot3(r10, r11, r12, a01, a11, a21),
            dot3(r10, r11, r12, a02, a12, a22),
            dot3(r20, r21, r22, a00, a10, a20),
            dot3(r20, r21, r22, a01, a11, a21),
            dot3(r20, r21, r22, a02, a12, a22),
            e0, e1, e2,
            dot3_add(p0, r00, r01, r02, s0, s1, s2),
            dot3_add(p1, r10, r11, r12, s0, s1, s2),
            dot3_add(p2, r20, r21, r22, s0, s1, s2),
            rad)


@nb.njit(cache=True, inline="always")
def _world_row(rot, pos, b, src, s, dst, d):
    """``dst[d]`` = world bounds of local row ``src[s]`` under body ``b``'s pose (``rot[b]`` (3, 3),
    ``pos[b]`` (3,)), `_pose_row`; returns the row (a 19-tuple) for the caller's AABB.

    Every input is read into a local before the first store: the rows are raw pointers the
    compiler cannot prove apart, and each store would otherwise force the later loads again.
    Indexing the pose arrays directly (no per-body views) spares numba's reference counting.
    """
    w = _pose_row(rot[b, 0, 0], rot[b, 0, 1], rot[b, 0, 2], rot[b, 1, 0], rot[b, 1, 1], rot[b, 1, 2],
                 rot[b, 2, 0], rot[b, 2, 1], rot[b, 2, 2], pos[b, 0], pos[b, 1], pos[b, 2], _row_of(src, s))
    # written out: a loop over a tuple indexes it at run time
    dst[d, 0] = w[0]
    dst[d, 1] = w[1]
    dst[d, 2] = w[2]
    dst[d, 3] = w[3]
    dst[d, 4] = w[4]
    dst[d, 5] = w[5]
    dst[d, 6] = w[6]
    dst[d, 7] = w[7]
    dst[d, 8] = w[8]
    dst[d, 9] = w[9]
    dst[d, 10] = w[10]
    dst[d, 11] = w[11]
    dst[d, 12] = w[12]
    dst[d, 13] = w[13]
    dst[d, 14] = w[14]
    dst[d, 15] = w[15]
    dst[d, 16] = w[16]
    dst[d, 17] = w[17]
    dst[d, 18] = w[18]
    return w


@nb.njit(cache=True, inline="always")
def _world_aabb(w, m, box, k):
    """``box[k]`` = (lo, hi): the world AABB of the OBB of row ``w`` (a 19-tuple) inflated by ``m``,
    half widths ``|M| (e + m) + tol`` per world axis with the OBB test's rounding slack
    (`aabb_slack`)."""
    e0 = w[12] + m
    e1 = w[13] + m
    e2 = w[14] + m
    tol = aabb_slack(e0, e1, e2, w[0], w[1], w[2])
    h0 = dot3(abs(w[3]), abs(w[4]), abs(w[5]), e0, e1, e2) + tol
    h1 = dot3(abs(w[6]), abs(w[7]), abs(w[8]), e0, e1, e2) + tol
    h2 = dot3(abs(w[9]), abs(w[10]), abs(w[11]), e0, e1, e2) + tol
    box[k, 0] = w[0] - h0
    box[k, 1] = w[1] - h1
    box[k, 2] = w[2] - h2
    box[k, 3] = w[0] + h0
    box[k, 4] = w[1] + h1
    box[k, 5] = w[2] + h2


@nb.njit(cache=True, inline="always")
def capsule_half(r00, r01, r02, r10, r11, r12, r20, r21, r22, d0, d1, d2, r, c0, c1, c2):
    """Half widths of the world AABB of a capsule (local half segment ``d``, radius ``r``) under
    rotation ``R``, centred at the world point ``c``: ``|R d| + r`` per axis, plus the rounding
    slack of `aabb_slack` (sizes ``|R d|`` and ``r``). The lanes compute the same (same bits)."""
    e0 = abs(dot3(r00, r01, r02, d0, d1, d2))
    e1 = abs(dot3(r10, r11, r12, d0, d1, d2))
    e2 = abs(dot3(r20, r21, r22, d0, d1, d2))
    tol = SLACK_REL * (e0 + e1 + e2 + r) + SLACK_POS * (abs(c0) + abs(c1) + abs(c2))
    return e0 + r + tol, e1 + r + tol, e2 + r + tol


@nb.njit(cache=True, inline="always")
def _cap_aabb(rot, b, cap, k, w, m, box, x):
    # box[x] (an AABB, lo then hi) cut to the world AABB of capsule cap[k] inflated by m, moved by
    # body b's rotation and centred at the row w's centre: both contain the shape, so their
    # intersection does.
    h0, h1, h2 = capsule_half(rot[b, 0, 0], rot[b, 0, 1], rot[b, 0, 2], rot[b, 1, 0], rot[b, 1, 1], rot[b, 1, 2],
                              rot[b, 2, 0], rot[b, 2, 1], rot[b, 2, 2], cap[k, 0], cap[k, 1], cap[k, 2],
                              cap[k, 3] + m, w[0], w[1], w[2])
    box[x, 0] = max(box[x, 0], w[0] - h0)
    box[x, 1] = max(box[x, 1], w[1] - h1)
    box[x, 2] = max(box[x, 2], w[2] - h2)
    box[x, 3] = min(box[x, 3], w[0] + h0)
    box[x, 4] = min(box[x, 4], w[1] + h1)
    box[x, 5] = min(box[x, 5], w[2] + h2)


@nb.njit(cache=True, inline="always")
def _pose_ok(r00, r01, r02, r10, r11, r12, r20, r21, r22, p0, p1, p2):
    # One test per body: R^T R = I within ORTHO_TOL, det > 0, a position within MAX_POSITION. Comparisons
    # with NaN are false, and an inf in R makes a product inf or NaN, so a non-finite pose
    # fails too (the caller tells which afterwards). det > 0 (no reflection): column 2 must
    # agree with column 0 x column 1 in sign.
    det = ((r10 * r21 - r20 * r11) * r02 + (r20 * r01 - r00 * r21) * r12
           + (r00 * r11 - r10 * r01) * r22)
    return ((abs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0) <= ORTHO_TOL)
            & (abs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0) <= ORTHO_TOL)
            & (abs(r02 * r02 + r12 * r12 + r22 * r22 - 1.0) <= ORTHO_TOL)
            & (abs(r00 * r01 + r10 * r11 + r20 * r21) <= ORTHO_TOL)
            & (abs(r00 * r02 + r10 * r12 + r20 * r22) <= ORTHO_TOL)
            & (abs(r01 * r02 + r11 * r12 + r21 * r22) <= ORTHO_TOL)
            & (det > 0.0) & (abs(p0) <= MAX_POSITION) & (abs(p1) <= MAX_POSITION) & (abs(p2) <= MAX_POSITION))


@nb.njit(cache=True, inline="always")
def aabb_slack(e0, e1, e2, c0, c1, c2):
    """The rounding slack added to each half-width of a world AABB (box half extents ``e``, centre
    ``c``): the OBB test's, so that rounding never lets a point of the box out of its AABB. One
    function for both kernels: the batch's lanes must round every AABB exactly as a single world
    does (a one-ulp difference lost a touching pair in `pairs_batch`)."""
    return SLACK_REL * (e0 + e1 + e2) + SLACK_POS * (abs(c0) + abs(c1) + abs(c2))


@nb.njit(cache=True, inline="always")
def _place(body_rot, body_pos, b, blocal, bcap, x, bw, baabb, saabb, baabb_t, has_flat, subtree):
    # World row of position x (body b's pose) and its AABB: the AABB of the world OBB cut to its
    # capsule's (`_cap_aabb`), also the start of its subtree AABB (stage 2 merges the descendants
    # in; with ``subtree``: the tree is walked), and its column of baabb_t with ``has_flat`` (flat
    # subtrees, or at most MASK_MAX positions: `_traverse` and `_scan_masks` read it there only).
    # baabb_t only with has_flat: its six stores into six rows were a visible part of the step of
    # a model that never reads it (the 64-link chain).
    # The slack of the OBB test (SLACK_REL of the size, SLACK_POS of the centre's magnitude): the
    # tree's AABB tests compare lo <= hi bare, and a tiny body far from the origin (1e-6 at 1e6)
    # would otherwise lose a pair the OBB test keeps (rounding of the centre > its guard).
    w = _world_row(body_rot, body_pos, b, blocal, x, bw, x)
    _world_aabb(w, 0.0, baabb, x)
    _cap_aabb(body_rot, b, bcap, x, w, 0.0, baabb, x)
    for i in range(6):
        v = baabb[x, i]
        if subtree:
            saabb[x, i] = v
        if has_flat:
            baabb_t[i, x] = v


@nb.njit(cache=True, inline="always")
def _sphere_hit(A, a, ma, B, b, mb, o=15):
    # Spheres (centre at columns o..o+2, radius at o+3) inflated by ma, mb overlap.
    dx = A[a, o] - B[b, o]
    dy = A[a, o + 1] - B[b, o + 1]
    dz = A[a, o + 2] - B[b, o + 2]
    r = A[a, o + 3] + ma + B[b, o + 3] + mb
    # Each box's magnitudes summed apart: the same bits in either order (the grid tests pairs in
    # its own order; with ma = mb = 0 the radius sum commutes too).
    pos = (abs(A[a, o]) + abs(A[a, o + 1]) + abs(A[a, o + 2])) + (abs(B[b, o]) + abs(B[b, o + 1]) + abs(B[b, o + 2]))
    r += SLACK_REL * r + SLACK_POS * pos
    return dot3(dx, dy, dz, dx, dy, dz) <= r * r


@nb.njit(cache=True, inline="always")
def _bounds_ok(ra, ma, rb, mb):
    """The one bounds test: spheres, then the OBBs' separating axes (15, Ericson 2005, *Real-Time
    Collision Detection* §4.4.1, in box A's frame: ``R[i, j] = A_i . B_j``, ``t`` = centre offset in
    A's frame; ``|R| + EPS_PAR`` so that near-parallel edge pairs never separate by rounding) of the
    bounds rows ``ra``, ``rb`` (19-tuples: a `ROW` each) inflated by ``ma``, ``mb``.

    Every axis is evaluated and the outcomes combined without a branch, so that a loop over pairs
    vectorises, and the vector forms are this source replayed (`pair_bits` here, `lanes.bounds8`):
    written with ``&`` and ``^ True`` (not ``not``) for that. An axis separates only when
    ``|t| > r`` holds: a NaN projection (inf - inf at coordinates near the float range) separates
    nothing. `_sphere_hit` is its first test alone, the cheap cull before it."""
    (A0, A1, A2, A3, A4, A5, A6, A7, A8, A9, A10, A11, A12, A13, A14, A15, A16, A17, A18) = ra
    (B0, B1, B2, B3, B4, B5, B6, B7, B8, B9, B10, B11, B12, B13, B14, B15, B16, B17, B18) = rb
    dx = A15 - B15
    dy = A16 - B16
    dz = A17 - B17
    r = A18 + ma + B18 + mb
    pos = ((abs(A15) + abs(A16) + abs(A17))
           + (abs(B15) + abs(B16) + abs(B17)))
    r += SLACK_REL * r + SLACK_POS * pos
    ok = dot3(dx, dy, dz, dx, dy, dz) <= r * r
    ea0 = A12 + ma
    ea1 = A13 + ma
    ea2 = A14 + ma
    eb0 = B12 + mb
    eb1 = B13 + mb
    eb2 = B14 + mb
    r00 = dot3(A3, A6, A9, B3, B6, B9)
    r01 = dot3(A3, A6, A9, B4, B7, B10)
    r02 = dot3(A3, A6, A9, B5, B8, B11)
    r10 = dot3(A4, A7, A10, B3, B6, B9)
    r11 = dot3(A4, A7, A10, B4, B7, B10)
    r12 = dot3(A4, A7, A10, B5, B8, B11)
    r20 = dot3(A5, A8, A11, B3, B6, B9)
    r21 = dot3(A5, A8, A11, B4, B7, B10)
    r22 = dot3(A5, A8, A11, B5, B8, B11)
    a00 = abs(r00) + EPS_PAR
    a01 = abs(r01) + EPS_PAR
    a02 = abs(r02) + EPS_PAR
    a10 = abs(r10) + EPS_PAR
    a11 = abs(r11) + EPS_PAR
    a12 = abs(r12) + EPS_PAR
    a20 = abs(r20) + EPS_PAR
    a21 = abs(r21) + EPS_PAR
    a22 = abs(r22) + EPS_PAR
    d0 = B0 - A0
    d1 = B1 - A1
    d2 = B2 - A2
    t0 = dot3(d0, d1, d2, A3, A6, A9)
    t1 = dot3(d0, d1, d2, A4, A7, A10)
    t2 = dot3(d0, d1, d2, A5, A8, A11)
    pos = abs(A0) + abs(A1) + abs(A2) + abs(B0) + abs(B1) + abs(B2)
    tol = SLACK_REL * (ea0 + ea1 + ea2 + eb0 + eb1 + eb2) + SLACK_POS * pos
    ok &= (abs(t0) > dot3_add(ea0, eb0, eb1, eb2, a00, a01, a02) + tol) ^ True
    ok &= (abs(t1) > dot3_add(ea1, eb0, eb1, eb2, a10, a11, a12) + tol) ^ True
    ok &= (abs(t2) > dot3_add(ea2, eb0, eb1, eb2, a20, a21, a22) + tol) ^ True
    ok &= (abs(dot3(t0, t1, t2, r00, r10, r20)) > dot3(ea0, ea1, ea2, a00, a10, a20) + eb0 + tol) ^ True
    ok &= (abs(dot3(t0, t1, t2, r01, r11, r21)) > dot3(ea0, ea1, ea2, a01, a11, a21) + eb1 + tol) ^ True
    ok &= (abs(dot3(t0, t1, t2, r02, r12, r22)) > dot3(ea0, ea1, ea2, a02, a12, a22) + eb2 + tol) ^ True
    ok &= (abs(fmuladd(-t1, r20, t2 * r10)) > fmuladd(eb2, a01, dot3(ea1, ea2, eb1, a20, a10, a02)) + tol) ^ True
    ok &= (abs(fmuladd(-t1, r21, t2 * r11)) > fmuladd(eb2, a00, dot3(ea1, ea2, eb0, a21, a11, a02)) + tol) ^ True
    ok &= (abs(fmuladd(-t1, r22, t2 * r12)) > fmuladd(eb1, a00, dot3(ea1, ea2, eb0, a22, a12, a01)) + tol) ^ True
    ok &= (abs(fmuladd(-t2, r00, t0 * r20)) > fmuladd(eb2, a11, dot3(ea0, ea2, eb1, a20, a00, a12)) + tol) ^ True
    ok &= (abs(fmuladd(-t2, r01, t0 * r21)) > fmuladd(eb2, a10, dot3(ea0, ea2, eb0, a21, a01, a12)) + tol) ^ True
    ok &= (abs(fmuladd(-t2, r02, t0 * r22)) > fmuladd(eb1, a10, dot3(ea0, ea2, eb0, a22, a02, a11)) + tol) ^ True
    ok &= (abs(fmuladd(-t0, r10, t1 * r00)) > fmuladd(eb2, a21, dot3(ea0, ea1, eb1, a10, a00, a22)) + tol) ^ True
    ok &= (abs(fmuladd(-t0, r11, t1 * r01)) > fmuladd(eb2, a20, dot3(ea0, ea1, eb0, a11, a01, a22)) + tol) ^ True
    ok &= (abs(fmuladd(-t0, r12, t1 * r02)) > fmuladd(eb1, a20, dot3(ea0, ea1, eb0, a12, a02, a21)) + tol) ^ True
    return ok


@nb.njit(cache=True, inline="always")
def _row_of_column(A, a, l):
    # Row l of the (ROW, n) block A[a] (rows as columns) as a 19-tuple.
    return (A[a, 0, l], A[a, 1, l], A[a, 2, l], A[a, 3, l], A[a, 4, l], A[a, 5, l], A[a, 6, l],
            A[a, 7, l], A[a, 8, l], A[a, 9, l], A[a, 10, l], A[a, 11, l], A[a, 12, l], A[a, 13, l],
            A[a, 14, l], A[a, 15, l], A[a, 16, l], A[a, 17, l], A[a, 18, l])


@nb.njit(cache=True, inline="always")
def _row_of(A, a):
    # Row A[a] of a (n, ROW) array as a 19-tuple.
    return (A[a, 0], A[a, 1], A[a, 2], A[a, 3], A[a, 4], A[a, 5], A[a, 6], A[a, 7], A[a, 8], A[a, 9],
            A[a, 10], A[a, 11], A[a, 12], A[a, 13], A[a, 14], A[a, 15], A[a, 16], A[a, 17], A[a, 18])


@nb.njit(cache=True, inline="always")
def bounds_mask(A, a, ma, B, b, mb, n):
    """Bit l set when the bounds in column l of ``A[a]`` and ``B[b]`` (``(ROW, n)`` blocks: rows as
    columns, one pair per column, n <= 64), inflated by ``ma``, ``mb``, overlap: `_bounds_ok`. The
    kernels use its vector form, `lanes.bounds8`; this loop is its twin in the tests."""
    m = np.uint64(0)
    for l in range(n):
        ok = _bounds_ok(_row_of_column(A, a, l), ma, _row_of_column(B, b, l), mb)
        m |= np.uint64(ok) << np.uint64(l)
    return m


@nb.njit(cache=True, inline="always")
def _pairs_mask(bw, bp, c0, n):
    """Bit l set when the body rows of pair ``bp[c0 + l]`` overlap (`_bounds_ok`, no inflation:
    the rows carry it), n <= 64; a marked second body (``~y``) is read as ``y``. The kernel runs
    its vector form, `pair_bits`, four pairs a call; this loop is its twin in the tests.

    Its rows are read where they are, into vectors (scalar loads and inserts on AMD Zen 3,
    four-lane gathers on the Intel Xeon): copying them into columns first made the stage slower."""
    m = np.uint64(0)
    for l in range(n):
        x = bp[c0 + l, 0]
        y = bp[c0 + l, 1]
        y = y ^ (y >> 63)
        ok = _bounds_ok(_row_of(bw, x), 0.0, _row_of(bw, y), 0.0)
        m |= np.uint64(ok) << np.uint64(l)
    return m


PAIR_LANES = 4  # pairs a call of `pair_bits` (see `_simd.gather_rows`: not LANES8)


@intrinsic
def pair_bits(typingctx, pw, pp, c, n):
    """`_pairs_mask` of the ``n`` (1..PAIR_LANES) pairs from row ``c`` of the ``(m, 2)`` int64 pair
    array at address ``pp`` (a second body marked ``~y`` read as ``y``), over the ``(L, ROW)`` rows at
    address ``pw``: `_bounds_ok`'s source replayed on ``<PAIR_LANES x double>`` vectors (`_simd._py`:
    the same operations in the same order, the same bits), the rows' fields gathered
    (`_simd.gather_rows`), the outcome one vector compare's mask. A lane past ``n`` tests pair ``c``
    again and its bit is dropped: no row past the pairs is read.

    The loop over the pairs it replaces (`_pairs_mask`, now the tests' twin) built its mask with a
    shift and an or a pair: slower in a simulation loop on scenes of many body pairs (cube_3x3x3,
    stonehenge), even on the robots with a few (Intel Xeon)."""
    if not all(a == types.int64 for a in (pw, pp, c, n)):
        return None
    sig = types.uint64(pw, pp, c, n)

    def codegen(context, builder, signature, args):
        aw, ap, cc, nn = args
        i64 = ir.IntType(64)
        pi = builder.inttoptr(ap, i64.as_pointer())
        xs, ys = [], []
        for l in range(PAIR_LANES):
            j = builder.add(cc, builder.select(builder.icmp_signed("<", ir.Constant(i64, l), nn),
                                               ir.Constant(i64, l), ir.Constant(i64, 0)))
            x = builder.load(builder.gep(pi, [builder.mul(j, ir.Constant(i64, 2))]), align=8)
            y = builder.load(builder.gep(pi, [builder.add(builder.mul(j, ir.Constant(i64, 2)), ir.Constant(i64, 1))]),
                             align=8)
            xs.append(x)
            ys.append(builder.xor(y, builder.ashr(y, ir.Constant(i64, 63))))  # ~y -> y
        ok = _py(_bounds_ok)(tuple(gather_rows(builder, aw, xs, ROW, ROW)), 0.0,
                             tuple(gather_rows(builder, aw, ys, ROW, ROW)), 0.0)
        keep = builder.sub(builder.shl(ir.Constant(i64, 1), nn), ir.Constant(i64, 1))
        return builder.and_(ok.bits(), keep)

    return sig, codegen


@nb.njit(cache=True, inline="always")
def _plane_hit_local(n0, n1, n2, lim, scale, Lr, g, mg):
    # Both of Lr[g]'s volumes, inflated by mg, reach the halfspace {n . x <= lim}; ``scale`` is
    # the magnitude of the world coordinates involved (the slack covers their rounding). Also in
    # a body's frame (n = R^T n_world, lim = d + mq - n_world . p), n . (R c + p) = (R^T n) . c +
    # n . p: a multi-geom body's geoms need their world AABBs only (their corner test), not their
    # sphere and box moved into the world.
    # Both tests always, no branch on the sphere's outcome (a misprediction costs more than the
    # box's dozen flops; see _subtree_pair).
    sc = dot3(n0, n1, n2, Lr[g, 15], Lr[g, 16], Lr[g, 17])
    r = Lr[g, 18] + mg
    c = dot3(n0, n1, n2, Lr[g, 0], Lr[g, 1], Lr[g, 2])
    ext = dot3(abs(dot3(n0, n1, n2, Lr[g, 3], Lr[g, 6], Lr[g, 9])),
               abs(dot3(n0, n1, n2, Lr[g, 4], Lr[g, 7], Lr[g, 10])),
               abs(dot3(n0, n1, n2, Lr[g, 5], Lr[g, 8], Lr[g, 11])), Lr[g, 12] + mg, Lr[g, 13] + mg, Lr[g, 14] + mg)
    return ((sc - r <= lim + SLACK_REL * r + SLACK_POS * scale)
            & (c - ext <= lim + SLACK_REL * ext + SLACK_POS * scale))


@nb.njit(cache=True, inline="always")
def _plane_hit(pl, q, mq, B, b, mb):
    # World row B[b], inflated by mb, against plane row pl[q] = (n, d) inflated by mq.
    return _plane_hit_local(pl[q, 0], pl[q, 1], pl[q, 2], pl[q, 3] + mq,
                            abs(B[b, 0]) + abs(B[b, 1]) + abs(B[b, 2]) + abs(pl[q, 3]), B, b, mb)


@nb.njit(cache=True, inline="always")
def _aabb_hit(X, x, Y, y):
    # The hot loops of the traversal write this test out instead of calling it: even inlined,
    # a call with array arguments keeps an incref/decref pair per array where numba counts
    # references, as in the walk (`_traverse`).
    return ((X[x, 0] <= Y[y, 3]) & (Y[y, 0] <= X[x, 3]) & (X[x, 1] <= Y[y, 4]) & (Y[y, 1] <= X[x, 4])
            & (X[x, 2] <= Y[y, 5]) & (Y[y, 2] <= X[x, 5]))


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


# ------------------------------------------------------------------------------- traversal

@nb.njit(cache=True, inline="always")
def _row_hits(bt_at, stride, base, a, keep):
    # The bits i of keep (the pair of column a and column base + i) whose boxes meet, the boxes the
    # columns of the (6, stride) array at address bt_at (lo x, y, z, hi x, y, z). Only the span of
    # keep's bits is tested (pairs are stored once, a < q: a row tests its later partners only),
    # LANES8 at a time in one vector compare
    # (`_simd.box_row8`; as a loop over the columns the compiler built the mask with a shift and an
    # or per column). Its reads past the span (at most LANES8 - 1 columns past the last, into what
    # follows the array in W: plw and tmp after baabb_t, the coherence state after fat_t) give bits
    # that keep drops. Scalars in (a pointer view inside): no reference counting in `_traverse`.
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
        hits |= box_row8(bt_at, stride, base + i, l0, l1, l2, h0, h1, h2) << np.uint64(i)
        i += LANES8
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
FLAT_DESC = 16  # a body with at most this many descendants tests them all flat, else walks
FLAT_MAX = 4096  # _subtree_pair: at most this many body x body tests flat, else the walk


@nb.njit(**NO_NRT)
def _subtree_pair(A, B, end, baabb, saabb, has_bounds, bp, nb_, stats, lst):
    """Every body of subtree A against every body of subtree B (disjoint subtrees whose AABBs meet).

    Flat and branch-free: the bodies of A whose AABB meets B's subtree AABB, those of B meeting
    A's (``lst``: int64 scratch of at least ``end[A] - A + end[B] - B``), then all pairs of the
    two lists. In a simulation loop the outcome of each test is data that the branch predictor,
    retrained by the engine between steps, cannot foresee: a walk that branches on it costs a
    misprediction per test (after `mj_step` on 22 humanoids the listed child pairs took less time
    than the walk). Past ``FLAT_MAX`` pair tests (two big subtrees deep in each other) the walk,
    whose culling then pays, runs instead.
    """
    ea = end[A]
    eb = end[B]
    if ea == A + 1 and eb == B + 1:  # two leaves: their subtree AABBs were just tested
        stats[ST_BODY_AABB] += 1
        return _push(bp, nb_, A, B) if has_bounds[A] and has_bounds[B] else nb_
    na = 0
    for a in range(A, ea):
        lst[na] = a
        na += np.int64((baabb[a, 0] <= saabb[B, 3]) & (saabb[B, 0] <= baabb[a, 3]) & (baabb[a, 1] <= saabb[B, 4])
                       & (saabb[B, 1] <= baabb[a, 4]) & (baabb[a, 2] <= saabb[B, 5]) & (saabb[B, 2] <= baabb[a, 5]))
    nbl = 0
    for b in range(B, eb):
        lst[na + nbl] = b
        nbl += np.int64((baabb[b, 0] <= saabb[A, 3]) & (saabb[A, 0] <= baabb[b, 3]) & (baabb[b, 1] <= saabb[A, 4])
                        & (saabb[A, 1] <= baabb[b, 4]) & (baabb[b, 2] <= saabb[A, 5]) & (saabb[A, 2] <= baabb[b, 5]))
    stats[ST_SUBTREE] += ea - A + eb - B
    if na * nbl > FLAT_MAX:
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
    # Bodies without bounds have an empty AABB (lo > hi): never in a list.
    cap = bp.shape[0]
    for i in range(na):
        a = lst[i]
        for j in range(na, na + nbl):
            b = lst[j]
            if nb_ < cap:
                bp[nb_, 0] = a
                bp[nb_, 1] = b
            nb_ += np.int64((baabb[a, 0] <= baabb[b, 3]) & (baabb[b, 0] <= baabb[a, 3]) & (baabb[a, 1] <= baabb[b, 4])
                            & (baabb[b, 1] <= baabb[a, 4]) & (baabb[a, 2] <= baabb[b, 5])
                            & (baabb[b, 2] <= baabb[a, 5]))
    stats[ST_BODY_AABB] += na * nbl
    return nb_


@nb.njit(cache=True, _nrt=True)  # allocates: counted (see NO_NRT; a callee takes its caller's flag)
def _grid_pairs(n, off, kc, children, saabb, end, baabb, has_bounds, bw, bp, nb_, stats, lst, use_sph):
    """Pairs of overlapping child subtrees of a wide node through a uniform hash grid.

    A sweep on one axis tests O(k^(5/3)) pairs when k children fill a volume (a scene of free
    bodies); a grid whose cell is at least every child's extent finds overlaps in O(k): each child
    sits in the cell of its AABB's min corner, and two overlapping AABBs have min corners at most
    one cell apart per axis, so a child's own cell and its 13 forward neighbours cover every pair
    exactly once. Children much larger than the mean (over four times) would inflate the cell;
    they are tested against every child instead. Without ``use_sph`` (a walk over fat boxes, see ``FAT_GROW``), two
    leaf bodies are paired on their boxes alone: the spheres in ``bw`` are the exact ones.
    """
    ext = np.empty(kc)
    total = 0.0
    nvalid = 0
    for i in range(kc):
        c = children[off + i]
        if saabb[c, 0] > saabb[c, 3]:
            ext[i] = -1.0  # no bounds in this subtree
            continue
        e = max(saabb[c, 3] - saabb[c, 0], saabb[c, 4] - saabb[c, 1], saabb[c, 5] - saabb[c, 2])
        ext[i] = e
        total += e
        nvalid += 1
    if nvalid < 2:
        return nb_
    lim = 4.0 * total / nvalid
    h = 0.0
    for i in range(kc):
        if ext[i] <= lim and ext[i] > h:
            h = ext[i]
    scale = 0.0
    for d in range(6):
        scale += abs(saabb[n, d])
    span = max(saabb[n, 3] - saabb[n, 0], saabb[n, 4] - saabb[n, 1], saabb[n, 5] - saabb[n, 2])
    # The slack (1e-9 of a cell) must dwarf the rounding of (lo - origin) / h, ~1e-16 of the cell
    # index: at most 1e6 cells per axis keeps it so (a coarser grid is still correct).
    h = max(h * (1.0 + 1e-9), 1e-6 * span, 1e-12 * scale, 1e-300)
    ox = saabb[n, 0]
    oy = saabb[n, 1]
    oz = saabb[n, 2]
    T = 16
    while T < 2 * nvalid:
        T *= 2
    # Cells as one int64 key (21 bits per axis: at most 1e6 cells per axis, see h above), counting
    # sort by hash slot, then everything a query reads copied contiguously in slot order.
    key = np.empty(kc, np.int64)
    slot = np.empty(kc, np.int64)
    cnt = np.zeros(T + 1, np.int64)
    for i in range(kc):
        if ext[i] < 0.0 or ext[i] > lim:
            slot[i] = -1
            continue
        c = children[off + i]
        cx = np.int64((saabb[c, 0] - ox) / h)
        cy = np.int64((saabb[c, 1] - oy) / h)
        cz = np.int64((saabb[c, 2] - oz) / h)
        key[i] = (cx << 42) | (cy << 21) | cz
        sl = ((cx * 73856093) ^ (cy * 19349663) ^ (cz * 83492791)) & (T - 1)
        slot[i] = sl
        cnt[sl + 1] += 1
    for t in range(T):
        cnt[t + 1] += cnt[t]
    m = cnt[T]
    skey = np.empty(m, np.int64)
    sbox = np.empty((m, 10))  # AABB, then a leaf body's sphere (centre, radius)
    schild = np.empty(m, np.int64)
    fill = cnt[:T].copy()
    for i in range(kc):
        sl = slot[i]
        if sl >= 0:
            u = fill[sl]
            fill[sl] += 1
            c = children[off + i]
            skey[u] = key[i]
            schild[u] = c
            for d in range(6):
                sbox[u, d] = saabb[c, d]
            for d in range(4):
                sbox[u, 6 + d] = bw[c, 15 + d]
    ntest = 0
    nsph = 0
    cap = bp.shape[0]
    for u in range(m):
        ci = schild[u]
        k0 = skey[u]
        cx = k0 >> 42
        cy = (k0 >> 21) & 0x1FFFFF
        cz = k0 & 0x1FFFFF
        lo0 = sbox[u, 0]
        lo1 = sbox[u, 1]
        lo2 = sbox[u, 2]
        hi0 = sbox[u, 3]
        hi1 = sbox[u, 4]
        hi2 = sbox[u, 5]
        leaf_i = end[ci] == ci + 1
        # Cells of the max corner: a box in the next cell along +x can only overlap this one if
        # this box reaches that cell (the cell index is monotone in the coordinate, so this is
        # exact under rounding); most boxes do not, and then 9 of the 13 neighbours are skipped.
        hx = np.int64((hi0 - ox) / h)
        hy = np.int64((hi1 - oy) / h)
        hz = np.int64((hi2 - oz) / h)
        for f in range(-1, 13):
            if f < 0:
                nx, ny, nz = cx, cy, cz
            else:
                nx = cx + _FWD[f, 0]
                ny = cy + _FWD[f, 1]
                nz = cz + _FWD[f, 2]
                if nx < 0 or ny < 0 or nz < 0:
                    continue
                if (nx > hx) or (ny > cy and ny > hy) or (nz > cz and nz > hz):
                    continue
            nkey = (nx << 42) | (ny << 21) | nz
            sl = ((nx * 73856093) ^ (ny * 19349663) ^ (nz * 83492791)) & (T - 1)
            # Own cell: the entries after u (each pair once). Another cell hashed to the same slot
            # fails the key test, folded into the hit like the boxes' (no branch on it).
            for v in range(u + 1 if f < 0 else cnt[sl], cnt[sl + 1]):
                ntest += 1
                sph = _sphere_hit(sbox, u, 0.0, sbox, v, 0.0, 6)  # before the AABB: no branch around it
                hit = ((skey[v] == nkey) & (sbox[v, 0] <= hi0) & (lo0 <= sbox[v, 3]) & (sbox[v, 1] <= hi1)
                       & (lo1 <= sbox[v, 4]) & (sbox[v, 2] <= hi2) & (lo2 <= sbox[v, 5]))
                cj = schild[v]
                if leaf_i and end[cj] == cj + 1:
                    # Two bodies (a leaf in the grid has bounds): their sphere test too, on the
                    # contiguous copies (the same arithmetic as _sphere_hit; ~x marks the pair as
                    # tested), both written without a branch on the outcome (see _subtree_pair:
                    # fewer mispredictions on a scene of many free hulls).
                    nsph += 1
                    if nb_ < cap:
                        bp[nb_, 0] = ~ci
                        bp[nb_, 1] = cj
                    nb_ += np.int64((sph | (not use_sph)) & hit)
                elif hit:
                    nb_ = _subtree_pair(ci, cj, end, baabb, saabb, has_bounds, bp, nb_, stats, lst)
    stats[ST_SUBTREE] += ntest
    stats[ST_BODY_SPHERE] += nsph
    # the oversized children against every child
    for i in range(kc):
        if ext[i] <= lim:
            continue
        ci = children[off + i]
        for j in range(kc):
            if j == i or ext[j] < 0.0 or (ext[j] > lim and j < i):
                continue
            cj = children[off + j]
            stats[ST_SUBTREE] += 1
            if ((saabb[ci, 0] <= saabb[cj, 3]) & (saabb[cj, 0] <= saabb[ci, 3]) & (saabb[ci, 1] <= saabb[cj, 4])
                    & (saabb[cj, 1] <= saabb[ci, 4]) & (saabb[ci, 2] <= saabb[cj, 5]) & (saabb[cj, 2] <= saabb[ci, 5])):
                nb_ = _subtree_pair(ci, cj, end, baabb, saabb, has_bounds, bp, nb_, stats, lst)
    return nb_


@nb.njit(cache=True, _nrt=True)  # allocates: counted (see NO_NRT; a callee takes its caller's flag)
def _traverse(L, end, nchild, child_start, children, has_bounds, baabb, saabb, bw, sap, bp, stats, filter_parent,
              baabb_t, flat_root, flat_n, flat_mask, use_sph):
    """Candidate body pairs (world AABBs overlap) into ``bp``; returns their count (may exceed cap).

    ``sap`` (`sap_state`): the sweep orders of the children lists, then scratch for `_subtree_pair`.
    ``baabb``, ``saabb``, ``baabb_t``: the exact boxes, or the fat ones with ``use_sph`` false (see
    `_grid_pairs`).
    """
    nb_ = 0
    lst = sap[L - 1:]
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
            # (baabb_t) in vector compares, into a bit mask; the static one keeps the pairs to
            # push. No walk, no sibling pairs, no call (faster than the pair tests one by one).
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
            if end[n] - n - 1 > FLAT_DESC or nchild[n] < 2:
                nb_ = _body_walk(n, n + 1, end[n], skip, end, baabb, saabb, has_bounds, bp, nb_, stats)
            else:
                # A small branching subtree: every descendant's body AABB against n's, flat,
                # independent tests (no subtree AABB steering a walk: fewer tests than the walk's
                # two per inner body, and no branch on their outcomes). Below a single child (a
                # chain) the walk stops after a few links, the flat loop would test them all. A body without bounds has
                # an empty AABB: never a hit.
                nxt = n + 1  # the next direct child
                cap = bp.shape[0]
                for q in range(n + 1, end[n]):
                    top = q == nxt
                    nxt = end[q] if top else nxt
                    if nb_ < cap:
                        bp[nb_, 0] = n
                        bp[nb_, 1] = q
                    nb_ += np.int64((baabb[n, 0] <= baabb[q, 3]) & (baabb[q, 0] <= baabb[n, 3])
                                    & (baabb[n, 1] <= baabb[q, 4]) & (baabb[q, 1] <= baabb[n, 4])
                                    & (baabb[n, 2] <= baabb[q, 5]) & (baabb[q, 2] <= baabb[n, 5]) & ~(top & skip))
                stats[ST_BODY_AABB] += end[n] - n - 1
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
                            nb_ = _subtree_pair(ci, cj, end, baabb, saabb, has_bounds, bp, nb_, stats, lst)
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
        if kc > GRID_MIN:
            # Grid or sweep: k children of mean width w on an axis of extent E give the sweep
            # ~k^2 w / E interval tests, the grid ~k cell probes of a few tests each. A scene
            # filling a volume (free bodies in a box) goes to the grid; bodies spread over a floor
            # (objects, robots, stones) overlap little along the sweep axis and the sweep, with
            # its persistent order and no set-up, wins (humanoid100, stonehenge). Up to GRID_MIN
            # children the sweep wins even in a filled volume (64 free hulls, cube_3x3x3's 26
            # cubelets); with a few hundred the grid does.
            sumw = 0.0
            for i in range(kc):
                c = children[off + i]
                w = saabb[c, 3 + ax] - saabb[c, ax]
                if w > 0.0:
                    sumw += w
            if sumw > GRID_SWEEP * best:
                nb_ = _grid_pairs(n, off, kc, children, saabb, end, baabb, has_bounds, bw, bp, nb_, stats, lst, use_sph)
                continue
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
                    # _subtree_pair); a body without bounds has an empty AABB, never a hit.
                    if nb_ < cap:
                        bp[nb_, 0] = ci
                        bp[nb_, 1] = cj
                    nb_ += np.int64(hit)
                elif hit:
                    nb_ = _subtree_pair(ci, cj, end, baabb, saabb, has_bounds, bp, nb_, stats, lst)
            stats[ST_SUBTREE] += ntest
    return nb_


# ------------------------------------------------------------------------------- one world

@nb.njit(**NO_NRT)
def _sweep(saabb, parent_pos, L):
    """Subtree AABBs: one reverse sweep over the positions, children before parents, each row of
    ``saabb`` started as its body's AABB.

    The box merged last is carried in registers when the next position is its parent (always,
    down a chain): through memory, each merge waits for the previous one's store. On the 64-link
    chain the gain was within this machine's run-to-run noise. Same min and max, same order: the
    same bits.
    """
    for x in range(L - 1, 0, -1):
        if x == L - 1 or parent_pos[x + 1] != x:  # else saabb[x] was merged last: a0..a5 hold it
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
        if x < 0:
            x = ~x  # the grid's sphere test mark: redone below with the OBB test, at no cost
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
        # batch's lanes test each pair in this order (a sweep or the grid may hand it reversed).
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
    # x < y; each row's box is tested against its partners' columns of the (6, L) boxes baabb_t,
    # LANES8 a vector compare (`_simd.box_row8`, as the flat roots' rows in `_traverse`), the pairs
    # that meet go into bp in (x, y) order (counted past its end, not written), y marked ~y when
    # loose (a multi-geom body's, ``single < 0``, as `_filter` writes it). Reads past column L - 1
    # (at most LANES8 - 1 float64, into plw and tmp after baabb_t in W) give bits the mask drops.
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


def sap_state(children: np.ndarray) -> np.ndarray:
    """The traversal's int64 state for ``L`` positions (``children``: ``L - 1`` ids): the children
    lists in their initial sweep order, then ``L`` of scratch (`_subtree_pair`)."""
    return np.concatenate([children, np.zeros(len(children) + 1, np.int64)]).astype(np.int64)


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
    # whatever the order). A sweep or a grid over many siblings shuffles the keys (cube_3x3x3: 85
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


@nb.njit(cache=True, inline="always")
def _geom_rows(x, order, gstart, pgeoms, glocal, gcap, gmargin, body_pos, body_rot, gw, gaabb, gstamp, stamp):
    # World rows and margin-inflated AABBs of the geoms of the multi-geom body at position x, once
    # per call. Each AABB (its OBB's cut to its capsule's, with the OBB test's slack) contains the
    # inflated shape; the capsule's cut rejects pairs whose OBBs still meet (limbs at an angle).
    if gstamp[x] == stamp:
        return
    gstamp[x] = stamp
    b = order[x]
    for ii in range(gstart[x], gstart[x + 1]):
        g = pgeoms[ii]
        w = _world_row(body_rot, body_pos, b, glocal, g, gw, g)
        _world_aabb(w, gmargin[g], gaabb, g)
        _cap_aabb(body_rot, b, gcap, g, w, gmargin[g], gaabb, g)


@nb.njit(cache=True, inline="always")
def plane_world(r00, r01, r02, r10, r11, r12, r20, r21, r22, p0, p1, p2, n0, n1, n2, d):
    """The world halfspace ``(m, e)``, ``{x : m . x <= e}``, unit ``m``, of the local one
    ``{y : n . y <= d}`` under ``x = R y + p``: ``m`` along ``R^-T n``, the cofactor matrix of R
    times n (``R^-T = cof(R) / det R``), exact for any proper R. ``R n`` is right only for an exact
    rotation: under one accepted within ORTHO_TOL the plane moved by up to the tolerance times the
    distance from the body (0.1 at 100 km; review, 2026-11-22). Both kernels call this (the
    lanes must round as one world does)."""
    # rows of cof(R): r1 x r2, r2 x r0, r0 x r1
    w0 = (r11 * r22 - r12 * r21) * n0 + (r12 * r20 - r10 * r22) * n1 + (r10 * r21 - r11 * r20) * n2
    w1 = (r21 * r02 - r22 * r01) * n0 + (r22 * r00 - r20 * r02) * n1 + (r20 * r01 - r21 * r00) * n2
    w2 = (r01 * r12 - r02 * r11) * n0 + (r02 * r10 - r00 * r12) * n1 + (r00 * r11 - r01 * r10) * n2
    det = r00 * (r11 * r22 - r12 * r21) + r01 * (r12 * r20 - r10 * r22) + r02 * (r10 * r21 - r11 * r20)
    norm = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    m0 = w0 / norm
    m1 = w1 / norm
    m2 = w2 / norm
    # n . R^-1 (x - p) <= d  <=>  w . x <= d det + w . p, divided by |w|. The offset carries the
    # rounding of m . p, ~eps |p|: covered here, where |p| is known (the plane tests' own slack
    # sees only |e|, which is small for a plane through the origin on a body at 1e9: a touching
    # ball was lost; review, 2026-11-22).
    e = d * (det / norm) + m0 * p0 + m1 * p1 + m2 * p2 + SLACK_POS * (abs(p0) + abs(p1) + abs(p2))
    return m0, m1, m2, e


@nb.njit(cache=True, inline="always")
def _plane_world(g, body_pos, body_rot, geom_bid, gplane, out, o):
    b = geom_bid[g]
    m0, m1, m2, e = plane_world(body_rot[b, 0, 0], body_rot[b, 0, 1], body_rot[b, 0, 2], body_rot[b, 1, 0],
                                body_rot[b, 1, 1], body_rot[b, 1, 2], body_rot[b, 2, 0], body_rot[b, 2, 1],
                                body_rot[b, 2, 2], body_pos[b, 0], body_pos[b, 1], body_pos[b, 2],
                                gplane[g, 0], gplane[g, 1], gplane[g, 2], gplane[g, 3])
    out[o, 0] = m0
    out[o, 1] = m1
    out[o, 2] = m2
    out[o, 3] = e


@nb.njit(cache=True, inline="always")
def _explicit_hit(i, pair_g, pair_m, gmargin, gplane, geom_bid, glocal, body_pos, body_rot, tmp, stats):
    # Explicit pair i: its geoms' world bounds (rows 0 and 1 of tmp), inflated by the pair's own
    # margin if given, else the geoms'; a plane against the other geom's bounds; never two planes.
    g1 = pair_g[i, 0]
    g2 = pair_g[i, 1]
    m1 = gmargin[g1] if np.isnan(pair_m[i]) else pair_m[i]
    m2 = gmargin[g2] if np.isnan(pair_m[i]) else pair_m[i]
    p1 = gplane[g1, 0] != 0.0 or gplane[g1, 1] != 0.0 or gplane[g1, 2] != 0.0
    p2 = gplane[g2, 0] != 0.0 or gplane[g2, 1] != 0.0 or gplane[g2, 2] != 0.0
    if p1 and p2:
        return False
    if p1 or p2:
        gp = g1 if p1 else g2
        gs = g2 if p1 else g1
        mp = m1 if p1 else m2
        ms = m2 if p1 else m1
        _plane_world(gp, body_pos, body_rot, geom_bid, gplane, tmp, 0)
        _world_row(body_rot, body_pos, geom_bid[gs], glocal, gs, tmp, 1)
        stats[ST_PLANE] += 1
        return _plane_hit(tmp, 0, mp, tmp, 1, ms)
    _world_row(body_rot, body_pos, geom_bid[g1], glocal, g1, tmp, 0)
    _world_row(body_rot, body_pos, geom_bid[g2], glocal, g2, tmp, 1)
    stats[ST_GEOM_SPHERE] += 1
    if not _sphere_hit(tmp, 0, m1, tmp, 1, m2):
        return False
    stats[ST_GEOM_OBB] += 1
    return _bounds_ok(_row_of(tmp, 0), m1, _row_of(tmp, 1), m2)


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
