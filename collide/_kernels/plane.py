"""Contacts of a plane and a convex geom (numba), for the narrow phase (`collide._kernels.manifold`).

The plane is the half-space ``z <= 0`` of its frame, normal ``n``; the signed distance is exact
from the support point along ``-n`` (``h_K(-n)``), and the contacts follow the rule of the convex
geom's type (`RULE_*`, `collide.contacts.GeomTable.rule`):

* `RULE_POINTS`, `RULE_VERTICES`: each core point of a sphere or capsule (a capsule's two end
  spheres), or the vertices of a box (those on its side of the centre facing the plane) or of a
  mesh without hull faces, within the contact distance; at most 4 (`reduce_four`), as MuJoCo's
  plane-box;
* `RULE_CYLINDER`: the four points MuJoCo's plane-cylinder test places (the rim points nearest
  the plane on both caps and two more on the nearer cap's rim, at 120 degrees);
* `RULE_SUPPORT`: the single support point;
* a mesh's hull (`plane_mesh`): the lowest vertex and the other vertices of a hull face through
  it that faces the plane.

Each writes ``(dist, pos x, y, z)`` rows, ``pos`` midway between the two surfaces.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._ptr import NO_NRT
from .support import support

# Plane rules of a convex geom (`collide.contacts.GeomTable.rule`).
RULE_SUPPORT, RULE_POINTS, RULE_VERTICES, RULE_CYLINDER = 0, 1, 2, 3

# Plane-mesh: the face through the lowest vertex gives contacts when its normal's dot with the
# plane's is at most -PLANE_FACE_TOL (fitted to MuJoCo 4.0.0's counts: see `plane_mesh`).
PLANE_FACE_TOL = 0.98


@njit(**NO_NRT)
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


@njit(**NO_NRT)
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
    # RULE_SUPPORT: the support point along -n, found in res[0]'s position (no allocation: the
    # function is compiled without reference counting) and moved to the contact's place there
    s = res[0, 1:4]
    _support_minus(shape, n, s)
    d = n[0] * (s[0] - p0[0]) + n[1] * (s[1] - p0[1]) + n[2] * (s[2] - p0[2]) - r
    if d > thr:
        return 0
    res[0, 0] = d
    for q in range(3):
        s[q] -= (r + 0.5 * d) * n[q]
    return 1


@njit(**NO_NRT)
def _support_minus(shape, n, out):
    support(shape, -n[0], -n[1], -n[2], -1, out)


@njit(**NO_NRT)
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


@njit(**NO_NRT)
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

