"""Signed distance of two posed convex shapes, with a certified bracket (numba driver).

GJK (`collide._kernels.gjk`) runs on the cores; when they overlap, EPA (`collide._kernels.epa`)
takes GJK's simplex. Two kinds of pair are tried in closed form first, with the same kind of
certificate, and go to GJK/EPA only where it is wider than the tolerance: two segments (spheres
and capsules, `segment_distance`) and a ball against a cylinder, cone or ellipsoid
(`collide._kernels.point_distance`). The balls are added afterwards (the core ⊕ ball form, DESIGN.md Wave 2):
with ``C`` the cores' difference and ``r = r_a + r_b``, ``h_{C ⊕ B(r)}(u) = h_C(u) + r`` for every
unit ``u``, so the signed distance of the full sets is exactly the cores' minus ``r``, and the
witness points move by their radius along the normal.

Every bound the two algorithms produce is valid on its own (a support value, a point of ``C``, a
certified inner ball of ``C``), so the result's bracket is the tightest of them, widened by a
rounding allowance proportional to the largest world coordinate seen. Iteration caps widen the
bracket, never break it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._ptr import NO_NRT, f64_ptr, i32_ptr, i64_ptr, view_of
from .epa import CONVERGED, DEGENERATE, E_NV, WARM_F, WARM_I, epa, epa_on, epa_sizes, epa_warm
from .gjk import _FLOOR, OVERLAP, gjk_within
from .point_distance import point_distance
from .support import POINTS

_EPS = float(np.finfo(np.float64).eps)

# Slots of the ``out`` array of `pair_distance`.
OUT_DISTANCE, OUT_LOWER, OUT_UPPER = 0, 1, 2
OUT_POINT_A, OUT_POINT_B, OUT_NORMAL = 3, 6, 9
OUT_PENETRATING, OUT_ITERATIONS, OUT_HINT_A, OUT_HINT_B = 12, 13, 14, 15
OUT_SIZE = 16

# Rounding allowance, in units of eps times the largest world coordinate: the supports (a
# rotation and a translation), their difference and a dot product each round by a few ulps.
ROUNDING = 64.0


@njit(cache=True, inline="always")
def _point(shape, j):
    # World point j of a core's points (its last one for j past the end: a core of one point
    # gives the same point twice), as three floats.
    pts, rot, pos = shape[2], shape[5], shape[6]
    i = min(j, pts.shape[0] - 1)
    return (rot[0, 0] * pts[i, 0] + rot[0, 1] * pts[i, 1] + rot[0, 2] * pts[i, 2] + pos[0],
            rot[1, 0] * pts[i, 0] + rot[1, 1] * pts[i, 1] + rot[1, 2] * pts[i, 2] + pos[1],
            rot[2, 0] * pts[i, 0] + rot[2, 1] * pts[i, 1] + rot[2, 2] * pts[i, 2] + pos[2])


@njit(**NO_NRT)
def segment_distance(sa, sb, tol, out):
    """`pair_distance` of two cores of at most two points each (spheres and capsules), closed form.

    The closest points of two segments (Ericson 2005, "Real-Time Collision Detection", §5.1.9,
    ``ClosestPtSegmentSegment``), then the same certificate GJK gives: with ``n`` the unit
    direction between them, ``min n.B - max n.A`` (support values) is a lower bound of the cores'
    distance and ``|pb - pa|`` an upper bound. Returns False, writing nothing, when the two are
    not within ``tol`` (rounding near parallel segments) or the cores nearly touch (the normal
    of ``pb - pa`` would be poorly known there): the caller runs GJK/EPA instead.
    """
    # the end points, in scalars (an array of them cost a reshaped view, or an allocation)
    a00, a01, a02 = _point(sa, 0)
    a10, a11, a12 = _point(sa, 1)
    b00, b01, b02 = _point(sb, 0)
    b10, b11, b12 = _point(sb, 1)
    d10, d11, d12 = a10 - a00, a11 - a01, a12 - a02
    d20, d21, d22 = b10 - b00, b11 - b01, b12 - b02
    r0, r1, r2 = a00 - b00, a01 - b01, a02 - b02
    a = d10 * d10 + d11 * d11 + d12 * d12
    c2 = d20 * d20 + d21 * d21 + d22 * d22
    f = d20 * r0 + d21 * r1 + d22 * r2
    s = t = 0.0
    if a == 0.0:
        if c2 > 0.0:
            t = min(max(f / c2, 0.0), 1.0)
    else:
        c = d10 * r0 + d11 * r1 + d12 * r2
        if c2 == 0.0:
            s = min(max(-c / a, 0.0), 1.0)
        else:
            b = d10 * d20 + d11 * d21 + d12 * d22
            den = a * c2 - b * b
            if den > 0.0:
                s = min(max((b * f - c * c2) / den, 0.0), 1.0)
            t = (b * s + f) / c2
            if t < 0.0:
                t = 0.0
                s = min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t = 1.0
                s = min(max((b - c) / a, 0.0), 1.0)
    scale = max(abs(a00), abs(a01), abs(a02), abs(a10), abs(a11), abs(a12),
                abs(b00), abs(b01), abs(b02), abs(b10), abs(b11), abs(b12))
    pa0, pa1, pa2 = a00 + s * d10, a01 + s * d11, a02 + s * d12
    pb0, pb1, pb2 = b00 + t * d20, b01 + t * d21, b02 + t * d22
    w = (pb0 - pa0, pb1 - pa1, pb2 - pa2)
    gap = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    if not gap > 1e-6 * scale:
        return False
    n0, n1, n2 = w[0] / gap, w[1] / gap, w[2] / gap
    ha = max(n0 * a00 + n1 * a01 + n2 * a02, n0 * a10 + n1 * a11 + n2 * a12)
    hb = min(n0 * b00 + n1 * b01 + n2 * b02, n0 * b10 + n1 * b11 + n2 * b12)
    lower = hb - ha
    if gap - lower > max(tol, _FLOOR * scale):
        return False
    ra = sa[1][3]
    rb = sb[1][3]
    slack = ROUNDING * _EPS * (scale + ra + rb)
    out[OUT_DISTANCE] = gap - ra - rb
    out[OUT_LOWER] = min(lower, gap) - ra - rb - slack
    out[OUT_UPPER] = gap - ra - rb + slack
    out[OUT_NORMAL] = n0
    out[OUT_NORMAL + 1] = n1
    out[OUT_NORMAL + 2] = n2
    out[OUT_POINT_A] = pa0 + ra * n0
    out[OUT_POINT_A + 1] = pa1 + ra * n1
    out[OUT_POINT_A + 2] = pa2 + ra * n2
    out[OUT_POINT_B] = pb0 - rb * n0
    out[OUT_POINT_B + 1] = pb1 - rb * n1
    out[OUT_POINT_B + 2] = pb2 - rb * n2
    out[OUT_PENETRATING] = 0.0
    out[OUT_ITERATIONS] = 1
    out[OUT_HINT_A] = -1
    out[OUT_HINT_B] = -1
    return True


@njit(**NO_NRT)
def _ball_primitive(sk, sp, k_first, tol, out, res):
    # `pair_distance`'s answer for a ball (sp) and a cylinder, cone or ellipsoid (sk) from
    # `collide._kernels.point_distance` (closed form), when certified within tol; k_first: sk is A.
    # res: (18,) scratch.
    found, d, lower, upper, cores = point_distance(sk, sp, tol, ROUNDING, res)
    if not found:
        return False
    out[OUT_DISTANCE] = d
    out[OUT_LOWER] = lower
    out[OUT_UPPER] = upper
    ia, ib, sg = (0, 3, 1.0) if k_first else (3, 0, -1.0)
    for k in range(3):
        out[OUT_POINT_A + k] = res[ia + k]
        out[OUT_POINT_B + k] = res[ib + k]
        out[OUT_NORMAL + k] = sg * res[6 + k]
    out[OUT_PENETRATING] = 1.0 if cores else 0.0
    out[OUT_ITERATIONS] = 1
    out[OUT_HINT_A] = -1
    out[OUT_HINT_B] = -1
    return True


# With reference counting even where its caller has none (it allocates).
@njit(cache=True, _nrt=True)
def pair_distance(sa, sb, tol, d0, hint_a, hint_b, max_iter, out):
    """Signed distance of two posed shapes (core ⊕ ball), its witnesses and a certified bracket:
    `pair_distance_within` with no cutoff, on scratch allocated here (parameters as there)."""
    pair_distance_within(sa, sb, tol, math.inf, d0, hint_a, hint_b, max_iter, out, np.empty(WS_F),
                         np.empty(WS_I, np.int64))


# `pair_distance_within`'s scratch, float64 (``WS_F``): GJK's simplex W, WA, WB ((3, 4, 3)) and its lam,
# dirn, v, pa, pb ((5, 4)), zeroed each call (GJK weighs all four rows, zero weights included);
# then EPA's result (13), the normal (3), the closed form's result (18), `collide._kernels.epa.epa_warm`'s
# scratch. int64 (``WS_I``): the climbs' hints and the simplex's vertex indices (10), `epa_warm`'s.
# Then, optionally (``WS_F_EPA``, ``WS_I_EPA`` long in all), EPA's own for a cap of `EPA_CAP` vertices
# (`collide._kernels.epa.epa_on`): the narrow phase's workspace holds it, so that a penetrating pair
# allocates nothing; shorter scratch (`query`'s, whose cap is its caller's) has EPA allocate its own.
_WS_SIMPLEX = 0
_WS_VEC = _WS_SIMPLEX + 36
_WS_RES = _WS_VEC + 20
_WS_NRM = _WS_RES + 13
_WS_BALL = _WS_NRM + 3
_WS_WARM = _WS_BALL + 18
WS_F = _WS_WARM + WARM_F
WS_I = 10 + WARM_I
EPA_CAP = 128  # the narrow phase's cap on GJK iterations and EPA vertices
WS_F_EPA = WS_F + epa_sizes.py_func(EPA_CAP)[0]
WS_I_EPA = WS_I + epa_sizes.py_func(EPA_CAP)[1]


@njit(**NO_NRT)
def _closed_form(sa, sb, tol, out, fws):
    # `pair_distance_within`'s answer in closed form, where it has one certified within tol (True,
    # ``out`` filled; False: GJK/EPA decide). Its own function: inlined into its caller, the two
    # closed forms made the GJK query of every other pair slower (tests/bench/distance.txt).
    if sa[0] == POINTS and sb[0] == POINTS and sa[2].shape[0] <= 2 and sb[2].shape[0] <= 2:
        # spheres and capsules: no iteration
        return segment_distance(sa, sb, tol, out)
    if sa[0] != POINTS and sb[0] == POINTS and sb[2].shape[0] == 1:
        # a ball and a cylinder, cone or ellipsoid
        return _ball_primitive(sa, sb, True, tol, out, fws[_WS_BALL:_WS_BALL + 18])
    if sb[0] != POINTS and sa[0] == POINTS and sa[2].shape[0] == 1:
        return _ball_primitive(sb, sa, False, tol, out, fws[_WS_BALL:_WS_BALL + 18])
    return False


# Compiled without reference counting (`collide._kernels._ptr.NO_NRT`), as every function it calls but `epa`
# (which allocates): in a counting function each array of the two shape tuples cost an atomic increment and
# decrement a call.
@njit(**NO_NRT)
def pair_distance_within(sa, sb, tol, cutoff, d0, hint_a, hint_b, max_iter, out, fws, iws, entry=None):
    """Signed distance of two posed shapes (core ⊕ ball), its witnesses and a certified bracket.

    Parameters
    ----------
    sa, sb : tuple
        Shape tuples ``(kind, prm, pts, nbr_start, nbr, rot, pos)`` (`collide._kernels.support`);
        ``prm[3]`` is the ball radius.
    tol : float
        Absolute convergence tolerance of GJK and EPA (the bracket's target width).
    cutoff : float
        Distances beyond it are not needed (a contact's caller: its contact distance): GJK stops
        once its certified lower bound exceeds it (`collide._kernels.gjk.gjk_within`), and the
        distance reported is then only known to exceed ``cutoff`` (``lower <= distance <=
        upper`` still holds, the bracket wider than ``tol``); ``inf``: the full query.
    d0 : (3,) float64
        First search direction, from A towards B (a warm start: the last normal); zeros for the
        difference of the two positions.
    hint_a, hint_b : int
        Hill-climb start vertices (warm start: the last ones returned in ``out``; -1: cold).
    max_iter : int
        Cap on GJK iterations and on EPA's polytope vertices.
    out : (16,) float64
        Receives, by slot (the ``OUT_*`` constants): distance, lower, upper, point_a (3),
        point_b (3), normal (3, unit, from A to B; when GJK stopped at ``cutoff``, the direction
        whose support values showed it: a separating plane's), penetrating (1.0 when the cores
        overlap and EPA ran), iterations (GJK's plus EPA's; 0 when ``entry`` answered), hint_a,
        hint_b.
    entry : (ENTRY,) int64, optional
        The pair's row of a warm-start cache (`collide._kernels.epa`'s ``E_*``), for two point
        clouds (``POINTS``) only: when it holds a polytope, `collide._kernels.epa.epa_warm` tries
        it first and its certified answer is the result (no GJK, no EPA); after GJK and EPA it
        receives their polytope (or is emptied). A hint only: whatever it holds, the result is
        certified as without it.
    fws : (WS_F,) or (WS_F_EPA,) float64
    iws : (WS_I,) or (WS_I_EPA,) int64
        Scratch (layout above), written before it is read; with EPA's part for ``max_iter``
        (``WS_F_EPA``, ``WS_I_EPA`` at `EPA_CAP`), EPA allocates nothing.
    """
    if _closed_form(sa, sb, tol, out, fws):
        return
    for i in range(_WS_RES):
        fws[i] = 0.0
    simplex = fws[_WS_SIMPLEX:_WS_VEC].reshape((3, 4, 3))
    W = simplex[0]
    WA = simplex[1]
    WB = simplex[2]
    vec = fws[_WS_VEC:_WS_RES].reshape((5, 4))
    lam = vec[0]
    dirn = vec[1]
    v = vec[2, :3]
    pa = vec[3, :3]
    pb = vec[4, :3]
    res = fws[_WS_RES:_WS_RES + 13]
    # With ``entry`` (a separate compilation: without it, none of this is in the code): its
    # polytope first; GJK then also records its simplex's vertex indices (``hints[2:]``) for EPA
    # to keep. Without, the cold query as it always was.
    warm = False
    s = 0.0
    if entry is None:
        hints = iws[0:2]
    else:
        hints = iws[0:10]
        if sa[0] != POINTS or sb[0] != POINTS:
            entry[E_NV] = 0  # a kept vertex is a point of C only for two point clouds
        elif entry[E_NV] > 0:
            st, s = epa_warm(sa, sb, entry, tol, res, fws[_WS_WARM:_WS_WARM + WARM_F], iws[10:10 + WARM_I])
            warm = st == CONVERGED
    hints[0] = hint_a
    hints[1] = hint_b
    r = sa[1][3] + sb[1][3]
    if warm:  # the kept polytope's certified answer: EPA's result below, GJK's bounds none
        status, n, lower, scale, iters = OVERLAP, 0, -math.inf, s, 0
        dirn[3] = math.inf
    elif entry is None:
        status, n, lower, scale, iters = gjk_within(sa, sb, d0, hints, tol, cutoff + r, max_iter, W, WA, WB, lam,
                                                    v, dirn, pa, pb)
    else:
        status, n, lower, scale, iters = gjk_within(sa, sb, d0, hints, tol, cutoff + r, max_iter, W, WA, WB, lam,
                                                    v, dirn, pa, pb, hints[2:])
        if status != OVERLAP:
            entry[E_NV] = 0
    pa[:] = 0.0
    pb[:] = 0.0
    for i in range(n):
        for k in range(3):
            pa[k] += lam[i] * WA[i, k]
            pb[k] += lam[i] * WB[i, k]
    gap = math.sqrt((pb[0] - pa[0]) ** 2 + (pb[1] - pa[1]) ** 2 + (pb[2] - pa[2]) ** 2)
    upper = gap  # the witnesses are points of A and B
    # The normal: the simplex feature's (GJK's last search direction) or the witnesses'
    # difference, whichever is better conditioned: the feature's is precise at a gap at
    # rounding level, where pb - pa is not; a tiny sliver's normal is not (its conditioning).
    nrm = fws[_WS_NRM:_WS_NRM + 3]
    nrm[0], nrm[1], nrm[2] = dirn[0], dirn[1], dirn[2]
    cond = dirn[3]
    sign = 1.0  # pb - pa points along the normal when apart, against it when overlapping
    estimate = gap
    penetrating = 0.0
    if status == OVERLAP:
        if warm:
            st = CONVERGED
        else:
            nf, ni = epa_sizes(max_iter)
            if fws.shape[0] >= WS_F + nf and iws.shape[0] >= WS_I + ni:  # EPA's scratch here
                if entry is None:
                    st, s, it = epa_on(sa, sb, W, WA, WB, n, hints, tol, max_iter, lower, res, fws[WS_F:], iws[WS_I:])
                else:
                    st, s, it = epa_on(sa, sb, W, WA, WB, n, hints, tol, max_iter, lower, res, fws[WS_F:],
                                       iws[WS_I:], entry)
            elif entry is None:
                st, s, it = epa(sa, sb, W, WA, WB, n, hints, tol, max_iter, lower, res)
            else:
                st, s, it = epa(sa, sb, W, WA, WB, n, hints, tol, max_iter, lower, res, entry)
            scale = max(scale, s)
            iters += it
        lower = max(lower, res[0])
        upper = min(upper, res[1])
        for k in range(3):
            nrm[k] = res[9 + k]
        cond = res[12]
        if st == DEGENERATE:
            estimate = min(max(0.0, lower), upper)
        else:
            penetrating = 1.0
            sign = -1.0
            estimate = min(max(res[2], lower), upper)
            for k in range(3):
                pa[k] = res[3 + k]
                pb[k] = res[6 + k]
            gap = math.sqrt((pb[0] - pa[0]) ** 2 + (pb[1] - pa[1]) ** 2 + (pb[2] - pa[2]) ** 2)
    if gap > 0.0 and 1.0 / gap < cond and not lower > cutoff + r:
        for k in range(3):
            nrm[k] = sign * (pb[k] - pa[k])
    ln = math.sqrt(nrm[0] ** 2 + nrm[1] ** 2 + nrm[2] ** 2)
    if ln == 0.0:
        nrm[2] = 1.0
        ln = 1.0
    ra = sa[1][3]
    rb = sb[1][3]
    slack = ROUNDING * _EPS * (scale + ra + rb)
    out[OUT_DISTANCE] = estimate - ra - rb
    out[OUT_LOWER] = lower - ra - rb - slack
    out[OUT_UPPER] = upper - ra - rb + slack
    for k in range(3):
        nk = nrm[k] / ln
        out[OUT_NORMAL + k] = nk
        out[OUT_POINT_A + k] = pa[k] + ra * nk
        out[OUT_POINT_B + k] = pb[k] - rb * nk
    out[OUT_PENETRATING] = penetrating
    out[OUT_ITERATIONS] = iters
    out[OUT_HINT_A] = hints[0]
    out[OUT_HINT_B] = hints[1]


@njit(cache=True)
def pose_error(rot, pos, tol, size, limit):
    """Check of a pose ``rot (3, 3)``, ``pos (3,)`` float64 for a shape of ``size``: 0 fine, 1 a
    non-finite entry, 2 not a rotation (an entry of ``|R^T R - I|`` above ``tol``, or
    ``det R <= 0``), 3 the shape reaching beyond ``limit`` (``max |pos| + size``)."""
    for i in range(3):
        if not np.isfinite(pos[i]):
            return 1
        for j in range(3):
            if not np.isfinite(rot[i, j]):
                return 1
    for i in range(3):
        for j in range(3):
            s = rot[0, i] * rot[0, j] + rot[1, i] * rot[1, j] + rot[2, i] * rot[2, j]
            if abs(s - (1.0 if i == j else 0.0)) > tol:
                return 2
    det = (rot[0, 0] * (rot[1, 1] * rot[2, 2] - rot[1, 2] * rot[2, 1])
           - rot[0, 1] * (rot[1, 0] * rot[2, 2] - rot[1, 2] * rot[2, 0])
           + rot[0, 2] * (rot[1, 0] * rot[2, 1] - rot[1, 1] * rot[2, 0]))
    if not det > 0.0:
        return 2
    if not max(abs(pos[0]), abs(pos[1]), abs(pos[2])) + size <= limit:
        return 3
    return 0


# Slots of a shape's descriptor for `query` (an int64 array; `collide.signed_distance` builds it
# once per shape from its `collide.support.SupportData`): the kind, then the length and address
# of each array of the shape tuple.
DESC_KIND, DESC_NPTS, DESC_PTS, DESC_NSTART, DESC_START, DESC_NNBR, DESC_NBR, DESC_PRM = range(8)
DESC_SIZE = 8


@njit(cache=True, inline="always")
def _described(addr, rot, pos):
    # The shape tuple of the descriptor at ``addr`` at a pose: views of the SupportData's arrays,
    # made from their addresses (no reference count; the caller holds the arrays for the call).
    desc = view_of(i64_ptr(addr), DESC_SIZE)
    return (desc[DESC_KIND], view_of(f64_ptr(desc[DESC_PRM]), 4),
            view_of(f64_ptr(desc[DESC_PTS]), (desc[DESC_NPTS], 3)),
            view_of(i32_ptr(desc[DESC_START]), desc[DESC_NSTART]),
            view_of(i32_ptr(desc[DESC_NBR]), desc[DESC_NNBR]), rot, pos)


@njit(cache=True)
def query(desc_a, desc_b, rot_a, pos_a, rot_b, pos_b, size_a, size_b, ortho_tol, limit, tol, warm, max_iter, out):
    """`collide.distance`'s one kernel call: both poses checked, then `pair_distance`.

    numba's dispatch pays for every array argument (a type check, and a reference-counted
    record made and freed), and most for tuples of arrays (element by element), so the shapes
    come as the addresses of two small descriptors and their tuples are made here.

    Parameters
    ----------
    desc_a, desc_b : int
        Addresses of the shapes' descriptors, ``(8,) int64`` C-contiguous arrays (the ``DESC_*``
        slots): kind, and length and address of ``pts`` ``(n, 3) float64``, ``nbr_start``,
        ``nbr`` ``int32`` and ``prm`` ``(4,) float64``, all C-contiguous and alive for the call.
    rot_a, pos_a, rot_b, pos_b : (3, 3) and (3,) float64, C-contiguous
        The poses; any other shape is refused (code 4), not read.
    size_a, size_b : float
        The shapes' sizes (`collide.support.SupportData.size`).
    ortho_tol, limit : float
        `pose_error`'s tolerance and coordinate limit.
    tol, max_iter, out
        As in `pair_distance`.
    warm : (16,) float64
        A previous ``out`` of the same pair: its normal is the first search direction and its
        hints the climbs' starts (a warm start); a zero or non-finite normal: a cold start.

    Returns
    -------
    int
        0 (``out`` filled), or the first bad pose's code: ``1..3`` `pose_error`'s, 4 a wrong
        shape, for A; ``11..14`` for B (``out`` untouched).
    """
    if rot_a.shape[0] != 3 or rot_a.shape[1] != 3 or pos_a.shape[0] != 3:
        return 4
    err = pose_error(rot_a, pos_a, ortho_tol, size_a, limit)
    if err:
        return err
    if rot_b.shape[0] != 3 or rot_b.shape[1] != 3 or pos_b.shape[0] != 3:
        return 14
    err = pose_error(rot_b, pos_b, ortho_tol, size_b, limit)
    if err:
        return 10 + err
    hint_a = hint_b = -1
    fws = np.empty(WS_F + 3)  # the distance's scratch, then the first search direction
    d0 = fws[WS_F:]
    d0[:] = 0.0
    if warm.shape[0] == OUT_SIZE:
        for k in range(3):
            d0[k] = warm[OUT_NORMAL + k]
        if not (math.isfinite(d0[0]) and math.isfinite(d0[1]) and math.isfinite(d0[2])):
            d0[:] = 0.0
        elif d0[0] != 0.0 or d0[1] != 0.0 or d0[2] != 0.0:
            # Scaled to a largest entry of one where GJK's squares of it would under- or overflow
            # (a direction of 1e155 inverted the bracket), and only there: a warm start from a
            # unit normal stays what it was.
            big = max(abs(d0[0]), abs(d0[1]), abs(d0[2]))
            if not 2.0 ** -300 <= big <= 2.0 ** 300:
                for k in range(3):
                    d0[k] = d0[k] / big
            # A hint out of range (a hand-built Distance's) makes a cold climb; a float beyond
            # int64 (or NaN) is not converted at all.
            if -2.0 < warm[OUT_HINT_A] < 2.0 ** 31:
                hint_a = int(warm[OUT_HINT_A])
            if -2.0 < warm[OUT_HINT_B] < 2.0 ** 31:
                hint_b = int(warm[OUT_HINT_B])
    pair_distance_within(_described(desc_a, rot_a, pos_a), _described(desc_b, rot_b, pos_b), tol, math.inf, d0,
                         hint_a, hint_b, max_iter, out, fws[:WS_F], np.empty(WS_I, np.int64))
    return 0
