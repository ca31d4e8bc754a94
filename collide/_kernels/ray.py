"""Ray casting through a flattened CSG hierarchy (numba): exact primitive spans and span arithmetic.

The tree is the one `collide.csg.build_bvh` flattens: every node has a world bound (an AABB
clipped by the top-down pass of Stürzlinger 1996, §3.5, or an OBB, or a sphere), transforms are
folded into the leaves (each leaf keeps its world -> local affine map), unions are n-ary,
intersections and differences binary.

Per ray, a *span list* is the sorted list of disjoint parameter intervals ``[t0, t1]`` where the
line ``o + t d`` is inside a node's solid; each endpoint remembers the leaf and the surface part
(``sub``: box axis, cylinder side or cap, mesh triangle) it lies on. Union, intersection and
difference of span lists give a CSG node's spans (Roth 1982, "Ray casting for modeling solids").

Traversal (the exactness argument, for the tests and for whoever changes this):
- every node bound contains the node's *positive geometry* (union -> union, intersection ->
  intersection, difference -> left operand), hence everything a pruned evaluation can return;
- the top-down pass clips a child's box to its parent's (clipped) box, which keeps it containing
  the part of the positive geometry that can matter; a child skipped because the ray segment
  ``[0, tmax]`` misses its bound is replaced by the empty set;
- by induction, a node's computed spans equal its true spans at every ray point of ``[0, tmax]``
  inside its bound. The root's bound contains the whole solid, so the first boundary point in
  ``[0, tmax)`` is exact.
The top of the tree (the nodes reached from the root through unions only) is traversed near-first
with ``tmax`` = the best hit so far, the usual BVH pruning; each non-union node reached there (an
*item*) is evaluated with span arithmetic. The first hit of a union is the nearest item entry only
when the origin is outside every item; an item containing the origin always meets the window
(t = 0 is in it), so that case is detected, and such rays are re-run without the ``tmax`` pruning,
merging all items into one span list.

Kernels take flat arrays only; `collide.csg` builds them. ``cache=True`` everywhere.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

# Node kinds (node_kind).
LEAF, UNION, INTERSECTION, DIFFERENCE = 0, 1, 2, 3
# Primitive kinds of the kernel (leaf_prim). Ellipsoids are unit spheres with the radii folded
# into the leaf's affine map.
P_BOX, P_SPHERE, P_CYLINDER, P_CONE, P_CAPSULE, P_MESH = 0, 1, 2, 3, 4, 5

RAYS_PER_BLOCK = 64
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
def _put(sp_t, sp_i, o, t0, l0, s0, t1, l1, s1):
    sp_t[o, 0] = t0
    sp_t[o, 1] = t1
    sp_i[o, 0] = l0
    sp_i[o, 1] = s0
    sp_i[o, 2] = l1
    sp_i[o, 3] = s1


@njit(cache=True)
def span_union(sp_t, sp_i, a, na, b, nb, out):
    """Union of sorted disjoint span lists at ``a`` and ``b``,
    written at ``out``; returns the count."""
    i = 0
    j = 0
    n = 0
    while i < na or j < nb:
        if j >= nb or (i < na and sp_t[a + i, 0] <= sp_t[b + j, 0]):
            k = a + i
            i += 1
        else:
            k = b + j
            j += 1
        if n > 0 and sp_t[k, 0] <= sp_t[out + n - 1, 1]:
            if sp_t[k, 1] > sp_t[out + n - 1, 1]:
                sp_t[out + n - 1, 1] = sp_t[k, 1]
                sp_i[out + n - 1, 2] = sp_i[k, 2]
                sp_i[out + n - 1, 3] = sp_i[k, 3]
        else:
            _put(sp_t, sp_i, out + n, sp_t[k, 0], sp_i[k, 0], sp_i[k, 1], sp_t[k, 1], sp_i[k, 2],
                 sp_i[k, 3])
            n += 1
    return n


@njit(cache=True)
def span_intersection(sp_t, sp_i, a, na, b, nb, out):
    """Intersection of sorted disjoint span lists; returns the count written at ``out``."""
    i = 0
    j = 0
    n = 0
    while i < na and j < nb:
        ka = a + i
        kb = b + j
        if sp_t[ka, 0] >= sp_t[kb, 0]:
            t0, l0, s0 = sp_t[ka, 0], sp_i[ka, 0], sp_i[ka, 1]
        else:
            t0, l0, s0 = sp_t[kb, 0], sp_i[kb, 0], sp_i[kb, 1]
        if sp_t[ka, 1] <= sp_t[kb, 1]:
            t1, l1, s1 = sp_t[ka, 1], sp_i[ka, 2], sp_i[ka, 3]
            i += 1
        else:
            t1, l1, s1 = sp_t[kb, 1], sp_i[kb, 2], sp_i[kb, 3]
            j += 1
        if t0 < t1:
            _put(sp_t, sp_i, out + n, t0, l0, s0, t1, l1, s1)
            n += 1
    return n


@njit(cache=True)
def span_difference(sp_t, sp_i, a, na, b, nb, out):
    """``a`` minus ``b`` for sorted disjoint span lists; returns the count written at ``out``.

    Where a ``b`` span cuts an ``a`` span, ``b``'s entry becomes the result's exit and ``b``'s
    exit its entry (the normal flips; `raycast` orients normals from entry/exit).
    """
    j = 0
    n = 0
    for i in range(na):
        ka = a + i
        c0, cl, cs = sp_t[ka, 0], sp_i[ka, 0], sp_i[ka, 1]
        e1 = sp_t[ka, 1]
        while j < nb and sp_t[b + j, 1] <= c0:
            j += 1
        q = j
        alive = True
        while q < nb and sp_t[b + q, 0] < e1:
            kb = b + q
            if sp_t[kb, 0] > c0:
                _put(sp_t, sp_i, out + n, c0, cl, cs, sp_t[kb, 0], sp_i[kb, 0], sp_i[kb, 1])
                n += 1
            if sp_t[kb, 1] >= e1:
                alive = False
                break
            if sp_t[kb, 1] > c0:
                c0, cl, cs = sp_t[kb, 1], sp_i[kb, 2], sp_i[kb, 3]
            q += 1
        if alive and c0 < e1:
            _put(sp_t, sp_i, out + n, c0, cl, cs, e1, sp_i[ka, 2], sp_i[ka, 3])
            n += 1
    return n


@njit(cache=True)
def _combine(kind, sp_t, sp_i, base, na, cb, nb):
    # acc at base (na spans) op child at cb (nb spans) -> written back at base; returns count.
    out = cb + nb
    if kind == UNION:
        n = span_union(sp_t, sp_i, base, na, cb, nb, out)
    elif kind == INTERSECTION:
        n = span_intersection(sp_t, sp_i, base, na, cb, nb, out)
    else:
        n = span_difference(sp_t, sp_i, base, na, cb, nb, out)
    for k in range(n):
        sp_t[base + k, 0] = sp_t[out + k, 0]
        sp_t[base + k, 1] = sp_t[out + k, 1]
        for c in range(4):
            sp_i[base + k, c] = sp_i[out + k, c]
    return n


@njit(cache=True)
def _eval_node(root, base, o, d, tmax, node_kind, node_first, node_count, child, bound, node_lo,
               node_hi, node_rot, node_center, node_radius, node_leaf, leaf_prim, leaf_param,
               leaf_inv, leaf_tri_first, leaf_tri_count, tri,
               sp_t, sp_i, ht, hi, ol, dl, fr_node, fr_next, fr_base, fr_cnt, counts):
    """Spans of ``root`` (its box already tested) at ``sp[base:]``; returns their count.

    Children whose box misses the segment ``[0, tmax]`` count as empty (see the module note).
    ``counts[0]`` += bound tests, ``counts[1]`` += primitive tests.
    """
    if node_kind[root] == LEAF:
        counts[1] += 1
        return _leaf_spans(node_leaf[root], o, d, leaf_prim, leaf_param, leaf_inv, leaf_tri_first,
                           leaf_tri_count, tri, sp_t, sp_i, base, ht, hi, ol, dl)
    fr_node[0] = root
    fr_next[0] = 0
    fr_base[0] = base
    fr_cnt[0] = -1
    depth = 1
    while True:
        k = depth - 1
        n = fr_node[k]
        i = fr_next[k]
        kind = node_kind[n]
        acc = fr_cnt[k]
        done = i >= node_count[n]
        if acc == 0 and kind != UNION:
            done = True  # empty left operand of a difference or operand of an intersection
        if done:
            res_base = fr_base[k]
            res = acc if acc > 0 else 0
            depth -= 1
            if depth == 0:
                return res
            k = depth - 1
            pa = fr_cnt[k]
            if pa < 0:
                fr_cnt[k] = res
            else:
                fr_cnt[k] = _combine(node_kind[fr_node[k]], sp_t, sp_i, fr_base[k], pa, res_base,
                res)
            continue
        c = child[node_first[n] + i]
        fr_next[k] = i + 1
        cb = fr_base[k] + (acc if acc > 0 else 0)
        counts[0] += 1
        hit, tn = _ray_bound(bound, c, o, d, tmax, node_lo, node_hi, node_rot, node_center,
                             node_radius)
        if hit and node_kind[c] != LEAF:
            fr_node[depth] = c
            fr_next[depth] = 0
            fr_base[depth] = cb
            fr_cnt[depth] = -1
            depth += 1
            continue
        res = 0
        if hit:
            counts[1] += 1
            res = _leaf_spans(node_leaf[c], o, d, leaf_prim, leaf_param, leaf_inv, leaf_tri_first,
                              leaf_tri_count, tri, sp_t, sp_i, cb, ht, hi, ol, dl)
        if acc < 0:
            fr_cnt[k] = res
        else:
            fr_cnt[k] = _combine(kind, sp_t, sp_i, fr_base[k], acc, cb, res)


@njit(cache=True)
def _first_boundary(sp_t, sp_i, base, n):
    # First span endpoint at t >= 0: (t, leaf, sub, entering, origin_inside).
    for k in range(base, base + n):
        if sp_t[k, 0] >= 0.0:
            return sp_t[k, 0], sp_i[k, 0], sp_i[k, 1], True, False
        if sp_t[k, 1] >= 0.0:
            return sp_t[k, 1], sp_i[k, 2], sp_i[k, 3], False, True
    return np.inf, -1, -1, False, False


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


@njit(cache=True)
def _trace(o, d, use_bounds, node_kind, node_first, node_count, child, bound, node_lo, node_hi,
           node_rot, node_center, node_radius, node_leaf,
           leaf_prim, leaf_param, leaf_inv, leaf_tri_first, leaf_tri_count, tri,
           sp_t, sp_i, ht, hi, ol, dl, fr_node, fr_next, fr_base, fr_cnt, st_node, st_t, tmp_node,
           tmp_t, counts):
    # One ray: (t, leaf, sub, entering). use_bounds=False is the second pass (origin inside).
    best_t = np.inf
    best_l = -1
    best_s = -1
    best_e = False
    inside = False
    nu = 0  # second pass: the union of all items so far, at sp[0:nu]
    counts[0] += 1
    hit, tn = _ray_bound(bound, 0, o, d, np.inf, node_lo, node_hi, node_rot, node_center,
                         node_radius)
    if not hit:
        return best_t, best_l, best_s, best_e, inside
    sp = 0
    st_node[0] = 0
    st_t[0] = tn
    sp = 1
    while sp > 0:
        sp -= 1
        n = st_node[sp]
        tmax = best_t if use_bounds else np.inf
        if st_t[sp] > tmax:
            continue
        if node_kind[n] == UNION:
            m = 0
            for i in range(node_count[n]):
                c = child[node_first[n] + i]
                counts[0] += 1
                h, tc = _ray_bound(bound, c, o, d, tmax, node_lo, node_hi, node_rot, node_center,
                                   node_radius)
                if h:
                    # insertion into tmp sorted by decreasing t_near: nearest pushed last
                    q = m
                    while q > 0 and tmp_t[q - 1] < tc:
                        tmp_t[q] = tmp_t[q - 1]
                        tmp_node[q] = tmp_node[q - 1]
                        q -= 1
                    tmp_t[q] = tc
                    tmp_node[q] = c
                    m += 1
            for q in range(m):
                st_node[sp] = tmp_node[q]
                st_t[sp] = tmp_t[q]
                sp += 1
            continue
        cnt = _eval_node(n, nu, o, d, tmax, node_kind, node_first, node_count, child, bound,
                         node_lo, node_hi, node_rot, node_center, node_radius, node_leaf,
                         leaf_prim, leaf_param, leaf_inv, leaf_tri_first,
                         leaf_tri_count, tri, sp_t, sp_i, ht, hi, ol, dl, fr_node, fr_next,
                         fr_base, fr_cnt, counts)
        if use_bounds:
            t, lf, sb, ent, ins = _first_boundary(sp_t, sp_i, 0, cnt)
            if ins:
                inside = True
            if t < best_t:
                best_t, best_l, best_s, best_e = t, lf, sb, ent
        else:
            nu = _combine(UNION, sp_t, sp_i, 0, nu, nu, cnt)
    if not use_bounds:
        best_t, best_l, best_s, best_e, ins = _first_boundary(sp_t, sp_i, 0, nu)
    return best_t, best_l, best_s, best_e, inside


@njit(cache=True, parallel=True)
def raycast_kernel(origins, directions, node_kind, node_first, node_count, child, bound, node_lo,
                   node_hi, node_rot, node_center, node_radius, node_leaf, leaf_prim, leaf_param,
                   leaf_inv, leaf_tri_first, leaf_tri_count, tri,
                   span_capacity, height, max_children, max_tri,
                   out_t, out_leaf, out_normal, out_bound, out_prim):
    """First hits of rays ``origins (R, 3)``, ``directions (R, 3)`` through the flat tree.

    ``bound`` selects the node bounds (see `_ray_bound`): 0 AABBs ``node_lo``/``node_hi``;
    1 OBBs ``node_center``, ``node_rot (N, 3, 3)``, half extents ``node_hi``; 2 spheres
    ``node_center``, ``node_radius (N,)``.

    Writes ``out_t (R,)`` (inf on a miss), ``out_leaf (R,) int32`` (-1 on a miss),
    ``out_normal (R, 3)`` (outward, unit; zero on a miss), ``out_bound``/``out_prim (R,) int64``
    (bound and primitive tests per ray).
    """
    r_count = origins.shape[0]
    n_nodes = node_kind.shape[0]
    n_blocks = (r_count + RAYS_PER_BLOCK - 1) // RAYS_PER_BLOCK
    for blk in prange(n_blocks):
        sp_t = np.empty((span_capacity, 2))
        sp_i = np.empty((span_capacity, 4), dtype=np.int32)
        ht = np.empty(max_tri + 1)
        hi = np.empty(max_tri + 1, dtype=np.int32)
        ol = np.empty(3)
        dl = np.empty(3)
        fr_node = np.empty(height + 1, dtype=np.int32)
        fr_next = np.empty(height + 1, dtype=np.int32)
        fr_base = np.empty(height + 1, dtype=np.int64)
        fr_cnt = np.empty(height + 1, dtype=np.int64)
        st_node = np.empty(n_nodes + 1, dtype=np.int32)
        st_t = np.empty(n_nodes + 1)
        tmp_node = np.empty(max_children + 1, dtype=np.int32)
        tmp_t = np.empty(max_children + 1)
        counts = np.zeros(2, dtype=np.int64)
        nrm = np.zeros(3)
        for r in range(blk * RAYS_PER_BLOCK, min(r_count, (blk + 1) * RAYS_PER_BLOCK)):
            o = origins[r]
            d = directions[r]
            counts[0] = 0
            counts[1] = 0
            t, lf, sb, ent, inside = _trace(
                o, d, True, node_kind, node_first, node_count, child, bound, node_lo, node_hi,
                node_rot, node_center, node_radius, node_leaf,
                leaf_prim, leaf_param, leaf_inv, leaf_tri_first, leaf_tri_count, tri, sp_t, sp_i,
                ht, hi, ol, dl, fr_node, fr_next, fr_base, fr_cnt, st_node, st_t, tmp_node, tmp_t,
                counts)
            if inside:
                t, lf, sb, ent, inside = _trace(
                    o, d, False, node_kind, node_first, node_count, child, bound, node_lo, node_hi,
                    node_rot, node_center, node_radius, node_leaf, leaf_prim, leaf_param,
                    leaf_inv, leaf_tri_first, leaf_tri_count, tri,
                    sp_t, sp_i, ht, hi, ol, dl, fr_node, fr_next, fr_base, fr_cnt, st_node, st_t,
                    tmp_node, tmp_t, counts)
            out_t[r] = t
            out_leaf[r] = lf
            out_bound[r] = counts[0]
            out_prim[r] = counts[1]
            if lf >= 0:
                _world_normal(lf, sb, t, ent, o, d, leaf_prim, leaf_param, leaf_inv,
                              leaf_tri_first, tri, ol, dl, nrm)
                out_normal[r, 0] = nrm[0]
                out_normal[r, 1] = nrm[1]
                out_normal[r, 2] = nrm[2]
            else:
                out_normal[r, 0] = 0.0
                out_normal[r, 1] = 0.0
                out_normal[r, 2] = 0.0
