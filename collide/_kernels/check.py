"""Collision checks of many configurations (numba): is each one in collision, and how close.

`check_worlds` takes a batch of configurations ``qpos (B, nq)`` of one MuJoCo-style model and,
threads across configurations (a ``prange`` over one worker a thread, each taking chunks of
configurations from a shared counter, `_threads.fetch_add`, so that a thread whose worlds end
early takes more), for each configuration:

1. its body poses (`kinematics._kinematics_world`, MuJoCo's ``mj_kinematics``) and, when first
   needed, a geom's world pose, as ``mj_kinematics`` places it (``mj_local2Global``: position
   ``xpos + xmat @ geom_pos``, rotation from the quaternion product ``xquat * geom_quat``);
2. ``in_collision``: over the configuration's candidate pairs (a broad phase's rows), the
   deepest contact MuJoCo would make for the pair (`deepest_contact`: the margins and the plane,
   bounding and box-box branches are `collide._kernels.manifold`'s own, `pair_margins` and
   `plane_box_contacts`, which `collide_pairs` calls too); the first pair whose deepest
   contact is active (``dist < margin``, not in the gap: MuJoCo's ``exclude == 0``) ends the
   configuration's search (an early exit), the pairs decided in closed form (spheres, capsules,
   planes) tried before those GJK may decide, with the answer of the rows' order (`decide_rows`);
3. with distances asked: the signed distance of the closest pair of a static list of filtered
   pairs (`pair_signed_distance`, the single-pair distance of ``mj_geomDistance``), by branch and
   bound: a lower bound per pair from balls about the geoms' origins (``|c1 - c2| - r1 - r2``, or
   a plane's ``n . (c - p) - r``, valid for the signed distance too: moving one geom by the balls'
   overlap separates them), the pair of smallest bound first, then every pair whose bound is
   below the best distance so far.

Each worker allocates its scratch once per call, the signed distance's among it (EPA's included:
`collide._kernels.distance.WS_F_EPA`), so that deciding allocates nothing per configuration; each distance
of step 3 (`pair_signed_distance`, as ``mj_geomDistance``'s single-pair call) still allocates its own.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ._ptr import borrow
from ._quat import _qmat, _qmul
from ._threads import fetch_add, set_chunksize
from .distance import EPA_CAP, ROUNDING, WS_F_EPA, WS_I_EPA, pair_distance_within
from .gjk import OVERLAP, SEPARATED, gjk_within
from .kinematics import _kinematics_world
from .support import CYLINDER, ELLIPSOID, POINTS, support
from .manifold import (BOX_WS, CONTACT_TOL, CONVEX, CONVEX_PAIR, MAX_PER_PAIR, OUT_DISTANCE, OUT_SIZE, PLANE, SKIPPED,
                       _finite_pose, _pair_rows, _shape, pair_margins, pair_signed_distance,
                       plane_box_contacts, scratch_caps, T_MESH)

_EPS = float(np.finfo(np.float64).eps)

# `deepest_contact`'s answers.
NO_CONTACT, ACTIVE, IN_GAP, NOT_COLLIDED = 0, 1, 2, 3

# Errors written to ``out_err`` (per configuration): a non-finite geom pose.
ERR_POSE = 1

# Subset modes (`collide.collider.Collider`'s ``geoms`` / ``bodies``): every pair; pairs inside
# group 1; pairs with one geom in group 1 and the other in group 2.
SUBSET_ALL, SUBSET_ONE, SUBSET_TWO = 0, 1, 2



@nb.njit(cache=True, inline="always")
def in_subset(mode, label, g1, g2):
    """Whether the pair ``(g1, g2)`` is checked: ``label (G,) int8`` bit 1 (group 1), bit 2 (group 2)."""
    if mode == SUBSET_ALL:
        return True
    a = label[g1]
    b = label[g2]
    if mode == SUBSET_ONE:
        return (a & 1) != 0 and (b & 1) != 0
    return ((a & 1) != 0 and (b & 2) != 0) or ((a & 2) != 0 and (b & 1) != 0)


@nb.njit(cache=True, inline="always")
def geom_pose(g, body_pos, body_rot, body_quat, geom_body, geom_pos, geom_quat, xpos, xmat):
    """World pose of geom ``g`` into ``xpos[g]``, ``xmat[g]`` from its body's (``mj_local2Global``)."""
    b = geom_body[g]
    for i in range(3):
        xpos[g, i] = (body_pos[b, i] + body_rot[b, i, 0] * geom_pos[g, 0] + body_rot[b, i, 1] * geom_pos[g, 1]
                      + body_rot[b, i, 2] * geom_pos[g, 2])
    q0, q1, q2, q3 = _qmul(body_quat[b, 0], body_quat[b, 1], body_quat[b, 2], body_quat[b, 3],
                           geom_quat[g, 0], geom_quat[g, 1], geom_quat[g, 2], geom_quat[g, 3])
    m = _qmat(q0, q1, q2, q3)
    xmat[g, 0, 0], xmat[g, 0, 1], xmat[g, 0, 2] = m[0], m[1], m[2]
    xmat[g, 1, 0], xmat[g, 1, 1], xmat[g, 1, 2] = m[3], m[4], m[5]
    xmat[g, 2, 0], xmat[g, 2, 1], xmat[g, 2, 2] = m[6], m[7], m[8]


@nb.njit(cache=True, inline="always")
def geom_pose_lane(g, l, ps, xq, geom_body, geom_pos, geom_quat, xpos, xmat):
    """`geom_pose` of geom ``g`` from lane ``l``'s body poses: ``ps (NB, 12, LANES)`` (position,
    then the rotation row-major: `layout.LW_POSES`) and ``xq (NB, 4, LANES)`` (the unit quaternions,
    `kinematics._kinematics_lanes`' scratch); the same operations in the same order."""
    b = geom_body[g]
    for i in range(3):
        xpos[g, i] = (ps[b, i, l] + ps[b, 3 + 3 * i, l] * geom_pos[g, 0] + ps[b, 4 + 3 * i, l] * geom_pos[g, 1]
                      + ps[b, 5 + 3 * i, l] * geom_pos[g, 2])
    q0, q1, q2, q3 = _qmul(xq[b, 0, l], xq[b, 1, l], xq[b, 2, l], xq[b, 3, l],
                           geom_quat[g, 0], geom_quat[g, 1], geom_quat[g, 2], geom_quat[g, 3])
    m = _qmat(q0, q1, q2, q3)
    xmat[g, 0, 0], xmat[g, 0, 1], xmat[g, 0, 2] = m[0], m[1], m[2]
    xmat[g, 1, 0], xmat[g, 1, 1], xmat[g, 1, 2] = m[3], m[4], m[5]
    xmat[g, 2, 0], xmat[g, 2, 1], xmat[g, 2, 2] = m[6], m[7], m[8]


@nb.njit(cache=True, inline="always")
def decider_scratch(cap, fmax):
    """One worker's scratch for `deepest_contact`, for ``cap`` support points of a geom and
    ``fmax`` vertices of a hull face at most (`collide._kernels.manifold.scratch_caps`): the
    tuple ``(scratch, dws, d0, gws, g4, dwi)`` it takes (``d0``, GJK's first direction, zero:
    the centres' difference)."""
    scratch = (np.empty((cap, 3)), np.empty(cap), np.zeros(4, np.int64), np.empty((MAX_PER_PAIR, 4)), np.zeros(3),
               np.empty(BOX_WS), np.empty((fmax, 3)), np.empty(fmax))  # cand, dep, sel, res, bnrm, bws, pcand, pdep
    # the signed distance's answer (OUT_SIZE) and scratch, EPA's included (`pair_distance_within`: nothing
    # allocated per pair); GJK's W, WA, WB (4, 3), then v, pa, pb (3,); its lam, dirn; the int64 scratch, whose
    # first two entries are GJK's hints
    return (scratch, np.empty(OUT_SIZE + WS_F_EPA), np.zeros(3), np.zeros((4, 4, 3)), np.zeros((2, 4)),
            np.empty(WS_I_EPA, np.int64))


@nb.njit(cache=True, inline="always")
def _apart_on_axis(s1, s2, xpos, g1, g2, r, thr, pa, pb):
    # Whether the axis through the two geoms' origins separates them by more than thr: with u the
    # unit axis, min over B of u.b - max over A of u.a (two support points, `support`) is a lower
    # bound of the cores' distance (a separating axis: the first lower bound GJK computes, from
    # the same direction), so a pair it puts beyond thr + r makes no contact. Less a rounding
    # allowance (`collide._kernels.distance.ROUNDING` ulps of the largest coordinate): never true
    # for a pair within reach.
    d0 = xpos[g2, 0] - xpos[g1, 0]
    d1 = xpos[g2, 1] - xpos[g1, 1]
    d2 = xpos[g2, 2] - xpos[g1, 2]
    ln = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if not ln > 0.0:
        return False
    support(s1, d0, d1, d2, -1, pa)
    support(s2, -d0, -d1, -d2, -1, pb)
    sep = ((pb[0] - pa[0]) * d0 + (pb[1] - pa[1]) * d1 + (pb[2] - pa[2]) * d2) / ln
    scale = max(abs(pa[0]), abs(pa[1]), abs(pa[2]), abs(pb[0]), abs(pb[1]), abs(pb[2]))
    return sep - ROUNDING * _EPS * (scale + r) - r > thr


# The most core points of a shape whose projection on an axis `_extent` takes by scanning them
# (a box's eight corners; a mesh's hull is left to GJK).
SAT_POINTS = 8

# `_plane_mesh_depth`'s slack, relative to the coordinates' magnitude: the hill-climbed support
# vertex and `collide._kernels.plane.plane_mesh`'s scan may differ by rounding (ties, and a climb
# stopped on a face almost parallel to the plane); a depth this close to a threshold is left to
# `plane_box_contacts`.
PLANE_MESH_SLACK = 1e-9


@nb.njit(cache=True, inline="always")
def _extent(s, u0, u1, u2):
    # The interval (lo, hi) of u . (x - pos) over the shape's core (u a world direction): a box's
    # or capsule's points scanned, a cylinder's and an ellipsoid's support in closed form; (nan,
    # nan) for a shape with more points (a mesh: left to GJK).
    kind, prm, pts, nbr_start, nbr, rot, pos = s
    l0 = rot[0, 0] * u0 + rot[1, 0] * u1 + rot[2, 0] * u2
    l1 = rot[0, 1] * u0 + rot[1, 1] * u1 + rot[2, 1] * u2
    l2 = rot[0, 2] * u0 + rot[1, 2] * u1 + rot[2, 2] * u2
    if kind == POINTS:
        if pts.shape[0] > SAT_POINTS:
            return np.nan, np.nan
        lo = np.inf
        hi = -np.inf
        for i in range(pts.shape[0]):
            v = pts[i, 0] * l0 + pts[i, 1] * l1 + pts[i, 2] * l2
            lo = min(lo, v)
            hi = max(hi, v)
        return lo, hi
    if kind == CYLINDER:
        e = prm[1] * abs(l2) + prm[0] * math.sqrt(l0 * l0 + l1 * l1)
        return -e, e
    if kind == ELLIPSOID:  # the core: the ellipsoid less its rolling ball (`collide.support.rolling_radius`)
        e = math.sqrt((prm[0] * l0) ** 2 + (prm[1] * l1) ** 2 + (prm[2] * l2) ** 2) \
            - prm[3] * math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
        return -e, e
    return np.nan, np.nan


@nb.njit(cache=True, inline="always")
def _axes_of(s):
    # How many of the shape's frame axes are separating-axis candidates, from the last: a box's
    # three face normals (3), a capsule's or cylinder's axis, its frame's z (1), none (0).
    kind, prm, pts, nbr_start, nbr, rot, pos = s
    if kind == POINTS:
        n = pts.shape[0]
        return 3 if n == SAT_POINTS else (1 if n == 2 else 0)
    return 1 if kind == CYLINDER else 0


@nb.njit(cache=True, inline="always")
def _sep_on(s1, s2, u0, u1, u2, r, thr):
    # Whether the unit axis u separates the two cores by more than thr + r (a lower bound of their
    # distance: the gap between the two projected intervals), less `_apart_on_axis`' rounding
    # allowance; False where a core has no closed-form extent.
    p1 = s1[6]
    p2 = s2[6]
    a0, a1 = _extent(s1, u0, u1, u2)
    b0, b1 = _extent(s2, u0, u1, u2)
    if not (a0 == a0 and b0 == b0):
        return False
    c = u0 * (p2[0] - p1[0]) + u1 * (p2[1] - p1[1]) + u2 * (p2[2] - p1[2])
    sep = max(c + b0 - a1, a0 - c - b1)
    scale = (max(abs(p1[0]), abs(p1[1]), abs(p1[2]), abs(p2[0]), abs(p2[1]), abs(p2[2])) + max(-a0, a1)
             + max(-b0, b1))
    return sep - ROUNDING * _EPS * (scale + r) - r > thr


@nb.njit(cache=True, inline="always")
def _apart_sat(s1, s2, r, thr):
    # Whether a separating axis of two boxes, capsules or cylinders (not a mesh, a sphere or an
    # ellipsoid) puts their cores more than thr + r apart: each shape's own axes (`_axes_of`), then the
    # cross products of one's with the other's (the separating-axis theorem's candidates for two
    # boxes, Gottschalk, Lin, Manocha 1996, "OBBTree", sec. 4; a segment's against a box's
    # edges). Each gap is a lower bound of the cores' distance, so a pair it passes makes no
    # contact (the decision GJK's certified lower bound gives); one it fails goes on to GJK.
    n1 = _axes_of(s1)
    n2 = _axes_of(s2)
    if n1 == 0 or n2 == 0:
        # a sphere or an ellipsoid: the axis through the centres (`_apart_on_axis`) was its
        # test; a box's faces rarely separate it where that axis did not (measured: stonehenge's
        # sphere among its boxes paid the axes and went on to GJK)
        return False
    if (s1[0] == POINTS and s1[2].shape[0] > SAT_POINTS) or (s2[0] == POINTS and s2[2].shape[0] > SAT_POINTS):
        return False
    R1 = s1[5]
    R2 = s2[5]
    for k in range(3 - n1, 3):
        if _sep_on(s1, s2, R1[0, k], R1[1, k], R1[2, k], r, thr):
            return True
    for k in range(3 - n2, 3):
        if _sep_on(s1, s2, R2[0, k], R2[1, k], R2[2, k], r, thr):
            return True
    for i in range(3 - n1, 3):
        for k in range(3 - n2, 3):
            c0 = R1[1, i] * R2[2, k] - R1[2, i] * R2[1, k]
            c1 = R1[2, i] * R2[0, k] - R1[0, i] * R2[2, k]
            c2 = R1[0, i] * R2[1, k] - R1[1, i] * R2[0, k]
            ln = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
            if ln > 1e-6 and _sep_on(s1, s2, c0 / ln, c1 / ln, c2 / ln, r, thr):
                return True
    return False


@nb.njit(cache=True, inline="always")
def _plane_mesh_depth(gp, gc, xpos, xmat, s, pa):
    # The signed distance of mesh gc's lowest hull point below plane gp (`support` along the
    # plane's -normal, hill-climbed: the depth `plane_mesh` finds by scanning every vertex, its
    # deepest contact), and the slack within which the two may differ (`PLANE_MESH_SLACK`).
    n0 = xmat[gp, 0, 2]
    n1 = xmat[gp, 1, 2]
    n2 = xmat[gp, 2, 2]
    support(s, -n0, -n1, -n2, -1, pa)
    d = n0 * (pa[0] - xpos[gp, 0]) + n1 * (pa[1] - xpos[gp, 1]) + n2 * (pa[2] - xpos[gp, 2])
    scale = max(abs(pa[0]), abs(pa[1]), abs(pa[2]), abs(xpos[gp, 0]), abs(xpos[gp, 1]), abs(xpos[gp, 2]),
                abs(xpos[gc, 0]), abs(xpos[gc, 1]), abs(xpos[gc, 2]))
    return d, PLANE_MESH_SLACK * (scale + 1.0)


@nb.njit(cache=True, inline="always")
def deepest_contact(g1, g2, xpos, xmat, cls, rule, below, rbound, size, geom_margin, geom_gap, pair_key, pair_margin,
                    pair_gap, override, o_margin, gtype, half, shapes, faces, scratch, dws, d0, gws, g4, dwi):
    """Whether MuJoCo would make an active contact for the pair ``(g1, g2)`` at these poses.

    The pair's contacts are those of `collide._kernels.manifold.collide_pairs`: the same
    margins (`pair_margins`) and, up to two convex geoms, the same code (`plane_box_contacts`:
    planes, the bounding tests, box-box); only their deepest ``dist`` is kept, which is all that
    decides whether a contact is active: a face manifold's deepest point is the pair's exact
    distance (`polytope_contacts` sets it so), so the manifold is not built. Two convex geoms
    (not two boxes) that the axis through their origins separates beyond the contact distance
    (`_apart_on_axis`), or an axis of their own (`_apart_sat`: boxes, capsules, cylinders), make
    no contact; a mesh on a plane is decided by its lowest point (`_plane_mesh_depth`, the depth
    `plane_mesh` finds first) where that is clear of the thresholds; the others are first
    decided by GJK alone, on its certified bounds: cores that GJK finds overlapping within its tolerance (`collide._kernels.manifold.CONTACT_TOL` of the two
    sizes, as `collide_pairs` gives `collide._kernels.distance.pair_distance`) make an active
    contact (no EPA: the depth is not needed), a lower bound beyond the contact distance none,
    an upper bound below the margin an active one; only a pair within the tolerance of a
    threshold, or a stalled GJK, runs the full signed distance. So a pair touching within that
    tolerance may count as active where `collide_pairs` finds it ``CONTACT_TOL`` of the sizes
    apart: the tolerance of the answer.

    Parameters
    ----------
    g1, g2 : int
        Geom ids, ``g1 < g2``; their poses must be in ``xpos``, ``xmat`` and finite.
    xpos : (G, 3) float64
    xmat : (G, 3, 3) float64
    cls ... half
        The per-geom tables, as `collide._kernels.manifold.collide_pairs` takes them.
    shapes, faces, scratch : tuple
        The support and face tables and the plane and box scratch, in the tuples
        `collide._kernels.manifold.plane_box_contacts` takes (made once per worker).
    dws, d0, gws, g4, dwi
        Scratch (`decider_scratch` sizes them): ``dws`` the signed distance's answer (``OUT_SIZE``)
        then its scratch, ``dwi`` its int64 scratch (`collide._kernels.distance.WS_F_EPA`,
        ``WS_I_EPA``); ``gws (4, 4, 3)``, ``g4 (2, 4)`` GJK's, and ``dwi[:2]`` its hints.

    Returns
    -------
    int
        `ACTIVE` (a contact with ``dist < margin``), `IN_GAP` (contacts, all in the gap),
        `NO_CONTACT`, or `NOT_COLLIDED` (a height field or SDF geom: reported, not decided).
    """
    c1 = cls[g1]
    c2 = cls[g2]
    if c1 == SKIPPED or c2 == SKIPPED:
        return NOT_COLLIDED
    if c1 == PLANE and c2 == PLANE:
        return NO_CONTACT
    G = cls.shape[0]
    j, nent, explicit = _pair_rows(pair_key, min(g1, g2) * G + max(g1, g2))
    kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num = shapes
    res = scratch[3]
    found = NO_CONTACT
    for e in range(nent):
        margin, thr = pair_margins(g1, g2, j + e, explicit, geom_margin, geom_gap, pair_margin, pair_gap, override,
                                   o_margin)
        if (c1 == PLANE) != (c2 == PLANE):
            gp = g1 if c1 == PLANE else g2
            gc = g2 if c1 == PLANE else g1
            if gtype[gc] == T_MESH and faces[1][gc] > 0 and prm[gc, 3] == 0.0:
                # a mesh on a plane: its lowest point (a hill climb) decides where it is clear of the
                # thresholds by the slack; `plane_mesh` (every vertex, then a face's) otherwise
                sc = _shape(gc, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr,
                            nbr_adr, nbr_num, xpos, xmat)
                dm, sl = _plane_mesh_depth(gp, gc, xpos, xmat, sc, gws[3, 1])
                if dm - sl > thr:
                    continue  # plane_mesh: no contact
                if dm + sl < margin and dm + sl <= thr:
                    return ACTIVE  # plane_mesh's deepest contact is made and active
        m = plane_box_contacts(g1, g2, thr, xpos, xmat, cls, rule, below, rbound, gtype, half, shapes, faces, scratch)
        d = np.inf
        if m != CONVEX_PAIR:
            for i in range(m):
                d = min(d, res[i, 0])
        else:
            s1 = _shape(g1, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr,
                        nbr_adr, nbr_num, xpos, xmat)
            s2 = _shape(g2, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr,
                        nbr_adr, nbr_num, xpos, xmat)
            tol = CONTACT_TOL * (size[g1] + size[g2])
            r = prm[g1, 3] + prm[g2, 3]
            if _round(g1, kind, pts_num) and _round(g2, kind, pts_num):
                # spheres and capsules: pair_distance_within's closed form (`segment_distance`, no iteration) decides
                pair_distance_within(s1, s2, tol, math.inf, d0, -1, -1, EPA_CAP, dws[:OUT_SIZE], dws[OUT_SIZE:], dwi)
                d = dws[OUT_DISTANCE]
                if d <= thr:
                    if d < margin:
                        return ACTIVE
                    found = IN_GAP
                continue
            # beyond thr + tol: cores GJK would find within tol of touching (OVERLAP, active) never rejected here
            if _apart_on_axis(s1, s2, xpos, g1, g2, r, thr + tol, gws[3, 1], gws[3, 2]):
                continue  # certainly no contact, before GJK
            if _apart_sat(s1, s2, r, thr + tol):
                continue  # likewise, on the shapes' own axes
            hints = dwi[:2]
            hints[0] = -1
            hints[1] = -1
            gws[:] = 0.0  # a fresh simplex, as pair_distance starts from
            g4[:] = 0.0
            # GJK stops once its certified lower bound passes thr + r (`gjk_within`): the pair is
            # then certainly beyond reach, the decision the full run's lower bound would give
            st, nsx, lower, scale, iters = gjk_within(s1, s2, d0, hints, tol, thr + r, 128, gws[0], gws[1], gws[2],
                                                      g4[0], gws[3, 0], g4[1], gws[3, 1], gws[3, 2])
            if st == OVERLAP:
                return ACTIVE  # cores within tol of touching: d <= tol - r
            if st == SEPARATED:
                if lower - r > thr:
                    continue  # certainly no contact
                v = gws[3, 0]
                upper = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])  # |v|: a point of A - B
                if upper - r < margin and upper - r <= thr:
                    return ACTIVE
            pair_distance_within(s1, s2, tol, math.inf, d0, -1, -1, EPA_CAP, dws[:OUT_SIZE], dws[OUT_SIZE:], dwi)
            d = dws[OUT_DISTANCE]
        if d <= thr:  # a contact is made (collide_pairs' rule) ...
            if d < margin:  # ... and active: MuJoCo's exclude == 0
                return ACTIVE
            found = IN_GAP
    return found


@nb.njit(cache=True, inline="always")
def closed_form_pair(g1, g2, cls, kind, pts_num):
    """Whether `deepest_contact` decides the pair ``(g1, g2)`` without an iteration: a height
    field or SDF geom (not decided), a plane (`plane_box_contacts`' planes), or two spheres or
    capsules (`pair_distance_within`'s closed form, `segment_distance`); the others may run GJK."""
    if cls[g1] != CONVEX or cls[g2] != CONVEX:
        return True
    return _round(g1, kind, pts_num) and _round(g2, kind, pts_num)


@nb.njit(cache=True, inline="always")
def _round(g, kind, pts_num):
    # A sphere or a capsule: a point or segment core, which `pair_distance_within` takes in closed form.
    return kind[g] == POINTS and pts_num[g] <= 2


@nb.njit(cache=True, inline="always")
def first_pass(cls, kind, pts_num):
    """`decide_rows`' first pass: 0, or 1 (the second) for a model where no pair is a
    `closed_form_pair` (every geom convex, none a sphere or capsule: meshes and boxes only)."""
    for g in range(cls.shape[0]):
        if cls[g] != CONVEX or _round(g, kind, pts_num):
            return 0
    return 1


@nb.njit(cache=True, inline="always")
def decide_rows(w, lane, r0, r1, src, pose, mode, label, geoms, tables, shapes, faces, xpos, xmat, stamp, scratch,
                dws, d0, gws, g4, dwi):
    """Configuration ``w``'s ``(hit, skipped, err)`` from its candidate rows ``r0 .. r1``: the
    answer of deciding them in row order with the early exit (the first pair whose
    `deepest_contact` is `ACTIVE` decides), found with the pairs `closed_form_pair` takes first.

    ``src = (keys, S, nf, rows, p0)``: the rows are ``keys[r] = g1 << S | g2`` (``S > 0``: the lanes'
    broad phase; the pairs of two ``nf`` geoms left out) or ``rows[r, 1:]`` (``S == 0``); ``p0``:
    `first_pass`. ``pose =
    (ps, xq, bpos, brot, bquat)``: the geom poses come from lane ``lane`` of ``ps``, ``xq``
    (`geom_pose_lane`, ``S > 0``) or from ``bpos``, ``brot``, ``bquat`` (`geom_pose`). ``geoms =
    (geom_body, geom_pos, geom_quat)``; ``stamp[g] == w`` marks geom ``g`` posed in ``xpos``,
    ``xmat``. ``tables`` (``cls`` ... ``half``), ``shapes``, ``faces``, ``scratch`` ... ``dwi``:
    `deepest_contact`'s arguments, in its order. The tuples hold borrowed views only
    (`_ptr.borrow`), made once per worker: a call of more than 30 arguments is compiled to a
    ``*args`` call, which numba does not inline, and an owned array in a tuple unpacked per
    configuration costs its reference count's atomic operations there.

    The first pass decides the closed-form pairs, in row order; the second the others, in row
    order; each poses a geom when a pair it decides first needs it. Why: a configuration in
    collision is usually decided by a closed-form pair as well, and a GJK pair tried before it
    costs several times more. The answer is the row order's: a hit where some row is active and
    every geom of the rows before it has a finite pose (the first pass poses the rows it left
    before its active one), which is where the row order stops too; where a non-finite pose
    turns up, the rows are decided again in their order (every geom posed again), which finds
    the row order's error, or its hit when an active row comes before the bad pose.
    `NOT_COLLIDED` (a height field's or SDF's pair) is a closed-form pair's only: ``skipped`` is
    the row order's where nothing is active.
    """
    keys, S, nf, rows, p = src
    (cls, rule, below, rbound, size, geom_margin, geom_gap, pair_key, pair_margin, pair_gap, override, o_margin, gtype,
     half) = tables
    skipped = False
    err = 0
    mask = (np.int64(1) << S) - 1
    later = False  # a row left to the second pass
    while True:
        for r in range(r0, r1):
            g1, g2, ok = _row(r, keys, S, mask, nf, rows, mode, label)
            if not ok:
                continue
            if p < 2 and closed_form_pair(g1, g2, cls, shapes[0], shapes[4]) != (p == 0):
                later = True
                continue
            err = _pose_pair(g1, g2, w, lane, pose, geoms, xpos, xmat, stamp, S, err)
            if err != 0:
                break
            a = deepest_contact(g1, g2, xpos, xmat, cls, rule, below, rbound, size, geom_margin, geom_gap, pair_key,
                                pair_margin, pair_gap, override, o_margin, gtype, half, shapes, faces, scratch, dws,
                                d0, gws, g4, dwi)
            if a == ACTIVE:
                for rr in range(r0, r if p == 0 else r0):  # the rows before it that the first pass left
                    h1, h2, ok = _row(rr, keys, S, mask, nf, rows, mode, label)
                    if ok and err == 0:
                        err = _pose_pair(h1, h2, w, lane, pose, geoms, xpos, xmat, stamp, S, err)
                if err == 0:
                    return True, False, 0  # the early exit: one active contact decides
                break
            if a == NOT_COLLIDED:
                skipped = True
        if err != 0 and p < 2:
            # a non-finite pose: the rows in order, every geom posed again (the order's own error)
            for g in range(stamp.shape[0]):
                if stamp[g] == w:
                    stamp[g] = -1
            err = 0
            skipped = False
            p = 2
        elif p == 0 and later:
            p = 1
        else:
            return False, skipped, err


@nb.njit(cache=True, inline="always")
def _row(r, keys, S, mask, nf, rows, mode, label):
    # `decide_rows`' row r: (g1, g2, whether it is decided)
    if S > 0:
        g1 = keys[r] >> S
        g2 = keys[r] & mask
        if nf[g1] and nf[g2]:
            return g1, g2, False
    else:
        g1 = np.int64(rows[r, 1])
        g2 = np.int64(rows[r, 2])
    return g1, g2, in_subset(mode, label, g1, g2)


@nb.njit(cache=True, inline="always")
def _pose_pair(g1, g2, w, lane, pose, geoms, xpos, xmat, stamp, S, err):
    # `decide_rows`: the poses of g1 and g2 unless posed for world w; err, or the first non-finite
    # one's error when err is 0
    ps, xq, bpos, brot, bquat = pose
    geom_body, geom_pos, geom_quat = geoms
    for g in (g1, g2):
        if stamp[g] != w:
            if S > 0:
                geom_pose_lane(g, lane, ps, xq, geom_body, geom_pos, geom_quat, xpos, xmat)
            else:
                geom_pose(g, bpos, brot, bquat, geom_body, geom_pos, geom_quat, xpos, xmat)
            stamp[g] = w
            if not _finite_pose(xpos, xmat, g) and err == 0:
                err = ERR_POSE + 8 * g
    return err


# `check_worlds`' worker, one call a thread: its own scratch, then chunks of configurations from the
# shared counter until none is left. A plain compiled function rather than the ``prange`` body: numba
# compiled the kernel with every decider inlined into its parallel loop about twice as slowly
# (`tests/bench/compile_time.py`). Not done for the broad phase's parallel kernels (the lanes,
# `batch`, `swept`), whose compile it made slower, nor for `check_lanes_kin` (no clear gain).
@nb.njit(cache=True, nogil=True)
def _check_chunks(qpos, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                  jnt_pos, jnt_axis, geom_body, geom_pos, geom_quat, rows, row_start, mode, label, dpairs, distmax,
                  want_distance, chunks, workers, counter, cls, rule, below, kind, prm, pts, pts_adr, pts_num,
                  nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, rbound, size, geom_margin,
                  geom_gap, pair_key, pair_margin, pair_gap, override, o_margin, gtype, half, hv_adr, hv_num, hv,
                  f_adr, f_num, f_normal, f_offset, f_vadr, f_vnum, f_vidx, out_hit, out_dist, out_closest,
                  out_skipped, out_err, cap, fmax):
    B = qpos.shape[0]
    L = body_parent.shape[0]
    G = geom_body.shape[0]
    nj = jnt_type.shape[0]
    P = dpairs.shape[0]
    addr = counter.ctypes.data
    bpos = np.empty((L, 3))
    brot = np.empty((L, 3, 3))
    bquat = np.empty((L, 4))
    sc = np.empty((max(nj, 1), 2))
    xpos = np.zeros((G, 3))
    xmat = np.zeros((G, 3, 3))
    stamp = np.full(G, -1, np.int64)
    scratch, dws, d0, gws, g4, dwi = decider_scratch(cap, fmax)
    out7 = np.empty(7)
    lb = np.empty(P if want_distance else 0)
    no_keys = np.empty(0, np.int64)  # `decide_rows`' lanes' arguments, never read here
    no_lanes = np.empty((0, 12, 1))
    # the shared tables borrowed (`borrow`): no counter the two threads take turns on
    cls_, rule_, below_, rbound_, size_ = borrow(cls), borrow(rule), borrow(below), borrow(rbound), borrow(size)
    gmargin, ggap, pkey = borrow(geom_margin), borrow(geom_gap), borrow(pair_key)
    pmargin, pgap, gtype_, half_ = borrow(pair_margin), borrow(pair_gap), borrow(gtype), borrow(half)
    kind_, prm_, pts_, pts_num_ = borrow(kind), borrow(prm), borrow(pts), borrow(pts_num)
    shapes = (kind_, prm_, pts_, borrow(pts_adr), pts_num_, borrow(nbr_start), borrow(nbr_start_adr),
              borrow(nbr_start_num), borrow(nbr), borrow(nbr_adr), borrow(nbr_num))
    faces = (borrow(hv_adr), borrow(hv_num), borrow(hv), borrow(f_adr), borrow(f_num), borrow(f_normal),
             borrow(f_vadr), borrow(f_vnum), borrow(f_vidx))
    geom_body_, geom_pos_, geom_quat_ = borrow(geom_body), borrow(geom_pos), borrow(geom_quat)
    rows_, row_start_, label_, dpairs_ = borrow(rows), borrow(row_start), borrow(label), borrow(dpairs)
    qpos_, qpos0_, parent_, bpos0, bquat0 = borrow(qpos), borrow(qpos0), borrow(body_parent), borrow(body_pos), \
        borrow(body_quat)
    jntadr, jntnum, jtype, jqadr = borrow(body_jntadr), borrow(body_jntnum), borrow(jnt_type), \
        borrow(jnt_qposadr)
    jpos, jaxis = borrow(jnt_pos), borrow(jnt_axis)
    # `decide_rows`' tuples, of borrowed views (the body poses are written in the loop: alive through it)
    src = (borrow(no_keys), 0, borrow(no_keys), rows_, first_pass(cls_, kind_, pts_num_))
    pose = (borrow(no_lanes), borrow(no_lanes), borrow(bpos), borrow(brot), borrow(bquat))
    geoms = (geom_body_, geom_pos_, geom_quat_)
    tables = (cls_, rule_, below_, rbound_, size_, gmargin, ggap, pkey, pmargin, pgap, override,
              o_margin, gtype_, half_)
    while True:
        c = fetch_add(addr, 1)
        if c >= chunks:
            break
        for w in range((B * c) // chunks, (B * (c + 1)) // chunks):
            posed = False  # body poses only for a configuration with a pair to decide
            for r in range(row_start_[w], row_start_[w + 1]):
                if in_subset(mode, label_, rows_[r, 1], rows_[r, 2]):
                    _kinematics_world(qpos_[w], qpos0_, parent_, bpos0, bquat0, jntadr, jntnum, jtype, jqadr, jpos,
                                      jaxis, bpos, brot, bquat, sc)
                    posed = True
                    break
            hit, skipped, err = False, False, 0
            if posed:
                hit, skipped, err = decide_rows(w, 0, row_start_[w], row_start_[w + 1], src, pose, mode, label_,
                                                geoms, tables, shapes, faces, xpos, xmat, stamp, scratch, dws, d0,
                                                gws, g4, dwi)
            out_hit[w] = hit
            out_skipped[w] = skipped and not hit
            if want_distance and err == 0:
                if not posed:
                    _kinematics_world(qpos_[w], qpos0_, parent_, bpos0, bquat0, jntadr, jntnum, jtype, jqadr, jpos,
                                      jaxis, bpos, brot, bquat, sc)
                err = _closest(w, dpairs_, distmax, bpos, brot, bquat, geom_body_, geom_pos_, geom_quat_, xpos,
                               xmat, stamp, lb, cls_, kind_, prm_, pts_, shapes[3], pts_num_, shapes[5],
                               shapes[6], shapes[7], shapes[8], shapes[9], shapes[10], rbound_, size_, out7,
                               out_dist, out_closest, out_skipped)
            out_err[w] = err
    return 0


@nb.njit(cache=True, parallel=True, nogil=True)
def check_worlds(qpos, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                 jnt_pos, jnt_axis, geom_body, geom_pos, geom_quat, rows, row_start, mode, label, dpairs, distmax,
                 want_distance, chunks, workers, counter, cls, rule, below, kind, prm, pts, pts_adr, pts_num,
                 nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, rbound, size, geom_margin,
                 geom_gap, pair_key, pair_margin, pair_gap, override, o_margin, gtype, half, hv_adr, hv_num, hv,
                 f_adr, f_num, f_normal, f_offset, f_vadr, f_vnum, f_vidx, out_hit, out_dist, out_closest,
                 out_skipped, out_err):
    """Collision checks of the configurations ``qpos (B, nq)`` (module docstring).

    Parameters
    ----------
    qpos : (B, nq) float64
        Finite (the caller checks).
    qpos0 ... jnt_axis
        The model's kinematics arrays (`collide._kernels.kinematics`).
    geom_body : (G,) int64
    geom_pos : (G, 3) float64
    geom_quat : (G, 4) float64
        Each geom's frame in its body's, as ``mj_kinematics`` places it (``geom_sameframe``
        applied), the quaternion unit.
    rows : (K, 3) int32
        Candidate pairs ``(world, g1, g2)``, ``g1 < g2``, sorted by world (a broad phase's).
    row_start : (B + 1,) int64
        World ``w``'s rows are ``rows[row_start[w]:row_start[w + 1]]``.
    mode : int
    label : (G,) int8
        The checked subset (`in_subset`).
    dpairs : (P, 2) int32
        The filtered pairs the distance is the minimum over (already restricted to the subset).
    distmax : float
        Distances at or beyond it are not reported.
    want_distance : bool
    chunks : int
        Chunks of configurations handed out to the workers.
    workers : int
        Parallel workers (the threads).
    counter : (1,) int64
        Zero: the shared chunk counter.
    cls ... f_vidx
        `collide.contacts.GeomTable.kernel_args`.
    out_hit : (B,) bool
        Receives ``in_collision``.
    out_dist : (B,) float64
    out_closest : (B, 2) int32
        Receive the closest filtered pair's signed distance and ids, ``inf`` and ``-1`` when none is
        closer than ``distmax`` (written only when ``want_distance``).
    out_skipped : (B,) bool
        Receives True where a pair with a height field or SDF geom was left undecided and no
        active contact was found.
    out_err : (B,) int64
        Receives 0, or ``ERR_POSE + 8 * g`` for a non-finite pose of geom ``g``.

    Returns
    -------
    int
        0.
    """
    cap, fmax = scratch_caps(pts_num, f_vnum)
    chunksize = set_chunksize(1)  # one iteration a worker (`_threads`)
    for wk in nb.prange(workers):
        _check_chunks(qpos, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                      jnt_pos, jnt_axis, geom_body, geom_pos, geom_quat, rows, row_start, mode, label, dpairs, distmax,
                      want_distance, chunks, workers, counter, cls, rule, below, kind, prm, pts, pts_adr, pts_num,
                      nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, rbound, size, geom_margin,
                      geom_gap, pair_key, pair_margin, pair_gap, override, o_margin, gtype, half, hv_adr, hv_num, hv,
                      f_adr, f_num, f_normal, f_offset, f_vadr, f_vnum, f_vidx, out_hit, out_dist, out_closest,
                      out_skipped, out_err, cap, fmax)
    set_chunksize(chunksize)
    return 0


@nb.njit(cache=True)
def _lower_bound(g1, g2, cls, rbound, xpos, xmat):
    # A lower bound of the pair's signed distance from balls about the geoms' origins (module
    # docstring); a plane's from its own equation.
    if cls[g1] == PLANE or cls[g2] == PLANE:
        gp = g1 if cls[g1] == PLANE else g2
        gc = g2 if cls[g1] == PLANE else g1
        return (xmat[gp, 0, 2] * (xpos[gc, 0] - xpos[gp, 0]) + xmat[gp, 1, 2] * (xpos[gc, 1] - xpos[gp, 1])
                + xmat[gp, 2, 2] * (xpos[gc, 2] - xpos[gp, 2]) - rbound[gc])
    cc = math.sqrt((xpos[g2, 0] - xpos[g1, 0]) ** 2 + (xpos[g2, 1] - xpos[g1, 1]) ** 2
                   + (xpos[g2, 2] - xpos[g1, 2]) ** 2)
    return cc - rbound[g1] - rbound[g2]


@nb.njit(cache=True)
def _closest(w, dpairs, distmax, bpos, brot, bquat, geom_body, geom_pos, geom_quat, xpos, xmat, stamp, lb, cls, kind,
             prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, rbound,
             size, out7, out_dist, out_closest, out_skipped):
    # The closest pair of dpairs of world w (branch and bound, module docstring): writes
    # out_dist[w], out_closest[w]; returns an error code (a non-finite geom pose) or 0.
    P = dpairs.shape[0]
    best = distmax
    bi = -1
    first = -1
    lo = np.inf
    for p in range(P):
        g1 = dpairs[p, 0]
        g2 = dpairs[p, 1]
        if cls[g1] == SKIPPED or cls[g2] == SKIPPED:
            lb[p] = np.inf
            out_skipped[w] = True
            continue
        for g in (g1, g2):
            if stamp[g] != w:
                geom_pose(g, bpos, brot, bquat, geom_body, geom_pos, geom_quat, xpos, xmat)
                stamp[g] = w
                if not _finite_pose(xpos, xmat, g):
                    return ERR_POSE + 8 * g
        v = _lower_bound(g1, g2, cls, rbound, xpos, xmat)
        lb[p] = v
        if v < lo:
            lo = v
            first = p
    for k in range(-1, P):
        p = first if k < 0 else k
        if p < 0 or (k >= 0 and p == first) or not lb[p] < best:
            continue
        e = pair_signed_distance(dpairs[p, 0], dpairs[p, 1], xpos, xmat, cls, kind, prm, pts, pts_adr, pts_num,
                                 nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, size, out7)
        if e == 0 and out7[0] < best:
            best = out7[0]
            bi = p
    if bi >= 0:
        out_dist[w] = best
        out_closest[w, 0] = dpairs[bi, 0]
        out_closest[w, 1] = dpairs[bi, 1]
    else:
        out_dist[w] = np.inf
        out_closest[w, 0] = -1
        out_closest[w, 1] = -1
    return 0


__all__ = ["ACTIVE", "ERR_POSE", "IN_GAP", "NOT_COLLIDED", "NO_CONTACT", "SUBSET_ALL", "SUBSET_ONE", "SUBSET_TWO",
           "check_worlds", "deepest_contact", "geom_pose", "in_subset"]
