"""EPA: the penetration depth of overlapping cores, with a certified bracket (numba).

The expanding polytope algorithm (van den Bergen 2001, "Proximity queries and penetration depth
computation on 3D game objects"; Ericson 2005, §9.5) grows a polytope ``P`` of support points of
``C = A - B`` that contains the origin, always splitting the face nearest the origin with the
support point along that face's normal, until the face is a face of ``C`` within ``tol``.

The bracket of the cores' signed distance ``sd = -depth``:

- lower: every face normal ``n`` tried gives ``sd >= -h_C(n)`` (the separating-axis form of
  `collide._kernels.gjk`); the best one is kept;
- upper: the vertices of ``P`` lie in ``C``, and ``P``'s surface is closed and consistently
  oriented by construction. When its faces' solid angles seen from the origin sum to 4π (winding
  number 1) and no triangle comes within ``r`` of the origin, every point of the ball of radius
  ``r`` about the origin has winding number 1 (the ball misses the surface, so the number is
  constant on it), and a point of nonzero winding number lies in the hull of the vertices, hence
  in ``C``: ``sd <= -r``. ``r`` is bounded on the triangles themselves, each by the plane through its
  computed nearest point (`_tri_lower`; a face's plane offset is only used where its rounding
  bound already clears the minimum), so the tiny slivers EPA
  makes near a curved surface, whose planes rounding leaves ill-defined, cost nothing. A polytope
  that fails the check gives no upper bound here: the caller keeps GJK's ``|v|``.

A cone face that would be degenerate, or leave the origin outside, makes the face across its
horizon edge visible too (the new point is on that plane up to rounding); an expansion whose
horizon still fails, or is not one simple cycle, is refused and the loop stops with the bracket
it has.

Warm start across calls (`epa_warm`; `collide._kernels.warm` keeps the rows): a converged,
certified polytope of two point clouds is kept as the vertex indices of its vertices and its
faces; at the next poses the same indices give points of the new ``C`` (so the polytope is again
inside it), and the support along its nearest face's normal with the certificate above decide
whether it answers. The row is checked (indices in range, a closed surface, every face in front
of the origin) before anything is built on it, so a stale or foreign row only costs its check.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._ptr import NO_NRT
from .gjk import s2d
from .support import support

_EPS = float(np.finfo(np.float64).eps)

# Outcome of `epa`; `epa_warm`'s when its polytope gives no certified answer.
CONVERGED, CAPPED, DEGENERATE, WARM_MISS = 0, 1, 2, 3

# A warm start across calls (`epa_warm`): a converged, certified polytope kept as one int64 row
# of a geom pair's cache (`collide._kernels.warm` keeps the rows in the narrow phase's scratch):
# ``E_NV`` vertices (0: empty) and ``E_NF`` faces, then ``WARM_NV``
# vertices as ``index_a | index_b << 32`` (vertex indices of the two point clouds, whose
# difference is the polytope's vertex) and ``WARM_NF`` faces as ``a | b << 8 | c << 16`` (their
# vertices, counter-clockwise seen from outside). Larger polytopes are not kept.
WARM_NV, WARM_NF = 16, 28
E_NV, E_NF, E_VERT = 0, 1, 2
E_FACE = E_VERT + WARM_NV
ENTRY = E_FACE + WARM_NF
# `epa_warm`'s scratch: float64 V, VA, VB (WARM_NV, 3), fn (WARM_NF, 3), fo, fl (WARM_NF,), two
# support points (6); int64 fv (WARM_NF, 3), two edge masks (WARM_NV,), two climb hints.
WARM_F = 3 * (3 * WARM_NV + WARM_NF) + 2 * WARM_NF + 6
WARM_I = 3 * WARM_NF + 2 * WARM_NV + 2


@njit(**NO_NRT)
def _support_c(sa, sb, d0, d1, d2, hints, pa, pb):
    # Support point of C = A - B along d; returns (w0, w1, w2, scale of the world points).
    hints[0] = support(sa, d0, d1, d2, hints[0], pa)
    hints[1] = support(sb, -d0, -d1, -d2, hints[1], pb)
    s = 0.0
    for k in range(3):
        s = max(s, abs(pa[k]), abs(pb[k]))
    return pa[0] - pb[0], pa[1] - pb[1], pa[2] - pb[2], s


@njit(**NO_NRT)
def _add_vertex(V, VA, VB, nv, w0, w1, w2, pa, pb):
    V[nv, 0], V[nv, 1], V[nv, 2] = w0, w1, w2
    for k in range(3):
        VA[nv, k] = pa[k]
        VB[nv, k] = pb[k]
    return nv + 1


@njit(**NO_NRT)
def _plane(V, a, b, c, out):
    # Unit normal of face (a, b, c) (counter-clockwise seen from outside) into out[0:3];
    # returns (offset, |cross|).
    e0, e1, e2 = V[b, 0] - V[a, 0], V[b, 1] - V[a, 1], V[b, 2] - V[a, 2]
    f0, f1, f2 = V[c, 0] - V[a, 0], V[c, 1] - V[a, 1], V[c, 2] - V[a, 2]
    n0 = e1 * f2 - e2 * f1
    n1 = e2 * f0 - e0 * f2
    n2 = e0 * f1 - e1 * f0
    ln = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if ln == 0.0:
        out[0] = out[1] = out[2] = 0.0
        return 0.0, 0.0
    out[0], out[1], out[2] = n0 / ln, n1 / ln, n2 / ln
    return out[0] * V[a, 0] + out[1] * V[a, 1] + out[2] * V[a, 2], ln


@njit(**NO_NRT)
def _offset_error(V, a, b, c, ln, vertex_err):
    # Bound on how far the plane offset of face (a, b, c) can move when each vertex moves by up
    # to vertex_err (rounding of the supports and of the subtraction): the normal turns by up to
    # ~ vertex_err (|e| + |f|) / |e x f|, which the largest |vertex| m turns into offset, plus the
    # offset's own rounding, 8 eps m. One square root a face (this runs on every face of every
    # certificate): m (|e| + |f|) <= sqrt(2 m^2 (|e|^2 + |f|^2)) (Cauchy-Schwarz), and a vertex is
    # the difference of two support points whose coordinates are at most the caller's scale
    # (vertex_err = 8 eps scale), so 8 eps m <= 8 eps 2 sqrt(3) scale < 4 vertex_err.
    m2 = 0.0
    for x in (a, b, c):
        m2 = max(m2, V[x, 0] ** 2 + V[x, 1] ** 2 + V[x, 2] ** 2)
    e2 = (V[b, 0] - V[a, 0]) ** 2 + (V[b, 1] - V[a, 1]) ** 2 + (V[b, 2] - V[a, 2]) ** 2
    f2 = (V[c, 0] - V[a, 0]) ** 2 + (V[c, 1] - V[a, 1]) ** 2 + (V[c, 2] - V[a, 2]) ** 2
    return 4.0 * vertex_err * (2.0 + math.sqrt(2.0 * m2 * (e2 + f2)) / ln)


@njit(**NO_NRT)
def _solid_angle(V, a, b, c):
    # Signed solid angle of triangle (a, b, c) seen from the origin (Van Oosterom & Strackee 1983).
    ax, ay, az = V[a, 0], V[a, 1], V[a, 2]
    bx, by, bz = V[b, 0], V[b, 1], V[b, 2]
    cx, cy, cz = V[c, 0], V[c, 1], V[c, 2]
    det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    lc = math.sqrt(cx * cx + cy * cy + cz * cz)
    den = la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (ax * cx + ay * cy + az * cz) * lb \
        + (bx * cx + by * cy + bz * cz) * la
    return 2.0 * math.atan2(det, den)


@njit(**NO_NRT)
def _tri_lower(V, a, b, c, vertex_err):
    # A certified lower bound of the origin's distance to triangle (a, b, c), for the upper
    # bound's inner ball. s2d's nearest point q is a point of the triangle, so |q| bounds that
    # distance from above, not below: on the slivers EPA makes near a curved surface its weights
    # are off by far more than vertex_err, and |q| over-claimed the ball (a point on a
    # cylinder's side was certified 3.5e-9 deep, 5e-11 of the size). The plane through q with
    # normal q / |q| separates instead: the least n . V over the vertices, which is |q| at the
    # exact nearest point, less the vertices' and the products' rounding.
    l0, l1, l2, d2 = s2d(V, a, b, c)
    q0 = l0 * V[a, 0] + l1 * V[b, 0] + l2 * V[c, 0]
    q1 = l0 * V[a, 1] + l1 * V[b, 1] + l2 * V[c, 1]
    q2 = l0 * V[a, 2] + l1 * V[b, 2] + l2 * V[c, 2]
    nq = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2)
    if not nq > 0.0:
        return -math.inf
    m = math.inf
    big = 0.0
    for x in (a, b, c):
        m = min(m, (q0 * V[x, 0] + q1 * V[x, 1] + q2 * V[x, 2]) / nq)
        big = max(big, abs(V[x, 0]) + abs(V[x, 1]) + abs(V[x, 2]))
    return m - vertex_err - 8.0 * _EPS * big


@njit(**NO_NRT)
def _nearest_triangle(V, fv, fo, nf, near, f):
    # Among the faces whose plane is within ``near`` of the origin (a dead face's offset is +inf:
    # never one, whatever ``near``), the triangle nearest the origin: (face, barycentric weights of
    # its point nearest the origin, squared distance); (f, 0, 0, 0, inf) when none is.
    best = math.inf
    la = lb = lc = 0.0
    for g in range(nf):
        if fo[g] <= near and fo[g] < math.inf:
            l0, l1, l2, d2 = s2d(V, fv[g, 0], fv[g, 1], fv[g, 2])
            if d2 < best:
                best, f, la, lb, lc = d2, g, l0, l1, l2
    return f, la, lb, lc, best


@njit(**NO_NRT)
def _witness(V, VA, VB, fv, fn, fl, f, la, lb, lc, res):
    # The witness of face f's point (la, lb, lc) into res[3:13]: that point carried to A and B,
    # the face's normal and its conditioning (`epa`'s ``res``).
    a, b, c = fv[f, 0], fv[f, 1], fv[f, 2]
    for k in range(3):
        res[3 + k] = la * VA[a, k] + lb * VA[b, k] + lc * VA[c, k]
        res[6 + k] = la * VB[a, k] + lb * VB[b, k] + lc * VB[c, k]
        res[9 + k] = fn[f, k]
    el = 0.0
    for x in (b, c):
        el += math.sqrt((V[x, 0] - V[a, 0]) ** 2 + (V[x, 1] - V[a, 1]) ** 2 + (V[x, 2] - V[a, 2]) ** 2)
    res[12] = el / fl[f] if fl[f] > 0.0 else math.inf


@njit(**NO_NRT)
def _new_face(V, fv, fn, fo, fl, slot, a, b, c):
    fv[slot, 0], fv[slot, 1], fv[slot, 2] = a, b, c
    off, ln = _plane(V, a, b, c, fn[slot])
    fo[slot] = off
    fl[slot] = ln
    return ln


@njit(**NO_NRT)
def _link(fv, fa, f, g):
    # Make faces f and g neighbours across their shared edge (f has (x, y), g has (y, x)).
    for i in range(3):
        x, y = fv[f, i], fv[f, (i + 1) % 3]
        for j in range(3):
            if fv[g, j] == y and fv[g, (j + 1) % 3] == x:
                fa[f, i] = g
                fa[g, j] = f


@njit(**NO_NRT)
def _tetrahedron(V, fv, fa, fn, fo, fl, p, q, r, s):
    # Faces 0..3 of the tetrahedron on vertices p, q, r, s, oriented outwards. The plane of
    # (p, q, r) goes to face 0's normal, which `_new_face` writes afterwards.
    e = fn[0]
    off, ln = _plane(V, p, q, r, e)
    if e[0] * V[s, 0] + e[1] * V[s, 1] + e[2] * V[s, 2] > off:
        q, r = r, q  # s must be behind face (p, q, r)
    _new_face(V, fv, fn, fo, fl, 0, p, q, r)
    _new_face(V, fv, fn, fo, fl, 1, p, s, q)
    _new_face(V, fv, fn, fo, fl, 2, q, s, r)
    _new_face(V, fv, fn, fo, fl, 3, r, s, p)
    for f in range(4):
        for g in range(f + 1, 4):
            _link(fv, fa, f, g)
    return 4


@njit(**NO_NRT)
def _bipyramid(V, fv, fa, fn, fo, fl, p, q, r, top, bottom):
    # Faces 0..5: triangle (p, q, r) with apexes on both sides, oriented outwards (the plane of
    # (p, q, r) in face 0's normal, as in `_tetrahedron`).
    e = fn[0]
    off, ln = _plane(V, p, q, r, e)
    if e[0] * V[top, 0] + e[1] * V[top, 1] + e[2] * V[top, 2] < off:
        q, r = r, q  # top must be in front of (p, q, r)
    _new_face(V, fv, fn, fo, fl, 0, p, q, top)
    _new_face(V, fv, fn, fo, fl, 1, q, r, top)
    _new_face(V, fv, fn, fo, fl, 2, r, p, top)
    _new_face(V, fv, fn, fo, fl, 3, q, p, bottom)
    _new_face(V, fv, fn, fo, fl, 4, r, q, bottom)
    _new_face(V, fv, fn, fo, fl, 5, p, r, bottom)
    for f in range(6):
        for g in range(f + 1, 6):
            _link(fv, fa, f, g)
    return 6


@njit(**NO_NRT)
def _horizon(V, nv, fv, fa, fn, fo, nf, f, seen, forced, stack, hz, tiny, vis):
    # Flood the faces visible from vertex nv (or forced visible) from face f; their horizon
    # edges (a, b, kept face) into hz, the visible faces into vis. Returns (the edge count, -1
    # when hz overflows; the visible face count).
    w0, w1, w2 = V[nv, 0], V[nv, 1], V[nv, 2]
    for g in range(nf):
        seen[g] = False
    seen[f] = True
    stack[0] = f
    vis[0] = f
    nvis = 1
    top = 1
    nh = 0
    while top > 0:
        top -= 1
        x = stack[top]
        for e in range(3):
            g = fa[x, e]
            if seen[g]:
                continue
            if forced[g] or fn[g, 0] * w0 + fn[g, 1] * w1 + fn[g, 2] * w2 - fo[g] > tiny:
                seen[g] = True
                stack[top] = g
                top += 1
                vis[nvis] = g
                nvis += 1
            else:  # horizon edge (a, b) of x, seen from the kept face g
                if nh == hz.shape[0]:
                    return -1, nvis
                hz[nh, 0] = fv[x, e]
                hz[nh, 1] = fv[x, (e + 1) % 3]
                hz[nh, 2] = g
                nh += 1
    return nh, nvis


@njit(**NO_NRT)
def _expand(V, nv, fv, fa, fn, fo, fl, alive, nf, f, seen, forced, stack, hz, tiny, hp, vis):
    # Replace the faces visible from vertex nv (a connected set grown from face f) by a cone of
    # new faces over their horizon. A cone face that would be degenerate (its edges parallel
    # within 1e-10) or leave the origin outside makes the kept face across its horizon edge
    # visible too (w is on that face's plane up to rounding), and the horizon is recomputed.
    # Returns the new face count, or -1 (nothing changed) when that does not settle or the
    # horizon is not one simple cycle.
    for g in range(nf):
        forced[g] = False
    nh = -1
    nvis = 0
    for _ in range(8):
        nh, nvis = _horizon(V, nv, fv, fa, fn, fo, nf, f, seen, forced, stack, hz, tiny, vis)
        if nh < 3:
            return -1
        ok = True
        for i in range(nh):
            a, b = hz[i, 0], hz[i, 1]
            off, ln = _plane(V, a, b, nv, hp[i])
            hp[i, 3] = off
            hp[i, 4] = ln
            ea2 = (V[b, 0] - V[a, 0]) ** 2 + (V[b, 1] - V[a, 1]) ** 2 + (V[b, 2] - V[a, 2]) ** 2
            eb2 = (V[nv, 0] - V[a, 0]) ** 2 + (V[nv, 1] - V[a, 1]) ** 2 + (V[nv, 2] - V[a, 2]) ** 2
            if not ln * ln > 1e-20 * ea2 * eb2 or off < -tiny:
                forced[hz[i, 2]] = True
                ok = False
        if ok:
            break
        nh = -1
    if nh < 3:
        return -1
    # The horizon must be one cycle: every start vertex once, every end vertex some start.
    for i in range(nh):
        starts = 0
        ends = 0
        for j in range(nh):
            if hz[j, 0] == hz[i, 0]:
                starts += 1
            if hz[j, 0] == hz[i, 1]:
                ends += 1
                hz[i, 4] = j  # the next edge around the cycle
        if starts != 1 or ends != 1:
            return -1
    j = 0  # and one cycle, not several: the next edges lead from edge 0 back to it in nh steps
    for i in range(1, nh):
        j = hz[j, 4]
        if j == 0:
            return -1
    # Commit: free the visible faces, fill their slots (and new ones) with the cone.
    # The visible faces' slots, in increasing order (insertion sort; a few faces), reused so.
    nfree = nvis
    for k in range(nvis):
        g = vis[k]
        alive[g] = False
        fo[g] = math.inf  # the nearest-face scan needs no alive test
        j = k
        while j > 0 and stack[j - 1] > g:
            stack[j] = stack[j - 1]
            j -= 1
        stack[j] = g
    for i in range(nh):
        if i < nfree:
            slot = stack[i]
        else:
            slot = nf
            nf += 1
        hz[i, 3] = slot
        fv[slot, 0], fv[slot, 1], fv[slot, 2] = hz[i, 0], hz[i, 1], nv
        fn[slot, 0], fn[slot, 1], fn[slot, 2] = hp[i, 0], hp[i, 1], hp[i, 2]
        fo[slot] = hp[i, 3]
        fl[slot] = hp[i, 4]
        alive[slot] = True
    for i in range(nh):
        slot = hz[i, 3]
        # edge 0 of the cone face, (a, b), is edge (b, a) of the kept face g
        a, b, g = hz[i, 0], hz[i, 1], hz[i, 2]
        fa[slot, 0] = g
        for j in range(3):
            if fv[g, j] == b and fv[g, (j + 1) % 3] == a:
                fa[g, j] = slot
        # the next face around the cone shares edge (b, nv)
        nxt = hz[hz[i, 4], 3]
        fa[slot, 1] = nxt
        fa[nxt, 2] = slot
    # Freed slots the cone did not reuse stay dead (alive False).
    return nf


# With reference counting, which its caller (`collide._kernels.distance.pair_distance_within`) has not: it
# allocates.
@njit(cache=True, _nrt=True)
def epa(sa, sb, W, WA, WB, n, hints, tol, max_vertices, lower, res, keep=None):
    """Penetration depth of two overlapping cores from GJK's final simplex.

    Parameters
    ----------
    sa, sb : tuple
        Shape tuples (`collide._kernels.support`).
    W, WA, WB : (4, 3) float64
        GJK's final simplex (first ``n`` rows), which holds the origin within ``tol``.
    n : int
        1 to 4.
    hints : (2,) int64, or (10,) with ``keep``
        Hill-climb start vertices, updated in place; with ``keep``, ``hints[2 + 2 i]``,
        ``hints[3 + 2 i]`` are the vertex indices of A and B of row ``i`` of the simplex
        (`collide._kernels.gjk.gjk_within`'s ``idx``).
    tol : float
        Absolute tolerance on the gap between a face and the support along its normal.
    max_vertices : int
        Polytope size cap (the bracket stays valid when it is reached).
    lower : float
        Lower bound on the signed distance known so far (GJK's).
    res : (13,) float64
        Receives ``lower, upper`` (``upper`` is ``+inf`` when the polytope is not certified),
        ``estimate`` (minus the nearest face's offset), ``point_a (3)``, ``point_b (3)``,
        ``normal (3)`` (the nearest face's outward normal of ``C``, i.e. from A to B) and that
        normal's conditioning ``(|e| + |f|) / |e x f|`` (its angle is known to about that times
        the vertices' rounding; a tiny sliver's is poor).
    keep : (ENTRY,) int64, optional
        A cache row (``E_*``) of two point clouds: receives the final polytope when it
        converged, its certificate holds with every face in front of the origin and it fits
        (``WARM_NV``, ``WARM_NF``); otherwise emptied (``E_NV`` 0). Omitted: nothing is
        recorded (numba compiles that call without the bookkeeping).

    Returns
    -------
    status : int
        `CONVERGED`, `CAPPED` (size cap or a refused expansion) or `DEGENERATE` (``C`` is flat,
        collinear or a point near the origin: no polytope; ``upper`` is ``+inf`` and the normal is
        the best separating direction found, ``estimate`` 0).
    scale : float
        Largest absolute world coordinate of the supports seen.
    iterations : int
    """
    mv = max(max_vertices, 6)
    # Its buffers, allocated here (uninitialised: zeroing them cost more than the rest of a typical
    # call; every entry is written before it is read, face arrays only below the face count), and
    # the algorithm in `_epa`, compiled without reference counting (`collide._kernels._ptr.NO_NRT`:
    # the views it takes of them cost nothing there). `epa_on` runs it on its caller's scratch.
    nf, ni = epa_sizes(mv)
    return epa_on(sa, sb, W, WA, WB, n, hints, tol, mv, lower, res, np.empty(nf), np.empty(ni, np.int64), keep)


@njit(cache=True, inline="always")
def epa_sizes(max_vertices):
    """Float64 and int64 entries of `epa_on`'s scratch for a cap of ``max_vertices`` (at least 6
    are used: `epa`'s floor)."""
    mv = max(max_vertices, 6)
    mf = 2 * mv
    return _EPA_F_FIXED + _EPA_F_VERTEX * mv + _EPA_F_FACE * mf, _EPA_I_FACE * mf + (3 * mf + 7) // 8


@njit(**NO_NRT)
def epa_on(sa, sb, W, WA, WB, n, hints, tol, max_vertices, lower, res, fws, iws, keep=None):
    """`epa` on the caller's scratch, ``fws`` float64 and ``iws`` int64 (C-contiguous), `epa_sizes`
    long at least (nothing allocated: the narrow phase's workspace holds them). Scratch too short for the cap
    lowers it to what fits (a capped answer, its bracket wider), and too short for 6 vertices
    gives `DEGENERATE` (no polytope: ``upper`` ``+inf``, the normal +z): never a write past the
    end."""
    mv = max(max_vertices, 6)
    nf, ni = epa_sizes(mv)
    if fws.shape[0] < nf or iws.shape[0] < ni:
        # what fits: floats FIXED + 29 mv; ints 32 mv, then 6 mv bools packed 8 an entry (<= 33 mv)
        mv = min(mv, (fws.shape[0] - _EPA_F_FIXED) // (_EPA_F_VERTEX + 2 * _EPA_F_FACE), iws.shape[0] // 33)
    if mv < 6:
        res[0], res[1], res[2] = lower, math.inf, 0.0
        for k in range(3):
            res[3 + k] = WA[0, k]
            res[6 + k] = WB[0, k]
            res[9 + k] = 0.0
        res[11] = 1.0
        res[12] = 0.0
        if keep is not None:
            keep[E_NV] = 0
        return DEGENERATE, 0.0, 0
    mf = 2 * mv
    nf, ni = epa_sizes(mv)
    fbuf = fws[:nf]
    ibuf = iws[:_EPA_I_FACE * mf]
    bbuf = iws[_EPA_I_FACE * mf:ni].view(np.bool_)[:3 * mf].reshape((3, mf))
    return _epa(sa, sb, W, WA, WB, n, hints, tol, mv, lower, res, fbuf, ibuf, bbuf, keep)


@njit(**NO_NRT)
def _cross(a, b, out):
    # out = a x b, (3,) each (numpy's np.cross, term for term).
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


# `_epa`'s buffers, per vertex and face of its polytope (``mv`` vertices, ``mf = 2 mv`` faces):
# float64 V, VA, VB (mv, 3); fn (mf, 3), hp (mf, 5) (the cone faces' planes: normal, offset,
# |cross|), fo, fl (mf,); then fixed: pa, pb, best_n and the degenerate simplex's directions d, e,
# u, t, x (3 each). int64 fv, fa, vi (mf, 3), hz (mf, 5: horizon edge a, b, kept face, new slot,
# next edge), stack, vis (mf,). bool alive, seen, forced (mf,).
_EPA_F_VERTEX, _EPA_F_FACE, _EPA_F_FIXED = 9, 10, 24
_EPA_I_FACE = 16


@njit(**NO_NRT)
def _epa(sa, sb, W, WA, WB, n, hints, tol, mv, lower, res, fbuf, ibuf, bbuf, keep):
    # `epa` on its buffers (``mv`` polytope vertices at most; layout above).
    mf = 2 * mv
    V = fbuf[0:3 * mv].reshape((mv, 3))
    VA = fbuf[3 * mv:6 * mv].reshape((mv, 3))
    VB = fbuf[6 * mv:9 * mv].reshape((mv, 3))
    o = _EPA_F_VERTEX * mv
    fn = fbuf[o:o + 3 * mf].reshape((mf, 3))
    hp = fbuf[o + 3 * mf:o + 8 * mf].reshape((mf, 5))
    fo = fbuf[o + 8 * mf:o + 9 * mf]
    fl = fbuf[o + 9 * mf:o + 10 * mf]
    o += _EPA_F_FACE * mf
    pa = fbuf[o:o + 3]
    pb = fbuf[o + 3:o + 6]
    best_n = fbuf[o + 6:o + 9]
    d = fbuf[o + 9:o + 12]
    e = fbuf[o + 12:o + 15]
    u = fbuf[o + 15:o + 18]
    t = fbuf[o + 18:o + 21]
    x = fbuf[o + 21:o + 24]
    fv = ibuf[0:3 * mf].reshape((mf, 3))
    fa = ibuf[3 * mf:6 * mf].reshape((mf, 3))
    vi = ibuf[6 * mf:9 * mf].reshape((mf, 3))  # with ``keep``: each vertex's indices in A, B (columns 0, 1)
    hz = ibuf[9 * mf:14 * mf].reshape((mf, 5))
    stack = ibuf[14 * mf:15 * mf]
    vis = ibuf[15 * mf:16 * mf]
    if keep is not None:
        keep[E_NV] = 0
    alive = bbuf[0]
    seen = bbuf[1]
    forced = bbuf[2]
    scale = 0.0
    for i in range(n):
        _add_vertex(V, VA, VB, i, W[i, 0], W[i, 1], W[i, 2], WA[i], WB[i])
        if keep is not None:
            vi[i, 0], vi[i, 1] = hints[2 + 2 * i], hints[3 + 2 * i]
        for k in range(3):
            scale = max(scale, abs(WA[i, k]), abs(WB[i, k]))
    nv = n
    best_n[0] = best_n[1] = 0.0
    best_n[2] = 1.0
    # Blow a lower-dimensional simplex up to a full polytope around the origin (Ericson §9.5.1):
    # supports along directions off its affine hull; none found means C is that thin there.
    # (Vectors element by element, in the buffer's slots: nothing is allocated here.)
    if nv == 1:
        for ax in range(6):
            d[0] = d[1] = d[2] = 0.0
            d[ax % 3] = 1.0 if ax < 3 else -1.0
            w0, w1, w2, s = _support_c(sa, sb, d[0], d[1], d[2], hints, pa, pb)
            scale = max(scale, s)
            if -(d[0] * w0 + d[1] * w1 + d[2] * w2) > lower:
                lower = -(d[0] * w0 + d[1] * w1 + d[2] * w2)
                best_n[0], best_n[1], best_n[2] = d[0], d[1], d[2]
            if math.sqrt((w0 - V[0, 0]) ** 2 + (w1 - V[0, 1]) ** 2 + (w2 - V[0, 2]) ** 2) > tol:
                nv = _add_vertex(V, VA, VB, nv, w0, w1, w2, pa, pb)
                if keep is not None:
                    vi[nv - 1, 0], vi[nv - 1, 1] = hints[0], hints[1]
                break
    if nv == 2:
        # e the segment's unit direction; u, t unit and perpendicular to it and to each other
        for q in range(3):
            e[q] = V[1, q] - V[0, q]
        le = math.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2)
        for q in range(3):
            e[q] /= le
        k = 0  # the axis least along e (the first of equals)
        if abs(e[1]) < abs(e[k]):
            k = 1
        if abs(e[2]) < abs(e[k]):
            k = 2
        x[0] = x[1] = x[2] = 0.0
        x[k] = 1.0
        _cross(e, x, u)
        lu = math.sqrt(u[0] ** 2 + u[1] ** 2 + u[2] ** 2)
        for q in range(3):
            u[q] /= lu
        _cross(e, u, t)
        for r in range(6):
            ang = r * math.pi / 3.0
            ca = math.cos(ang)
            sn = math.sin(ang)
            for q in range(3):
                d[q] = ca * u[q] + sn * t[q]
            w0, w1, w2, s = _support_c(sa, sb, d[0], d[1], d[2], hints, pa, pb)
            scale = max(scale, s)
            if -(d[0] * w0 + d[1] * w1 + d[2] * w2) > lower:
                lower = -(d[0] * w0 + d[1] * w1 + d[2] * w2)
                best_n[0], best_n[1], best_n[2] = d[0], d[1], d[2]
            x[0], x[1], x[2] = w0 - V[0, 0], w1 - V[0, 1], w2 - V[0, 2]
            xe = x[0] * e[0] + x[1] * e[1] + x[2] * e[2]
            for q in range(3):
                x[q] -= xe * e[q]
            if math.sqrt(x[0] ** 2 + x[1] ** 2 + x[2] ** 2) > tol:
                nv = _add_vertex(V, VA, VB, nv, w0, w1, w2, pa, pb)
                if keep is not None:
                    vi[nv - 1, 0], vi[nv - 1, 1] = hints[0], hints[1]
                break
    nf = 0
    if nv == 3:
        nrm = u
        off, ln = _plane(V, 0, 1, 2, nrm)
        sides = 0
        for sgn in (1.0, -1.0):
            for q in range(3):
                d[q] = sgn * nrm[q]
            w0, w1, w2, s = _support_c(sa, sb, d[0], d[1], d[2], hints, pa, pb)
            scale = max(scale, s)
            h = d[0] * w0 + d[1] * w1 + d[2] * w2
            if -h > lower:
                lower = -h
                best_n[0], best_n[1], best_n[2] = d[0], d[1], d[2]
            if h - sgn * off > tol:
                nv = _add_vertex(V, VA, VB, nv, w0, w1, w2, pa, pb)
                if keep is not None:
                    vi[nv - 1, 0], vi[nv - 1, 1] = hints[0], hints[1]
                sides += 1
        if sides == 2:
            nf = _bipyramid(V, fv, fa, fn, fo, fl, 0, 1, 2, 3, 4)
        elif sides == 1:
            nf = _tetrahedron(V, fv, fa, fn, fo, fl, 0, 1, 2, 3)
    elif nv == 4:
        nf = _tetrahedron(V, fv, fa, fn, fo, fl, 0, 1, 2, 3)
    if nf == 0:
        res[0], res[1], res[2] = lower, math.inf, 0.0
        for k in range(3):
            res[3 + k] = WA[0, k]
            res[6 + k] = WB[0, k]
            res[9 + k] = best_n[k]
        res[12] = 0.0
        return DEGENERATE, scale, 0
    for g in range(nf):
        alive[g] = True
    status = CAPPED
    it = 0
    f = 0
    while True:
        it += 1
        f = 0  # the nearest face (a dead face's offset is +inf: `_expand`)
        fmin = fo[0]
        for g in range(1, nf):
            if fo[g] < fmin:
                fmin = fo[g]
                f = g
        d0, d1, d2 = fn[f, 0], fn[f, 1], fn[f, 2]
        w0, w1, w2, s = _support_c(sa, sb, d0, d1, d2, hints, pa, pb)
        scale = max(scale, s)
        h = d0 * w0 + d1 * w1 + d2 * w2
        if -h > lower:
            lower = -h
        if h - fo[f] <= max(tol, 16.0 * _EPS * scale):
            status = CONVERGED
            break
        if nv == mv:
            break
        _add_vertex(V, VA, VB, nv, w0, w1, w2, pa, pb)
        if keep is not None:
            vi[nv, 0], vi[nv, 1] = hints[0], hints[1]
        tiny = 16.0 * _EPS * scale
        nf_new = _expand(V, nv, fv, fa, fn, fo, fl, alive, nf, f, seen, forced, stack, hz, tiny, hp, vis)
        if nf_new < 0:
            break
        nf = nf_new
        nv += 1
    # Certificate of the upper bound (module docstring): the winding number about the origin
    # and the distance from the origin to the nearest triangle. A face's plane offset minus its
    # rounding bound is a cheap lower bound of that triangle's distance; the triangle itself is
    # measured only where that bound does not already clear the running minimum; the nearest
    # face's first, so that the others' bounds mostly clear it (the minimum, and so the answer, is
    # the same in any order).
    # When every face's plane provably has the origin behind it (offset minus its rounding bound
    # positive), every face's solid angle is positive, so the winding number is at least 1 and the
    # solid angles need not be summed (the ball argument above needs it nonzero only).
    vertex_err = 8.0 * _EPS * scale
    inner = math.inf
    front = True
    for k in range(-1, nf):
        g = f if k < 0 else k
        if (k >= 0 and g == f) or not alive[g]:
            continue
        a, b, c = fv[g, 0], fv[g, 1], fv[g, 2]
        bound = fo[g] - _offset_error(V, a, b, c, fl[g], vertex_err) if fl[g] > 0.0 else -math.inf
        if not bound > 0.0:
            front = False
        if bound < inner:
            bound = max(bound, _tri_lower(V, a, b, c, vertex_err))
            inner = min(inner, bound)
    upper = math.inf
    if inner > 0.0:
        winding = front
        if not front:
            omega = 0.0
            for g in range(nf):
                if alive[g]:
                    omega += _solid_angle(V, fv[g, 0], fv[g, 1], fv[g, 2])
            winding = abs(omega - 4.0 * math.pi) < math.pi
        if winding:
            upper = -inner
    # Witness: the surface point closest to the origin, carried to A and B. The nearest plane's
    # face need not hold the origin's foot point (a face of C split into coplanar triangles):
    # among the faces within the tolerance of the nearest plane, the nearest triangle.
    near = fo[f] + max(tol, 16.0 * _EPS * scale)
    f, la, lb, lc, _ = _nearest_triangle(V, fv, fo, nf, near, f)
    _witness(V, VA, VB, fv, fn, fl, f, la, lb, lc, res)
    res[0], res[1], res[2] = lower, upper, -fo[f]
    if keep is not None:
        if status == CONVERGED and front and upper < math.inf:
            _keep(keep, vi, fv, alive, nf, nv, stack)
    return status, scale, it


@njit(**NO_NRT)
def _keep(keep, vi, fv, alive, nf, nv, remap):
    # The live faces and the vertices they use, renumbered, into the cache row ``keep`` (left
    # empty when they do not fit or a vertex has no point-cloud index).
    for i in range(nv):
        remap[i] = -1
    m = 0
    k = 0
    for g in range(nf):
        if not alive[g]:
            continue
        if k == WARM_NF:
            return
        code = 0
        for j in range(3):
            x = fv[g, j]
            if remap[x] < 0:
                if m == WARM_NV or vi[x, 0] < 0 or vi[x, 1] < 0:
                    return
                remap[x] = m
                keep[E_VERT + m] = vi[x, 0] | (vi[x, 1] << 32)
                m += 1
            code |= remap[x] << (8 * j)
        keep[E_FACE + k] = code
        k += 1
    keep[E_NF] = k
    keep[E_NV] = m  # last: the row is whole


@njit(**NO_NRT)
def epa_warm(sa, sb, entry, tol, res, fws, iws):
    """EPA's answer from a kept polytope (``entry``, the ``E_*`` row `epa` keeps) at new poses.

    The polytope's vertices are rebuilt from their vertex indices in the two point clouds at the
    shapes' poses (each a point of ``C = A - B``, whatever the poses); then the support along its
    nearest face's normal and `epa`'s certificate: the answer when the face is a face of ``C``
    within ``tol`` (EPA's convergence test) and the certificate holds with every face in front of
    the origin. The row is only a hint and is checked first: vertex indices within the clouds,
    face vertices within the row's vertices and distinct, and the faces a closed surface (every
    directed edge once, its reverse once: a 2-cycle, whose winding number about the origin is
    the positive sum of its faces' solid angles when every face is in front of it, so `epa`'s
    ball argument holds). Anything else is `WARM_MISS`: the caller runs GJK and EPA.

    Parameters
    ----------
    sa, sb : tuple
        Shape tuples (`collide._kernels.support`), both ``POINTS``.
    entry : (ENTRY,) int64
        The cache row.
    tol : float
        As `epa` takes it.
    res : (13,) float64
        As `epa` fills it, on `CONVERGED` only.
    fws : (WARM_F,) float64
    iws : (WARM_I,) int64
        Scratch (its caller's: nothing is allocated here).

    Returns
    -------
    status : int
        `CONVERGED` or `WARM_MISS`.
    scale : float
        Largest absolute world coordinate of the points used.
    """
    nv = entry[E_NV]
    nf = entry[E_NF]
    if not (4 <= nv <= WARM_NV and 4 <= nf <= WARM_NF):
        return WARM_MISS, 0.0
    pts_a, rot_a, pos_a = sa[2], sa[5], sa[6]
    pts_b, rot_b, pos_b = sb[2], sb[5], sb[6]
    na = pts_a.shape[0]
    nb = pts_b.shape[0]
    fbuf = fws[0:3 * (3 * WARM_NV + WARM_NF)].reshape((3 * WARM_NV + WARM_NF, 3))
    V = fbuf[0:WARM_NV]
    VA = fbuf[WARM_NV:2 * WARM_NV]
    VB = fbuf[2 * WARM_NV:3 * WARM_NV]
    fn = fbuf[3 * WARM_NV:]
    o = 3 * (3 * WARM_NV + WARM_NF)
    fo = fws[o:o + WARM_NF]
    fl = fws[o + WARM_NF:o + 2 * WARM_NF]
    pp = fws[o + 2 * WARM_NF:o + 2 * WARM_NF + 6]
    fv = iws[0:3 * WARM_NF].reshape((WARM_NF, 3))
    outm = iws[3 * WARM_NF:3 * WARM_NF + WARM_NV]  # directed edges leaving each vertex, as bits
    inm = iws[3 * WARM_NF + WARM_NV:3 * WARM_NF + 2 * WARM_NV]  # and entering it
    hints = iws[3 * WARM_NF + 2 * WARM_NV:3 * WARM_NF + 2 * WARM_NV + 2]
    for i in range(nv):
        code = entry[E_VERT + i]
        ia = code & 0xFFFFFFFF
        ib = code >> 32
        if not (0 <= ia < na and 0 <= ib < nb):
            return WARM_MISS, 0.0
        for k in range(3):  # as `collide._kernels.support.support` poses a vertex
            VA[i, k] = rot_a[k, 0] * pts_a[ia, 0] + rot_a[k, 1] * pts_a[ia, 1] + rot_a[k, 2] * pts_a[ia, 2] + pos_a[k]
            VB[i, k] = rot_b[k, 0] * pts_b[ib, 0] + rot_b[k, 1] * pts_b[ib, 1] + rot_b[k, 2] * pts_b[ib, 2] + pos_b[k]
            V[i, k] = VA[i, k] - VB[i, k]
        outm[i] = 0
        inm[i] = 0
    for g in range(nf):
        code = entry[E_FACE + g]
        if code < 0 or code >= 1 << 24:
            return WARM_MISS, 0.0
        for j in range(3):
            fv[g, j] = (code >> (8 * j)) & 0xFF
            if fv[g, j] >= nv:
                return WARM_MISS, 0.0
        for j in range(3):
            x = fv[g, j]
            y = fv[g, (j + 1) % 3]
            if x == y or (outm[x] >> y) & 1:
                return WARM_MISS, 0.0  # a repeated vertex or directed edge
            outm[x] |= 1 << y
            inm[y] |= 1 << x
    for i in range(nv):
        if outm[i] != inm[i]:
            return WARM_MISS, 0.0  # an edge without its reverse: not closed
    scale = 0.0
    for i in range(nv):
        for k in range(3):
            scale = max(scale, abs(VA[i, k]), abs(VB[i, k]))
    f = 0
    for g in range(nf):
        _new_face(V, fv, fn, fo, fl, g, fv[g, 0], fv[g, 1], fv[g, 2])
        if fo[g] < fo[f]:
            f = g
    if not fl[f] > 0.0:
        return WARM_MISS, 0.0
    # EPA's convergence test on the nearest face (its support hill-climbs from the face's vertex)
    code = entry[E_VERT + fv[f, 0]]
    hints[0] = code & 0xFFFFFFFF
    hints[1] = code >> 32
    w0, w1, w2, s = _support_c(sa, sb, fn[f, 0], fn[f, 1], fn[f, 2], hints, pp[0:3], pp[3:6])
    scale = max(scale, s)
    h = fn[f, 0] * w0 + fn[f, 1] * w1 + fn[f, 2] * w2
    if not h - fo[f] <= max(tol, 16.0 * _EPS * scale):
        return WARM_MISS, scale
    # `epa`'s certificate, every face in front of the origin (the 2-cycle's winding number then
    # at least 1, as `epa`'s closed surface by construction)
    vertex_err = 8.0 * _EPS * scale
    inner = math.inf
    for k in range(-1, nf):  # the nearest face first, as in `epa`
        g = f if k < 0 else k
        if k >= 0 and g == f:
            continue
        a, b, c = fv[g, 0], fv[g, 1], fv[g, 2]
        bound = fo[g] - _offset_error(V, a, b, c, fl[g], vertex_err) if fl[g] > 0.0 else -math.inf
        if not bound > 0.0:
            return WARM_MISS, scale
        if bound < inner:
            bound = max(bound, _tri_lower(V, a, b, c, vertex_err))
            inner = min(inner, bound)
    if not inner > 0.0:
        return WARM_MISS, scale
    # the witness, as `epa` takes it
    near = fo[f] + max(tol, 16.0 * _EPS * scale)
    f0 = f
    f, la, lb, lc, best = _nearest_triangle(V, fv, fo, nf, near, f)
    # A kept polytope need not be convex at the new poses (`epa`'s holds the origin's foot point
    # in its nearest face): the nearest triangle may lie off the checked face's foot point, or
    # on a face within the tolerance of the nearest plane that is no face of C (its normal, the
    # contact's, then far from the depth's direction: tests/test_adversary_warm.py). Such a
    # witness face is checked as the nearest one was, and a witness beyond the tolerance of the
    # nearest plane is declined.
    if not math.sqrt(best) - vertex_err <= near:
        return WARM_MISS, scale
    if f != f0:
        w0, w1, w2, s = _support_c(sa, sb, fn[f, 0], fn[f, 1], fn[f, 2], hints, pp[0:3], pp[3:6])
        scale = max(scale, s)
        if not fn[f, 0] * w0 + fn[f, 1] * w1 + fn[f, 2] * w2 - fo[f] <= max(tol, 16.0 * _EPS * scale):
            return WARM_MISS, scale
    _witness(V, VA, VB, fv, fn, fl, f, la, lb, lc, res)
    res[0], res[1], res[2] = -h, -inner, -fo[f]
    return CONVERGED, scale
