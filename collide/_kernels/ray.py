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

Kernels take flat arrays only; `collide.csg` builds them. ``cache=True`` everywhere. The tests of
one primitive or bound are in `ray_primitives`, the span arithmetic in `ray_spans`; this module
is the traversal.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .ray_primitives import _leaf_spans, _ray_bound, _world_normal
from .ray_spans import span_difference, span_intersection, span_union

# Node kinds (node_kind).
LEAF, UNION, INTERSECTION, DIFFERENCE = 0, 1, 2, 3

RAYS_PER_BLOCK = 64


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
