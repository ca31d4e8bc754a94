"""Bounds rows and their tests, for the per-step broad phase (`broadphase`) and its lanes (`lanes`).

A bounds row (`layout.ROW` float64) is a body's or geom's OBB and sphere; each also has a capsule. Here:
a row moved to the world by a pose (`_world_row`; `_pose_row` is the arithmetic the lanes replay), its
world AABB (the OBB's cut to its capsule's), the pose check (`_pose._pose_ok`, read here), the one
sphere + separating-axis test (`_bounds_ok`, whose source the lanes' vector form `lane_tests.bounds8`
replays), planes as half-spaces, a multi-geom body's geom rows, and the explicit pairs' test. Every
comparison carries a conservative slack: rounding never separates touching bounds.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._pose import MAX_POSITION, ORTHO_TOL, _pose_ok  # noqa: F401 (read here by the kernels and callers)
from ._quat import fmuladd
from .layout import ST_GEOM_OBB, ST_GEOM_SPHERE, ST_PLANE

BIG = 1e300  # empty AABB: lo = BIG, hi = -BIG (finite, so n . lo never meets inf - inf)
# Conservative slack: rounding must never separate touching bounds. AbsR gets EPS_PAR (Ericson's
# guard against near-parallel edge pairs, whose cross product is ~0); every comparison gets
# SLACK_REL of the sizes involved plus SLACK_POS of the coordinates' magnitude (a difference of
# world centres far from the origin carries ~1e-16 of their size as rounding).
EPS_PAR = 1e-12
SLACK_REL = 1e-12
SLACK_POS = 1e-13

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
def _sphere_hit(A, a, ma, B, b, mb):
    # The spheres of rows A[a] and B[b] (centre at columns 15..17, radius at 18) inflated by ma, mb
    # overlap: `_bounds_ok`'s first test, the same arithmetic.
    dx = A[a, 15] - B[b, 15]
    dy = A[a, 16] - B[b, 16]
    dz = A[a, 17] - B[b, 17]
    r = A[a, 18] + ma + B[b, 18] + mb
    # Each box's magnitudes summed apart: the same bits in either order (with ma = mb = 0 the
    # radius sum commutes too).
    pos = (abs(A[a, 15]) + abs(A[a, 16]) + abs(A[a, 17])) + (abs(B[b, 15]) + abs(B[b, 16]) + abs(B[b, 17]))
    r += SLACK_REL * r + SLACK_POS * pos
    return dot3(dx, dy, dz, dx, dy, dz) <= r * r


@nb.njit(cache=True, inline="always")
def _bounds_ok(ra, ma, rb, mb):
    """The one bounds test: spheres, then the OBBs' separating axes (15, Ericson 2005, *Real-Time
    Collision Detection* §4.4.1, in box A's frame: ``R[i, j] = A_i . B_j``, ``t`` = centre offset in
    A's frame; ``|R| + EPS_PAR`` so that near-parallel edge pairs never separate by rounding) of the
    bounds rows ``ra``, ``rb`` (19-tuples: a `ROW` each) inflated by ``ma``, ``mb``.

    Every axis is evaluated and the outcomes combined without a branch, so that a loop over pairs
    vectorises, and the lanes' vector form is this source replayed (`lane_tests.bounds8`): written
    with ``&`` and ``^ True`` (not ``not``) for that. An axis separates only when
    ``|t| > r`` holds: a NaN projection (inf - inf at coordinates near the float range) separates
    nothing. `_sphere_hit` is its first test alone (the explicit pairs' cull, `_explicit_hit`)."""
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
    kernels use its vector form, `lane_tests.bounds8`; this loop is its twin in the tests."""
    m = np.uint64(0)
    for l in range(n):
        ok = _bounds_ok(_row_of_column(A, a, l), ma, _row_of_column(B, b, l), mb)
        m |= np.uint64(ok) << np.uint64(l)
    return m


@nb.njit(cache=True, inline="always")
def _pairs_mask(bw, bp, c0, n):
    """Bit l set when the body rows of pair ``bp[c0 + l]`` overlap (`_bounds_ok`, no inflation:
    the rows carry it), n <= 64; a marked second body (``~y``) is read as ``y``."""
    m = np.uint64(0)
    for l in range(n):
        x = bp[c0 + l, 0]
        y = bp[c0 + l, 1]
        y = y ^ (y >> 63)
        ok = _bounds_ok(_row_of(bw, x), 0.0, _row_of(bw, y), 0.0)
        m |= np.uint64(ok) << np.uint64(l)
    return m


@nb.njit(cache=True, inline="always")
def _plane_hit_local(n0, n1, n2, lim, scale, Lr, g, mg):
    # Both of Lr[g]'s volumes, inflated by mg, reach the halfspace {n . x <= lim}; ``scale`` is
    # the magnitude of the world coordinates involved (the slack covers their rounding). Also in
    # a body's frame (n = R^T n_world, lim = d + mq - n_world . p), n . (R c + p) = (R^T n) . c +
    # n . p: a multi-geom body's geoms need their world AABBs only (their corner test), not their
    # sphere and box moved into the world.
    # Both tests always, no branch on the sphere's outcome (a misprediction costs more than the
    # box's dozen flops; see `culling`).
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
def explicit_pair(i, pair_g, pair_m, gmargin, gplane):
    """Explicit pair ``i``: its geoms ``g1, g2``, their inflations (the pair's own margin if given,
    else the geoms') and whether each is a plane (a plane row has a nonzero normal)."""
    g1 = pair_g[i, 0]
    g2 = pair_g[i, 1]
    m1 = gmargin[g1] if np.isnan(pair_m[i]) else pair_m[i]
    m2 = gmargin[g2] if np.isnan(pair_m[i]) else pair_m[i]
    p1 = gplane[g1, 0] != 0.0 or gplane[g1, 1] != 0.0 or gplane[g1, 2] != 0.0
    p2 = gplane[g2, 0] != 0.0 or gplane[g2, 1] != 0.0 or gplane[g2, 2] != 0.0
    return g1, g2, m1, m2, p1, p2


@nb.njit(cache=True, inline="always")
def _explicit_hit(i, pair_g, pair_m, gmargin, gplane, geom_bid, glocal, body_pos, body_rot, tmp, stats):
    # Explicit pair i: its geoms' world bounds (rows 0 and 1 of tmp), inflated by the pair's own
    # margin if given, else the geoms'; a plane against the other geom's bounds; never two planes.
    g1, g2, m1, m2, p1, p2 = explicit_pair(i, pair_g, pair_m, gmargin, gplane)
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
