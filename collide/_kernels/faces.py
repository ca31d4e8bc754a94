"""Face contacts (numba): box-box by separating axes and clipping, polytope faces clipped.

Both follow what MuJoCo 4 makes for these pairs (the behaviour, read from
``src/engine/engine_collision_box.c`` ``mjc_BoxBox`` and ``engine_collision_gjk.c``
``multicontact``; the code here is ours):

* `box_box`: the axis of largest separation among the 15 of the separating-axis theorem
  (Gottschalk, Lin and Manocha 1996, "OBBTree", section 4). A face axis wins near-ties with an
  edge axis (an edge axis must beat it by a relative 1e-6, and an edge axis within about 8
  degrees of the best face axis that is not 5 % deeper gives way to it): a face gives a
  manifold. Face axis: the other box's face most opposed to the reference face is clipped to
  the reference face's rectangle (Sutherland and Hodgman 1974), and every clipped corner within
  the contact distance is a contact (up to 8), its ``dist`` its height above the reference face
  and its position midway. Edge axis: one contact at the closest points of the two supporting
  edges.
* `clip_faces`: a polygon (a face of one polytope, or an edge) clipped to the prism over another
  face's polygon; the points below that face are the contacts, at most 4 (the largest-area
  quadrilateral of the clipped polygon) or 2 for an edge (its two farthest points).

Everything is in flat arrays; no allocation per call beyond the caller's scratch.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._ptr import NO_NRT

# Most contacts of one box-box manifold: a quadrilateral clipped by 4 half-planes.
BOX_MAX = 8
# Length of `box_box`'s workspace.
BOX_WS = 48 + 12 + 6 * (BOX_MAX + 4)
# Relative slack of the separation tests (rounding of sums of products of the half sizes).
_SEP_EPS = 1e-13
# An edge-cross axis of two edges closer to parallel than this (sin^2) is rounding noise.
_PAR_EPS = 1e-16
# An edge axis must beat the best face axis by this relative amount (a face wins ties).
_EDGE_BIAS = 1e-6
# |cos| above which an edge axis stands for the best face axis, unless 5 % deeper.
_EDGE_FACE_COS = 0.99
_EDGE_FACE_GAIN = 0.05
# Axis components below which a box's supporting corner is ambiguous (both are tried).
_SGN_EPS = 1e-9
# Squared duplicate radius of clipped corners, relative to the reference face's size.
_DUP_EPS = 1e-14


@njit(**NO_NRT)
def _clip_plane(poly, n, tmp, s0, s1, s2, off, segment):
    # One Sutherland-Hodgman step (Sutherland and Hodgman 1974): the first n rows of poly (x, y, z)
    # clipped to the half-space s . p <= off; the result back in poly, its count returned (tmp:
    # scratch of the same shape). A vertex on the plane is kept; an edge crossing it strictly adds
    # the crossing point. With segment, two rows are an open segment (no closing edge back).
    m = 0
    for k in range(n):
        k1 = k + 1 if k + 1 < n else 0
        if segment and n == 2 and k == 1:
            k1 = 1
        dp = s0 * poly[k, 0] + s1 * poly[k, 1] + s2 * poly[k, 2] - off
        dq = s0 * poly[k1, 0] + s1 * poly[k1, 1] + s2 * poly[k1, 2] - off
        if dp <= 0.0:
            for q in range(3):
                tmp[m, q] = poly[k, q]
            m += 1
        if (dp < 0.0 < dq) or (dq < 0.0 < dp):
            t = dp / (dp - dq)
            for q in range(3):
                tmp[m, q] = poly[k, q] + t * (poly[k1, q] - poly[k, q])
            m += 1
    for k in range(m):
        for q in range(3):
            poly[k, q] = tmp[k, q]
    return m


@njit(**NO_NRT)
def _clip_half(poly, n, tmp, coord, sign, limit):
    # Clip the first n rows of poly (x, y, z) to sign * p[coord] <= limit, z carried along (a
    # side of the reference rectangle); the result back in poly, its count returned.
    inside = True
    for k in range(n):
        if sign * poly[k, coord] - limit > 0.0:
            inside = False
            break
    if inside:
        return n
    # the axis as a plane normal: its zero components add exact zeros to the one product
    return _clip_plane(poly, n, tmp, sign if coord == 0 else 0.0, sign if coord == 1 else 0.0,
                       sign if coord == 2 else 0.0, limit, False)


@njit(**NO_NRT)
def box_box(p1, r1, h1, p2, r2, h2, thr, res, normal, ws):
    """Contacts of two boxes.

    Parameters
    ----------
    p1, p2 : (3,) float64
        Centres, world frame.
    r1, r2 : (3, 3) float64
        Rotations (columns: the box axes in the world).
    h1, h2 : (3,) float64
        Half sizes.
    thr : float
        Contact distance: contacts at ``dist <= thr``.
    res : (8, 4) float64
        Receives ``(dist, pos x, y, z)`` per contact.
    normal : (3,) float64
        Receives the contacts' common normal, unit, from box 1 to box 2.
    ws : (BOX_WS,) float64
        Workspace (allocated once by the caller).

    Returns
    -------
    int
        Contacts written, 0 to `BOX_MAX`.
    """
    # c[i, j] = a_i . b_j; t1: centre 2 in box 1's frame; t2: centre 1 in box 2's frame
    c = ws[0:9].reshape((3, 3))
    t1 = ws[9:12]
    t2 = ws[12:15]
    d0 = p2[0] - p1[0]
    d1 = p2[1] - p1[1]
    d2 = p2[2] - p1[2]
    for i in range(3):
        t1[i] = r1[0, i] * d0 + r1[1, i] * d1 + r1[2, i] * d2
        t2[i] = -(r2[0, i] * d0 + r2[1, i] * d1 + r2[2, i] * d2)
        for j in range(3):
            c[i, j] = r1[0, i] * r2[0, j] + r1[1, i] * r2[1, j] + r1[2, i] * r2[2, j]
    tol = thr + _SEP_EPS * (h1[0] + h1[1] + h1[2] + h2[0] + h2[1] + h2[2])
    best = -np.inf
    code = -1
    for i in range(3):  # faces of box 1
        s = abs(t1[i]) - h1[i] - (abs(c[i, 0]) * h2[0] + abs(c[i, 1]) * h2[1] + abs(c[i, 2]) * h2[2])
        if s > tol:
            return 0
        if s > best:
            best, code = s, i
    for j in range(3):  # faces of box 2
        s = abs(t2[j]) - h2[j] - (abs(c[0, j]) * h1[0] + abs(c[1, j]) * h1[1] + abs(c[2, j]) * h1[2])
        if s > tol:
            return 0
        if s > best:
            best, code = s, 3 + j
    face_best = best
    face_code = code
    ax = ws[15:18]
    for i in range(3):  # edges: a_i x b_j, in box 1's frame (e_i x c[:, j])
        i1 = (i + 1) % 3
        i2 = (i + 2) % 3
        for j in range(3):
            u1 = -c[i2, j]
            u2 = c[i1, j]
            nn = u1 * u1 + u2 * u2
            if nn < _PAR_EPS:
                continue  # parallel edges: the face axes cover them
            inv = 1.0 / math.sqrt(nn)
            u1 *= inv
            u2 *= inv
            rad1 = h1[i1] * abs(u1) + h1[i2] * abs(u2)
            rad2 = 0.0
            for q in range(3):
                rad2 += h2[q] * abs(u1 * c[i1, q] + u2 * c[i2, q])
            s = abs(u1 * t1[i1] + u2 * t1[i2]) - rad1 - rad2
            if s > tol:
                return 0
            if s - _EDGE_BIAS * abs(s) > best and s > face_best:
                best, code = s, 6 + 3 * i + j
    if code >= 6:
        # an edge axis close to the best face axis gives way to it unless clearly deeper
        i = (code - 6) // 3
        j = (code - 6) % 3
        _edge_axis(c, i, j, ax)
        if face_code < 3:
            cf = abs(ax[face_code])
        else:
            f = face_code - 3
            cf = abs(ax[0] * c[0, f] + ax[1] * c[1, f] + ax[2] * c[2, f])
        if cf > _EDGE_FACE_COS and best < face_best + _EDGE_FACE_GAIN * abs(face_best) + 1e-15:
            code = face_code
            best = face_best
    if code >= 6:
        return _edge_edge(code, c, t1, p1, r1, h1, h2, tol, ax, res, normal, ws[18:48])
    return _face(code, c, t1, t2, p1, r1, h1, p2, r2, h2, thr, res, normal, ws[48:])


@njit(**NO_NRT)
def _edge_axis(c, i, j, ax):
    # a_i x b_j in box 1's frame, unit
    i1 = (i + 1) % 3
    i2 = (i + 2) % 3
    ax[i] = 0.0
    ax[i1] = -c[i2, j]
    ax[i2] = c[i1, j]
    n = math.sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2])
    for q in range(3):
        ax[q] /= n


@njit(**NO_NRT)
def _edge_edge(code, c, t1, p1, r1, h1, h2, tol, ax, res, normal, ws):
    # One contact: the closest points of the supporting edges (box 1's along e_i, box 2's along
    # b_j), in box 1's frame; an ambiguous corner (an axis component near zero) tried both ways.
    i = (code - 6) // 3
    j = (code - 6) % 3
    i1 = (i + 1) % 3
    i2 = (i + 2) % 3
    j1 = (j + 1) % 3
    j2 = (j + 2) % 3
    _edge_axis(c, i, j, ax)
    if ax[0] * t1[0] + ax[1] * t1[1] + ax[2] * t1[2] < 0.0:
        for q in range(3):
            ax[q] = -ax[q]
    a2 = ws[0:3]  # the axis in box 2's frame
    for q in range(3):
        a2[q] = ax[0] * c[0, q] + ax[1] * c[1, q] + ax[2] * c[2, q]
    amb1 = i1 if abs(ax[i1]) < _SGN_EPS else (i2 if abs(ax[i2]) < _SGN_EPS else -1)
    amb2 = j1 if abs(a2[j1]) < _SGN_EPS else (j2 if abs(a2[j2]) < _SGN_EPS else -1)
    e2 = ws[3:6]  # b_j in box 1's frame
    for q in range(3):
        e2[q] = c[q, j]
    b = e2[i]
    den = 1.0 - b * b
    c1 = ws[6:9]
    cc = ws[9:12]
    c2 = ws[12:15]
    w1 = ws[15:18]
    w2 = ws[18:21]
    bestd = np.inf
    for v1 in range(2 if amb1 >= 0 else 1):
        for v2 in range(2 if amb2 >= 0 else 1):
            c1[i] = 0.0
            c1[i1] = h1[i1] if ax[i1] >= 0.0 else -h1[i1]
            c1[i2] = h1[i2] if ax[i2] >= 0.0 else -h1[i2]
            if v1 == 1:
                c1[amb1] = -c1[amb1]
            cc[j] = 0.0
            cc[j1] = -h2[j1] if a2[j1] >= 0.0 else h2[j1]
            cc[j2] = -h2[j2] if a2[j2] >= 0.0 else h2[j2]
            if v2 == 1:
                cc[amb2] = -cc[amb2]
            for q in range(3):
                c2[q] = c[q, 0] * cc[0] + c[q, 1] * cc[1] + c[q, 2] * cc[2] + t1[q]
            de1 = c2[i] - c1[i]
            de2 = e2[0] * (c2[0] - c1[0]) + e2[1] * (c2[1] - c1[1]) + e2[2] * (c2[2] - c1[2])
            s = 0.0 if den < 1e-15 else (de1 - b * de2) / den
            s = min(max(s, -h1[i]), h1[i])
            t = min(max(b * s - de2, -h2[j]), h2[j])
            s = min(max(de1 + b * t, -h1[i]), h1[i])
            g2 = 0.0
            for q in range(3):
                x1 = c1[q] + (s if q == i else 0.0)
                x2 = c2[q] + t * e2[q]
                g2 += (x2 - x1) ** 2
            if g2 < bestd:
                bestd = g2
                for q in range(3):
                    w1[q] = c1[q] + (s if q == i else 0.0)
                    w2[q] = c2[q] + t * e2[q]
    dist = (w2[0] - w1[0]) * ax[0] + (w2[1] - w1[1]) * ax[1] + (w2[2] - w1[2]) * ax[2]
    if dist > tol:
        return 0
    res[0, 0] = dist
    for q in range(3):
        mq = 0.5 * (w1[0] + w2[0]) * r1[q, 0] + 0.5 * (w1[1] + w2[1]) * r1[q, 1] + 0.5 * (w1[2] + w2[2]) * r1[q, 2]
        res[0, 1 + q] = mq + p1[q]
        normal[q] = r1[q, 0] * ax[0] + r1[q, 1] * ax[1] + r1[q, 2] * ax[2]
    return 1


@njit(**NO_NRT)
def _face(code, c, t1, t2, p1, r1, h1, p2, r2, h2, thr, res, normal, ws):
    # Reference box: the owner of the winning face (axis a); the other box's face most opposed
    # to it is clipped to the reference face, in the reference frame: (x, y) along the face's two
    # axes, z the height above the face (negative inside the reference box).
    ref1 = code < 3
    a = code if ref1 else code - 3
    if ref1:
        href, hinc, pref, rref, to = h1, h2, p1, r1, t1
    else:
        href, hinc, pref, rref, to = h2, h1, p2, r2, t2
    # rinc[r, k]: component r (reference frame) of the incident box's axis k
    rinc = ws[0:9].reshape((3, 3))
    for r in range(3):
        for k in range(3):
            rinc[r, k] = c[r, k] if ref1 else c[k, r]
    sgn = 1.0 if to[a] >= 0.0 else -1.0
    binc = 0
    for k in range(1, 3):
        if abs(rinc[a, k]) > abs(rinc[a, binc]):
            binc = k
    tinc = -1.0 if sgn * rinc[a, binc] > 0.0 else 1.0
    ax_ = (a + 1) % 3
    ay_ = (a + 2) % 3
    bu = (binc + 1) % 3
    bv = (binc + 2) % 3
    nv = BOX_MAX + 4
    poly = ws[9:9 + 3 * nv].reshape((nv, 3))
    tmp = ws[9 + 3 * nv:9 + 6 * nv].reshape((nv, 3))
    for k in range(4):
        su = 1.0 if k == 0 or k == 3 else -1.0
        sv = 1.0 if k < 2 else -1.0
        for r in range(3):
            cr = ax_ if r == 0 else (ay_ if r == 1 else a)
            v = (to[cr] + tinc * hinc[binc] * rinc[cr, binc] + su * hinc[bu] * rinc[cr, bu]
                 + sv * hinc[bv] * rinc[cr, bv])
            if r == 2:
                v = sgn * v - href[a]
            poly[k, r] = v
    n = 4
    n = _clip_half(poly, n, tmp, 0, 1.0, href[ax_])
    n = _clip_half(poly, n, tmp, 0, -1.0, href[ax_])
    n = _clip_half(poly, n, tmp, 1, 1.0, href[ay_])
    n = _clip_half(poly, n, tmp, 1, -1.0, href[ay_])
    dup = _DUP_EPS * (href[ax_] * href[ax_] + href[ay_] * href[ay_])
    ns = sgn if ref1 else -sgn
    for q in range(3):
        normal[q] = ns * rref[q, a]
    m = 0
    loc = ws[9 + 6 * nv:12 + 6 * nv]
    for k in range(n):
        if poly[k, 2] > thr:
            continue
        seen = False
        for q in range(m):
            # res rows keep (dist, world pos): compare in the reference plane via the stored poly
            if (tmp[q, 0] - poly[k, 0]) ** 2 + (tmp[q, 1] - poly[k, 1]) ** 2 < dup:
                seen = True
                break
        if seen or m >= BOX_MAX:
            continue
        tmp[m, 0] = poly[k, 0]
        tmp[m, 1] = poly[k, 1]
        loc[ax_] = poly[k, 0]
        loc[ay_] = poly[k, 1]
        loc[a] = sgn * (href[a] + 0.5 * poly[k, 2])
        res[m, 0] = poly[k, 2]
        for q in range(3):
            res[m, 1 + q] = rref[q, 0] * loc[0] + rref[q, 1] * loc[1] + rref[q, 2] * loc[2] + pref[q]
        m += 1
    return m


@njit(**NO_NRT)
def quad_max_area(poly, n, sel):
    """The 4 of ``n`` >= 4 convex-polygon vertices (in order) spanning the largest quadrilateral.

    Exhaustive over ordered 4-subsets: the polygons clipped here have at most a few dozen
    vertices (a face of a convex mesh clipped by another).

    Parameters
    ----------
    poly : (m, 3) float64
        Polygon vertices in order around it (first ``n`` rows read).
    n : int
    sel : (4,) int64
        Receives the chosen rows, in polygon order.
    """
    best = -1.0
    for a in range(n - 3):
        for b in range(a + 1, n - 2):
            for cc in range(b + 1, n - 1):
                for d in range(cc + 1, n):
                    # twice the area: |(c - a) x (d - b)|
                    x0 = poly[cc, 0] - poly[a, 0]
                    x1 = poly[cc, 1] - poly[a, 1]
                    x2 = poly[cc, 2] - poly[a, 2]
                    y0 = poly[d, 0] - poly[b, 0]
                    y1 = poly[d, 1] - poly[b, 1]
                    y2 = poly[d, 2] - poly[b, 2]
                    z0 = x1 * y2 - x2 * y1
                    z1 = x2 * y0 - x0 * y2
                    z2 = x0 * y1 - x1 * y0
                    ar = z0 * z0 + z1 * z1 + z2 * z2
                    if ar > best:
                        best = ar
                        sel[0], sel[1], sel[2], sel[3] = a, b, cc, d


@njit(**NO_NRT)
def clip_faces(ref, nref, nrm, inc, ninc, poly, tmp, res, sel):
    """Clip polygon ``inc`` to the prism over the face ``ref``; the points below ``ref``'s plane.

    Parameters
    ----------
    ref : (m, 3) float64
        The reference face's vertices, world frame, in order (counter-clockwise about ``nrm``).
    nref : int
        Its vertex count, ``>= 3``.
    nrm : (3,) float64
        Its outward unit normal.
    inc : (k, 3) float64
        The incident polygon (a face, or an edge when ``ninc == 2``), world frame, in order.
    ninc : int
    poly, tmp : (M, 3) float64
        Scratch, ``M >= ninc + nref``.
    res : (4, 4) float64
        Receives ``(depth, x, y, z)``: the depth (signed height above ``ref``'s plane, at most
        0) and the clipped point (on the incident polygon).
    sel : (4,) int64
        Scratch.

    Returns
    -------
    int
        Points written: at most 4 (the largest quadrilateral of the clipped polygon), 2 for an
        edge (its two farthest points).
    """
    for k in range(ninc):
        for q in range(3):
            poly[k, q] = inc[k, q]
    n = ninc
    for e in range(nref):
        e1 = e + 1 if e + 1 < nref else 0
        # side plane through edge (ref[e], ref[e1]) containing nrm, normal pointing out of the face
        u0 = ref[e1, 0] - ref[e, 0]
        u1 = ref[e1, 1] - ref[e, 1]
        u2 = ref[e1, 2] - ref[e, 2]
        s0 = u1 * nrm[2] - u2 * nrm[1]
        s1 = u2 * nrm[0] - u0 * nrm[2]
        s2 = u0 * nrm[1] - u1 * nrm[0]
        sl = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        if sl == 0.0:
            continue
        s0 /= sl
        s1 /= sl
        s2 /= sl
        off = s0 * ref[e, 0] + s1 * ref[e, 1] + s2 * ref[e, 2]
        n = _clip_plane(poly, n, tmp, s0, s1, s2, off, True)  # an edge (n == 2): an open segment
        if n == 0:
            return 0
    # keep the points below the reference plane
    off = nrm[0] * ref[0, 0] + nrm[1] * ref[0, 1] + nrm[2] * ref[0, 2]
    m = 0
    for k in range(n):
        h = nrm[0] * poly[k, 0] + nrm[1] * poly[k, 1] + nrm[2] * poly[k, 2] - off
        if h <= 0.0:
            for q in range(3):
                tmp[m, q] = poly[k, q]
            poly[m, 0] = h  # poly's column 0 reused for the depths
            m += 1
    if m == 0:
        return 0
    if ninc == 2 and m > 2:
        bi, bj, bd = 0, 1, -1.0
        for i in range(m):
            for j in range(i + 1, m):
                dd = (tmp[i, 0] - tmp[j, 0]) ** 2 + (tmp[i, 1] - tmp[j, 1]) ** 2 + (tmp[i, 2] - tmp[j, 2]) ** 2
                if dd > bd:
                    bi, bj, bd = i, j, dd
        res[0, 0] = poly[bi, 0]
        res[1, 0] = poly[bj, 0]
        for q in range(3):
            res[0, 1 + q] = tmp[bi, q]
            res[1, 1 + q] = tmp[bj, q]
        return 2
    if m > 4:
        quad_max_area(tmp, m, sel)
        for r in range(4):
            res[r, 0] = poly[sel[r], 0]
            for q in range(3):
                res[r, 1 + q] = tmp[sel[r], q]
        return 4
    for r in range(m):
        res[r, 0] = poly[r, 0]
        for q in range(3):
            res[r, 1 + q] = tmp[r, q]
    return m
