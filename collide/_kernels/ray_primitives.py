"""Rays against one primitive or one bound (numba): the exact entry and exit of a ray through a
box, sphere, cylinder, cone or capsule (in the leaf's local frame), through a closed triangle
mesh (watertight ray-triangle tests), the slab tests of the node bounds, and surface normals.

Used by the traversal in `collide._kernels.ray`; see its docstring for the span conventions
(``sub``: which surface part an endpoint lies on). ``cache=True`` everywhere.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# Primitive kinds of the kernel (leaf_prim). Ellipsoids are unit spheres with the radii folded
# into the leaf's affine map.
P_BOX, P_SPHERE, P_CYLINDER, P_CONE, P_CAPSULE, P_MESH = 0, 1, 2, 3, 4, 5

_EPS = float(np.finfo(np.float64).eps)



@njit(cache=True)
def _ray_box(o, d, lo, hi, tmax):
    # Slab test of the segment o + t d, t in [0, tmax], against [lo, hi]; returns (hit, t_near).
    t0 = 0.0
    t1 = tmax
    for a in range(3):
        ta, tb, ok = _slab(o[a], d[a], lo[a], hi[a])
        t0 = max(t0, ta)
        t1 = min(t1, tb)
        if not ok or t0 > t1:
            return False, 0.0
    return True, t0


@njit(cache=True)
def _ray_bound(kind, n, o, d, tmax, node_lo, node_hi, node_rot, node_center, node_radius):
    # Segment [0, tmax] against node n's bound: 0 world AABB [lo, hi]; 1 OBB (centre, rotation
    # columns = axes, half extents in node_hi); 2 sphere (centre, radius). (hit, t_near).
    if kind == 0:
        return _ray_box(o, d, node_lo[n], node_hi[n], tmax)
    c = node_center[n]
    if kind == 1:
        r = node_rot[n]
        h = node_hi[n]
        t0 = 0.0
        t1 = tmax
        for a in range(3):
            oa = r[0, a] * (o[0] - c[0]) + r[1, a] * (o[1] - c[1]) + r[2, a] * (o[2] - c[2])
            da = r[0, a] * d[0] + r[1, a] * d[1] + r[2, a] * d[2]
            ta, tb, ok = _slab(oa, da, -h[a], h[a])
            t0 = max(t0, ta)
            t1 = min(t1, tb)
            if not ok or t0 > t1:
                return False, 0.0
        return True, t0
    ox = o[0] - c[0]
    oy = o[1] - c[1]
    oz = o[2] - c[2]
    a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    # From the ray's point closest to the centre (see _recentre): the textbook discriminant
    # b^2 - a c culled most hits from 1e8 away. The radius gets the rounding of that point,
    # a few ulps of the origin's distance, so the test never culls a hit.
    tc = -(ox * d[0] + oy * d[1] + oz * d[2]) / a
    px = ox + tc * d[0]
    py = oy + tc * d[1]
    pz = oz + tc * d[2]
    rad = node_radius[n] + 8.0 * _EPS * (abs(ox) + abs(oy) + abs(oz))
    h = rad * rad - (px * px + py * py + pz * pz)
    if h < 0.0:
        return False, 0.0
    sq = np.sqrt(h / a)
    t0 = tc - sq
    t1 = tc + sq
    if t0 < 0.0:
        t0 = 0.0
    if t1 > tmax:
        t1 = tmax
    return t0 <= t1, t0


@njit(cache=True)
def _quad_interval(a, b, c):
    # {t : a t^2 + 2 b t + c <= 0} as up to two intervals (lo0, hi0, lo1, hi1, n); n = 0, 1 or 2.
    inf = np.inf
    if a == 0.0:
        if b == 0.0:
            if c <= 0.0:
                return -inf, inf, 0.0, 0.0, 1
            return 0.0, 0.0, 0.0, 0.0, 0
        r = -c / (2.0 * b)
        if b > 0.0:
            return -inf, r, 0.0, 0.0, 1
        return r, inf, 0.0, 0.0, 1
    disc = b * b - a * c
    if disc <= 0.0:
        if a > 0.0:
            return 0.0, 0.0, 0.0, 0.0, 0
        return -inf, inf, 0.0, 0.0, 1
    s = np.sqrt(disc)
    r0 = (-b - s) / a
    r1 = (-b + s) / a
    if r0 > r1:
        r0, r1 = r1, r0
    if a > 0.0:
        return r0, r1, 0.0, 0.0, 1
    return -inf, r0, r1, inf, 2


@njit(cache=True)
def _slab(o, d, lo, hi):
    # {t : lo <= o + t d <= hi} along one axis: (t0, t1, ok) with t0 at the lo/hi plane it enters.
    if d == 0.0:
        if o < lo or o > hi:
            return 0.0, 0.0, False
        return -np.inf, np.inf, True
    ta = (lo - o) / d
    tb = (hi - o) / d
    if ta > tb:
        ta, tb = tb, ta
    return ta, tb, True


@njit(cache=True)
def leaf_interval(prim, p, ol, dl):
    """Span of a convex primitive in its local frame: (t0, sub0, t1, sub1, hit).

    ``ol``, ``dl`` are the ray in the local frame (``dl`` not normalised, so ``t`` is the world
    parameter). Zero-length spans (tangent rays) are misses.
    """
    inf = np.inf
    if prim == P_BOX:
        t0 = -inf
        t1 = inf
        s0 = 0
        s1 = 0
        for a in range(3):
            ta, tb, ok = _slab(ol[a], dl[a], -p[a], p[a])
            if not ok:
                return 0.0, 0, 0.0, 0, False
            if ta > t0:
                t0 = ta
                s0 = a
            if tb < t1:
                t1 = tb
                s1 = a
        return t0, s0, t1, s1, t0 < t1
    if prim == P_SPHERE:
        r = p[0]
        a = dl[0] * dl[0] + dl[1] * dl[1] + dl[2] * dl[2]
        b = ol[0] * dl[0] + ol[1] * dl[1] + ol[2] * dl[2]
        c = ol[0] * ol[0] + ol[1] * ol[1] + ol[2] * ol[2] - r * r
        lo0, hi0, lo1, hi1, n = _quad_interval(a, b, c)
        if n == 0:
            return 0.0, 0, 0.0, 0, False
        return lo0, 0, hi0, 0, lo0 < hi0
    if prim == P_CYLINDER or prim == P_CAPSULE:
        r = p[0]
        h = p[1]
        a = dl[0] * dl[0] + dl[1] * dl[1]
        b = ol[0] * dl[0] + ol[1] * dl[1]
        c = ol[0] * ol[0] + ol[1] * ol[1] - r * r
        lo0, hi0, lo1, hi1, n = _quad_interval(a, b, c)
        t0 = lo0
        t1 = hi0
        s0 = 0
        s1 = 0
        hit = n == 1
        if hit:
            za, zb, ok = _slab(ol[2], dl[2], -h, h)
            if not ok:
                hit = False
            else:
                if za > t0:
                    t0 = za
                    s0 = 1
                if zb < t1:
                    t1 = zb
                    s1 = 1
                hit = t0 < t1
        if prim == P_CYLINDER:
            return t0, s0, t1, s1, hit
        # Capsule = cylinder u sphere(-h) u sphere(+h): convex, so the union of the three
        # intervals is one interval (Minkowski sum of a segment and a ball).
        if not hit:
            t0 = inf
            t1 = -inf
        a3 = dl[0] * dl[0] + dl[1] * dl[1] + dl[2] * dl[2]
        for k in range(2):
            zc = -h if k == 0 else h
            oz = ol[2] - zc
            b3 = ol[0] * dl[0] + ol[1] * dl[1] + oz * dl[2]
            c3 = ol[0] * ol[0] + ol[1] * ol[1] + oz * oz - r * r
            lo0, hi0, lo1, hi1, n = _quad_interval(a3, b3, c3)
            if n == 1 and lo0 < hi0:
                if lo0 < t0:
                    t0 = lo0
                    s0 = 2 + k
                if hi0 > t1:
                    t1 = hi0
                    s1 = 2 + k
        return t0, s0, t1, s1, t0 < t1
    if prim == P_CONE:
        # Solid: x^2 + y^2 <= k^2 (H - z)^2 with 0 <= z <= H. The quadric's {f <= 0} is the
        # double cone; the slab keeps the lower nappe (the other one lies in z >= H).
        r = p[0]
        hh = p[1]
        k2 = (r / hh) ** 2
        u0 = hh - ol[2]
        a = dl[0] * dl[0] + dl[1] * dl[1] - k2 * dl[2] * dl[2]
        b = ol[0] * dl[0] + ol[1] * dl[1] + k2 * u0 * dl[2]
        c = ol[0] * ol[0] + ol[1] * ol[1] - k2 * u0 * u0
        lo0, hi0, lo1, hi1, n = _quad_interval(a, b, c)
        if n == 0:
            return 0.0, 0, 0.0, 0, False
        za, zb, ok = _slab(ol[2], dl[2], 0.0, hh)
        if not ok:
            return 0.0, 0, 0.0, 0, False
        best0 = 0.0
        best1 = 0.0
        bs0 = 0
        bs1 = 0
        found = False
        for j in range(n):
            q0 = lo0 if j == 0 else lo1
            q1 = hi0 if j == 0 else hi1
            e0 = q0
            e1 = q1
            f0 = 0
            f1 = 0
            if za > e0:
                e0 = za
                f0 = 1
            if zb < e1:
                e1 = zb
                f1 = 1
            if e0 < e1 and (not found or e1 - e0 > best1 - best0):
                best0 = e0
                best1 = e1
                bs0 = f0
                bs1 = f1
                found = True
        return best0, bs0, best1, bs1, found
    return 0.0, 0, 0.0, 0, False


@njit(cache=True)
def _shear(dl):
    # Watertight ray/triangle intersection (Woop, Benthin & Wald 2013, JCGT 2(1)), per ray: the
    # dominant axis kz of d, the other two in the order that keeps a triangle's winding, and the
    # shear (sx, sy, sz) taking d to +z. ok is False for a zero direction (no hit).
    ax = abs(dl[0])
    ay = abs(dl[1])
    az = abs(dl[2])
    kz = 0 if (ax >= ay and ax >= az) else (1 if ay >= az else 2)
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    if dl[kz] < 0.0:
        kx, ky = ky, kx
    if dl[kz] == 0.0:
        return kx, ky, kz, 0.0, 0.0, 0.0, False
    sz = 1.0 / dl[kz]
    return kx, ky, kz, dl[kx] * sz, dl[ky] * sz, sz, True


@njit(cache=True, inline="always")
def _owns(px, py, qx, qy):
    # Tie rule for a ray exactly on the projected edge p -> q (edge function 0): of p -> q and
    # q -> p exactly one owns it (the top-left rule of rasterisers), so the two triangles sharing
    # the edge count the crossing once; around a shared vertex, one triangle of the fan does.
    dy = qy - py
    return dy > 0.0 or (dy == 0.0 and qx - px > 0.0)


@njit(cache=True)
def _tri_hit(ol, kx, ky, kz, sx, sy, sz, v0, v1, v2):
    """(t, hit) of the full line ``ol + t dl`` and a triangle (any sign of t), `_shear`'s frame.

    Woop, Benthin & Wald (2013), §3: the vertices relative to the origin, sheared so the ray runs
    along +z; the edge functions U, V, W are 2D cross products of the projected vertices. Two
    triangles sharing an edge compute that edge's function from the same two projected points
    in opposite order: exactly negated values (a product difference, rounded once), so a ray
    never slips between them or hits both, except exactly on the edge (0 in both), where
    `_owns` picks one. Moller-Trumbore, used before, hit both triangles or neither there: a
    ray through a box mesh's face diagonal (its centre, say) saw two entries and two exits,
    paired into empty spans, and missed the box (review, 2026-11-22). A triangle seen from
    behind (det < 0) applies the rule to its edges reversed, so a ray grazing a silhouette edge
    counts both of its triangles or neither (an entry and an exit at one t, or nothing).
    """
    ax = v0[kx] - ol[kx]
    ay = v0[ky] - ol[ky]
    az = v0[kz] - ol[kz]
    bx = v1[kx] - ol[kx]
    by = v1[ky] - ol[ky]
    bz = v1[kz] - ol[kz]
    cx = v2[kx] - ol[kx]
    cy = v2[ky] - ol[ky]
    cz = v2[kz] - ol[kz]
    Ax = ax - sx * az
    Ay = ay - sy * az
    Bx = bx - sx * bz
    By = by - sy * bz
    Cx = cx - sx * cz
    Cy = cy - sy * cz
    U = Cx * By - Cy * Bx  # edge B -> C
    V = Ax * Cy - Ay * Cx  # edge C -> A
    W = Bx * Ay - By * Ax  # edge A -> B
    det = U + V + W
    if det > 0.0:
        inside = ((U > 0.0 or (U == 0.0 and _owns(Bx, By, Cx, Cy)))
                  and (V > 0.0 or (V == 0.0 and _owns(Cx, Cy, Ax, Ay)))
                  and (W > 0.0 or (W == 0.0 and _owns(Ax, Ay, Bx, By))))
    elif det < 0.0:
        inside = ((U < 0.0 or (U == 0.0 and _owns(Cx, Cy, Bx, By)))
                  and (V < 0.0 or (V == 0.0 and _owns(Ax, Ay, Cx, Cy)))
                  and (W < 0.0 or (W == 0.0 and _owns(Bx, By, Ax, Ay))))
    else:
        return 0.0, False  # edge-on in the projection: a crossing there is its neighbours'
    if not inside:
        return 0.0, False
    T = U * (sz * az) + V * (sz * bz) + W * (sz * cz)
    return T / det, True


@njit(cache=True)
def _local_ray(inv, o, d, ol, dl):
    for i in range(3):
        ol[i] = inv[i, 0] * o[0] + inv[i, 1] * o[1] + inv[i, 2] * o[2] + inv[i, 3]
        dl[i] = inv[i, 0] * d[0] + inv[i, 1] * d[1] + inv[i, 2] * d[2]


@njit(cache=True)
def _recentre(prim, ol, dl):
    # Quadric leaves: moves the ray's origin to its point closest to the leaf's origin and returns
    # that point's parameter tc (spans found from there are shifted by tc). From far away the
    # quadratics' coefficients (|o|^2 - r^2, b^2 - a c) cancel catastrophically: a unit sphere
    # seen from 1e8 was missed by most rays through it (review, 2026-11-21). From the closest
    # point they are of the primitive's size, and the only loss is the rounding of o itself.
    if prim == P_BOX or prim == P_MESH:
        return 0.0
    a = dl[0] * dl[0] + dl[1] * dl[1] + dl[2] * dl[2]
    if a == 0.0:
        return 0.0
    tc = -(ol[0] * dl[0] + ol[1] * dl[1] + ol[2] * dl[2]) / a
    for i in range(3):
        ol[i] += tc * dl[i]
    return tc


@njit(cache=True)
def _leaf_spans(lf, o, d, leaf_prim, leaf_param, leaf_inv, leaf_tri_first, leaf_tri_count, tri,
                sp_t, sp_i, pos, ht, hi, ol, dl):
    # Writes the leaf's spans at sp[pos:], returns their count. Meshes: sorted hits paired
    # (closed meshes: inside between odd and even crossings).
    _local_ray(leaf_inv[lf], o, d, ol, dl)
    prim = leaf_prim[lf]
    if prim != P_MESH:
        tc = _recentre(prim, ol, dl)
        t0, s0, t1, s1, hit = leaf_interval(prim, leaf_param[lf], ol, dl)
        if not hit:
            return 0
        sp_t[pos, 0] = t0 + tc
        sp_t[pos, 1] = t1 + tc
        sp_i[pos, 0] = lf
        sp_i[pos, 1] = s0
        sp_i[pos, 2] = lf
        sp_i[pos, 3] = s1
        return 1
    first = leaf_tri_first[lf]
    m = 0
    kx, ky, kz, sx, sy, sz, ok = _shear(dl)
    for k in range(leaf_tri_count[lf] if ok else 0):
        j = first + k
        t, ok = _tri_hit(ol, kx, ky, kz, sx, sy, sz, tri[j, 0], tri[j, 1], tri[j, 2])
        if ok:
            # insertion sort by t (meshes are small; a hit list is short)
            q = m
            while q > 0 and ht[q - 1] > t:
                ht[q] = ht[q - 1]
                hi[q] = hi[q - 1]
                q -= 1
            ht[q] = t
            hi[q] = k
            m += 1
    cnt = 0
    for q in range(0, m - 1, 2):
        if ht[q] < ht[q + 1]:
            sp_t[pos + cnt, 0] = ht[q]
            sp_t[pos + cnt, 1] = ht[q + 1]
            sp_i[pos + cnt, 0] = lf
            sp_i[pos + cnt, 1] = hi[q]
            sp_i[pos + cnt, 2] = lf
            sp_i[pos + cnt, 3] = hi[q + 1]
            cnt += 1
    return cnt


@njit(cache=True)
def _local_normal(prim, p, q, tri_v):
    # Outward normal of the primitive surface part ``q`` at local point ``p`` (not normalised).
    n = np.zeros(3)
    if prim == P_BOX:
        n[q] = 1.0 if p[q] >= 0.0 else -1.0
    elif prim == P_SPHERE:
        n[0], n[1], n[2] = p[0], p[1], p[2]
    elif prim == P_CYLINDER or prim == P_CAPSULE:
        if q == 0:
            n[0], n[1] = p[0], p[1]
        elif q == 1:
            n[2] = 1.0 if p[2] >= 0.0 else -1.0
        else:
            zc = -tri_v[0, 0] if q == 2 else tri_v[0, 0]  # capsule: half length passed in tri_v
            n[0], n[1], n[2] = p[0], p[1], p[2] - zc
    elif prim == P_CONE:
        if q == 1 and p[2] < 0.5 * tri_v[0, 1]:
            n[2] = -1.0
        else:
            k2 = tri_v[0, 0]
            n[0], n[1], n[2] = p[0], p[1], k2 * (tri_v[0, 1] - p[2])
    else:
        e1 = tri_v[1] - tri_v[0]
        e2 = tri_v[2] - tri_v[0]
        n[0] = e1[1] * e2[2] - e1[2] * e2[1]
        n[1] = e1[2] * e2[0] - e1[0] * e2[2]
        n[2] = e1[0] * e2[1] - e1[1] * e2[0]
    return n


@njit(cache=True)
def _world_normal(lf, sub, t, entering, o, d, leaf_prim, leaf_param, leaf_inv, leaf_tri_first, tri,
                  ol, dl, out):
    _local_ray(leaf_inv[lf], o, d, ol, dl)
    p = ol + t * dl
    prim = leaf_prim[lf]
    aux = np.zeros((3, 3))
    if prim == P_MESH:
        aux[:, :] = tri[leaf_tri_first[lf] + sub]
    elif prim == P_CAPSULE:
        aux[0, 0] = leaf_param[lf, 1]
    elif prim == P_CONE:
        aux[0, 0] = (leaf_param[lf, 0] / leaf_param[lf, 1]) ** 2
        aux[0, 1] = leaf_param[lf, 1]
    nl = _local_normal(prim, p, sub, aux)
    inv = leaf_inv[lf]
    s = 0.0
    for i in range(3):
        # normals map with the inverse transpose of the local -> world linear part
        out[i] = inv[0, i] * nl[0] + inv[1, i] * nl[1] + inv[2, i] * nl[2]
        s += out[i] * out[i]
    s = np.sqrt(s)
    if s > 0.0:
        for i in range(3):
            out[i] /= s
    else:
        # No tangent plane (a cone's apex): face the ray.
        s = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        for i in range(3):
            out[i] = -d[i] / s
    dot = out[0] * d[0] + out[1] * d[1] + out[2] * d[2]
    # Outward normal of the solid: against the ray at an entry, along it at an exit.
    if (entering and dot > 0.0) or ((not entering) and dot < 0.0):
        for i in range(3):
            out[i] = -out[i]
