"""Face contacts of two penetrating polytopes (numba): MuJoCo 4's multi-contact of boxes and meshes.

`polytope_contacts` starts from the exact contact (GJK/EPA's witness points and normal) and
follows what MuJoCo 4 does (``multicontact`` in ``engine_collision_gjk.c``, the behaviour read,
the code ours): the faces of each geom that hold its witness point (`_touching_faces`); two of
them nearly opposed (`FACE_TOL`): one face clipped to the other (`collide._kernels.faces.clip_faces`);
else an edge through one witness lying in a face of the other (`EDGE_TOL`, `_edge_in_face`): the
edge clipped to that face. The narrow phase's driver (`collide._kernels.manifold.collide_pairs`)
calls it for two boxes or meshes in penetration with no contact distance.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._ptr import NO_NRT
from .faces import clip_faces

# Polytope face contacts (MuJoCo 4's multi-contact of box and mesh pairs, engine_collision_gjk.h):
# two faces are aligned when their normals' dot is below -FACE_TOL; an edge lies in a face when
# |edge . normal| < EDGE_TOL.
FACE_TOL = 0.996
EDGE_TOL = 0.0888

_EPS = float(np.finfo(np.float64).eps)


@njit(**NO_NRT)
def _world_face(hv, a, vidx, vadr, vnum, f, rot, pos, out):
    # Face f's polygon in the world (rows of out), its vertex count returned.
    for r in range(vnum[f]):
        i = a + vidx[vadr[f] + r]
        for q in range(3):
            out[r, q] = pos[q] + rot[q, 0] * hv[i, 0] + rot[q, 1] * hv[i, 1] + rot[q, 2] * hv[i, 2]
    return vnum[f]


@njit(**NO_NRT)
def _touching_faces(g, x, u0, u1, u2, xpos, xmat, hv_adr, f_adr, f_num, f_normal, f_offset, tol, cand, cnrm):
    # Faces of geom g whose plane holds the witness x (within tol), their world normals in cnrm;
    # returns their count (cand: face ids) and puts the one best aligned with (u0, u1, u2) first.
    rot = xmat[g]
    k = 0
    best = -2.0
    # The witness in the geom's frame: a face's plane is tested there (3 products a face, where
    # the world test takes 15); the faces kept are tested again, as before, in the world.
    y0, y1, y2 = x[0] - xpos[g, 0], x[1] - xpos[g, 1], x[2] - xpos[g, 2]
    l0 = rot[0, 0] * y0 + rot[1, 0] * y1 + rot[2, 0] * y2
    l1 = rot[0, 1] * y0 + rot[1, 1] * y1 + rot[2, 1] * y2
    l2 = rot[0, 2] * y0 + rot[1, 2] * y1 + rot[2, 2] * y2
    # the two forms round differently, by a few ulps of the coordinates: a looser prefilter
    loose = 2.0 * tol + 64.0 * _EPS * (abs(x[0]) + abs(x[1]) + abs(x[2]) + abs(xpos[g, 0]) + abs(xpos[g, 1])
                                       + abs(xpos[g, 2]))
    for f in range(f_adr[g], f_adr[g] + f_num[g]):
        if abs(f_normal[f, 0] * l0 + f_normal[f, 1] * l1 + f_normal[f, 2] * l2 - f_offset[f]) > loose:
            continue
        nw0 = rot[0, 0] * f_normal[f, 0] + rot[0, 1] * f_normal[f, 1] + rot[0, 2] * f_normal[f, 2]
        nw1 = rot[1, 0] * f_normal[f, 0] + rot[1, 1] * f_normal[f, 1] + rot[1, 2] * f_normal[f, 2]
        nw2 = rot[2, 0] * f_normal[f, 0] + rot[2, 1] * f_normal[f, 1] + rot[2, 2] * f_normal[f, 2]
        off = nw0 * xpos[g, 0] + nw1 * xpos[g, 1] + nw2 * xpos[g, 2] + f_offset[f]
        if abs(nw0 * x[0] + nw1 * x[1] + nw2 * x[2] - off) > tol or k >= cand.shape[0]:
            continue
        cand[k] = f
        cnrm[k, 0], cnrm[k, 1], cnrm[k, 2] = nw0, nw1, nw2
        al = nw0 * u0 + nw1 * u1 + nw2 * u2
        if al > best:
            best = al
            if k > 0:  # swap to the front
                cand[0], cand[k] = cand[k], cand[0]
                for q in range(3):
                    cnrm[0, q], cnrm[k, q] = cnrm[k, q], cnrm[0, q]
        k += 1
    return k


@njit(**NO_NRT)
def polytope_contacts(g1, g2, xpos, xmat, d, nrm, pa, pb, tol, hv_adr, hv, f_adr, f_num, f_normal, f_offset,
                      f_vadr, f_vnum, f_vidx, face1, face2, poly, tmp, cand1, cnrm1, cand2, cnrm2, seg, sel, res):
    """Face contacts of two penetrating polytopes (boxes, convex meshes) from their exact contact.

    The behaviour of MuJoCo 4's multi-contact (``multicontact`` in engine_collision_gjk.c): the
    faces of each geom holding its witness point; two of them nearly opposed (`FACE_TOL`): the
    second's face clipped to the first's (at most 4 points, the largest quadrilateral); else an
    edge through one witness lying in a face of the other (`EDGE_TOL`): the edge clipped to that
    face (2 points). The points below the reference face are the contacts, at their depth along
    its normal, placed midway; the deepest is given the exact ``d`` (and no contact is deeper).

    Parameters
    ----------
    g1, g2 : int
    xpos, xmat : world poses of the geoms
    d : float
        The exact signed distance (negative).
    nrm, pa, pb : (3,) float64
        Unit normal from g1 to g2 and the witness points on g1 and g2.
    tol : float
        Distance of a witness from a face's plane still on it.
    hv_adr, hv, f_adr, f_num, f_normal, f_offset, f_vadr, f_vnum, f_vidx
        The face tables (`collide.faces.FaceTable`).
    face1, face2, poly, tmp : (M, 3) float64
        Scratch, ``M`` at least twice the largest face's vertex count plus 8.
    cand1, cand2 : (C,) int64, cnrm1, cnrm2 : (C, 3) float64, seg : (2, 3) float64, sel : (4,) int64
        Scratch.
    res : (4, 4) float64
        Receives ``(dist, pos x, y, z)``.

    Returns
    -------
    int
        Contacts written (0: none found; the caller keeps its single contact).
    """
    c1 = _touching_faces(g1, pa, nrm[0], nrm[1], nrm[2], xpos, xmat, hv_adr, f_adr, f_num, f_normal, f_offset, tol,
                         cand1, cnrm1)
    c2 = _touching_faces(g2, pb, -nrm[0], -nrm[1], -nrm[2], xpos, xmat, hv_adr, f_adr, f_num, f_normal, f_offset, tol,
                         cand2, cnrm2)
    if c1 == 0 or c2 == 0:
        return 0
    # the most opposed pair of touching faces
    bi, bj, bd = 0, 0, 2.0
    for i in range(c1):
        for j in range(c2):
            dd = cnrm1[i, 0] * cnrm2[j, 0] + cnrm1[i, 1] * cnrm2[j, 1] + cnrm1[i, 2] * cnrm2[j, 2]
            if dd < bd:
                bi, bj, bd = i, j, dd
    k = 0
    side = 0  # 1: points on g2 below g1's face; 2: points on g1's edge below g2's face; 3: g2's edge
    if bd < -FACE_TOL:
        n1 = _world_face(hv, hv_adr[g1], f_vidx, f_vadr, f_vnum, cand1[bi], xmat[g1], xpos[g1], face1)
        n2 = _world_face(hv, hv_adr[g2], f_vidx, f_vadr, f_vnum, cand2[bj], xmat[g2], xpos[g2], face2)
        k = clip_faces(face1, n1, cnrm1[bi], face2, n2, poly, tmp, res, sel)
        side = 1
        ref = bi
    else:
        dim1 = 3 if c1 == 1 else (2 if c1 == 2 else 1)
        dim2 = 3 if c2 == 1 else (2 if c2 == 2 else 1)
        if dim1 < 3 and dim1 <= dim2:
            k, ref = _edge_in_face(g1, g2, pa, tol, c1, cand1, c2, cand2, cnrm2, xpos, xmat, hv_adr, hv, f_vadr,
                                   f_vnum, f_vidx, face1, face2, poly, tmp, seg, sel, res)
            side = 2
        elif dim2 < 3:
            k, ref = _edge_in_face(g2, g1, pb, tol, c2, cand2, c1, cand1, cnrm1, xpos, xmat, hv_adr, hv, f_vadr,
                                   f_vnum, f_vidx, face2, face1, poly, tmp, seg, sel, res)
            side = 3
    if k == 0:
        return 0
    # place each point midway: the clipped point lies on the incident feature, the other surface
    # |h| away along the reference face's normal
    ideep = 0
    for r in range(k):
        h = res[r, 0]
        for q in range(3):
            res[r, 1 + q] -= 0.5 * h * (cnrm2[ref, q] if side == 2 else cnrm1[ref, q])
        if h < res[ideep, 0]:
            ideep = r
    for r in range(k):
        if res[r, 0] < d:
            res[r, 0] = d
    res[ideep, 0] = d
    return k


@njit(**NO_NRT)
def _edge_in_face(ge, gf, x, tol, ce, cande, cf, candf, cnrmf, xpos, xmat, hv_adr, hv, f_vadr, f_vnum, f_vidx,
                  bufe, buff, poly, tmp, seg, sel, res):
    # An edge of geom ge through its witness x (an edge of one of its touching faces) lying in a
    # touching face of geom gf: the edge clipped to that face. Returns (points, the face's row).
    for i in range(ce):
        ne = _world_face(hv, hv_adr[ge], f_vidx, f_vadr, f_vnum, cande[i], xmat[ge], xpos[ge], bufe)
        for e in range(ne):
            e1 = e + 1 if e + 1 < ne else 0
            u0 = bufe[e1, 0] - bufe[e, 0]
            u1 = bufe[e1, 1] - bufe[e, 1]
            u2 = bufe[e1, 2] - bufe[e, 2]
            ll = u0 * u0 + u1 * u1 + u2 * u2
            if ll == 0.0:
                continue
            t = ((x[0] - bufe[e, 0]) * u0 + (x[1] - bufe[e, 1]) * u1 + (x[2] - bufe[e, 2]) * u2) / ll
            t = min(max(t, 0.0), 1.0)
            dx = bufe[e, 0] + t * u0 - x[0]
            dy = bufe[e, 1] + t * u1 - x[1]
            dz = bufe[e, 2] + t * u2 - x[2]
            if dx * dx + dy * dy + dz * dz > tol * tol:
                continue  # the witness is not on this edge
            il = 1.0 / math.sqrt(ll)
            for j in range(cf):
                if abs((u0 * cnrmf[j, 0] + u1 * cnrmf[j, 1] + u2 * cnrmf[j, 2]) * il) < EDGE_TOL:
                    nf = _world_face(hv, hv_adr[gf], f_vidx, f_vadr, f_vnum, candf[j], xmat[gf], xpos[gf], buff)
                    for q in range(3):
                        seg[0, q] = bufe[e, q]
                        seg[1, q] = bufe[e1, q]
                    return clip_faces(buff, nf, cnrmf[j], seg, 2, poly, tmp, res, sel), j
    return 0, 0
