"""One body's and one geom's motion over a step, for the swept broad phase (`collide._kernels.swept`).

The motion, its proof (`collide.sweep`'s chord deviation ``ρ θ² / 8``) and every bound below are
stated in `collide._kernels.swept`'s docstring; this module holds the per-body and per-geom half:
each body's turn and shift (`_body_motion`, with where its start places come from,
`_start_source`), each solid geom's swept box, sphere and reach (`_geom_sweep`), and the tests of
one swept geom against another's sphere (`_spheres_meet`) or a fixed plane (`_plane_reach`).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .bounds import ORTHO_TOL, SLACK_POS, SLACK_REL, _pose_ok, _world_aabb, _world_row, capsule_half, dot3
from ._ptr import i64_ptr, view_of

# Lowering of cos θ (see `collide._kernels.swept`'s docstring): 2 x 9 entries x ORTHO_TOL, doubled.
COS_SLACK = 4e-5

# Where a body's places at s = 0 come from (Y_BODY column 4): placed, the last call's end places
# (its start pose is bitwise the last call's end pose), or its own end places (at rest: both poses
# bitwise equal).
SRC_PLACE, SRC_KEPT, SRC_REST = 0.0, 1.0, 2.0


@nb.njit(cache=True, inline="always")
def _bits(arr, n):
    # The C-contiguous float64 array arr as n int64 (its bits: a bitwise comparison, where ==
    # would take -0.0 for 0.0)
    return view_of(i64_ptr(np.int64(arr.ctypes.data)), n)


@nb.njit(cache=True, inline="always")
def _same_bits(a, i, b, j, n):
    # a[i:i + n] and b[j:j + n] hold the same bits (no early exit: a short pass without a branch)
    same = True
    for t in range(n):
        same &= a[i + t] == b[j + t]
    return same


@nb.njit(cache=True, inline="always")
def _body_motion(pos0, rot0, pos1, rot1, body, kept_pose, kept):
    # Per body: k = θ² / 8 (θ the angle of R1 R0ᵀ), moved flag, min(θ, 2), |t1 - t0| and where its
    # start places come from (`_start_source`); returns -1 or 2 b + t of a bad pose.
    NB = pos0.shape[0]
    p0 = _bits(pos0, 3 * NB)
    r0 = _bits(rot0, 9 * NB)
    p1 = _bits(pos1, 3 * NB)
    r1 = _bits(rot1, 9 * NB)
    for b in range(NB):
        src = _start_source(p0, r0, p1, r1, kept_pose, kept, b)
        body[b, 4] = src
        # each pose checked once: a kept start passed as the last call's end; a start at rest is
        # the end (checked as the start, so that a bad one is named as such)
        for t in range(1 if src == SRC_KEPT else 0, 1 if src == SRC_REST else 2):
            r = rot0 if t == 0 else rot1
            p = pos0 if t == 0 else pos1
            if not _pose_ok(r[b, 0, 0], r[b, 0, 1], r[b, 0, 2], r[b, 1, 0], r[b, 1, 1], r[b, 1, 2], r[b, 2, 0],
                            r[b, 2, 1], r[b, 2, 2], p[b, 0], p[b, 1], p[b, 2]):
                return 2 * b + t
        tr = 0.0
        same = True
        for i in range(3):
            same &= pos0[b, i] == pos1[b, i]
            for j in range(3):
                tr += rot0[b, i, j] * rot1[b, i, j]  # trace of R1 R0ᵀ
                same &= rot0[b, i, j] == rot1[b, i, j]
        c = min(1.0, max(-1.0, 0.5 * (tr - 1.0) - COS_SLACK))
        th = math.acos(c)
        body[b, 0] = 0.0 if same else th * th * (0.125 * (1.0 + 1e-12))
        body[b, 1] = 0.0 if same else 1.0
        # the chord 2 sin(θ / 2) |R0 x| <= min(θ, 2) |R0 x|, and |R0 x| <= (1 + 1.5 ORTHO_TOL) |x| for
        # an accepted R0 (|R0ᵀ R0 - I| <= ORTHO_TOL entrywise: σmax² <= 1 + 3 ORTHO_TOL). θ's cos
        # slack covers the factor below θ = 2, not at θ = π, where the turn's chord is 2 |R0 x|: a
        # point 1 from its body's origin, turned by π from a start rotation stretched by 5e-7,
        # landed 2 + 5e-7 from its end place, and its start pose's pair was lost (adversarial
        # review of issue 44)
        body[b, 2] = 0.0 if same else min(th, 2.0) * (1.0 + 2.0 * ORTHO_TOL)
        body[b, 3] = 0.0 if same else _norm3(pos1[b, 0] - pos0[b, 0], pos1[b, 1] - pos0[b, 1], pos1[b, 2] - pos0[b, 2])
    return -1


@nb.njit(cache=True, inline="always")
def _start_source(p0, r0, p1, r1, kept_pose, kept, b):
    # Where body b's places at s = 0 come from. A place is a function of the pose's bits and the
    # model's static rows alone (the same code at both ends): at a start pose bitwise equal to the
    # end pose, or to the last call's end pose (a simulation loop: each step starts where the last
    # ended), the places already made are the ones placing would make, so the answer is the same
    # bit for bit. kept_pose: the last call's end poses (int64 bits, 12 a body), valid when kept.
    if _same_bits(p0, 3 * b, p1, 3 * b, 3) and _same_bits(r0, 9 * b, r1, 9 * b, 9):
        return SRC_REST
    if kept and _same_bits(p0, 3 * b, kept_pose, 12 * b, 3) and _same_bits(r0, 9 * b, kept_pose, 12 * b + 3, 9):
        return SRC_KEPT
    return SRC_PLACE


@nb.njit(cache=True, inline="always")
def _norm3(a, b, c):
    return math.sqrt(a * a + b * b + c * c)


@nb.njit(cache=True, inline="always")
def _geom_statics(g, glocal, gcap, gmargin, gstat):
    # gstat[g] = (ρ, |sphere centre|): the farthest point of the box and of the capsule (inflated by
    # the margin) from the body's origin, the box's cut to the capsule's holds the geom, so the
    # larger of the two reaches covers every point of it; and its sphere centre's distance from it
    m = gmargin[g]
    c = _norm3(glocal[g, 0], glocal[g, 1], glocal[g, 2])
    gstat[g, 0] = max(c + _norm3(glocal[g, 12] + m, glocal[g, 13] + m, glocal[g, 14] + m),
                      c + _norm3(gcap[g, 0], gcap[g, 1], gcap[g, 2]) + gcap[g, 3] + m)
    gstat[g, 1] = _norm3(glocal[g, 15], glocal[g, 16], glocal[g, 17])


@nb.njit(cache=True, inline="always")
def _geom_sweep(g, b, pos0, rot0, pos1, rot1, glocal, gcap, m, body, box, sph, row0, row, tmp, ends, gstat):
    # box[g] = the swept AABB of geom g (margin m) on body b (its motion in body[b]); sph[g] its
    # sphere and reach; row[g] its world row at s = 1; ends[g] its boxes at s = 1 (kept for the
    # next call, `_start_source`).
    src = body[b, 4]
    if src == SRC_KEPT:  # the last call's end places (read before this call's end overwrites them)
        for i in range(6):
            tmp[0, i] = ends[g, i]
            tmp[2, i] = ends[g, 6 + i]
        sph[g, 0] = sph[g, 3]
        sph[g, 1] = sph[g, 4]
        sph[g, 2] = sph[g, 5]
    for t in range(0 if src == SRC_PLACE else 1, 2):
        r = rot0 if t == 0 else rot1
        p = pos0 if t == 0 else pos1
        w = _world_row(r, p, b, glocal, g, row0, 0) if t == 0 else _world_row(r, p, b, glocal, g, row, g)
        _world_aabb(w, m, tmp, t)
        h0, h1, h2 = capsule_half(r[b, 0, 0], r[b, 0, 1], r[b, 0, 2], r[b, 1, 0], r[b, 1, 1], r[b, 1, 2],
                                  r[b, 2, 0], r[b, 2, 1], r[b, 2, 2], gcap[g, 0], gcap[g, 1], gcap[g, 2],
                                  gcap[g, 3] + m, w[0], w[1], w[2])
        # the capsule's box apart (rows 2, 3): a single step cuts the OBB's box to it
        # (`bounds._cap_aabb`), but the cut of an intermediate time is not inside the union of the
        # ends' cuts (the OBB's the tighter at one end, the capsule's at the other, neither in
        # between): each box is swept on its own and the two swept boxes are cut
        tmp[2 + t, 0] = w[0] - h0
        tmp[2 + t, 1] = w[1] - h1
        tmp[2 + t, 2] = w[2] - h2
        tmp[2 + t, 3] = w[0] + h0
        tmp[2 + t, 4] = w[1] + h1
        tmp[2 + t, 5] = w[2] + h2
        sph[g, 3 * t] = w[15]
        sph[g, 3 * t + 1] = w[16]
        sph[g, 3 * t + 2] = w[17]
    if src == SRC_REST:  # both poses the same bits: the same places
        for i in range(6):
            tmp[0, i] = tmp[1, i]
            tmp[2, i] = tmp[3, i]
        sph[g, 0] = sph[g, 3]
        sph[g, 1] = sph[g, 4]
        sph[g, 2] = sph[g, 5]
    for i in range(6):
        ends[g, i] = tmp[1, i]
        ends[g, 6 + i] = tmp[3, i]
    rho = gstat[g, 0]
    d = rho * body[b, 0] * (1.0 + SLACK_REL)
    # the reach δ: every point x of the volumes stays within |(R(s) - R1) x| + |t(s) - t1| <=
    # |x| min(θ, 2) + |t1 - t0| of its place at s = 1 (a chord of the turn, at most the arc)
    reach = (rho * body[b, 2] + body[b, 3]) * (1.0 + SLACK_REL)
    # (the end box at s = 1, cut, grown by δ: each of its two boxes' points moves at most δ)
    for i in range(3):
        lo = max(min(tmp[0, i], tmp[1, i]), min(tmp[2, i], tmp[3, i])) - d
        hi = min(max(tmp[0, 3 + i], tmp[1, 3 + i]), max(tmp[2, 3 + i], tmp[3, 3 + i])) + d
        box[g, i] = max(lo, max(tmp[1, i], tmp[3, i]) - reach)
        box[g, 3 + i] = min(hi, min(tmp[1, 3 + i], tmp[3, 3 + i]) + reach)
    sph[g, 6] = glocal[g, 18]
    sph[g, 7] = gstat[g, 1] * body[b, 0]
    sph[g, 8] = reach


@nb.njit(cache=True, inline="always")
def _spheres_meet(sph, a, ma, b, mb):
    # The continuous sphere test: min over s in [0, 1] of |ℓa(s) - ℓb(s)| <= the radii, margins
    # and deviations, with the single step's rounding slack (SLACK_REL of the radius, SLACK_POS of
    # the coordinates).
    d0 = sph[a, 0] - sph[b, 0]
    d1 = sph[a, 1] - sph[b, 1]
    d2 = sph[a, 2] - sph[b, 2]
    v0 = (sph[a, 3] - sph[b, 3]) - d0
    v1 = (sph[a, 4] - sph[b, 4]) - d1
    v2 = (sph[a, 5] - sph[b, 5]) - d2
    vv = dot3(v0, v1, v2, v0, v1, v2)
    s = 0.0
    if vv > 0.0:
        s = min(1.0, max(0.0, -dot3(d0, d1, d2, v0, v1, v2) / vv))
    e0 = d0 + s * v0
    e1 = d1 + s * v1
    e2 = d2 + s * v2
    r = sph[a, 6] + ma + sph[a, 7] + sph[b, 6] + mb + sph[b, 7]
    pos = 0.0
    for i in range(6):
        pos += abs(sph[a, i]) + abs(sph[b, i])
    r += SLACK_REL * r + SLACK_POS * pos
    return dot3(e0, e1, e2, e0, e1, e2) <= r * r


@nb.njit(cache=True, inline="always")
def _plane_reach(pl, q, mq, sph, g, mg, box, corner_too):
    # Does geom g (margin mg) reach the fixed plane pl[q] = (n, e), inflated by mq, at some s: its
    # sphere (the lower end of its centre's chord, less the deviation) and, with corner_too, its
    # swept box (the corner deepest along n; made with the geom's own margin) both reach
    # {n . x <= e + mq}.
    n0 = pl[q, 0]
    n1 = pl[q, 1]
    n2 = pl[q, 2]
    lim = pl[q, 3] + mq
    c = min(dot3(n0, n1, n2, sph[g, 0], sph[g, 1], sph[g, 2]), dot3(n0, n1, n2, sph[g, 3], sph[g, 4], sph[g, 5]))
    r = sph[g, 6] + mg + sph[g, 7]
    corner = dot3(n0, n1, n2, box[g, 3] if n0 < 0.0 else box[g, 0], box[g, 4] if n1 < 0.0 else box[g, 1],
                  box[g, 5] if n2 < 0.0 else box[g, 2])
    scale = abs(pl[q, 3])
    for i in range(6):
        scale += abs(sph[g, i]) + abs(box[g, i])
    tol = SLACK_REL * r + SLACK_POS * scale
    return (c - r <= lim + tol) & ((corner <= lim + tol) | (not corner_too))


@nb.njit(cache=True, inline="always")
def _pair_reach(sph, g, m, gm, turn):
    # Geom g's reach δ (`_geom_sweep`, its volumes inflated by its own margin gm) for an explicit
    # pair's margin m: the farthest point of the volumes inflated by m is at most √3 (m - gm) (a
    # box's half diagonal) farther from the body's origin, so it turns at most that times the
    # body's min(θ, 2) farther.
    return sph[g, 8] + 1.7320508075688774 * max(0.0, m - gm) * turn * (1.0 + SLACK_REL)
