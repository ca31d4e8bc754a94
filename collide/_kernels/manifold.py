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
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .distance import OUT_DISTANCE, OUT_NORMAL, OUT_POINT_A, OUT_POINT_B, OUT_SIZE, pair_distance
from .faces import BOX_MAX, BOX_WS, box_box, clip_faces
from .support import support

# Geom classes (`collide.contacts.GeomTable.cls`).
PLANE, CONVEX, SKIPPED = 0, 1, 2

# Plane rules of a convex geom (`collide.contacts.GeomTable.rule`).
RULE_SUPPORT, RULE_POINTS, RULE_VERTICES, RULE_CYLINDER = 0, 1, 2, 3

# Most contacts per pair: a box-box face manifold's (MuJoCo 4 keeps every clipped corner).
MAX_PER_PAIR = BOX_MAX

# MuJoCo's geom types (mjtGeom), as `collide.contacts` passes them in ``gtype``.
T_PLANE, T_HFIELD, T_SPHERE, T_CAPSULE, T_ELLIPSOID, T_CYLINDER, T_BOX, T_MESH = range(8)

# Plane-mesh: the face through the lowest vertex gives contacts when its normal's dot with the
# plane's is at most -PLANE_FACE_TOL (fitted to MuJoCo 4.0.0's counts: see `plane_mesh`).
PLANE_FACE_TOL = 0.98

# Polytope face contacts (MuJoCo 4's multi-contact of box and mesh pairs, engine_collision_gjk.h):
# two faces are aligned when their normals' dot is below -FACE_TOL; an edge lies in a face when
# |edge . normal| < EDGE_TOL.
FACE_TOL = 0.996
EDGE_TOL = 0.0888

# Errors of `collide_pairs` (negative returns: -(code + 8 * geom) - 1 for a non-finite pose).
ERR_POSE = 1


@njit(cache=True, inline="always")
def _shape(g, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr, nbr_adr,
           nbr_num, xpos, xmat):
    # The support kernels' shape tuple of geom g at its world pose (views, no copies).
    a = pts_adr[g]
    b = nbr_start_adr[g]
    c = nbr_adr[g]
    return (kind[g], prm[g], pts[a:a + pts_num[g]], nbr_start[b:b + nbr_start_num[g]], nbr[c:c + nbr_num[g]],
            xmat[g], xpos[g])


@njit(cache=True)
def _finite_pose(xpos, xmat, g):
    for i in range(3):
        if not math.isfinite(xpos[g, i]):
            return False
        for j in range(3):
            if not math.isfinite(xmat[g, i, j]):
                return False
    return True


@njit(cache=True)
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


@njit(cache=True)
def reduce_four(pts, dep, n, sel):
    """Pick up to 4 of ``n`` points spanning a large area, the deepest first.

    Parameters
    ----------
    pts : (n, 3) float64
        Candidate points, world frame (only the first ``n`` rows are read).
    dep : (n,) float64
        Their signed distances; the smallest is picked first.
    n : int
    sel : (4,) int64
        Receives the picked rows.

    Returns
    -------
    int
        How many were picked, ``min(n, 4)``: the deepest; the farthest from it; the one making the
        largest triangle with them; the one adding the largest triangle beyond an edge of that
        triangle (the contact-reduction heuristic of Bullet's ``btPersistentManifold``: a
        manifold wide enough to hold the body up, from a face's points).
    """
    if n <= 0:
        return 0
    if n <= 4:
        # deepest first, the rest in order
        i0 = 0
        for i in range(1, n):
            if dep[i] < dep[i0]:
                i0 = i
        sel[0] = i0
        k = 1
        for i in range(n):
            if i != i0:
                sel[k] = i
                k += 1
        return n
    i0 = 0
    for i in range(1, n):
        if dep[i] < dep[i0]:
            i0 = i
    sel[0] = i0
    best = -1.0
    i1 = -1
    for i in range(n):
        d2 = (pts[i, 0] - pts[i0, 0]) ** 2 + (pts[i, 1] - pts[i0, 1]) ** 2 + (pts[i, 2] - pts[i0, 2]) ** 2
        if d2 > best:
            best = d2
            i1 = i
    if best <= 0.0:
        return 1  # all at one point
    sel[1] = i1
    e0 = pts[i1, 0] - pts[i0, 0]
    e1 = pts[i1, 1] - pts[i0, 1]
    e2 = pts[i1, 2] - pts[i0, 2]
    best = 0.0
    i2 = -1
    nx = ny = nz = 0.0
    for i in range(n):
        f0 = pts[i, 0] - pts[i0, 0]
        f1 = pts[i, 1] - pts[i0, 1]
        f2 = pts[i, 2] - pts[i0, 2]
        c0 = e1 * f2 - e2 * f1
        c1 = e2 * f0 - e0 * f2
        c2 = e0 * f1 - e1 * f0
        a2 = c0 * c0 + c1 * c1 + c2 * c2
        if a2 > best:
            best = a2
            i2 = i
            nx, ny, nz = c0, c1, c2
    if i2 < 0:
        return 2  # collinear
    sel[2] = i2
    # The fourth: the largest area added beyond one edge of the triangle (i0, i1, i2), measured
    # against the triangle's normal (nx, ny, nz).
    best = 0.0
    i3 = -1
    for i in range(n):
        if i == i0 or i == i1 or i == i2:
            continue
        add = 0.0
        for e in range(3):
            a = sel[e]
            b = sel[(e + 1) % 3]
            u0 = pts[b, 0] - pts[a, 0]
            u1 = pts[b, 1] - pts[a, 1]
            u2 = pts[b, 2] - pts[a, 2]
            w0 = pts[i, 0] - pts[a, 0]
            w1 = pts[i, 1] - pts[a, 1]
            w2 = pts[i, 2] - pts[a, 2]
            # signed area of (a, b, i) along the normal: negative beyond edge a -> b
            s = (u1 * w2 - u2 * w1) * nx + (u2 * w0 - u0 * w2) * ny + (u0 * w1 - u1 * w0) * nz
            if -s > add:
                add = -s
        if add > best:
            best = add
            i3 = i
    if i3 < 0:
        return 3
    sel[3] = i3
    return 4


@njit(cache=True)
def plane_convex(rule, below_centre, shape, n, p0, thr, cand, dep, sel, res):
    """Contacts of a plane (normal ``n``, through ``p0``) and a convex geom's ``shape``.

    Parameters
    ----------
    rule : int
        The geom's `RULE_*`.
    below_centre : bool
        Vertices only on the plane's side of the geom's centre (a box, as MuJoCo's plane-box).
    shape : tuple
        ``(kind, prm, pts, nbr_start, nbr, rot, pos)`` (`collide._kernels.support`).
    n, p0 : (3,) float64
    thr : float
        Contact distance: contacts at signed distance ``<= thr``.
    cand : (m, 3) float64, dep : (m,) float64, sel : (4,) int64
        Scratch, ``m`` at least the shape's point count.
    res : (4, 4) float64
        Receives ``(dist, pos x, y, z)`` per contact, the deepest first.

    Returns
    -------
    int
        Contacts written, 0 to 4.
    """
    kind, prm, pts, nbr_start, nbr, rot, pos = shape
    r = prm[3]
    c = n[0] * (pos[0] - p0[0]) + n[1] * (pos[1] - p0[1]) + n[2] * (pos[2] - p0[2])
    if rule == RULE_POINTS or rule == RULE_VERTICES:
        m = 0
        for i in range(pts.shape[0]):
            w0 = rot[0, 0] * pts[i, 0] + rot[0, 1] * pts[i, 1] + rot[0, 2] * pts[i, 2]
            w1 = rot[1, 0] * pts[i, 0] + rot[1, 1] * pts[i, 1] + rot[1, 2] * pts[i, 2]
            w2 = rot[2, 0] * pts[i, 0] + rot[2, 1] * pts[i, 1] + rot[2, 2] * pts[i, 2]
            ld = n[0] * w0 + n[1] * w1 + n[2] * w2
            d = c + ld - r
            if d > thr or (below_centre and ld > 0.0):
                continue
            cand[m, 0] = w0 + pos[0]
            cand[m, 1] = w1 + pos[1]
            cand[m, 2] = w2 + pos[2]
            dep[m] = d
            m += 1
        k = reduce_four(cand, dep, m, sel)
        for j in range(k):
            i = sel[j]
            d = dep[i]
            res[j, 0] = d
            for q in range(3):
                res[j, 1 + q] = cand[i, q] - (r + 0.5 * d) * n[q]
        return k
    if rule == RULE_CYLINDER:
        return _plane_cylinder(prm[0], prm[1], rot, pos, n, c, thr, res)
    # RULE_SUPPORT: the support point along -n
    s = np.empty(3)
    _support_minus(shape, n, s)
    d = n[0] * (s[0] - p0[0]) + n[1] * (s[1] - p0[1]) + n[2] * (s[2] - p0[2]) - r
    if d > thr:
        return 0
    res[0, 0] = d
    for q in range(3):
        res[0, 1 + q] = s[q] - (r + 0.5 * d) * n[q]
    return 1


@njit(cache=True)
def _support_minus(shape, n, out):
    support(shape, -n[0], -n[1], -n[2], -1, out)


@njit(cache=True)
def _plane_cylinder(radius, half, rot, pos, n, c, thr, res):
    # A cylinder's contacts with a plane: the rim point nearest the plane on the nearer cap (the
    # exact signed distance: the support along -n), the same on the other cap, and two more on
    # the nearer cap's rim at +-120 degrees from the first (a triangle on the cap that holds a
    # cylinder standing on the plane), as MuJoCo's mjc_PlaneCylinder places them.
    a0, a1, a2 = rot[0, 2], rot[1, 2], rot[2, 2]
    pa = n[0] * a0 + n[1] * a1 + n[2] * a2
    if pa > 0.0:  # the axis towards the plane
        a0, a1, a2 = -a0, -a1, -a2
        pa = -pa
    # the radial direction of -n: -n + (n . a) a, scaled to the radius
    v0 = pa * a0 - n[0]
    v1 = pa * a1 - n[1]
    v2 = pa * a2 - n[2]
    ll = v0 * v0 + v1 * v1 + v2 * v2
    if ll >= 1e-30:
        s = radius / math.sqrt(ll)
        v0, v1, v2 = v0 * s, v1 * s, v2 * s
    else:  # a cap parallel to the plane: any rim point (the frame's x axis)
        v0, v1, v2 = rot[0, 0] * radius, rot[1, 0] * radius, rot[2, 0] * radius
    pv = v0 * n[0] + v1 * n[1] + v2 * n[2]
    h0, h1, h2 = a0 * half, a1 * half, a2 * half
    ph = pa * half
    d = c + ph + pv
    if d > thr:
        return 0
    k = 0
    res[k, 0] = d
    res[k, 1] = pos[0] + v0 + h0 - 0.5 * d * n[0]
    res[k, 2] = pos[1] + v1 + h1 - 0.5 * d * n[1]
    res[k, 3] = pos[2] + v2 + h2 - 0.5 * d * n[2]
    k += 1
    d = c - ph + pv
    if d <= thr:
        res[k, 0] = d
        res[k, 1] = pos[0] + v0 - h0 - 0.5 * d * n[0]
        res[k, 2] = pos[1] + v1 - h1 - 0.5 * d * n[1]
        res[k, 3] = pos[2] + v2 - h2 - 0.5 * d * n[2]
        k += 1
    d = c + ph - 0.5 * pv
    if d <= thr:
        # sideways: v x h, of length radius * sqrt(3) / 2
        w0 = v1 * h2 - v2 * h1
        w1 = v2 * h0 - v0 * h2
        w2 = v0 * h1 - v1 * h0
        lw = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        if lw > 0.0:
            s = radius * math.sqrt(3.0) / 2.0 / lw
            w0, w1, w2 = w0 * s, w1 * s, w2 * s
        for sg in (1.0, -1.0):
            res[k, 0] = d
            res[k, 1] = pos[0] + sg * w0 + h0 - 0.5 * v0 - 0.5 * d * n[0]
            res[k, 2] = pos[1] + sg * w1 + h1 - 0.5 * v1 - 0.5 * d * n[1]
            res[k, 3] = pos[2] + sg * w2 + h2 - 0.5 * v2 - 0.5 * d * n[2]
            k += 1
    return k


@njit(cache=True)
def plane_mesh(hv, f0, nf, f_normal, f_vadr, f_vnum, f_vidx, rot, pos, n, p0, thr, cand, dep, sel, res):
    """Contacts of a plane (normal ``n`` through ``p0``) and a convex mesh's hull.

    The lowest hull vertex (the exact signed distance); when a hull face through it faces the
    plane (its normal's dot with ``n`` at most ``-PLANE_FACE_TOL``), also that face's other
    vertices within the contact distance, at most 4 contacts in all (`reduce_four`, the lowest
    kept). This is fitted to what MuJoCo 4.0.0 does (its counts per pair on the shared models'
    mesh-plane contacts; the source of its ``mjc_PlaneConvex`` read here, a development version,
    takes graph neighbours instead, which the installed binary does not match).

    Parameters
    ----------
    hv : (H, 3) float64
        The mesh's hull vertices, geom frame.
    f0, nf : int
        The mesh's rows in the face arrays.
    f_normal, f_vadr, f_vnum, f_vidx
        Face tables (`collide.faces.FaceTable`; vertex ids local to ``hv``).
    rot : (3, 3) float64
    pos, n, p0 : (3,) float64
    thr : float
    cand : (m, 3) float64, dep : (m,) float64, sel : (4,) int64
        Scratch, ``m`` at least the largest face's vertex count.
    res : (4+, 4) float64
        Receives ``(dist, pos x, y, z)``, the lowest first.

    Returns
    -------
    int
        Contacts written, 0 to 4.
    """
    H = hv.shape[0]
    if H == 0:
        return 0
    c = n[0] * (pos[0] - p0[0]) + n[1] * (pos[1] - p0[1]) + n[2] * (pos[2] - p0[2])
    best = np.inf
    ib = 0
    for i in range(H):
        ld = 0.0
        for q in range(3):
            ld += n[q] * (rot[q, 0] * hv[i, 0] + rot[q, 1] * hv[i, 1] + rot[q, 2] * hv[i, 2])
        if ld < best:
            best = ld
            ib = i
    d = c + best
    if d > thr:
        return 0
    # the face through the lowest vertex most opposed to n
    fb = -1
    al_best = -PLANE_FACE_TOL
    for f in range(f0, f0 + nf):
        has = False
        for r in range(f_vnum[f]):
            if f_vidx[f_vadr[f] + r] == ib:
                has = True
                break
        if not has:
            continue
        al = 0.0
        for q in range(3):
            al += n[q] * (rot[q, 0] * f_normal[f, 0] + rot[q, 1] * f_normal[f, 1] + rot[q, 2] * f_normal[f, 2])
        if al <= al_best:
            al_best = al
            fb = f
    m = 0
    if fb >= 0:
        for r in range(f_vnum[fb]):
            j = f_vidx[f_vadr[fb] + r]
            dj = c
            for q in range(3):
                cand[m, q] = pos[q] + rot[q, 0] * hv[j, 0] + rot[q, 1] * hv[j, 1] + rot[q, 2] * hv[j, 2]
                dj += n[q] * (cand[m, q] - pos[q])
            if j == ib:
                dj = d  # the lowest: exactly as found
            elif not dj <= thr:
                continue
            dep[m] = dj
            m += 1
    if m == 0:
        for q in range(3):
            cand[0, q] = pos[q] + rot[q, 0] * hv[ib, 0] + rot[q, 1] * hv[ib, 1] + rot[q, 2] * hv[ib, 2]
        dep[0] = d
        m = 1
    k = reduce_four(cand, dep, m, sel)
    for r in range(k):
        i = sel[r]
        res[r, 0] = dep[i]
        for q in range(3):
            res[r, 1 + q] = cand[i, q] - 0.5 * dep[i] * n[q]
    return k


@njit(cache=True)
def _world_face(hv, a, vidx, vadr, vnum, f, rot, pos, out):
    # Face f's polygon in the world (rows of out), its vertex count returned.
    for r in range(vnum[f]):
        i = a + vidx[vadr[f] + r]
        for q in range(3):
            out[r, q] = pos[q] + rot[q, 0] * hv[i, 0] + rot[q, 1] * hv[i, 1] + rot[q, 2] * hv[i, 2]
    return vnum[f]


@njit(cache=True)
def _touching_faces(g, x, u, xpos, xmat, hv_adr, f_adr, f_num, f_normal, f_offset, tol, cand, cnrm):
    # Faces of geom g whose plane holds the witness x (within tol), their world normals in cnrm;
    # returns their count (cand: face ids) and puts the one best aligned with u first.
    rot = xmat[g]
    k = 0
    best = -2.0
    for f in range(f_adr[g], f_adr[g] + f_num[g]):
        nw0 = rot[0, 0] * f_normal[f, 0] + rot[0, 1] * f_normal[f, 1] + rot[0, 2] * f_normal[f, 2]
        nw1 = rot[1, 0] * f_normal[f, 0] + rot[1, 1] * f_normal[f, 1] + rot[1, 2] * f_normal[f, 2]
        nw2 = rot[2, 0] * f_normal[f, 0] + rot[2, 1] * f_normal[f, 1] + rot[2, 2] * f_normal[f, 2]
        off = nw0 * xpos[g, 0] + nw1 * xpos[g, 1] + nw2 * xpos[g, 2] + f_offset[f]
        if abs(nw0 * x[0] + nw1 * x[1] + nw2 * x[2] - off) > tol or k >= cand.shape[0]:
            continue
        cand[k] = f
        cnrm[k, 0], cnrm[k, 1], cnrm[k, 2] = nw0, nw1, nw2
        al = nw0 * u[0] + nw1 * u[1] + nw2 * u[2]
        if al > best:
            best = al
            if k > 0:  # swap to the front
                cand[0], cand[k] = cand[k], cand[0]
                for q in range(3):
                    cnrm[0, q], cnrm[k, q] = cnrm[k, q], cnrm[0, q]
        k += 1
    return k


@njit(cache=True)
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
    mn = np.empty(3)
    for q in range(3):
        mn[q] = -nrm[q]
    c1 = _touching_faces(g1, pa, nrm, xpos, xmat, hv_adr, f_adr, f_num, f_normal, f_offset, tol, cand1, cnrm1)
    c2 = _touching_faces(g2, pb, mn, xpos, xmat, hv_adr, f_adr, f_num, f_normal, f_offset, tol, cand2, cnrm2)
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


@njit(cache=True)
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



@njit(cache=True)
def _polytope(t):
    return t == T_BOX or t == T_MESH


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
        Contacts written; ``-(8 g + ERR_POSE) - 1`` for a non-finite pose of geom ``g``.
    """
    G = cls.shape[0]
    P = pair_key.shape[0]
    k = 0
    cap = 1
    for g in range(G):
        if pts_num[g] > cap:
            cap = pts_num[g]
    cand = np.empty((cap, 3))
    dep = np.empty(cap)
    sel = np.zeros(4, np.int64)
    res = np.empty((MAX_PER_PAIR, 4))
    bnrm = np.empty(3)
    bws = np.empty(BOX_WS)
    seg = np.empty((2, 3))
    fmax = 4
    for f in range(f_vnum.shape[0]):
        if f_vnum[f] > fmax:
            fmax = f_vnum[f]
    pcand = np.empty((fmax, 3))
    pdep = np.empty(fmax)
    face1 = np.empty((fmax, 3))
    face2 = np.empty((fmax, 3))
    poly = np.empty((2 * fmax + 8, 3))
    tmp = np.empty((2 * fmax + 8, 3))
    cand1 = np.empty(32, np.int64)
    cand2 = np.empty(32, np.int64)
    cnrm1 = np.empty((32, 3))
    cnrm2 = np.empty((32, 3))
    pa = np.empty(3)
    pb = np.empty(3)
    nv = np.empty(3)
    out = np.empty(OUT_SIZE)
    d0 = np.zeros(3)
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
        if not _finite_pose(xpos, xmat, g1):
            return -(8 * g1 + ERR_POSE) - 1
        if not _finite_pose(xpos, xmat, g2):
            return -(8 * g2 + ERR_POSE) - 1
        # the pair's margin and gap: an explicit pair's own, else the geoms' sums; a geom pair
        # listed in several <pair>s is collided once for each, with its own (as MuJoCo does)
        lo = min(g1, g2)
        hi = max(g1, g2)
        key = lo * G + hi
        j = np.searchsorted(pair_key, key) if P > 0 else 0
        nent = 1
        explicit = j < P and pair_key[j] == key
        if explicit:
            while j + nent < P and pair_key[j + nent] == key:
                nent += 1
        for e in range(nent):
            if explicit:
                margin = pair_margin[j + e]
                gap = pair_gap[j + e]
            else:
                margin = geom_margin[g1] + geom_margin[g2]
                gap = geom_gap[g1] + geom_gap[g2]
            if override:
                margin = o_margin
            thr = margin + gap
            if c1 == PLANE or c2 == PLANE:
                gp = g1 if c1 == PLANE else g2
                gc = g2 if c1 == PLANE else g1
                sg = 1.0 if c1 == PLANE else -1.0  # the normal from the first geom to the second
                n = xmat[gp, :, 2].copy()
                p0 = xpos[gp]
                cd = n[0] * (xpos[gc, 0] - p0[0]) + n[1] * (xpos[gc, 1] - p0[1]) + n[2] * (xpos[gc, 2] - p0[2])
                if cd - rbound[gc] > thr:
                    continue
                if gtype[gc] == T_MESH and hv_num[gc] > 0:
                    a = hv_adr[gc]
                    m = plane_mesh(hv[a:a + hv_num[gc]], f_adr[gc], f_num[gc], f_normal, f_vadr, f_vnum, f_vidx,
                                   xmat[gc], xpos[gc], n, p0, thr, pcand, pdep, sel, res)
                else:
                    sc = _shape(gc, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr,
                                nbr_adr, nbr_num, xpos, xmat)
                    m = plane_convex(rule[gc], below[gc], sc, n, p0, thr, cand, dep, sel, res)
                for i in range(m):
                    _emit(k, g1, g2, res[i, 0], res[i, 1], res[i, 2], res[i, 3], sg * n[0], sg * n[1], sg * n[2],
                          margin, out_geom, out_dist, out_pos, out_normal, out_margin)
                    k += 1
                continue
            # two convex geoms: a bounding-sphere test, then the signed distance
            cc = math.sqrt((xpos[g2, 0] - xpos[g1, 0]) ** 2 + (xpos[g2, 1] - xpos[g1, 1]) ** 2
                           + (xpos[g2, 2] - xpos[g1, 2]) ** 2)
            if cc - rbound[g1] - rbound[g2] > thr:
                continue
            t1 = gtype[g1]
            t2 = gtype[g2]
            if t1 == T_BOX and t2 == T_BOX:
                # MuJoCo's box-box: separating axes and a clipped face (up to 8 contacts)
                m = box_box(xpos[g1], xmat[g1], half[g1], xpos[g2], xmat[g2], half[g2], thr, res, bnrm, bws)
                for i in range(m):
                    _emit(k, g1, g2, res[i, 0], res[i, 1], res[i, 2], res[i, 3], bnrm[0], bnrm[1], bnrm[2], margin,
                          out_geom, out_dist, out_pos, out_normal, out_margin)
                    k += 1
                continue
            s1 = _shape(g1, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr,
                        nbr_adr, nbr_num, xpos, xmat)
            s2 = _shape(g2, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr, nbr_start_num, nbr,
                        nbr_adr, nbr_num, xpos, xmat)
            pair_distance(s1, s2, 1e-12 * (size[g1] + size[g2]), d0, -1, -1, 128, out)
            d = out[OUT_DISTANCE]
            if d > thr:
                continue
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


@njit(cache=True)
def pair_signed_distance(g1, g2, xpos, xmat, cls, kind, prm, pts, pts_adr, pts_num, nbr_start, nbr_start_adr,
                         nbr_start_num, nbr, nbr_adr, nbr_num, size, out):
    """Signed distance of geoms ``g1`` and ``g2`` and the nearest points (for ``mj_geomDistance``).

    Parameters
    ----------
    (see `collide_pairs`)
    out : (7,) float64
        Receives ``dist`` and ``fromto`` (a point on ``g1``, a point on ``g2``, world frame).

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
    pair_distance(s1, s2, 1e-12 * (size[g1] + size[g2]), np.zeros(3), -1, -1, 128, res)
    out[0] = res[OUT_DISTANCE]
    for q in range(3):
        out[1 + q] = res[OUT_POINT_A + q]
        out[4 + q] = res[OUT_POINT_B + q]
    return 0
