"""The swept broad phase: every geom pair that may touch at *some* time of a step (issue 44).

The motion of a body over the step is the one `collide.sweep` bounds: ``p(s) = R(s) x + t(s)``,
``s`` in ``[0, 1]``, ``R(s) = exp(s log(R1 R0ᵀ)) R0`` (a constant-rate turn by the angle ``θ`` of
``R1 R0ᵀ``) and ``t`` linear. `collide.sweep` proves ``|p(s) - ℓ(s)| <= ρ θ² / 8`` for the point's
chord ``ℓ(s) = (1 - s) p(0) + s p(1)``, ``ρ`` its distance from the turn's axis through the body's
origin; here ``ρ <= |x|`` (the body-frame distance from the origin), so each body needs only its
``k = θ² / 8`` and no axis (and the two ways round at ``θ = π`` are covered alike).

Per geom, from the broad phase's own bounds rows (`layout.F_GLOCAL`, `F_GCAP`, inflated by the
margins exactly as a single step inflates them):

- its **swept AABB**: the union of its OBB's world AABBs at ``s = 0`` and ``s = 1``
  (`bounds._world_aabb`) grown by ``ρ k``, cut to the same of its capsule's (`bounds._cap_aabb`),
  with ``ρ`` the farthest body-frame point of either volume (``|centre| + |half extents|``,
  ``|centre| + |half segment| + radius``). Every chord point lies in the union's box, so each grown
  box holds every position of its volume during the step, and the cut holds every AABB (the OBB's
  cut to the capsule's) a single step computes at any ``s``. (The union of the ends' cut boxes
  does not: where the OBB's box is the tighter at one end and the capsule's at the other, the cut
  in between can be wider than both);
- its **sphere's centre** at both ends and that centre's deviation ``|c| k``. Two geoms may meet at
  time ``s`` only if ``|ℓa(s) - ℓb(s)| <= ra + rb + ma + mb + |ca| ka + |cb| kb``; ``ℓa - ℓb`` is
  linear in ``s``, so its smallest norm on ``[0, 1]`` is one projection (a continuous sphere test,
  tighter than the spheres' two swept capsules).

Pairs: the solid geoms are swept and pruned along one axis (an insertion sort of an order kept
between calls: a step moves little; by groups, the robots of a crowd, `_sweep_pairs`), each
overlap tested on the other two axes, the static filter
(a bit matrix made once from `broadphase.tables.StaticFilter`, the filter's one home) and the
continuous sphere test. A plane on a body that did not move is a fixed half-space: a geom pairs
with it when its swept sphere or its swept box reaches it at either end; a plane whose body moved
(rare: a tilting floor) pairs with every geom the filter lets it (the half-space's own sweep is not
convex). Explicit pairs: the continuous sphere test with the pair's margins (planes as above).

Each geom's places at s = 1 are kept (the workspace's Y_POSE, Y_END) for the next call: in a
simulation loop each step starts where the last ended, and a body whose start pose is bitwise the
kept end pose takes its geoms' kept places instead of placing them again; a body whose two poses
are bitwise equal places once (`swept_motion._start_source`). A place depends on nothing but the
pose's bits and the model's rows, so neither changes an answer. The per-body and per-geom half
(each body's turn, each geom's swept box, sphere and reach, the sphere and plane tests) is in
`collide._kernels.swept_motion`; the pairs (groups, sweep, filter) and the entry points are here.

So the output contains every pair a single step (`broadphase._world`) reports at any ``s`` of
the motion (its tests are the sphere, the OBBs and the AABBs; each swept test here is implied by
the single step's at that ``s``), and every pair whose geoms touch during the step.

Rotations are accepted within `bounds.ORTHO_TOL` of orthonormal, as for a single step; ``cos θ`` is
lowered by `COS_SLACK` so that ``θ`` is never underestimated for the orthonormal rotation nearest to
each (a trace moved by 9 entries of at most the tolerance each, at both ends), and the reach's
``min(θ, 2)`` carries the factor ``1 + 2 ORTHO_TOL`` (such a rotation stretches ``|x|`` by up to
``1 + 1.5 ORTHO_TOL``; at ``θ = π`` no cos slack covers it).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from .bounds import _bounds_ok, _plane_hit, _row_of, explicit_pair, plane_world
from ._ptr import NO_NRT, f64_ptr, i32_ptr, i64_ptr, view_of
from .keys import _emit, _sort_keys, scratch_size
from .layout import (F_GCAP, F_GLOCAL, F_GMARGIN, F_GPLANE, F_PAIR_M, I_GEOM_BID, I_PAIR_G, I_PGEOMS, I_PLANES,
                     Layout, Tables, address, view_f1, view_f2, view_i1, view_i2)
from .swept_motion import (_bits, _body_motion, _geom_statics, _geom_sweep, _pair_reach, _plane_reach,
                           _spheres_meet)


# ---------------------------------------------------------------------------- the declarations
# Counts: G geoms, Gs solid geoms, NB bodies, Q planes, NW = ceil(G / 64) words a bit row, R >= 1
# groups of the sweep.
SWEPT = Tables("X", header=5)
XTAB = Layout(SWEPT, "X", np.int64)  # static, made once (`collide.broadphase.swept`)
X_ALLOW = XTAB.field("allow", "G, NW")  # bit h of allow[g, w]: the pair (g, 64 w + h) passes the static filter
# The sweep's groups (`_sweep_pairs`; R of them, each a set of solid geoms): a solid geom's group, and
# each group's span of the members list (its size, made once)
X_GROUP = XTAB.field("group", "G")
X_GSTART = XTAB.field("gstart", "R + 1")
XWORK = Layout(SWEPT, "XW", np.int64)  # a caller's int64 workspace
XW_ORDER = XWORK.field("order", "max(Gs, 1)")  # solid geoms by their swept boxes' low ends, kept between calls
XW_GORDER = XWORK.field("gorder", "R")  # the groups by their boxes' low ends, kept between calls
XW_GMEM = XWORK.field("gmem", "max(Gs, 1)")  # the members of each group (X_GSTART's spans) in sweep order
XW_FILL = XWORK.field("fill", "R")  # scratch: each group's next free member slot
# the sweep axis; 1 once the order is set; 1 while Y_POSE, Y_END hold an end; 1 once Y_GSTAT is made
XW_STATE = XWORK.field("state", "4")
YWORK = Layout(SWEPT, "Y", np.float64)  # a caller's float64 workspace
# per body: k = θ² / 8, 1.0 when the pose changed, min(θ, 2), |t1 - t0|, where its start places come from
Y_BODY = YWORK.field("body", "NB, 5")
Y_BOX = YWORK.field("box", "G, 6")  # swept AABB (lo, hi) of each solid geom
Y_SPH = YWORK.field("sph", "G, 9")  # sphere centre at s = 0 (3) and s = 1 (3), radius, centre deviation, reach δ
Y_ROW = YWORK.field("row", "G, ROW")  # world bounds rows at s = 1
Y_ROW0 = YWORK.field("row0", "1, ROW")  # scratch row (s = 0)
Y_TMP = YWORK.field("tmp", "4, 6")  # scratch boxes: the OBB's at s = 0, 1, the capsule's at s = 0, 1
Y_GBOX = YWORK.field("gbox", "R, 6")  # the AABB of each group's members' swept boxes
Y_PLANE = YWORK.field("plane", "max(Q, 1), 4")  # a fixed plane's world (n, e); e = nan: its body moved
# The last call's end (see `swept_motion._start_source`): each body's end pose (position, rotation row-major)
# and each solid geom's boxes at it (its OBB's, its capsule's); its sphere's centre is sph[g, 3:6].
Y_POSE = YWORK.field("pose", "NB, 12")
Y_END = YWORK.field("end", "G, 12")
Y_GSTAT = YWORK.field("gstat", "G, 2")  # per solid geom, made on a workspace's first call (`_geom_statics`)
H_G, H_GS, H_NB, H_Q, H_S = range(5)  # X's header: the counts, and S of the pair keys (`keys.key_shift`)

BAD_POSE = -1  # returned as BAD_POSE - (2 b + t): body b's pose at t (0: start, 1: end) refused
BAD_SHAPE = -(1 << 62)  # `swept_call`: a pose array of another shape than (NB, 3), (NB, 3, 3)


@nb.njit(cache=True, inline="always")
def _allowed(allow, a, b):
    return (allow[a, b >> 6] >> (b & 63)) & 1 != 0


@nb.njit(cache=True, inline="always")
def _sort_order(order, box, n, axis):
    # Insertion sort of order[:n] by box[., axis] (the low ends): the previous call's order is
    # nearly right when bodies move a little, so this costs about one pass.
    for i in range(1, n):
        g = order[i]
        v = box[g, axis]
        j = i - 1
        while j >= 0 and box[order[j], axis] > v:
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = g


@nb.njit(cache=True, inline="always")
def _pair_hit(box, a, b, a1, a2, allow, sph, gmargin, row):
    # Geoms a, b whose swept boxes overlap on the sweep axis: the other two axes, the static
    # filter, the continuous sphere test and the end rows' tests grown by the reaches
    return (((box[a, a1] <= box[b, 3 + a1]) & (box[b, a1] <= box[a, 3 + a1]) & (box[a, a2] <= box[b, 3 + a2])
             & (box[b, a2] <= box[a, 3 + a2]))
            and _allowed(allow, a, b) and _spheres_meet(sph, a, gmargin[a], b, gmargin[b])
            and _bounds_ok(_row_of(row, a), gmargin[a] + sph[a, 8], _row_of(row, b), gmargin[b] + sph[b, 8]))


@nb.njit(cache=True, inline="always")
def _sweep_pairs(order, box, Gs, axis, X, XW, Y, allow, sph, gmargin, row, keys, S):
    # The solid geom pairs whose swept boxes overlap and that pass `_pair_hit`, as keys from 0 on;
    # returns their count. order: the solid geoms sorted by box[., axis].
    #
    # By groups (`collide.broadphase.swept.sweep_groups`: the subtrees of the world's children, as
    # the robots of a crowd), each a box around its members' boxes: a sweep within each group, and
    # one across each two groups whose boxes overlap (a pair across groups overlaps only if its
    # groups' boxes do). So a crowd spread along the sweep axis costs its neighbours' overlaps, not
    # the overlaps of every robot in the same row. Each overlapping pair is met exactly once.
    group = view_i1(X, X, X_GROUP)
    gstart = view_i1(X, X, X_GSTART)
    gorder = view_i1(X, XW, XW_GORDER)
    gmem = view_i1(X, XW, XW_GMEM)
    fill = view_i1(X, XW, XW_FILL)
    gbox = view_f2(X, Y, Y_GBOX)
    R = gorder.shape[0]
    a1 = (axis + 1) % 3
    a2 = (axis + 2) % 3
    for r in range(R):
        fill[r] = gstart[r]
        for i in range(3):
            gbox[r, i] = np.inf
            gbox[r, 3 + i] = -np.inf
    for ii in range(Gs):  # each group's members in sweep order, and its box
        g = order[ii]
        r = group[g]
        gmem[fill[r]] = g
        fill[r] += 1
        for i in range(3):
            gbox[r, i] = min(gbox[r, i], box[g, i])
            gbox[r, 3 + i] = max(gbox[r, 3 + i], box[g, 3 + i])
    k = 0
    for r in range(R):  # within each group
        e = gstart[r + 1]
        for ii in range(gstart[r], e):
            a = gmem[ii]
            hi = box[a, 3 + axis]
            for jj in range(ii + 1, e):
                b = gmem[jj]
                if box[b, axis] > hi:
                    break
                if _pair_hit(box, a, b, a1, a2, allow, sph, gmargin, row):
                    k = _emit(keys, k, a, b, S)
    if R < 2:
        return k
    _sort_order(gorder, gbox, R, axis)
    for ii in range(R):  # across each two groups whose boxes overlap
        p = gorder[ii]
        hi = gbox[p, 3 + axis]
        for jj in range(ii + 1, R):
            q = gorder[jj]
            if gbox[q, axis] > hi:
                break
            if not ((gbox[p, a1] <= gbox[q, 3 + a1]) & (gbox[q, a1] <= gbox[p, 3 + a1])
                    & (gbox[p, a2] <= gbox[q, 3 + a2]) & (gbox[q, a2] <= gbox[p, 3 + a2])):
                continue
            # the two sorted member lists merged: each member meets the other list's members
            # from where its own low end falls up to its high end
            i = gstart[p]
            ie = gstart[p + 1]
            j = gstart[q]
            je = gstart[q + 1]
            while i < ie and j < je:
                a = gmem[i]
                b = gmem[j]
                if box[a, axis] <= box[b, axis]:
                    hi2 = box[a, 3 + axis]
                    for jj2 in range(j, je):
                        c = gmem[jj2]
                        if box[c, axis] > hi2:
                            break
                        if _pair_hit(box, a, c, a1, a2, allow, sph, gmargin, row):
                            k = _emit(keys, k, a, c, S)
                    i += 1
                else:
                    hi2 = box[b, 3 + axis]
                    for ii2 in range(i, ie):
                        c = gmem[ii2]
                        if box[c, axis] > hi2:
                            break
                        if _pair_hit(box, c, b, a1, a2, allow, sph, gmargin, row):
                            k = _emit(keys, k, c, b, S)
                    j += 1
    return k


@nb.njit(cache=True, inline="always")
def _swept(pos0, rot0, pos1, rot1, I, F, X, XW, Y, keys, scr):
    # One world's swept pairs as keys ``g1 << S | g2`` in ``keys``, sorted when they fit (``scr``:
    # `keys.scratch_size` int64); returns their count (which may exceed ``keys``' length: then only
    # the first were written), or ``BAD_POSE - (2 b + t)``. See `swept_world`.
    Gs = X[H_GS]
    body = view_f2(X, Y, Y_BODY)
    state = view_i1(X, XW, XW_STATE)
    NB = pos0.shape[0]
    kept_pose = view_of(i64_ptr(address(X, Y, Y_POSE)), 12 * NB)
    bad = _body_motion(pos0, rot0, pos1, rot1, body, kept_pose, state[2] == 1)
    if bad >= 0:
        return BAD_POSE - bad
    glocal = view_f2(I, F, F_GLOCAL)
    gcap = view_f2(I, F, F_GCAP)
    gmargin = view_f1(I, F, F_GMARGIN)
    gplane = view_f2(I, F, F_GPLANE)
    pair_m = view_f1(I, F, F_PAIR_M)
    geom_bid = view_i1(I, I, I_GEOM_BID)
    solid = view_i1(I, I, I_PGEOMS)
    planes = view_i1(I, I, I_PLANES)
    pair_g = view_i2(I, I, I_PAIR_G)
    allow = view_i2(X, X, X_ALLOW)
    order = view_i1(X, XW, XW_ORDER)
    box = view_f2(X, Y, Y_BOX)
    sph = view_f2(X, Y, Y_SPH)
    row = view_f2(X, Y, Y_ROW)
    row0 = view_f2(X, Y, Y_ROW0)
    tmp = view_f2(X, Y, Y_TMP)
    plw = view_f2(X, Y, Y_PLANE)
    ends = view_f2(X, Y, Y_END)
    gstat = view_f2(X, Y, Y_GSTAT)
    if state[3] == 0:
        for ii in range(Gs):
            _geom_statics(solid[ii], glocal, gcap, gmargin, gstat)
        state[3] = 1
    S = X[H_S]
    # 1. every solid geom's swept box and sphere; the spread of their centres per axis. The kept
    # end (Y_POSE, Y_END) is not whole while this runs: marked invalid until it is again
    state[2] = 0
    m0 = m1 = m2 = q0 = q1 = q2 = 0.0
    for ii in range(Gs):
        g = solid[ii]
        b = geom_bid[g]
        _geom_sweep(g, b, pos0, rot0, pos1, rot1, glocal, gcap, gmargin[g], body, box, sph, row0, row, tmp, ends,
                    gstat)
        c0 = box[g, 0] + box[g, 3]
        c1 = box[g, 1] + box[g, 4]
        c2 = box[g, 2] + box[g, 5]
        m0 += c0
        m1 += c1
        m2 += c2
        q0 += c0 * c0
        q1 += c1 * c1
        q2 += c2 * c2
    p1 = _bits(pos1, 3 * NB)
    r1 = _bits(rot1, 9 * NB)
    for b in range(NB):
        for i in range(3):
            kept_pose[12 * b + i] = p1[3 * b + i]
        for i in range(9):
            kept_pose[12 * b + 3 + i] = r1[9 * b + i]
    state[2] = 1
    # 2. the sweep axis: the widest spread of centres; kept unless another is 1.5x as wide (each
    # change costs the sort a full pass)
    if state[1] == 0:
        for ii in range(Gs):
            order[ii] = solid[ii]
        gorder = view_i1(X, XW, XW_GORDER)
        for r in range(gorder.shape[0]):
            gorder[r] = r
        state[1] = 1
    n = max(Gs, 1)
    v0 = q0 - m0 * m0 / n
    v1 = q1 - m1 * m1 / n
    v2 = q2 - m2 * m2 / n
    axis = state[0]
    va = v0 if axis == 0 else v1 if axis == 1 else v2
    best = 0 if (v0 >= v1) & (v0 >= v2) else 1 if v1 >= v2 else 2
    vb = v0 if best == 0 else v1 if best == 1 else v2
    if vb > 1.5 * va:
        axis = best
        state[0] = axis
    _sort_order(order, box, Gs, axis)
    k = _sweep_pairs(order, box, Gs, axis, X, XW, Y, allow, sph, gmargin, row, keys, S)
    k4 = min(k, keys.shape[0])  # the sweep's keys end here (`keys._sort_keys` sorts the two runs apart)
    # 3. planes: fixed ones as half-spaces, moving ones against every geom the filter lets them
    for qi in range(planes.shape[0]):
        q = planes[qi]
        bq = geom_bid[q]
        moving = body[bq, 1] != 0.0
        if not moving:
            m0, m1, m2, e = plane_world(rot1[bq, 0, 0], rot1[bq, 0, 1], rot1[bq, 0, 2], rot1[bq, 1, 0],
                                        rot1[bq, 1, 1], rot1[bq, 1, 2], rot1[bq, 2, 0], rot1[bq, 2, 1],
                                        rot1[bq, 2, 2], pos1[bq, 0], pos1[bq, 1], pos1[bq, 2], gplane[q, 0],
                                        gplane[q, 1], gplane[q, 2], gplane[q, 3])
            plw[qi, 0] = m0
            plw[qi, 1] = m1
            plw[qi, 2] = m2
            plw[qi, 3] = e
        else:
            plw[qi, 3] = np.nan
        for ii in range(Gs):
            g = solid[ii]
            if _allowed(allow, q, g) and (moving or (_plane_reach(plw, qi, gmargin[q], sph, g, gmargin[g], box, True)
                                                     and _plane_hit(plw, qi, gmargin[q], row, g,
                                                                    gmargin[g] + sph[g, 8]))):
                k = _emit(keys, k, q, g, S)
    # 4. explicit pairs: the pair's margins where given, else the geoms'. A single step tests them
    # with their spheres and OBBs only (`bounds._explicit_hit`), inflated by the pair's margin: no
    # swept box here (it carries the geom's own margin, and a plane pair with a larger pair margin
    # was lost even without motion; adversarial review of issue 44), and the reach grown to the
    # pair's margin (`_pair_reach`)
    for i in range(pair_g.shape[0]):
        g1, g2, m1, m2, p1, p2 = explicit_pair(i, pair_g, pair_m, gmargin, gplane)
        if p1 and p2:
            continue
        if p1 or p2:
            gp = g1 if p1 else g2
            gs = g2 if p1 else g1
            qi = -1
            for j in range(planes.shape[0]):
                if planes[j] == gp:
                    qi = j
            mq = m1 if p1 else m2
            mg = m2 if p1 else m1
            hit = np.isnan(plw[qi, 3]) or (
                _plane_reach(plw, qi, mq, sph, gs, mg, box, False)
                and _plane_hit(plw, qi, mq, row, gs, mg + _pair_reach(sph, gs, mg, gmargin[gs], body[geom_bid[gs], 2])))
        else:
            hit = (_spheres_meet(sph, g1, m1, g2, m2)
                   and _bounds_ok(_row_of(row, g1), m1 + _pair_reach(sph, g1, m1, gmargin[g1], body[geom_bid[g1], 2]),
                                  _row_of(row, g2), m2 + _pair_reach(sph, g2, m2, gmargin[g2], body[geom_bid[g2], 2])))
        if hit:
            k = _emit(keys, k, g1, g2, S)
    if k <= keys.shape[0]:
        _sort_keys(keys, k, k4, S, X[H_G], scr)
    return k


@nb.njit(cache=True)
def swept_world(pos0, rot0, pos1, rot1, I, F, X, XW, Y, keys, scr, out):
    """One world's swept pairs as sorted keys ``g1 << S | g2`` in ``keys``, and as ``(g1, g2)`` rows
    in ``out`` (an int32 ``(n, 2)`` view of ``keys``' memory, or an empty array: keys only); returns
    their count (which may exceed ``keys``' length: then only the first were written, and the caller
    grows the buffer and calls again), or ``BAD_POSE - (2 b + t)`` for body b's refused pose at end
    t.

    ``I``, ``F``: the broad phase's model (`layout.MODEL`); ``X``: `XTAB` (its counts at 0..3);
    ``XW``, ``Y``: workspaces of `XWORK` and `YWORK`, owned by one caller at a time (they keep the
    last call's end between calls, `swept_motion._start_source`); ``scr``: `keys.scratch_size` int64 for
    ``keys``. The pose arrays: C-contiguous float64 of shapes (NB, 3), (NB, 3, 3).
    """
    k = _swept(pos0, rot0, pos1, rot1, I, F, X, XW, Y, keys, scr)
    _rows(keys, k, X[H_S], out)
    return k


@nb.njit(cache=True, inline="always")
def _rows(keys, k, S, out):
    # The first min(k, len(keys)) keys as (g1, g2) rows into out (keys' own memory, or empty: none)
    if out.shape[0] > 0:
        n = min(k, keys.shape[0])
        mask = (np.int64(1) << S) - 1
        for i in range(n):
            key = keys[i]  # read before out[i] (the same 8 bytes) is written
            out[i, 0] = np.int32(key >> S)
            out[i, 1] = np.int32(key & mask)


# `swept_call`'s context: the addresses and lengths of one caller's buffers (see `_ptr`, and
# `step.context` for the single step's): the model (I, F), the static table X, the workspaces XW,
# Y, the keys and their sort scratch; and an output arena of SC_NOUT (K, 2) int32 rows filled
# from SC_OFF on (`_swept_call`; `context` leaves these three). The owner keeps every buffer alive
# while the context holds it.
(SC_I, SC_NI, SC_F, SC_NF, SC_X, SC_NX, SC_XW, SC_NXW, SC_Y, SC_NY, SC_KEYS, SC_NKEYS, SC_SCR, SC_NSCR, SC_OUT,
 SC_NOUT, SC_OFF) = range(17)
NSCTX = 17


def context(I, F, X, XW, Y, keys, scr, out=None) -> np.ndarray:
    """The context of these buffers (into ``out`` when given); each must be C-contiguous of the
    kernel's dtype, ``scr`` at least ``keys.scratch_size(G, keys.size)`` long."""
    ctx = np.zeros(NSCTX, np.int64) if out is None else out
    for arr, dt in ((I, np.int64), (F, np.float64), (X, np.int64), (XW, np.int64), (Y, np.float64),
                    (keys, np.int64), (scr, np.int64)):
        if arr.dtype != dt or not arr.flags.c_contiguous:
            raise ValueError("swept context: buffers must be C-contiguous arrays of the kernel's dtypes")
    if scr.size < scratch_size(int(X[H_G]), keys.size):
        raise ValueError("swept context: the sort scratch is shorter than scratch_size(G, keys)")
    ctx[:SC_OUT] = (I.ctypes.data, I.size, F.ctypes.data, F.size, X.ctypes.data, X.size, XW.ctypes.data, XW.size,
                    Y.ctypes.data, Y.size, keys.ctypes.data, keys.size, scr.ctypes.data, scr.size)
    return ctx


def _swept_call(pos0, rot0, pos1, rot1, ctx):
    """`swept_world` on the buffers of the context ``ctx`` (`context`); `BAD_SHAPE` for a pose
    array of another shape. The K rows go to the output arena at ``ctx[SC_OFF]``, which then
    advances by K; where it has no room left, over the keys' own memory (``ctx[SC_OFF]`` stays).
    Compiled for one signature (`swept_call`): five arguments where `swept_world` takes twelve (a
    numba call pays for each array), and no reference counting (views of pointers carry none)."""
    X = view_of(i64_ptr(ctx[SC_X]), ctx[SC_NX])
    NB = X[H_NB]
    if (pos0.shape[0] != NB or pos0.shape[1] != 3 or rot0.shape[0] != NB or rot0.shape[1] != 3
            or rot0.shape[2] != 3 or pos1.shape[0] != NB or pos1.shape[1] != 3 or rot1.shape[0] != NB
            or rot1.shape[1] != 3 or rot1.shape[2] != 3):
        return BAD_SHAPE
    I = view_of(i64_ptr(ctx[SC_I]), ctx[SC_NI])
    F = view_of(f64_ptr(ctx[SC_F]), ctx[SC_NF])
    XW = view_of(i64_ptr(ctx[SC_XW]), ctx[SC_NXW])
    Y = view_of(f64_ptr(ctx[SC_Y]), ctx[SC_NY])
    keys = view_of(i64_ptr(ctx[SC_KEYS]), ctx[SC_NKEYS])
    scr = view_of(i64_ptr(ctx[SC_SCR]), ctx[SC_NSCR])
    k = _swept(pos0, rot0, pos1, rot1, I, F, X, XW, Y, keys, scr)
    if k < 0 or k > keys.shape[0]:
        return k
    off = ctx[SC_OFF]
    if off + k <= ctx[SC_NOUT]:
        # Rows handed out are never written again (the owner starts a new arena when this one is
        # full): the caller needs no copy
        S = X[H_S]
        mask = (np.int64(1) << S) - 1
        out = view_of(i32_ptr(ctx[SC_OUT] + 8 * off), (k, 2))
        for i in range(k):
            key = keys[i]
            out[i, 0] = np.int32(key >> S)
            out[i, 1] = np.int32(key & mask)
        ctx[SC_OFF] = off + k
    else:
        _rows(keys, k, X[H_S], view_of(i32_ptr(ctx[SC_KEYS]), (ctx[SC_NKEYS], 2)))
    return k


# One signature: any other argument type (float32, a strided view, a list) makes the dispatcher
# raise TypeError instead of compiling a new specialisation (the caller then checks and converts).
SWEPT_SIGNATURE = ("int64(float64[:, ::1], float64[:, :, ::1], float64[:, ::1], float64[:, :, ::1], "
                   "int64[::1])")
_call_dispatcher = None


def swept_call():
    """The compiled `_swept_call` (``SWEPT_SIGNATURE`` only; from numba's cache after the first run)."""
    global _call_dispatcher
    if _call_dispatcher is None:
        _call_dispatcher = nb.njit(SWEPT_SIGNATURE, **NO_NRT)(_swept_call)
    return _call_dispatcher


@nb.njit(cache=True, parallel=True)
def swept_batch(pos0, rot0, pos1, rot1, I, F, X, XWs, Ys, scratch, scrs, counts, offsets, out):
    """The worlds of a batch, threads over them (``T = XWs.shape[0]`` workers, worker t owning
    ``XWs[t]``, ``Ys[t]``, ``scratch[t]`` and its sort scratch ``scrs[t]``). With ``out`` empty: ``counts[w]`` = `swept_world`'s
    return for world w (a count, or a refused pose), keys written nowhere. Else each world's
    sorted keys (``counts[w]`` of them, at most ``scratch``' width) into
    ``out[offsets[w]:offsets[w] + counts[w]]``."""
    B = pos0.shape[0]
    T = XWs.shape[0]
    write = out.shape[0] > 0
    none = np.zeros((0, 2), np.int32)
    for t in nb.prange(T):
        for w in range(t, B, T):
            if not write:
                counts[w] = swept_world(pos0[w], rot0[w], pos1[w], rot1[w], I, F, X, XWs[t], Ys[t], scratch[t, :0],
                                        scrs[t], none)
            elif counts[w] > 0:
                n = swept_world(pos0[w], rot0[w], pos1[w], rot1[w], I, F, X, XWs[t], Ys[t], scratch[t], scrs[t],
                                none)
                o = offsets[w]
                for i in range(n):
                    out[o + i] = scratch[t, i]
