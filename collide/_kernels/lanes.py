"""Batched broad phase, eight worlds at a time in SIMD lanes, for models of a few thousand body pairs.

The per-world kernel (`broadphase._world`) branches on every outcome it can and walks the tree:
right for one world, where most bodies are far apart. A batch of worlds of one small model (a
robot, a creature: reinforcement learning, sampling-based planning) runs the same model many
times; here every static candidate -- each body pair that passes the static filter, each (plane,
body) pair, each explicit pair -- is tested in ``LANES`` worlds at once, without a branch, and the
outcomes kept as a lane bit mask. Only a pair that hits in some lane goes on to its next test. The
hot tests (`lane_tests`: `bounds8`, `place8`, `pose_ok8`, `plane8`, `corner8`, `plane_hit8`) are the scalar
functions' source replayed on ``<LANES x double>`` LLVM vectors (`_simd._py`): one instruction an
operation on AVX-512, the mask one compare's; written as loops over the lanes they compiled to
4-wide vectors and built each mask with a shift and an or per lane.

The answer is the per-world kernel's, bit for bit: the same tests (body AABBs, the static filter,
body sphere and OBB, the geoms' AABB, sphere and OBB, the planes', explicit pairs) in the same
floating-point operations, and every key a world may report has a *rank* (its place among all of
them, sorted): a world's hits set bits of a bitset, which read in order give its sorted keys, no
sort. A group holding a bad pose is run world by world by `broadphase._world` instead, which names
the offender.

Static tables (``J``, int64; `pack_lanes` builds them from the per-world model, see
`collide.broadphase.BroadPhase`): the body pairs ``(x, y)`` (positions, x < y), each with its geom
pairs ``(g1, g2, rank)``; the (plane, position) pairs, each with its geoms ``(g, rank)``; the rank of
each explicit pair; the keys by rank.
"""

from __future__ import annotations

import numba as nb
from numba.cpython.unsafe.numbers import trailing_zeros
import numpy as np

from ._ptr import check_span, f64_ptr, i64_ptr
from ._simd import LANES, aabb_mask8, aabb_merge8
from ._threads import set_chunksize
from .batch import CI_KEYS, _batch_world, chunk_buffers, gather_batch, next_chunk, start_chunks
from .bounds import BIG, SLACK_POS, _explicit_hit, _plane_hit_local, dot3
from .lane_tests import AABB_BYTES, POSE_BYTES, ROW_BYTES, bounds8, corner8, place8, plane8, plane_hit8, pose_ok8
from .layout import (F_BCAP, F_BLOCAL, F_GCAP, F_GLOCAL, F_GMARGIN, F_GPLANE, F_PAIR_M, H_L, H_NB, I_END, I_GEOM_BID,
                     I_GSTART, I_HAS_BOUNDS, I_ORDER, I_PAIR_G, I_PARENT_POS, I_PGEOMS, I_PLANES, I_SINGLE,
                     J_BODY_PAIRS, J_EXPLICIT_RANK, J_PAIR_GEOMS, J_PAIR_GSTART, J_PLANE_GEOMS, J_PLANE_GSTART,
                     J_PLANE_POS, J_PLANE_START, J_RANK_KEYS, J_ROW_START, LB_BITS, LB_STAMP, LTAB, LW_GA, LW_GW,
                     LW_PLN, LW_POSES, LW_SA, LW_WA, LW_WB, N_STATS, ROW, ST_BODY_OBB, ST_BODY_SPHERE, ST_GEOM_AABB,
                     ST_GEOM_OBB, ST_GEOM_SPHERE, ST_OUT, ST_PLANE, ST_SUBTREE, W_TMP, address, view_f1, view_f2,
                     view_f3, view_i1, view_i2)
from .step import C_KEYS, C_NKEYS
MAX_BODY_PAIRS = 4096  # above this many static body pairs, the tree of the per-world kernel culls better

# Header of J: counts (then the field table of `layout.LANE_TABLES`).
J_NP, J_NLG, J_NPL, J_NPLG, J_NR, J_P, J_NV, J_Q = range(8)
J_HEADER = 8


def lane_dims(J: np.ndarray, L: int) -> dict:
    """The counts of the layouts of `layout.LANE_TABLES` (``J``, the bitsets ``LB``) from ``J``'s
    header, for ``L`` positions."""
    NR = int(J[J_NR])
    return {"NP": int(J[J_NP]), "NLG": int(J[J_NLG]), "NPL": int(J[J_NPL]), "NPLG": int(J[J_NPLG]), "NR": NR,
            "P": int(J[J_P]), "L": L, "Q": int(J[J_Q]), "NWd": (NR + 63) // 64}


def pack_lanes(L: int, Q: int, **fields) -> np.ndarray:
    """The lane tables as one int64 array (`layout.LTAB`'s fields by name, for ``L`` positions and
    ``Q`` planes).

    ``body_pairs`` (NP, 2) positions, sorted, position a's at ``row_start[a]:row_start[a + 1]``;
    ``pair_geoms`` (NLG, 3) ``(g1, g2, rank)`` with pair p's at ``pair_gstart[p]:pair_gstart[p + 1]``;
    ``plane_pos`` (NPL,) positions, plane i's at ``plane_start[i]:plane_start[i + 1]``;
    ``plane_geoms`` (NPLG, 2) ``(g, rank)``, entry e's at ``plane_gstart[e]:plane_gstart[e + 1]``;
    ``explicit_rank`` (P,) (-1: never reported); ``rank_keys`` (NR,) sorted keys.
    """
    head = np.zeros(J_HEADER, np.int64)
    head[[J_NP, J_NLG, J_NPL, J_NPLG, J_NR, J_P, J_NV, J_Q]] = (
        len(fields["body_pairs"]), len(fields["pair_geoms"]), len(fields["plane_pos"]), len(fields["plane_geoms"]),
        len(fields["rank_keys"]), len(fields["explicit_rank"]), LANES, Q)
    return LTAB.pack(lane_dims(head, L), head, **fields)


# ------------------------------------------------------------------------------- lane tests
# The hot ones are `lane_tests`' intrinsics; here the rest, as loops over the lanes, the lane index
# innermost.

@nb.njit(cache=True, inline="always")
def _corner_in(n0, n1, n2, pd, lim, box, k, l):
    # Lane l of AABB box[k] ((6, LANES): lo then hi) reaches the halfspace {n . x <= lim} of a
    # plane at offset pd: its corner deepest along -n, as `broadphase._world`'s stage 5a. Both
    # corners are loaded and one selected by value (a load under a condition keeps the loop over
    # the lanes from vectorising).
    lo0 = box[k, 0, l]
    lo1 = box[k, 1, l]
    lo2 = box[k, 2, l]
    hi0 = box[k, 3, l]
    hi1 = box[k, 4, l]
    hi2 = box[k, 5, l]
    v = dot3(n0, n1, n2, lo0 if n0 > 0 else hi0, lo1 if n1 > 0 else hi1, lo2 if n2 > 0 else hi2)
    return v <= lim + SLACK_POS * (abs(v) + abs(pd))


@nb.njit(cache=True, inline="always")
def _set_bits(bits, r, m, nv):
    # Rank r in the bitset of every lane in mask m.
    wi = r >> 6
    bit = np.uint64(1) << np.uint64(r & 63)
    for l in range(nv):
        bits[wi, l] |= np.int64(bit * ((m >> np.uint64(l)) & np.uint64(1)))


@nb.njit(cache=True, inline="always")
def _lane_pair(p, m, x, y, single, wb, wa_at, stamp, order, gstart, pgeoms, glocal, gcap, gmargin, ps, gwl, gal,
               gal_at, pair_gstart, pair_geoms, bits, stats, nv):
    # Static body pair p = (x, y), whose AABBs meet in the lanes of m: body sphere and OBB, then
    # its geom pairs (`_world`, stage 4), the hits into the lanes' bitsets.
    sx = single[x] > 0
    sy = single[y] > 0
    wb_at = np.int64(wb.ctypes.data)
    gw_at = np.int64(gwl.ctypes.data)
    if single[x] >= 0 and single[y] >= 0:  # a loose body skips its body-level tests (see _world)
        n = _popcount(m)
        stats[ST_BODY_SPHERE] += n
        stats[ST_BODY_OBB] += n
        m &= bounds8(wb_at + ROW_BYTES * x, 0.0, wb_at + ROW_BYTES * y, 0.0)
        if m == 0:
            return
    if not sx:
        _lane_geoms(x, stamp, order, gstart, pgeoms, glocal, gcap, gmargin, ps, gwl, gal, nv)
    if not sy:
        _lane_geoms(y, stamp, order, gstart, pgeoms, glocal, gcap, gmargin, ps, gwl, gal, nv)
    for e in range(pair_gstart[p], pair_gstart[p + 1]):
        g1 = pair_geoms[e, 0]
        g2 = pair_geoms[e, 1]
        mm = m
        if not (sx and sy):
            n = _popcount(m)
            stats[ST_GEOM_AABB] += n
            stats[ST_GEOM_SPHERE] += n
            stats[ST_GEOM_OBB] += n
            mm &= aabb_mask8(wa_at + AABB_BYTES * x if sx else gal_at + AABB_BYTES * g1,
                             wa_at + AABB_BYTES * y if sy else gal_at + AABB_BYTES * g2)
            mm &= bounds8(wb_at + ROW_BYTES * x if sx else gw_at + ROW_BYTES * g1, 0.0 if sx else gmargin[g1],
                          wb_at + ROW_BYTES * y if sy else gw_at + ROW_BYTES * g2, 0.0 if sy else gmargin[g2])
        _set_bits(bits, pair_geoms[e, 2], mm, nv)


# ------------------------------------------------------------------------------- one group

@nb.njit(cache=True, inline="always")
def _lane_bodies(L, row_start, body_pairs, end, wa_at, sa_at, valid, single, wb, stamp, order, gstart, pgeoms, glocal,
                 gcap, gmargin, ps, gwl, gal, gal_at, pair_gstart, pair_geoms, bits, stats, nlanes, nv):
    # 2. body pairs: each position a against the positions after it in depth-first order (every
    # later subtree whole), a subtree missed in every lane skipped (as `_body_walk` in one world:
    # a 64-link chain tests a few links below each body, not all 2000 pairs); a body hit in some
    # lane that is a's static partner (the next in a's sorted row) goes on to sphere and OBB, then
    # its geom pairs.
    ntest = 0
    for a in range(L):
        ptr = row_start[a]
        pend = row_start[a + 1]
        if ptr == pend:
            continue
        last = body_pairs[pend - 1, 1]
        pa = wa_at + AABB_BYTES * a
        q = a + 1
        while q <= last:
            ntest += 1
            m = aabb_mask8(pa, sa_at + AABB_BYTES * q) & valid
            if m == 0:
                q = end[q]
                continue
            while body_pairs[ptr, 1] < q:
                ptr += 1
            if body_pairs[ptr, 1] == q:
                if end[q] != q + 1:  # a leaf's subtree AABB is its body's
                    ntest += 1
                    m &= aabb_mask8(pa, wa_at + AABB_BYTES * q)
                if m != 0:
                    _lane_pair(ptr, m, a, q, single, wb, wa_at, stamp, order, gstart, pgeoms, glocal, gcap, gmargin,
                               ps, gwl, gal, gal_at, pair_gstart, pair_geoms, bits, stats, nv)
            q += 1
    stats[ST_SUBTREE] += ntest * nlanes


@nb.njit(cache=True, inline="always")
def _lane_planes(planes, geom_bid, gmargin, pln_at, ps_at, gp_at, plane_start, plane_pos, plane_gstart, plane_geoms,
                 wa_at, wb_at, valid, single, bits, stamp, order, gstart, pgeoms, glocal, gcap, ps, gwl, gal, pln,
                 stats, nlanes, nv):
    Q = planes.shape[0]
    # 3. planes: each (plane, position) pair that passes the static filter.
    for i in range(Q):
        qg = planes[i]
        b = geom_bid[qg]
        mq = gmargin[qg]
        pa = pln_at + 32 * LANES * i
        plane8(ps_at + POSE_BYTES * b, gp_at + 32 * qg, pa)
        stats[ST_PLANE] += (plane_start[i + 1] - plane_start[i]) * nlanes
        for e in range(plane_start[i], plane_start[i + 1]):
            x = plane_pos[e]
            # the AABB corner deepest along -n, then the bounds (`_world`, stage 5a)
            m = corner8(pa, mq, wa_at + AABB_BYTES * x) & valid
            if m == 0:
                continue
            stats[ST_PLANE] += _popcount(m)
            m &= plane_hit8(pa, mq, wb_at + ROW_BYTES * x)  # `_plane_hit` on the body's world row
            if m == 0:
                continue
            if single[x] > 0:
                for f in range(plane_gstart[e], plane_gstart[e + 1]):
                    _set_bits(bits, plane_geoms[f, 1], m, nv)
                continue
            # several geoms: each one's AABB corner, then its sphere and box in the body's frame, as
            # `_world` does
            _lane_geoms(x, stamp, order, gstart, pgeoms, glocal, gcap, gmargin, ps, gwl, gal, nv)
            bb = order[x]
            for f in range(plane_gstart[e], plane_gstart[e + 1]):
                g = plane_geoms[f, 0]
                stats[ST_PLANE] += _popcount(m)
                mg = np.uint64(0)
                for l in range(nv):
                    n0 = pln[i, 0, l]
                    n1 = pln[i, 1, l]
                    n2 = pln[i, 2, l]
                    pd = pln[i, 3, l]
                    lim = pd + mq
                    cok = _corner_in(n0, n1, n2, pd, lim, gal, g, l)
                    ln0 = dot3(ps[bb, 3, l], ps[bb, 6, l], ps[bb, 9, l], n0, n1, n2)
                    ln1 = dot3(ps[bb, 4, l], ps[bb, 7, l], ps[bb, 10, l], n0, n1, n2)
                    ln2 = dot3(ps[bb, 5, l], ps[bb, 8, l], ps[bb, 11, l], n0, n1, n2)
                    llim = lim - dot3(n0, n1, n2, ps[bb, 0, l], ps[bb, 1, l], ps[bb, 2, l])
                    lscale = abs(ps[bb, 0, l]) + abs(ps[bb, 1, l]) + abs(ps[bb, 2, l]) + abs(pd)
                    mg |= np.uint64(cok & _plane_hit_local(ln0, ln1, ln2, llim, lscale + abs(glocal[g, 0])
                                                       + abs(glocal[g, 1]) + abs(glocal[g, 2]), glocal, g,
                                                       gmargin[g])) << np.uint64(l)
                _set_bits(bits, plane_geoms[f, 1], m & mg, nv)


@nb.njit(cache=True, inline="always")
def _lane_explicit(pos_all, rot_all, w0, nl, pair_g, explicit_rank, pair_m, gmargin, gplane, geom_bid, glocal, tmp,
                   ps, bits, stats, posed, nv):
    # 4. explicit pairs, lane by lane on the worlds' own pose arrays (`_world`, stage 5b). Posed,
    # those arrays were never written (`step_lanes_kin` fills them only for a group with a bad
    # pose): the two bodies' poses are copied out of the lanes first, so that no stale or zero
    # pose is read.
    for i in range(pair_g.shape[0]):
        r = explicit_rank[i]
        if r < 0:
            continue
        if posed:
            for k in range(2):
                b = geom_bid[pair_g[i, k]]
                for l in range(nl):
                    for ii in range(3):
                        pos_all[w0 + l, b, ii] = ps[b, ii, l]
                        for j in range(3):
                            rot_all[w0 + l, b, ii, j] = ps[b, 3 + 3 * ii + j, l]
        for l in range(nl):
            if _explicit_hit(i, pair_g, pair_m, gmargin, gplane, geom_bid, glocal, pos_all[w0 + l],
                             rot_all[w0 + l], tmp, stats):
                _set_bits(bits, r, np.uint64(1) << np.uint64(l), nv)


@nb.njit(cache=True)
def _group(pos_all, rot_all, w0, nl, I, F, W, J, LW, LB, stats, posed=False):
    """Worlds ``w0 .. w0 + nl - 1`` (nl <= LANES) into the bitsets ``LB[:LANES * NWd]``; returns
    False (nothing written) when a pose is bad. ``posed``: the poses are in the lanes already (the
    workspace's `layout.LW_POSES`; ``pos_all`` and ``rot_all`` are not read)."""
    L = I[H_L]
    order = view_i1(I, I, I_ORDER)
    end = view_i1(I, I, I_END)
    parent_pos = view_i1(I, I, I_PARENT_POS)
    single = view_i1(I, I, I_SINGLE)
    has_bounds = view_i1(I, I, I_HAS_BOUNDS)
    gstart = view_i1(I, I, I_GSTART)
    pgeoms = view_i1(I, I, I_PGEOMS)
    planes = view_i1(I, I, I_PLANES)
    geom_bid = view_i1(I, I, I_GEOM_BID)
    pair_g = view_i2(I, I, I_PAIR_G)
    blocal = view_f2(I, F, F_BLOCAL)
    glocal = view_f2(I, F, F_GLOCAL)
    gplane = view_f2(I, F, F_GPLANE)
    gmargin = view_f1(I, F, F_GMARGIN)
    pair_m = view_f1(I, F, F_PAIR_M)
    bcap = view_f2(I, F, F_BCAP)
    gcap = view_f2(I, F, F_GCAP)
    tmp = view_f2(I, W, W_TMP)
    body_pairs = view_i2(J, J, J_BODY_PAIRS)
    row_start = view_i1(J, J, J_ROW_START)
    pair_gstart = view_i1(J, J, J_PAIR_GSTART)
    pair_geoms = view_i2(J, J, J_PAIR_GEOMS)
    plane_start = view_i1(J, J, J_PLANE_START)
    plane_pos = view_i1(J, J, J_PLANE_POS)
    plane_gstart = view_i1(J, J, J_PLANE_GSTART)
    plane_geoms = view_i2(J, J, J_PLANE_GEOMS)
    explicit_rank = view_i1(J, J, J_EXPLICIT_RANK)
    NB = I[H_NB]
    ps = view_f3(I, LW, LW_POSES)
    ps_at = address(I, LW, LW_POSES)
    wb = view_f3(I, LW, LW_WB)
    wa = view_f3(I, LW, LW_WA)
    wa_at = address(I, LW, LW_WA)  # (6, LANES) blocks of AABB_BYTES, for aabb_mask8
    gwl = view_f3(I, LW, LW_GW)
    gal = view_f3(I, LW, LW_GA)
    gal_at = address(I, LW, LW_GA)
    sa = view_f3(I, LW, LW_SA)
    sa_at = address(I, LW, LW_SA)
    pln = view_f3(I, LW, LW_PLN)
    pln_at = address(I, LW, LW_PLN)
    gp_at = np.int64(gplane.ctypes.data)
    bits = view_i2(J, LB, LB_BITS)
    stamp = view_i1(J, LB, LB_STAMP)
    valid = (np.uint64(1) << np.uint64(nl)) - np.uint64(1)  # nl <= LANES < 64
    nv = J[J_NV]  # LANES, unknown to the compiler

    # 1. poses into lanes (lanes past nl repeat world w0: valid poses, results ignored), checked
    # as `_world` checks them, and the bounds of every position.
    for b in range(0 if posed else NB):
        for l in range(nv):
            w = w0 + l if l < nl else w0
            for i in range(3):
                ps[b, i, l] = pos_all[w, b, i]
                for j in range(3):
                    ps[b, 3 + 3 * i + j, l] = rot_all[w, b, i, j]
    bad = False
    every = (np.uint64(1) << np.uint64(LANES)) - np.uint64(1)
    for b in range(NB):
        bad |= pose_ok8(ps_at + POSE_BYTES * b) != every
    if bad:
        return False
    wb_at = address(I, LW, LW_WB)
    bl_at = np.int64(blocal.ctypes.data)
    bc_at = np.int64(bcap.ctypes.data)
    for x in range(L):
        stamp[x] = 0
        if has_bounds[x]:
            # world rows and AABBs (the OBB's cut to the capsule's), as bounds._place
            place8(ps_at + POSE_BYTES * order[x], bl_at + 8 * ROW * x, bc_at + 32 * x, 0.0, wb_at + ROW_BYTES * x,
                   wa_at + AABB_BYTES * x, sa_at + AABB_BYTES * x)
        else:
            for i in range(3):
                for l in range(nv):
                    wa[x, i, l] = BIG
                    wa[x, 3 + i, l] = -BIG
                    sa[x, i, l] = BIG
                    sa[x, 3 + i, l] = -BIG
    # subtree AABBs in every lane (`_world`, stage 2)
    for x in range(L - 1, 0, -1):
        aabb_merge8(sa_at + AABB_BYTES * parent_pos[x], sa_at + AABB_BYTES * x)
    for wi in range(bits.shape[0]):
        for l in range(nv):
            bits[wi, l] = 0
    nlanes = np.int64(nl)

    # 2. body pairs, 3. planes, 4. explicit pairs
    _lane_bodies(L, row_start, body_pairs, end, wa_at, sa_at, valid, single, wb, stamp, order, gstart, pgeoms, glocal,
                 gcap, gmargin, ps, gwl, gal, gal_at, pair_gstart, pair_geoms, bits, stats, nlanes, nv)
    _lane_planes(planes, geom_bid, gmargin, pln_at, ps_at, gp_at, plane_start, plane_pos, plane_gstart, plane_geoms,
                 wa_at, wb_at, valid, single, bits, stamp, order, gstart, pgeoms, glocal, gcap, ps, gwl, gal, pln,
                 stats, nlanes, nv)
    _lane_explicit(pos_all, rot_all, w0, nl, pair_g, explicit_rank, pair_m, gmargin, gplane, geom_bid, glocal, tmp, ps,
                   bits, stats, posed, nv)
    return True


@nb.njit(cache=True, inline="always")
def _popcount(m):
    # Set bits of a lane mask (< 2**LANES), without a loop: a data-dependent trip count would
    # cost a mispredicted branch per call.
    m = m - ((m >> np.uint64(1)) & np.uint64(0x55))
    m = (m & np.uint64(0x33)) + ((m >> np.uint64(2)) & np.uint64(0x33))
    return np.int64((m + (m >> np.uint64(4))) & np.uint64(0x0F))


@nb.njit(cache=True, inline="always")
def _lane_geoms(x, stamp, order, gstart, pgeoms, glocal, gcap, gmargin, ps, gwl, gal, nv):
    # World rows and margin-inflated AABBs of the geoms of the multi-geom body at position x in
    # every lane, once per group (`bounds._geom_rows`).
    if stamp[x] != 0:
        return
    stamp[x] = 1
    pb = np.int64(ps.ctypes.data) + POSE_BYTES * order[x]
    gl_at = np.int64(glocal.ctypes.data)
    gc_at = np.int64(gcap.ctypes.data)
    gw_at = np.int64(gwl.ctypes.data)
    ga_at = np.int64(gal.ctypes.data)
    for ii in range(gstart[x], gstart[x + 1]):
        g = pgeoms[ii]
        # the geom's rows and margin-inflated AABBs, as bounds._geom_rows
        place8(pb, gl_at + 8 * ROW * g, gc_at + 32 * g, gmargin[g], gw_at + ROW_BYTES * g, ga_at + AABB_BYTES * g,
               ga_at + AABB_BYTES * g)


# ------------------------------------------------------------------------------- entry point

@nb.njit(cache=True, inline="always")
def _lane_group(pos_src, rot_src, l0, g0, nl, I, F, W, sap, bp, scr, stats, info, Jv, LW, LB, ctx, off, st,
                world_count, world_info, ci, posed=False):
    """Worlds ``g0 .. g0 + nl - 1`` (poses ``pos_src[l0 + l]``, ``rot_src[l0 + l]``) of a chunk whose
    keys (in ``ctx``) run to ``off``: `_group`, then each world's keys read from the bitsets, or on a
    bad pose world by world through `broadphase._world`; returns the new ``off``. ``posed``: the
    poses are in the lanes already (`layout.LW_POSES`), copied out to ``pos_src[l0:]``, ``rot_src[l0:]``
    only for a group that holds a bad pose."""
    bits = view_i2(Jv, LB, LB_BITS)
    rank_keys = view_i1(Jv, Jv, J_RANK_KEYS)
    cap = ctx[C_NKEYS]
    kp = ctx[C_KEYS]
    keys_all = nb.carray(i64_ptr(kp), cap)
    for s in range(N_STATS):
        stats[s] = 0
    if _group(pos_src, rot_src, l0, nl, I, F, W, Jv, LW, LB, stats, posed):
        for s in range(N_STATS):
            st[s] += stats[s]
        for l in range(nl):
            k = 0
            for wi in range(bits.shape[0]):
                word = np.uint64(bits[wi, l])
                while word != 0:
                    if off + k < cap:
                        keys_all[off + k] = rank_keys[wi * 64 + np.int64(trailing_zeros(word))]
                    k += 1
                    word &= word - np.uint64(1)
            world_count[g0 + l] = k
            off += k
            st[ST_OUT] += k
        return off
    if posed:
        ps = view_f3(I, LW, LW_POSES)
        for l in range(nl):
            for b in range(I[H_NB]):
                for i in range(3):
                    pos_src[l0 + l, b, i] = ps[b, i, l]
                    for j in range(3):
                        rot_src[l0 + l, b, i, j] = ps[b, 3 + 3 * i + j, l]
    for l in range(nl):
        off = _batch_world(g0 + l, pos_src[l0 + l], rot_src[l0 + l], I, F, W, sap, bp, kp, cap, off, scr, stats, info,
                           world_info, world_count, st, 0, ci)
    return off


@nb.njit(cache=True, inline="always")
def lane_buffers(LWs, LBs, wk):
    """Worker wk's lane workspace: the float64 row ``LWs[wk]`` (`layout.LANE_WORK`) and the int64
    row ``LBs[wk]`` (`layout.LANE_BITS`), pointer-built."""
    check_span(wk + 1, min(LWs.shape[0], LBs.shape[0]))
    la = np.int64(LWs.ctypes.data) + 8 * LWs.shape[1] * wk
    return (nb.carray(f64_ptr(la), LWs.shape[1]),
            nb.carray(i64_ptr(np.int64(LBs.ctypes.data) + 8 * LBs.shape[1] * wk), LBs.shape[1]))


@nb.njit(cache=True, parallel=True)
def step_lanes(body_pos, body_rot, ctxs, J, LWs, LBs, world_count, world_info, chunk_info, S, stats_out):
    """`batch.step_batch` through the lanes: each chunk's worlds ``LANES`` at a time, each
    world's sorted keys after the previous worlds' in its chunk's keys; a lane workspace (a row of
    ``LWs`` and of ``LBs``) a worker, ``chunk_info`` as there (`batch.start_chunks`). A group with a bad pose
    runs world by world through `broadphase._world` (which reports the offender, and whose
    answers are the same)."""
    B = body_pos.shape[0]
    NB = body_pos.shape[1]
    C = ctxs.shape[0]
    pos_all = nb.carray(f64_ptr(np.int64(body_pos.ctypes.data)), (B, NB, 3))
    rot_all = nb.carray(f64_ptr(np.int64(body_rot.ctypes.data)), (B, NB, 3, 3))
    Jv = nb.carray(i64_ptr(np.int64(J.ctypes.data)), J.shape[0])
    nw = min(start_chunks(chunk_info, C), LWs.shape[0], LBs.shape[0])  # a lane workspace a worker
    chunksize = set_chunksize(1)  # one worker a thread (`_threads`)
    for wk in nb.prange(nw):
        LW, LB = lane_buffers(LWs, LBs, wk)
        st = np.zeros(N_STATS, np.int64)
        while True:
            c = next_chunk(chunk_info, C)
            if c >= C:
                break
            ctx, ci, I, F, W, sap, bp, scr, stats, info = chunk_buffers(ctxs, chunk_info, c)
            for s in range(N_STATS):
                st[s] = 0
            w0 = (B * c) // C
            w1 = (B * (c + 1)) // C
            off = 0
            for g0 in range(w0, w1, LANES):
                off = _lane_group(pos_all, rot_all, g0, g0, min(LANES, w1 - g0), I, F, W, sap, bp, scr, stats, info,
                                  Jv, LW, LB, ctx, off, st, world_count, world_info, ci)
            for s in range(N_STATS):
                stats[s] = st[s]
            ci[CI_KEYS] = off
    set_chunksize(chunksize)
    return gather_batch(ctxs, world_count, chunk_info, S, stats_out)
