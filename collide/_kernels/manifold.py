"""Contact manifolds of geom pairs (numba): the narrow phase's driver over a broad phase's pairs.

Input is flat (DESIGN.md, Wave 2): the pairs ``(K, 2)``, the geoms' world poses, and per-geom
tables built once from a model (`collide.contacts.GeomTable`); nothing of the broad phase.

Per pair, with ``thr`` the pair's contact distance (MuJoCo's ``margin + gap``):

* plane (the half-space ``z <= 0`` of its frame, normal ``n``) against a convex geom: the signed
  distance is exact from the support point along ``-n`` (``h_K(-n)``); the contacts follow the
  rule of the convex geom's type (`RULE_*`): each core point of a sphere or capsule (a capsule's
  two end spheres), the corners of a box that lie within ``thr`` on its side of the centre
  facing the plane (at most 4, as MuJoCo's plane-box), the lowest vertex of a mesh's hull and
  the other vertices of a hull face through it that faces the plane (`plane_mesh`), the four
  points MuJoCo's plane-cylinder test places (the rim points nearest the plane on both caps and
  two more on the nearer cap's rim, at 120 degrees), or the single support point;
* two boxes: MuJoCo 4's box-box manifold (`collide._kernels.faces.box_box`: separating axes, a
  face clipped to a face, up to 8 contacts, or one edge-edge contact);
* two other convex geoms: one contact from `collide._kernels.distance.pair_distance` (GJK/EPA on
  the cores, radii added), after a bounding-sphere test; two polytopes (boxes, meshes) in
  penetration with no contact distance get the face contacts of their touching faces instead
  (`polytope_contacts`, MuJoCo 4's multi-contact), the deepest at the exact distance;
* a height field or SDF geom: no contact, the pair flagged as skipped (reported, never dropped
  silently); two planes: none (MuJoCo has no function for them either).

A contact's ``pos`` is midway between the two surfaces and its ``normal`` points from the pair's
first geom to its second, as MuJoCo places them (``mjContact.pos``, ``frame[:3]``).

This module is the pair dispatch (`collide_pairs`, `pair_signed_distance`), and the one home of
MuJoCo's rule for a pair's margins (`pair_margins`) and of its branches up to two convex geoms
(`plane_box_contacts`), which `collide._kernels.check.deepest_contact` shares; the routines live
by concept, each importing only downward:

* `collide._kernels.plane`: a plane against a convex geom (`plane_convex`, `plane_mesh`) and
  the four-point reduction (`reduce_four`);
* `collide._kernels.polytope`: face contacts of penetrating boxes and meshes (`polytope_contacts`);
* `collide._kernels.faces`: box-box (`box_box`) and polygon clipping (`clip_faces`);
* `collide._kernels.distance`: the GJK/EPA signed distance of two convex geoms (`pair_distance`).

Their names are re-exported here (``from collide._kernels.manifold import plane_mesh`` keeps
working); new code imports them from their own module.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._ptr import NO_NRT, bool_ptr, check_span, f64_ptr, i8_ptr, i32_ptr, i64_ptr, view_of
from ._pose import _pose_ok
from .distance import (OUT_DISTANCE, OUT_NORMAL, OUT_PENETRATING, OUT_POINT_A, OUT_POINT_B, OUT_SIZE, ROUNDING,
                       EPA_CAP, WS_F, WS_F_EPA, WS_I, WS_I_EPA, pair_distance, pair_distance_within, segment_distance)
from .faces import BOX_MAX, BOX_WS, box_box, clip_faces
from .plane import (PLANE_FACE_TOL, RULE_CYLINDER, RULE_POINTS, RULE_SUPPORT, RULE_VERTICES, _plane_cylinder,
                    _support_minus, plane_convex, plane_mesh, reduce_four)
from .polytope import EDGE_TOL, FACE_TOL, _edge_in_face, _touching_faces, _world_face, polytope_contacts
from .support import POINTS, support
from .warm import (SEP_LEN, WARM_KEYS, WARM_LEN, distance_warm, sep_forget, sep_keep, sep_test, warm_claim,
                   warm_slot)

# This module's own names, and those of the routines moved out of it (plane, polytope), which
# importers of `collide._kernels.manifold` still read here.
__all__ = [
    "CONVEX", "MAX_PER_PAIR", "PLANE", "SKIPPED", "T_BOX", "T_CAPSULE", "T_CYLINDER",
    "T_ELLIPSOID", "T_HFIELD", "T_MESH", "T_PLANE", "T_SPHERE", "CONVEX_PAIR", "F_DIST", "F_END", "F_MARGIN",
    "F_NORMAL", "F_POS", "N_SLOTS", "SLOT_BUFFER", "SLOT_COLS", "BUFFER_DTYPES", "TI_HEADER", "carve_scratch",
    "ARENA_FIELDS", "CTX_FIELDS", "NARENA", "NCTX", "OUT_FULL", "collide_bound", "collide_pairs", "pair_margins",
    "scratch_caps", "scratch_sizes", "pair_signed_distance", "pair_signed_distance_bound",
    "plane_box_contacts",
    # re-exported
    "BOX_MAX", "BOX_WS", "EDGE_TOL", "FACE_TOL", "OUT_DISTANCE", "OUT_NORMAL", "OUT_POINT_A", "OUT_POINT_B",
    "OUT_SIZE", "PLANE_FACE_TOL", "RULE_CYLINDER", "RULE_POINTS", "RULE_SUPPORT", "RULE_VERTICES",
    "_edge_in_face", "_plane_cylinder", "_support_minus", "_touching_faces", "_world_face", "box_box",
    "clip_faces", "pair_distance", "plane_convex", "plane_mesh", "polytope_contacts", "reduce_four", "support",
]

# Geom classes (`collide.contacts.GeomTable.cls`).
PLANE, CONVEX, SKIPPED = 0, 1, 2

_EPS = float(np.finfo(np.float64).eps)

# Most contacts per pair: a box-box face manifold's (MuJoCo 4 keeps every clipped corner).
MAX_PER_PAIR = BOX_MAX

# Convergence tolerance of a contact's signed distance (GJK/EPA in `pair_distance`), relative to
# the two geoms' sizes (``CONTACT_TOL * (size[g1] + size[g2])``). Issue 46 asks contacts to agree
# with MuJoCo within its ``ccd_tolerance`` (1e-6 by default) and, for polytopes and primitive pairs,
# within 1e-9 of the size: 1e-9 meets both, and EPA stops sooner on penetrating pairs than at a
# tighter one. `collide._kernels.check.deepest_contact` uses it too, so that ``check_batch``'s
# ``in_collision`` is `collide_pairs`' answer. (`pair_signed_distance`, a distance query, keeps 1e-12.)
CONTACT_TOL = 1e-9

# MuJoCo's geom types (mjtGeom), as `collide.contacts` passes them in ``gtype``.
T_PLANE, T_HFIELD, T_SPHERE, T_CAPSULE, T_ELLIPSOID, T_CYLINDER, T_BOX, T_MESH = range(8)


@njit(cache=True, inline="always")
def _shape(g, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr,
           nbr_num, xpos, xmat):
    # The support kernels' shape tuple of geom g at its world pose (views, no copies).
    a = pts_adr[g]
    b = nbr_start_adr[g]
    c = nbr_adr[g]
    return (kind[g], prm[g], pts[a:a + pts_num[g]], nbr_start[b:b + nbr_start_num[g]], nbr[c:c + nbr_num[g]],
            xmat[g], xpos[g])


@njit(**NO_NRT)
def _finite_pose(xpos, xmat, g):
    for i in range(3):
        if not math.isfinite(xpos[g, i]):
            return False
        for j in range(3):
            if not math.isfinite(xmat[g, i, j]):
                return False
    return True


@njit(**NO_NRT)
def _pose_refused(xpos, xmat, g):
    # True for a geom pose the narrow phase refuses: xmat[g] off a proper rotation (an entry of
    # |R^T R - I| above `_pose.ORTHO_TOL`, or det <= 0), a non-finite entry, or xpos[g] beyond
    # `_pose.MAX_POSITION`: the bodies' one test (`_pose._pose_ok`). Every support, face and plane
    # computation takes R as a rotation: a scaled or sheared one gave a silently wrong distance
    # (review, 2026-12-01). What is wrong is worded on the Python side (`contacts._pose_problem`).
    return not _pose_ok(xmat[g, 0, 0], xmat[g, 0, 1], xmat[g, 0, 2], xmat[g, 1, 0], xmat[g, 1, 1], xmat[g, 1, 2],
                        xmat[g, 2, 0], xmat[g, 2, 1], xmat[g, 2, 2], xpos[g, 0], xpos[g, 1], xpos[g, 2])


@njit(**NO_NRT)
def _emit(k, g1, g2, d, px, py, pz, nx, ny, nz, margin, out_geom, out_dist, out_pos, out_normal, out_margin):
    out_geom[k, 0] = g1
    out_geom[k, 1] = g2
    out_dist[k] = d
    out_pos[k, 0] = px
    out_pos[k, 1] = py
    out_pos[k, 2] = pz
    out_normal[k, 0] = nx
    out_normal[k, 1] = ny
    out_normal[k, 2] = nz
    out_margin[k] = margin


@njit(**NO_NRT)
def _polytope(t):
    return t == T_BOX or t == T_MESH


@njit(cache=True, inline="always")
def _scratch_lengths(cap, fmax):
    # The float64 fields of `carve_scratch`, in order: their lengths (the one place the layout is
    # counted; `scratch_sizes` sums them, `carve_scratch` walks them). ``poly``/``tmp`` hold a
    # face clipped by another: at most ``2 fmax + 8`` vertices; ``dws`` is the signed distance's
    # (`collide._kernels.distance.pair_distance_within`), EPA's included: a pair allocates nothing.
    npoly = 2 * fmax + 8
    return (3 * cap, cap, 4 * MAX_PER_PAIR, 3, BOX_WS, 6, 3 * fmax, fmax, 3 * fmax, 3 * fmax, 3 * npoly,
            3 * npoly, 3 * 32, 3 * 32, 3, 3, 3, OUT_SIZE, 3, WS_F_EPA)


# The int64 fields of `carve_scratch`: ``sel`` (4), ``cand1`` and ``cand2`` (32 each), ``dwi`` (the signed
# distance's, EPA's included).
_SCRATCH_INT = (4, 32, 32, WS_I_EPA)


@njit(cache=True)
def scratch_sizes(cap, fmax):
    """Float64 and int64 entries of `collide_pairs`' scratch (`carve_scratch`), for ``cap`` support
    points of a geom at most and ``fmax`` vertices of a hull face at most (at least 4)."""
    nf = 0
    for n in _scratch_lengths(cap, fmax):
        nf += n
    ni = 0
    for n in _SCRATCH_INT:
        ni += n
    # then the separation cache and the warm-start cache (`collide._kernels.warm`), never cleared
    return nf, ni + SEP_LEN + WARM_LEN


# Inlined: called once a `collide_bound` call, where a call returning its 22 views cost more
# than the views themselves (numba's reference counting on each, across the call).
@njit(cache=True, inline="always")
def carve_scratch(wsf, wsi, cap, fmax):
    """`collide_pairs`' scratch as views of two flat workspaces (`scratch_sizes` long at least).

    Returns the tuple ``(cand, dep, sel, res, bnrm, bws, seg, pcand, pdep, face1, face2, poly, tmp,
    cand1, cand2, cnrm1, cnrm2, pa, pb, nv, out, d0, dws, dwi, sep, cache)``; ``sel`` and ``d0`` are zeroed
    (``d0`` is GJK's cold start, zeros), ``sep`` and ``cache`` (`collide._kernels.warm`'s separation
    and warm-start caches, the rest of ``wsi``) are kept across calls, the rest is written before it
    is read.
    """
    (n_cand, n_dep, n_res, n_bnrm, n_bws, n_seg, n_pcand, n_pdep, n_face1, n_face2, n_poly, n_tmp, n_cnrm1,
     n_cnrm2, n_pa, n_pb, n_nv, n_out, n_d0, n_dws) = _scratch_lengths(cap, fmax)
    o = 0
    cand = wsf[o:o + n_cand].reshape((n_cand // 3, 3))
    o += n_cand
    dep = wsf[o:o + n_dep]
    o += n_dep
    res = wsf[o:o + n_res].reshape((n_res // 4, 4))
    o += n_res
    bnrm = wsf[o:o + n_bnrm]
    o += n_bnrm
    bws = wsf[o:o + n_bws]
    o += n_bws
    seg = wsf[o:o + n_seg].reshape((2, 3))
    o += n_seg
    pcand = wsf[o:o + n_pcand].reshape((n_pcand // 3, 3))
    o += n_pcand
    pdep = wsf[o:o + n_pdep]
    o += n_pdep
    face1 = wsf[o:o + n_face1].reshape((n_face1 // 3, 3))
    o += n_face1
    face2 = wsf[o:o + n_face2].reshape((n_face2 // 3, 3))
    o += n_face2
    poly = wsf[o:o + n_poly].reshape((n_poly // 3, 3))
    o += n_poly
    tmp = wsf[o:o + n_tmp].reshape((n_tmp // 3, 3))
    o += n_tmp
    cnrm1 = wsf[o:o + n_cnrm1].reshape((n_cnrm1 // 3, 3))
    o += n_cnrm1
    cnrm2 = wsf[o:o + n_cnrm2].reshape((n_cnrm2 // 3, 3))
    o += n_cnrm2
    pa = wsf[o:o + n_pa]
    o += n_pa
    pb = wsf[o:o + n_pb]
    o += n_pb
    nv = wsf[o:o + n_nv]
    o += n_nv
    out = wsf[o:o + n_out]
    o += n_out
    d0 = wsf[o:o + n_d0]
    d0[:] = 0.0
    o += n_d0
    dws = wsf[o:o + n_dws]
    n_sel, n_cand1, n_cand2, n_dwi = _SCRATCH_INT
    sel = wsi[0:n_sel]
    sel[:] = 0
    o = n_sel
    cand1 = wsi[o:o + n_cand1]
    o += n_cand1
    cand2 = wsi[o:o + n_cand2]
    o += n_cand2
    dwi = wsi[o:o + n_dwi]
    o += n_dwi
    rest = wsi[o:]
    ns = SEP_LEN if rest.shape[0] >= SEP_LEN + WARM_LEN else 0  # shorter (`_scratch`): no cache, cold
    sep = rest[:ns]
    cache = rest[ns:]
    return (cand, dep, sel, res, bnrm, bws, seg, pcand, pdep, face1, face2, poly, tmp, cand1, cand2, cnrm1, cnrm2,
            pa, pb, nv, out, d0, dws, dwi, sep, cache)


@njit(cache=True)
def scratch_caps(pts_num, f_vnum):
    """``(cap, fmax)`` of `scratch_sizes`: the most support points of a geom (plane contacts of a
    convex geom, at least 1) and the most vertices of a hull face (clipped faces, at least 4)."""
    cap = 1
    for g in range(pts_num.shape[0]):
        if pts_num[g] > cap:
            cap = pts_num[g]
    fmax = 4
    for f in range(f_vnum.shape[0]):
        if f_vnum[f] > fmax:
            fmax = f_vnum[f]
    return cap, fmax


@njit(cache=True)
def _scratch(pts_num, f_vnum):
    # `collide_pairs`' scratch, allocated once a call (`collide_bound` takes a workspace instead).
    cap, fmax = scratch_caps(pts_num, f_vnum)
    nf, ni = scratch_sizes(cap, fmax)
    return carve_scratch(np.empty(nf), np.empty(ni - SEP_LEN - WARM_LEN, np.int64), cap, fmax)  # no cache: cold


@njit(cache=True, inline="always")
def _pair_rows(pair_key, key):
    # The explicit pairs of the geom pair ``key`` (``lo * G + hi``): their first row in the sorted
    # ``pair_key``, how many, and whether there is one (else one entry, the geoms' own margins).
    P = pair_key.shape[0]
    j = np.searchsorted(pair_key, key) if P > 0 else 0
    nent = 1
    explicit = j < P and pair_key[j] == key
    if explicit:
        while j + nent < P and pair_key[j + nent] == key:
            nent += 1
    return j, nent, explicit


@njit(cache=True, inline="always")
def pair_margins(g1, g2, row, explicit, geom_margin, geom_gap, pair_margin, pair_gap, override, o_margin):
    """The margin and the contact distance (``margin + gap``) of one collision of a geom pair.

    MuJoCo's rule: an explicit ``<pair>``'s own (``row`` of the sorted explicit pairs, from
    `_pair_rows`), else the sums of the two geoms'; ``mjENBL_OVERRIDE`` replaces every margin
    by ``o_margin``, the gaps stay.
    """
    if explicit:
        margin = pair_margin[row]
        gap = pair_gap[row]
    else:
        margin = geom_margin[g1] + geom_margin[g2]
        gap = geom_gap[g1] + geom_gap[g2]
    if override:
        margin = o_margin
    return margin, margin + gap


# `plane_box_contacts`' answer for two convex geoms (not two boxes) within reach of each other:
# the caller's narrow phase decides them (`collide_pairs`: the signed distance and a manifold;
# `collide._kernels.check.deepest_contact`: GJK's bounds first, only the deepest distance).
CONVEX_PAIR = -1


@njit(cache=True, inline="always")
def plane_box_contacts(g1, g2, thr, xpos, xmat, cls, rule, below, rbound, gtype, half, shapes, faces, scratch):
    """The contacts of a geom pair (not two planes, no skipped class) up to the convex narrow phase.

    The one home of MuJoCo's dispatch (module docstring) that `collide_pairs` and
    `collide._kernels.check.deepest_contact` share: a plane against a convex geom (a bounding
    test on the plane's equation, then `plane_mesh` for a mesh with a hull, `plane_convex`
    otherwise); two convex geoms: a bounding-ball test, then two boxes by `box_box`. Inlined
    (numba's IR): the tables come in three tuples, since a call of more than 30 arguments
    compiles to a ``*args`` call, which numba does not inline, and a call per pair would cost
    the batch checks the passing of some 40 arrays.

    Parameters
    ----------
    g1, g2 : int
        Geom ids, finite poses.
    thr : float
        The pair's contact distance (`pair_margins`).
    xpos ... half
        As `collide_pairs` takes them.
    shapes : tuple
        ``(kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr,
        nbr_adr, nbr_num)``, as `collide_pairs` takes them.
    faces : tuple
        ``(hv_adr, hv_num, hv, f_adr, f_num, f_normal, f_vadr, f_vnum, f_vidx)``, likewise.
    scratch : tuple
        ``(cand, dep, sel, res, nrm, bws, pcand, pdep)``: `collide_pairs`' scratch (`_scratch`),
        ``nrm (3,)`` its ``bnrm``.

    Returns
    -------
    int
        ``m >= 0``: the pair's contacts, ``res[:m]`` ``(dist, pos x, y, z)``, their normal in
        ``nrm`` (from ``g1`` to ``g2``), none where the bounding test leaves the pair out; or
        `CONVEX_PAIR`: two convex geoms, not two boxes, within reach (the caller decides).
    """
    kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num = shapes
    hv_adr, hv_num, hv, f_adr, f_num, f_normal, f_vadr, f_vnum, f_vidx = faces
    cand, dep, sel, res, nrm, bws, pcand, pdep = scratch
    c1 = cls[g1]
    if c1 == PLANE or cls[g2] == PLANE:
        gp = g1 if c1 == PLANE else g2
        gc = g2 if c1 == PLANE else g1
        for q in range(3):
            nrm[q] = xmat[gp, q, 2]
        p0 = xpos[gp]
        cd = nrm[0] * (xpos[gc, 0] - p0[0]) + nrm[1] * (xpos[gc, 1] - p0[1]) + nrm[2] * (xpos[gc, 2] - p0[2])
        if cd - rbound[gc] > thr:
            return 0
        if gtype[gc] == T_MESH and hv_num[gc] > 0:
            a = hv_adr[gc]
            m = plane_mesh(hv[a:a + hv_num[gc]], f_adr[gc], f_num[gc], f_normal, f_vadr, f_vnum, f_vidx,
                           xmat[gc], xpos[gc], nrm, p0, thr, pcand, pdep, sel, res)
        else:
            sc = _shape(gc, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr,
                        nbr_num, xpos, xmat)
            m = plane_convex(rule[gc], below[gc], sc, nrm, p0, thr, cand, dep, sel, res)
        if c1 != PLANE:  # the normal from the first geom to the second
            for q in range(3):
                nrm[q] = -nrm[q]
        return m
    cc = math.sqrt((xpos[g2, 0] - xpos[g1, 0]) ** 2 + (xpos[g2, 1] - xpos[g1, 1]) ** 2
                   + (xpos[g2, 2] - xpos[g1, 2]) ** 2)
    if cc - rbound[g1] - rbound[g2] > thr:
        return 0
    if gtype[g1] == T_BOX and gtype[g2] == T_BOX:
        # MuJoCo's box-box: separating axes and a clipped face (up to 8 contacts)
        return box_box(xpos[g1], xmat[g1], half[g1], xpos[g2], xmat[g2], half[g2], thr, res, nrm, bws)
    return CONVEX_PAIR


@njit(cache=True)
def collide_pairs(pairs, xpos, xmat, cls, rule, below, kind, prm, pts, pts_adr, pts_num, nbr_start,
                  nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num, rbound, size, geom_margin, geom_gap,
                  pair_key, pair_margin, pair_gap, override, o_margin, gtype, half, hv_adr, hv_num, hv, f_adr, f_num,
                  f_normal, f_offset, f_vadr, f_vnum, f_vidx, out_geom, out_dist,
                  out_pos, out_normal, out_margin, skipped):
    """Contacts of the geom pairs ``pairs`` at the world poses ``xpos``, ``xmat``.

    Parameters
    ----------
    pairs : (K, 2) int32
        Geom ids, the first geom of a row is the contacts' first.
    xpos : (G, 3) float64
    xmat : (G, 3, 3) float64
        World poses of the geoms (MuJoCo's ``geom_xpos``, ``geom_xmat``).
    cls, rule : (G,) int8
        `PLANE` / `CONVEX` / `SKIPPED`, and the plane rule (`RULE_*`).
    below : (G,) bool
        Plane contacts only from vertices on the plane's side of the centre (boxes).
    kind : (G,) int64
    prm : (G, 4) float64
    pts : (N, 3) float64
    pts_adr, pts_num : (G,) int64
    nbr_start : (M,) int32
    nbr_start_adr, nbr_start_num : (G,) int64
    nbr : (E,) int32
    nbr_adr, nbr_num : (G,) int64
        The support data of each geom (`collide.support.SupportData`), concatenated.
    rbound : (G,) float64
        Radius of a ball about the geom's origin holding it.
    size : (G,) float64
        `collide.support.SupportData.size`: convergence tolerances are relative to it.
    geom_margin, geom_gap : (G,) float64
    pair_key : (P,) int64
        ``g1 * G + g2`` (``g1 < g2``) of the explicit pairs, sorted.
    pair_margin, pair_gap : (P,) float64
        Their margins and gaps, in ``pair_key``'s order.
    override : bool
        Every margin is ``o_margin`` (MuJoCo's ``mjENBL_OVERRIDE``); gaps stay.
    o_margin : float
    gtype : (G,) int8
        MuJoCo's geom types (``T_*``): boxes pair by `collide._kernels.faces.box_box`, meshes
        meet planes by `plane_mesh`, boxes and meshes in penetration get `polytope_contacts`.
    half : (G, 3) float64
        Half sizes of the boxes.
    hv_adr, hv_num, hv, f_adr, f_num, f_normal, f_offset, f_vadr, f_vnum, f_vidx
        The hull faces of boxes and meshes (`collide.faces.FaceTable`).
    out_geom : (M K, 2) int32
    out_dist : (M K,) float64
    out_pos, out_normal : (M K, 3) float64
    out_margin : (M K,) float64
        ``M`` is `MAX_PER_PAIR`.
        Receive the contacts; ``out_margin`` is the pair's margin (a contact at or beyond it
        lies in the gap: MuJoCo flags it ``exclude``).
    skipped : (K,) bool
        Receives True for a pair with a height field or SDF geom.

    Returns
    -------
    int
        Contacts written; ``-g - 2`` for a pose of geom ``g`` refused (`_pose_refused`: non-finite,
        not a proper rotation, or beyond the positions taken).
    """
    return _collide(pairs, xpos, xmat, (cls, rule, below, rbound, size, gtype, half),
                    (kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num),
                    (geom_margin, geom_gap, pair_key, pair_margin, pair_gap, override, o_margin),
                    (hv_adr, hv_num, hv, f_adr, f_num, f_normal, f_offset, f_vadr, f_vnum, f_vidx),
                    _scratch(pts_num, f_vnum), (out_geom, out_dist, out_pos, out_normal, out_margin, skipped))


@njit(cache=True, inline="always")
def _collide(pairs, xpos, xmat, gtab, shapes, margins, faces, ws, outs):
    # `collide_pairs`' body, its tables in tuples (see its docstring): ``gtab`` ``(cls, rule,
    # below, rbound, size, gtype, half)``, ``shapes`` (`plane_box_contacts`'), ``margins``
    # ``(geom_margin, geom_gap, pair_key, pair_margin, pair_gap, override, o_margin)``, ``faces``
    # (`collide.faces.FaceTable.kernel_args`), ``ws`` the scratch (`carve_scratch`), ``outs``
    # ``(out_geom, out_dist, out_pos, out_normal, out_margin, skipped)``.
    cls, rule, below, rbound, size, gtype, half = gtab
    kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr, nbr_num = shapes
    geom_margin, geom_gap, pair_key, pair_margin, pair_gap, override, o_margin = margins
    hv_adr, hv_num, hv, f_adr, f_num, f_normal, f_offset, f_vadr, f_vnum, f_vidx = faces
    out_geom, out_dist, out_pos, out_normal, out_margin, skipped = outs
    G = cls.shape[0]
    (cand, dep, sel, res, bnrm, bws, seg, pcand, pdep, face1, face2, poly, tmp, cand1, cand2, cnrm1, cnrm2, pa, pb,
     nv, out, d0, dws, dwi, sep, cache) = ws
    pfaces = (hv_adr, hv_num, hv, f_adr, f_num, f_normal, f_vadr, f_vnum, f_vidx)
    scratch = (cand, dep, sel, res, bnrm, bws, pcand, pdep)
    k = 0
    for p in range(pairs.shape[0]):
        g1 = pairs[p, 0]
        g2 = pairs[p, 1]
        skipped[p] = False
        c1 = cls[g1]
        c2 = cls[g2]
        if c1 == SKIPPED or c2 == SKIPPED:
            skipped[p] = True
            continue
        if c1 == PLANE and c2 == PLANE:
            continue  # no collision function (MuJoCo's mjCOLLISIONFUNC is NULL there)
        if _pose_refused(xpos, xmat, g1):
            return -g1 - 2  # below `OUT_FULL` (-1), which `collide_bound` returns for a full arena
        if _pose_refused(xpos, xmat, g2):
            return -g2 - 2
        # the pair's margin and gap: an explicit pair's own, else the geoms' sums; a geom pair
        # listed in several <pair>s is collided once for each, with its own (as MuJoCo does)
        j, nent, explicit = _pair_rows(pair_key, min(g1, g2) * G + max(g1, g2))
        for e in range(nent):
            margin, thr = pair_margins(g1, g2, j + e, explicit, geom_margin, geom_gap, pair_margin, pair_gap,
                                       override, o_margin)
            m = plane_box_contacts(g1, g2, thr, xpos, xmat, cls, rule, below, rbound, gtype, half, shapes, pfaces,
                                   scratch)
            if m != CONVEX_PAIR:
                for i in range(m):
                    _emit(k, g1, g2, res[i, 0], res[i, 1], res[i, 2], res[i, 3], bnrm[0], bnrm[1], bnrm[2], margin,
                          out_geom, out_dist, out_pos, out_normal, out_margin)
                    k += 1
                continue
            # two convex geoms, not two boxes, within reach: the signed distance
            t1 = gtype[g1]
            t2 = gtype[g2]
            s1 = _shape(g1, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr,
                        nbr_adr, nbr_num, xpos, xmat)
            s2 = _shape(g2, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr,
                        nbr_adr, nbr_num, xpos, xmat)
            # GJK stops once the pair is certainly beyond its contact distance (by the tolerance:
            # the converged distance would exceed thr too), as MuJoCo's GJK at its dist_cutoff
            tol = CONTACT_TOL * (size[g1] + size[g2])
            # the caches across calls (`collide._kernels.warm`), for pairs that GJK/EPA decide
            # (not two spheres or capsules, whose closed form, `distance.segment_distance`, is
            # as cheap as the test): a pair last found apart is settled by its last separating
            # direction when that still shows it apart; two point clouds last found penetrating
            # try their kept polytope. Any other pair takes the cold query, after the look-ups.
            # (A GJK started from the kept direction, which has just failed, was no faster over
            # the models: tests/bench/contacts.txt, session 51.)
            key = 0
            skey = 0
            round_pair = kind[g1] == POINTS and kind[g2] == POINTS and max(pts_num[g1], pts_num[g2]) <= 2
            if not round_pair:
                if sep.shape[0] == SEP_LEN:
                    skey = g1 * G + g2 + 1
                    if sep_test(sep, skey, s1, s2, thr, pa, pb):
                        continue
                if kind[g1] == POINTS and kind[g2] == POINTS and cache.shape[0] >= WARM_LEN:
                    key = g1 * G + g2 + 1
            if key != 0 and cache[WARM_KEYS + warm_slot(key)] == key:
                distance_warm(s1, s2, tol, thr + tol, d0, out, cache, key, dws, dwi)
            elif not (round_pair and segment_distance(s1, s2, tol, out)):  # spheres and capsules: at once
                pair_distance_within(s1, s2, tol, thr + tol, d0, -1, -1, EPA_CAP, out, dws, dwi)
                if key != 0 and out[OUT_PENETRATING] == 1.0:
                    warm_claim(cache, key)
            d = out[OUT_DISTANCE]
            if d > thr:
                if skey != 0:
                    sep_keep(sep, skey, out)
                continue
            if skey != 0:
                sep_forget(sep, skey)
            if d < 0.0 and not thr > 0.0 and _polytope(t1) and _polytope(t2) and f_num[g1] > 0 and f_num[g2] > 0:
                # two polytopes in penetration without a margin: MuJoCo's multi-contact of faces
                for q in range(3):
                    pa[q] = out[OUT_POINT_A + q]
                    pb[q] = out[OUT_POINT_B + q]
                    nv[q] = out[OUT_NORMAL + q]
                m = polytope_contacts(g1, g2, xpos, xmat, d, nv, pa, pb, 1e-7 * (size[g1] + size[g2]), hv_adr, hv,
                                      f_adr, f_num, f_normal, f_offset, f_vadr, f_vnum, f_vidx, face1, face2, poly,
                                      tmp, cand1, cnrm1, cand2, cnrm2, seg, sel, res)
                if m > 0:
                    for i in range(m):
                        _emit(k, g1, g2, res[i, 0], res[i, 1], res[i, 2], res[i, 3], nv[0], nv[1], nv[2], margin,
                              out_geom, out_dist, out_pos, out_normal, out_margin)
                        k += 1
                    continue
            _emit(k, g1, g2, d,
                  0.5 * (out[OUT_POINT_A] + out[OUT_POINT_B]),
                  0.5 * (out[OUT_POINT_A + 1] + out[OUT_POINT_B + 1]),
                  0.5 * (out[OUT_POINT_A + 2] + out[OUT_POINT_B + 2]),
                  out[OUT_NORMAL], out[OUT_NORMAL + 1], out[OUT_NORMAL + 2],
                  margin, out_geom, out_dist, out_pos, out_normal, out_margin)
            k += 1
    return k


# Slots of the packed tables of `collide_bound` (`collide.contacts.GeomTable` builds them): one
# flat buffer a dtype, so that a call passes a few arrays, not forty (numba's dispatch unboxes
# each argument). Slot ``s`` is rows ``ti[2 s + 1]`` from element ``ti[2 s]`` of its buffer.
(S_PRM, S_PTS, S_RBOUND, S_SIZE, S_GEOM_MARGIN, S_GEOM_GAP, S_PAIR_MARGIN, S_PAIR_GAP, S_HALF, S_HV, S_F_NORMAL,
 S_F_OFFSET) = range(12)  # float64: tf
(S_KIND, S_PTS_ADR, S_PTS_NUM, S_NBR_START_ADR, S_NBR_START_NUM, S_NBR_ADR, S_NBR_NUM, S_PAIR_KEY, S_HV_ADR,
 S_HV_NUM, S_F_ADR, S_F_NUM, S_F_VADR, S_F_VNUM) = range(12, 26)  # int64: ti
S_CLS, S_RULE, S_BELOW, S_GTYPE = range(26, 30)  # int8: t8 (``below`` viewed as bool)
S_NBR_START, S_NBR, S_F_VIDX = range(30, 33)  # int32: t32
N_SLOTS = 33
# ti's header: the slots' (offset, rows), then the scratch's ``cap`` and ``fmax`` (`scratch_caps`).
TI_HEADER = 2 * N_SLOTS + 2
# Each slot's buffer (0: tf, 1: ti, 2: t8, 3: t32) and the buffers' dtypes, in that order.
SLOT_BUFFER = tuple(0 if s <= S_F_OFFSET else 1 if s <= S_F_VNUM else 2 if s <= S_GTYPE else 3 for s in range(N_SLOTS))
BUFFER_DTYPES = (np.dtype(np.float64), np.dtype(np.int64), np.dtype(np.int8), np.dtype(np.int32))
# Columns of each slot's rows (1: a flat array; ``prm`` (G, 4), points and face vertices (N, 3), ...).
SLOT_COLS = tuple(4 if s == S_PRM else 3 if s in (S_PTS, S_HALF, S_HV, S_F_NORMAL) else 1 for s in range(N_SLOTS))

# `collide_bound`'s float output ``out_f`` for ``M`` contacts at most: field ``F_X`` begins at
# ``F_X * M`` (``dist (M,)``, ``pos (M, 3)``, ``normal (M, 3)``, ``margin (M,)``); ``F_END * M`` long.
F_DIST, F_POS, F_NORMAL, F_MARGIN, F_END = 0, 1, 4, 7, 8



@njit(cache=True, inline="always")
def _slot(buf, ti, s):
    o = ti[2 * s]
    return buf[o:o + ti[2 * s + 1]]


@njit(cache=True, inline="always")
def _slot2(buf, ti, s):
    o = ti[2 * s]
    n = ti[2 * s + 1]
    c = SLOT_COLS[s]
    return buf[o:o + n * c].reshape((n, c))


# `collide_bound`'s answer when its output arena has fewer free rows than ``per_pair * K``
# (nothing written: the caller starts a new arena and calls again).
OUT_FULL = -1

# `collide_bound`'s context: one int64 array (`collide.contacts.GeomTable` owns and fills it) of
# the addresses and lengths of the table's buffers and the call's scalars, so that a call passes
# six arguments, not sixteen (each array argument is unboxed on every call). ``o_margin`` holds
# the float64's bits.
CTX_FIELDS = ("tf", "tf_len", "ti", "ti_len", "t8", "t8_len", "t32", "t32_len", "wsf", "wsf_len", "wsi",
              "wsi_len", "per_pair", "override", "o_margin")
(C_TF, C_TF_LEN, C_TI, C_TI_LEN, C_T8, C_T8_LEN, C_T32, C_T32_LEN, C_WSF, C_WSF_LEN, C_WSI, C_WSI_LEN, C_PER_PAIR,
 C_OVERRIDE, C_O_MARGIN) = range(len(CTX_FIELDS))
NCTX = len(CTX_FIELDS)
# An output arena's own state (an int64 array of each arena, `GeomTable._new_out`): its buffers'
# addresses, its rows and its first free row. Its own, not the table's: a caller that holds an
# arena reads its rows from that arena, whichever arena the table has started since.
ARENA_FIELDS = ("geom", "f", "rows", "next")
A_GEOM, A_F, A_ROWS, A_NEXT = range(len(ARENA_FIELDS))
NARENA = len(ARENA_FIELDS)


# Compiled without numba's reference counting (`_ptr.NO_NRT`): every table, scratch and output
# view here is made from an address and carries no count, and numba's runtime calls on them (the
# table tuples unpacked and passed on at every pair) were a large part of a small model's call.
# Its callees state their own: ``_nrt=True`` where they allocate
# (`collide._kernels.distance.pair_distance_within`), `NO_NRT` where they do not (`box_box`,
# `plane_convex`, `plane_mesh`, `polytope_contacts`, `collide._kernels.warm.distance_warm`, ...).
# A callee that states none is compiled with the flags of the first caller that compiles it, and
# numba compiles (and caches) one version a signature whatever the flags: left to inherit them,
# `box_box` kept the counting of whichever kernel reached it first (a slower box-box step;
# tests/bench/contacts.txt, block "session 49").
@njit(**NO_NRT)
def collide_bound(pairs, xpos, xmat, skipped, addr, arena):
    """`collide_pairs` on a table's packed buffers and workspace, into an output arena (the per-step call).

    Parameters
    ----------
    pairs, xpos, xmat, skipped
        As `collide_pairs` takes them (``skipped`` at least ``K`` long).
    addr : int
        Address of the table's context (``NCTX`` int64, fields ``C_*``):

        - ``tf`` (float64), ``ti`` (int64, beginning with the header ``TI_HEADER``), ``t8``
          (int8), ``t32`` (int32): the tables of `collide_pairs`, packed by slot (``S_*``);
        - ``wsf`` (float64), ``wsi`` (int64): the scratch (`scratch_sizes` of ``ti``'s ``cap``,
          ``fmax``), overwritten, the warm-start cache kept in ``wsi``;
        - ``per_pair``: the most contacts a pair may make (`MAX_PER_PAIR` times the most
          ``<pair>`` s of a geom pair): a call needs ``per_pair * K`` free rows;
        - ``override``, ``o_margin``: as `collide_pairs` takes them.
    arena : int
        Address of an output arena's state (``NARENA`` int64, fields ``A_*``): ``geom``
        ((rows, 2) int32) and ``f`` (``F_END * rows`` float64: ``dist``, ``pos (rows, 3)``,
        ``normal (rows, 3)``, ``margin`` from ``F_DIST rows``, ``F_POS rows``, ``F_NORMAL rows``,
        ``F_MARGIN rows`` on), written from row ``next`` on, which is advanced past the contacts
        written (rows before it are never written again: the caller hands them out).

        Every buffer must be C-contiguous and outlive the call; nothing is checked (the owner,
        `collide.contacts.GeomTable`, holds them). The call holds the GIL throughout: calls on
        one table from threads, or from a signal handler, never share the scratch at once.

    Returns
    -------
    int
        ``(row << 32) | n``: ``n`` contacts written from ``row`` on; `OUT_FULL` when fewer than
        ``per_pair * K`` rows are free (nothing written, ``out_next`` unchanged); a refused
        pose as `collide_pairs` reports it, below `OUT_FULL` (``out_next`` unchanged).
    """
    ctx = view_of(i64_ptr(addr), NCTX)
    out = view_of(i64_ptr(arena), NARENA)
    K = pairs.shape[0]
    M = out[A_ROWS]
    row = out[A_NEXT]
    if M - row < ctx[C_PER_PAIR] * K:
        return OUT_FULL
    check_span(K, skipped.shape[0])
    tf = view_of(f64_ptr(ctx[C_TF]), ctx[C_TF_LEN])
    ti = view_of(i64_ptr(ctx[C_TI]), ctx[C_TI_LEN])
    t8 = view_of(i8_ptr(ctx[C_T8]), ctx[C_T8_LEN])
    t32 = view_of(i32_ptr(ctx[C_T32]), ctx[C_T32_LEN])
    wsf = view_of(f64_ptr(ctx[C_WSF]), ctx[C_WSF_LEN])
    wsi = view_of(i64_ptr(ctx[C_WSI]), ctx[C_WSI_LEN])
    below = view_of(bool_ptr(ctx[C_T8] + ti[2 * S_BELOW]), ti[2 * S_BELOW + 1])  # t8's slot as bool
    gtab = (_slot(t8, ti, S_CLS), _slot(t8, ti, S_RULE), below, _slot(tf, ti, S_RBOUND), _slot(tf, ti, S_SIZE),
            _slot(t8, ti, S_GTYPE), _slot2(tf, ti, S_HALF))
    shapes = (_slot(ti, ti, S_KIND), _slot2(tf, ti, S_PRM), _slot2(tf, ti, S_PTS), _slot(ti, ti, S_PTS_ADR),
              _slot(ti, ti, S_PTS_NUM), _slot(t32, ti, S_NBR_START), _slot(ti, ti, S_NBR_START_ADR),
              _slot(ti, ti, S_NBR_START_NUM), _slot(t32, ti, S_NBR), _slot(ti, ti, S_NBR_ADR),
              _slot(ti, ti, S_NBR_NUM))
    margins = (_slot(tf, ti, S_GEOM_MARGIN), _slot(tf, ti, S_GEOM_GAP), _slot(ti, ti, S_PAIR_KEY),
               _slot(tf, ti, S_PAIR_MARGIN), _slot(tf, ti, S_PAIR_GAP), ctx[C_OVERRIDE] != 0,
               view_of(f64_ptr(addr + 8 * C_O_MARGIN), 1)[0])
    faces = (_slot(ti, ti, S_HV_ADR), _slot(ti, ti, S_HV_NUM), _slot2(tf, ti, S_HV), _slot(ti, ti, S_F_ADR),
             _slot(ti, ti, S_F_NUM), _slot2(tf, ti, S_F_NORMAL), _slot(tf, ti, S_F_OFFSET),
             _slot(ti, ti, S_F_VADR), _slot(ti, ti, S_F_VNUM), _slot(t32, ti, S_F_VIDX))
    ws = carve_scratch(wsf, wsi, ti[2 * N_SLOTS], ti[2 * N_SLOTS + 1])
    R = M - row
    f = out[A_F]
    outs = (view_of(i32_ptr(out[A_GEOM] + 8 * row), (R, 2)), view_of(f64_ptr(f + 8 * (F_DIST * M + row)), R),
            view_of(f64_ptr(f + 8 * (F_POS * M + 3 * row)), (R, 3)),
            view_of(f64_ptr(f + 8 * (F_NORMAL * M + 3 * row)), (R, 3)),
            view_of(f64_ptr(f + 8 * (F_MARGIN * M + row)), R), skipped)
    n = _collide(pairs, xpos, xmat, gtab, shapes, margins, faces, ws, outs)
    if n < 0:
        return n
    out[A_NEXT] = row + n
    return (row << 32) | n


@njit(cache=True)
def pair_signed_distance_bound(g1, g2, xpos, xmat, addr, cutoff, out):
    """`pair_signed_distance` on a table's packed buffers (``mj_geomDistance``'s per-call form).

    ``addr`` is the table's context (as `collide_bound` takes it); its tables are read as views,
    so a call passes seven arguments where `pair_signed_distance` takes eighteen (numba's dispatch
    pays for each). ``g1``, ``g2`` must be geom ids of the table and ``xpos`` ``(G, 3)``,
    ``xmat`` ``(G, 3, 3)`` its poses, C-contiguous: nothing is checked. Returns, ``cutoff`` and
    ``out`` as `pair_signed_distance`, 3 also for a pose `_pose_refused` refuses (not a rotation,
    or beyond the positions taken), and 4 (``out`` not written) when the geoms' bounding balls
    are farther apart than ``cutoff`` (as ``mj_geomDistance`` first tests them). Both early
    answers (that one and GJK's cutoff) take a pair only when it is beyond ``cutoff`` by more
    than the query's tolerance and rounding, so a pair at ``cutoff`` gets the full query's answer.
    """
    ctx = view_of(i64_ptr(addr), NCTX)
    tf = view_of(f64_ptr(ctx[C_TF]), ctx[C_TF_LEN])
    ti = view_of(i64_ptr(ctx[C_TI]), ctx[C_TI_LEN])
    t8 = view_of(i8_ptr(ctx[C_T8]), ctx[C_T8_LEN])
    t32 = view_of(i32_ptr(ctx[C_T32]), ctx[C_T32_LEN])
    cls = _slot(t8, ti, S_CLS)
    size = _slot(tf, ti, S_SIZE)
    c1 = cls[g1]
    c2 = cls[g2]
    if c1 != SKIPPED and c2 != SKIPPED and not (c1 == PLANE and c2 == PLANE):
        # a pose that is not a rotation (or beyond the positions taken) is refused here, at the
        # user's entry point; `pair_signed_distance` itself (check_batch's, on poses from our own
        # kinematics) keeps its finiteness test
        if _pose_refused(xpos, xmat, g1) or _pose_refused(xpos, xmat, g2):
            return 3
    if c1 == CONVEX and c2 == CONVEX:
        rbound = _slot(tf, ti, S_RBOUND)
        # Either early answer must be the full query's: a pair is only cut off when it is beyond
        # ``cutoff`` by more than the query's tolerance and the rounding of its coordinates (a
        # cutoff of exactly the distance would otherwise decide by the last bits).
        reach = rbound[g1] + rbound[g2]
        for q in range(3):
            reach += abs(xpos[g1, q]) + abs(xpos[g2, q])
        cutoff += 2e-12 * (size[g1] + size[g2]) + ROUNDING * _EPS * reach
        cc = math.sqrt((xpos[g2, 0] - xpos[g1, 0]) ** 2 + (xpos[g2, 1] - xpos[g1, 1]) ** 2
                       + (xpos[g2, 2] - xpos[g1, 2]) ** 2)
        if cc - rbound[g1] - rbound[g2] > cutoff:
            return 4
    return pair_signed_distance(g1, g2, xpos, xmat, cls, _slot(ti, ti, S_KIND),
                                _slot2(tf, ti, S_PRM), _slot2(tf, ti, S_PTS), _slot(ti, ti, S_PTS_ADR),
                                _slot(ti, ti, S_PTS_NUM), _slot(t32, ti, S_NBR_START),
                                _slot(ti, ti, S_NBR_START_ADR), _slot(ti, ti, S_NBR_START_NUM),
                                _slot(t32, ti, S_NBR), _slot(ti, ti, S_NBR_ADR), _slot(ti, ti, S_NBR_NUM),
                                size, out, cutoff)


@njit(cache=True)
def pair_signed_distance(g1, g2, xpos, xmat, cls, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr,
                         nbr_start_num, nbr, nbr_adr, nbr_num, size, out, cutoff=math.inf):
    """Signed distance of geoms ``g1`` and ``g2`` and the nearest points (for ``mj_geomDistance``).

    Parameters
    ----------
    (see `collide_pairs`)
    out : (7,) float64
        Receives ``dist`` and ``fromto`` (a point on ``g1``, a point on ``g2``, world frame).
    cutoff : float, default inf
        GJK stops once the pair is certainly farther than this (``dist`` then exceeds it, and the
        points are not the nearest): ``mj_geomDistance``'s ``distmax``.

    Returns
    -------
    int
        0, or 1 when both are planes (no distance), 2 for a skipped class, 3 for a non-finite pose.
    """
    c1 = cls[g1]
    c2 = cls[g2]
    if c1 == SKIPPED or c2 == SKIPPED:
        return 2
    if c1 == PLANE and c2 == PLANE:
        return 1
    if not (_finite_pose(xpos, xmat, g1) and _finite_pose(xpos, xmat, g2)):
        return 3
    if c1 == PLANE or c2 == PLANE:
        gp = g1 if c1 == PLANE else g2
        gc = g2 if c1 == PLANE else g1
        n = xmat[gp, :, 2].copy()
        sc = _shape(gc, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr,
                    nbr_num, xpos, xmat)
        s = np.empty(3)
        _support_minus(sc, n, s)
        r = prm[gc, 3]
        d = n[0] * (s[0] - xpos[gp, 0]) + n[1] * (s[1] - xpos[gp, 1]) + n[2] * (s[2] - xpos[gp, 2]) - r
        out[0] = d
        oc = 1 if c1 != PLANE else 4  # the convex geom's point
        op = 4 if c1 != PLANE else 1
        for q in range(3):
            out[oc + q] = s[q] - r * n[q]
            out[op + q] = s[q] - (r + d) * n[q]
        return 0
    s1 = _shape(g1, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr,
                nbr_num, xpos, xmat)
    s2 = _shape(g2, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr,
                nbr_num, xpos, xmat)
    res = np.empty(OUT_SIZE)
    pair_distance_within(s1, s2, 1e-12 * (size[g1] + size[g2]), cutoff, np.zeros(3), -1, -1, 128, res,
                         np.empty(WS_F), np.empty(WS_I, np.int64))
    out[0] = res[OUT_DISTANCE]
    for q in range(3):
        out[1 + q] = res[OUT_POINT_A + q]
        out[4 + q] = res[OUT_POINT_B + q]
    return 0
