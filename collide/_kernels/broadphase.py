"""numba kernels of the per-step broad phase: flat arrays in, sorted geom-pair keys out.

Layout (built by `collide.broadphase.BroadPhase` from an `Articulation`): bodies are addressed by
depth-first *position* ``p`` (every subtree is the range ``[p, end[p])``), geoms by their ids.
A bounds record ("row") is 19 float64: OBB centre (3), OBB rotation (9, row-major, columns are the
box axes), OBB half extents (3), sphere centre (3), sphere radius (1).

One step, for one world (`_world`):
1. validate each body's pose (finite, proper orthonormal rotation) and move its local bounds to
   the world (one rotation per body; no point is touched), then the same for the geoms of bodies
   with several geoms (single-geom bodies' bounds *are* their geom's, inflated);
2. subtree AABBs by one reverse sweep over the positions (each body's AABB of its world OBB,
   merged into its parent's): the tree is a one-level bounding hierarchy, never boxes of boxes;
3. every body pair exactly once, at its lowest common ancestor ``n``: body ``n`` against its own
   subtree, and each pair of ``n``'s child subtrees (sweep-and-prune on one axis when ``n`` has many
   children, all pairs otherwise); a subtree whose AABB misses is skipped whole (``q = end[q]``);
4. body pair -> static filter -> sphere test -> OBB separating-axis test (15 axes, Ericson 2005,
   *Real-Time Collision Detection* §4.4.1) -> geom pairs, the same tests on the geoms' bounds;
5. planes (halfspaces) against the tree, explicit pairs last; keys ``g1 * G + g2`` sorted.
"""

from __future__ import annotations

import numba as nb
import numpy as np

ROW = 19
BIG = 1e300  # empty AABB: lo = BIG, hi = -BIG (finite, so n . lo never meets inf - inf)
ORTHO_TOL = 1e-6  # max |R^T R - I| accepted for a body rotation
# Conservative slack: rounding must never separate touching bounds. AbsR gets EPS_PAR (Ericson's
# guard against near-parallel edge pairs, whose cross product is ~0); every comparison gets
# SLACK_REL of the sizes involved plus SLACK_POS of the coordinates' magnitude (a difference of
# world centres far from the origin carries ~1e-16 of their size as rounding).
EPS_PAR = 1e-12
SLACK_REL = 1e-12
SLACK_POS = 1e-13
SAP_MIN = 8  # a node with more children than this sorts them (sweep-and-prune)

# Status codes written to info[0]
OK = 0
BAD_NONFINITE = 1
BAD_ROTATION = 2

# stats slots
ST_SUBTREE, ST_BODY_AABB, ST_BODY_SPHERE, ST_BODY_OBB, ST_GEOM_SPHERE, ST_GEOM_OBB, ST_PLANE, ST_OUT = range(8)
N_STATS = 8


@nb.njit(cache=True, inline="always")
def _world_row(R, p, src, s, dst, d, inflate):
    # dst[d] = world bounds of local row src[s] under rotation R (3, 3) and translation p (3,)
    for i in range(3):
        acc = p[i]
        for k in range(3):
            acc += R[i, k] * src[s, k]
        dst[d, i] = acc
        acc = p[i]
        for k in range(3):
            acc += R[i, k] * src[s, 15 + k]
        dst[d, 15 + i] = acc
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += R[i, k] * src[s, 3 + 3 * k + j]
            dst[d, 3 + 3 * i + j] = acc
    for j in range(3):
        dst[d, 12 + j] = src[s, 12 + j] + inflate
    dst[d, 18] = src[s, 18] + inflate


@nb.njit(cache=True, inline="always")
def _sphere_hit(A, a, ma, B, b, mb):
    dx = A[a, 15] - B[b, 15]
    dy = A[a, 16] - B[b, 16]
    dz = A[a, 17] - B[b, 17]
    r = A[a, 18] + ma + B[b, 18] + mb
    pos = abs(A[a, 15]) + abs(A[a, 16]) + abs(A[a, 17]) + abs(B[b, 15]) + abs(B[b, 16]) + abs(B[b, 17])
    r += SLACK_REL * r + SLACK_POS * pos
    return dx * dx + dy * dy + dz * dz <= r * r


@nb.njit(cache=True)
def obb_hit(A, a, ma, B, b, mb):
    """Separating-axis test of OBB rows ``A[a]`` and ``B[b]`` inflated by ``ma``, ``mb`` (15 axes)."""
    ea0 = A[a, 12] + ma
    ea1 = A[a, 13] + ma
    ea2 = A[a, 14] + ma
    eb0 = B[b, 12] + mb
    eb1 = B[b, 13] + mb
    eb2 = B[b, 14] + mb
    R = np.empty((3, 3))
    AR = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            v = A[a, 3 + i] * B[b, 3 + j] + A[a, 6 + i] * B[b, 6 + j] + A[a, 9 + i] * B[b, 9 + j]
            R[i, j] = v
            AR[i, j] = abs(v) + EPS_PAR
    d0 = B[b, 0] - A[a, 0]
    d1 = B[b, 1] - A[a, 1]
    d2 = B[b, 2] - A[a, 2]
    t0 = d0 * A[a, 3] + d1 * A[a, 6] + d2 * A[a, 9]
    t1 = d0 * A[a, 4] + d1 * A[a, 7] + d2 * A[a, 10]
    t2 = d0 * A[a, 5] + d1 * A[a, 8] + d2 * A[a, 11]
    pos = abs(A[a, 0]) + abs(A[a, 1]) + abs(A[a, 2]) + abs(B[b, 0]) + abs(B[b, 1]) + abs(B[b, 2])
    tol = SLACK_REL * (ea0 + ea1 + ea2 + eb0 + eb1 + eb2) + SLACK_POS * pos
    # A's face axes
    if abs(t0) > ea0 + eb0 * AR[0, 0] + eb1 * AR[0, 1] + eb2 * AR[0, 2] + tol:
        return False
    if abs(t1) > ea1 + eb0 * AR[1, 0] + eb1 * AR[1, 1] + eb2 * AR[1, 2] + tol:
        return False
    if abs(t2) > ea2 + eb0 * AR[2, 0] + eb1 * AR[2, 1] + eb2 * AR[2, 2] + tol:
        return False
    # B's face axes
    for j in range(3):
        ebj = eb0 if j == 0 else (eb1 if j == 1 else eb2)
        tj = t0 * R[0, j] + t1 * R[1, j] + t2 * R[2, j]
        if abs(tj) > ea0 * AR[0, j] + ea1 * AR[1, j] + ea2 * AR[2, j] + ebj + tol:
            return False
    # the nine edge-edge axes A_i x B_j
    if abs(t2 * R[1, 0] - t1 * R[2, 0]) > ea1 * AR[2, 0] + ea2 * AR[1, 0] + eb1 * AR[0, 2] + eb2 * AR[0, 1] + tol:
        return False
    if abs(t2 * R[1, 1] - t1 * R[2, 1]) > ea1 * AR[2, 1] + ea2 * AR[1, 1] + eb0 * AR[0, 2] + eb2 * AR[0, 0] + tol:
        return False
    if abs(t2 * R[1, 2] - t1 * R[2, 2]) > ea1 * AR[2, 2] + ea2 * AR[1, 2] + eb0 * AR[0, 1] + eb1 * AR[0, 0] + tol:
        return False
    if abs(t0 * R[2, 0] - t2 * R[0, 0]) > ea0 * AR[2, 0] + ea2 * AR[0, 0] + eb1 * AR[1, 2] + eb2 * AR[1, 1] + tol:
        return False
    if abs(t0 * R[2, 1] - t2 * R[0, 1]) > ea0 * AR[2, 1] + ea2 * AR[0, 1] + eb0 * AR[1, 2] + eb2 * AR[1, 0] + tol:
        return False
    if abs(t0 * R[2, 2] - t2 * R[0, 2]) > ea0 * AR[2, 2] + ea2 * AR[0, 2] + eb0 * AR[1, 1] + eb1 * AR[1, 0] + tol:
        return False
    if abs(t1 * R[0, 0] - t0 * R[1, 0]) > ea0 * AR[1, 0] + ea1 * AR[0, 0] + eb1 * AR[2, 2] + eb2 * AR[2, 1] + tol:
        return False
    if abs(t1 * R[0, 1] - t0 * R[1, 1]) > ea0 * AR[1, 1] + ea1 * AR[0, 1] + eb0 * AR[2, 2] + eb2 * AR[2, 0] + tol:
        return False
    if abs(t1 * R[0, 2] - t0 * R[1, 2]) > ea0 * AR[1, 2] + ea1 * AR[0, 2] + eb0 * AR[2, 1] + eb1 * AR[2, 0] + tol:
        return False
    return True


@nb.njit(cache=True, inline="always")
def _plane_hit(pl, q, mq, B, b, mb):
    # Both of B[b]'s volumes, inflated by mb, reach the halfspace {n . x <= d + mq}.
    n0 = pl[q, 0]
    n1 = pl[q, 1]
    n2 = pl[q, 2]
    lim = pl[q, 3] + mq
    pos = abs(B[b, 0]) + abs(B[b, 1]) + abs(B[b, 2]) + abs(pl[q, 3])
    sc = n0 * B[b, 15] + n1 * B[b, 16] + n2 * B[b, 17]
    r = B[b, 18] + mb
    if sc - r > lim + SLACK_REL * r + SLACK_POS * pos:
        return False
    c = n0 * B[b, 0] + n1 * B[b, 1] + n2 * B[b, 2]
    ext = 0.0
    for i in range(3):
        ext += abs(n0 * B[b, 3 + i] + n1 * B[b, 6 + i] + n2 * B[b, 9 + i]) * (B[b, 12 + i] + mb)
    return c - ext <= lim + SLACK_REL * ext + SLACK_POS * pos


@nb.njit(cache=True, inline="always")
def _aabb_hit(X, x, Y, y):
    return (X[x, 0] <= Y[y, 3] and Y[y, 0] <= X[x, 3] and X[x, 1] <= Y[y, 4] and Y[y, 1] <= X[x, 4]
            and X[x, 2] <= Y[y, 5] and Y[y, 2] <= X[x, 5])


@nb.njit(cache=True, inline="always")
def _aabb_plane_hit(X, x, pl, q, mq):
    v = 0.0
    for k in range(3):
        n = pl[q, k]
        v += n * (X[x, k] if n > 0 else X[x, 3 + k])
    return v <= pl[q, 3] + mq + SLACK_POS * (abs(v) + abs(pl[q, 3]))


@nb.njit(cache=True, inline="always")
def _in_sorted(keys, key):
    i = np.searchsorted(keys, key)
    return i < keys.shape[0] and keys[i] == key


@nb.njit(cache=True, inline="always")
def _emit(keys, k, g1, g2, G):
    if k < keys.shape[0]:
        keys[k] = g1 * G + g2 if g1 < g2 else g2 * G + g1
    return k + 1


@nb.njit(cache=True)
def _body_filter(x, y, order, parent_pos, weld, filter_parent, ctor, caor, excl, L):
    # Static body-level filter; True when some geom pair of x, y may still pass.
    if (ctor[x] & caor[y]) == 0 and (ctor[y] & caor[x]) == 0:
        return False
    return _body_rules(x, y, order, parent_pos, weld, filter_parent, excl, L)


@nb.njit(cache=True)
def _body_rules(x, y, order, parent_pos, weld, filter_parent, excl, L):
    # Weld groups, the parent rule and excluded body pairs (positions x, y).
    if weld[x] == weld[y]:
        return False
    if filter_parent:
        if (parent_pos[x] == y and y != 0) or (parent_pos[y] == x and x != 0):
            return False
    if excl.shape[0] > 0:
        bx = order[x]
        by = order[y]
        key = bx * L + by if bx < by else by * L + bx
        if _in_sorted(excl, key):
            return False
    return True


@nb.njit(cache=True)
def _body_pair(x, y, st, ws, keys, k, stats):
    (order, parent_pos, weld, filter_parent, ctor, caor, excl, gstart, pgeoms, single, pairflag,
     pair_keys, gct, gca, gmargin, G, L) = st
    bw, gw = ws
    if not _body_filter(x, y, order, parent_pos, weld, filter_parent, ctor, caor, excl, L):
        return k
    stats[ST_BODY_SPHERE] += 1
    if not _sphere_hit(bw, x, 0.0, bw, y, 0.0):
        return k
    stats[ST_BODY_OBB] += 1
    if not obb_hit(bw, x, 0.0, bw, y, 0.0):
        return k
    both_single = single[x] and single[y]
    check_pairs = pair_keys.shape[0] > 0 and pairflag[x] and pairflag[y]
    for ii in range(gstart[x], gstart[x + 1]):
        g1 = pgeoms[ii]
        for jj in range(gstart[y], gstart[y + 1]):
            g2 = pgeoms[jj]
            if (gct[g1] & gca[g2]) == 0 and (gct[g2] & gca[g1]) == 0:
                continue
            if check_pairs:
                key = g1 * G + g2 if g1 < g2 else g2 * G + g1
                if _in_sorted(pair_keys, key):
                    continue
            if not both_single:
                A = bw if single[x] else gw
                a = x if single[x] else g1
                ma = 0.0 if single[x] else gmargin[g1]
                B = bw if single[y] else gw
                b = y if single[y] else g2
                mb = 0.0 if single[y] else gmargin[g2]
                stats[ST_GEOM_SPHERE] += 1
                if not _sphere_hit(A, a, ma, B, b, mb):
                    continue
                stats[ST_GEOM_OBB] += 1
                if not obb_hit(A, a, ma, B, b, mb):
                    continue
            k = _emit(keys, k, g1, g2, G)
    return k


@nb.njit(cache=True)
def _body_vs_subtree(a, root, end, baabb, saabb, hasb, st, ws, keys, k, stats):
    # Body a against every body of the subtree at position root, skipping missed subtrees whole.
    q = root
    stop = end[root]
    while q < stop:
        stats[ST_SUBTREE] += 1
        if _aabb_hit(baabb, a, saabb, q):
            if hasb[q]:
                stats[ST_BODY_AABB] += 1
                if _aabb_hit(baabb, a, baabb, q):
                    k = _body_pair(a, q, st, ws, keys, k, stats)
            q += 1
        else:
            q = end[q]
    return k


@nb.njit(cache=True)
def _subtree_pair(A, B, end, baabb, saabb, hasb, st, ws, keys, k, stats):
    # Every body of subtree A against every body of subtree B (disjoint subtrees).
    a = A
    stop = end[A]
    while a < stop:
        stats[ST_SUBTREE] += 1
        if _aabb_hit(saabb, a, saabb, B):
            if hasb[a]:
                k = _body_vs_subtree(a, B, end, baabb, saabb, hasb, st, ws, keys, k, stats)
            a += 1
        else:
            a = end[a]
    return k


@nb.njit(cache=True)
def _children_pairs(n, nchild, child_start, children, sap, saabb, end, baabb, hasb, st, ws, keys, k, stats):
    kc = nchild[n]
    off = child_start[n]
    if kc <= SAP_MIN:
        for i in range(kc):
            ci = children[off + i]
            for j in range(i + 1, kc):
                cj = children[off + j]
                stats[ST_SUBTREE] += 1
                if _aabb_hit(saabb, ci, saabb, cj):
                    k = _subtree_pair(ci, cj, end, baabb, saabb, hasb, st, ws, keys, k, stats)
        return k
    # Sweep and prune on the axis of the node's largest extent. The order persists between calls
    # (sap holds it), so insertion sort is ~linear under small motion; a big reshuffle (a new
    # world in a batch, an axis change) falls back to a full sort.
    ax = 0
    best = -1.0
    for d in range(3):
        e = saabb[n, 3 + d] - saabb[n, d]
        if e > best:
            best = e
            ax = d
    swaps = 0
    limit = 16 * kc + 64
    for i in range(1, kc):
        c = sap[off + i]
        v = saabb[c, ax]
        j = i - 1
        while j >= 0 and saabb[sap[off + j], ax] > v:
            sap[off + j + 1] = sap[off + j]
            j -= 1
            swaps += 1
        sap[off + j + 1] = c
        if swaps > limit:
            break
    if swaps > limit:
        lo = np.empty(kc)
        for i in range(kc):
            lo[i] = saabb[children[off + i], ax]
        idx = np.argsort(lo)
        for i in range(kc):
            sap[off + i] = children[off + idx[i]]
    for i in range(kc):
        ci = sap[off + i]
        hi = saabb[ci, 3 + ax]
        for j in range(i + 1, kc):
            cj = sap[off + j]
            if saabb[cj, ax] > hi:
                break
            stats[ST_SUBTREE] += 1
            if _aabb_hit(saabb, ci, saabb, cj):
                k = _subtree_pair(ci, cj, end, baabb, saabb, hasb, st, ws, keys, k, stats)
    return k


@nb.njit(cache=True)
def _geom_world(g, body_pos, body_rot, geom_bid, glocal, out, o):
    b = geom_bid[g]
    _world_row(body_rot[b], body_pos[b], glocal, g, out, o, 0.0)


@nb.njit(cache=True)
def _plane_world(g, body_pos, body_rot, geom_bid, gplane, out, o):
    b = geom_bid[g]
    R = body_rot[b]
    d = gplane[g, 3]
    for i in range(3):
        n = R[i, 0] * gplane[g, 0] + R[i, 1] * gplane[g, 1] + R[i, 2] * gplane[g, 2]
        out[o, i] = n
        d += n * body_pos[b, i]
    out[o, 3] = d


@nb.njit(cache=True)
def _world(body_pos, body_rot, order, pos_of, end, parent_pos, weld, filter_parent, nchild,
           child_start, children, gstart, pgeoms, single, hasb, pairflag, ctor, caor, excl,
           planes, plane_pos, geom_bid, gct, gca, gmargin, blocal, glocal, gplane, pair_g,
           pair_m, pair_keys, bw, gw, baabb, saabb, plw, tmp, sap, keys, stats, info):
    """One world: validate poses, world bounds, tree culling, filters; returns the pair count.

    On a bad pose, info[0] gets the status code, info[1] the body id, and -1 is returned.
    Keys beyond ``keys.shape[0]`` are counted but not written (the caller grows and reruns).
    """
    L = order.shape[0]
    G = gct.shape[0]
    for s in range(N_STATS):
        stats[s] = 0
    # 1. poses -> world bounds of bodies, by body id so the first offender is named.
    for b in range(L):
        R = body_rot[b]
        p = body_pos[b]
        fin = True
        for i in range(3):
            if not np.isfinite(p[i]):
                fin = False
            for j in range(3):
                if not np.isfinite(R[i, j]):
                    fin = False
        if not fin:
            info[0] = BAD_NONFINITE
            info[1] = b
            return -1
        err = 0.0
        for i in range(3):
            for j in range(3):
                v = R[0, i] * R[0, j] + R[1, i] * R[1, j] + R[2, i] * R[2, j] - (1.0 if i == j else 0.0)
                err = max(err, abs(v))
        det = (R[0, 0] * (R[1, 1] * R[2, 2] - R[1, 2] * R[2, 1]) - R[0, 1] * (R[1, 0] * R[2, 2] - R[1, 2] * R[2, 0])
               + R[0, 2] * (R[1, 0] * R[2, 1] - R[1, 1] * R[2, 0]))
        if err > ORTHO_TOL or det <= 0.0:
            info[0] = BAD_ROTATION
            info[1] = b
            return -1
        x = pos_of[b]
        if hasb[x]:
            _world_row(R, p, blocal, x, bw, x, 0.0)
            for i in range(3):
                h = (abs(bw[x, 3 + 3 * i]) * bw[x, 12] + abs(bw[x, 4 + 3 * i]) * bw[x, 13]
                     + abs(bw[x, 5 + 3 * i]) * bw[x, 14])
                baabb[x, i] = bw[x, i] - h
                baabb[x, 3 + i] = bw[x, i] + h
        else:
            for i in range(3):
                baabb[x, i] = BIG
                baabb[x, 3 + i] = -BIG
            for i in range(ROW):
                bw[x, i] = 0.0
            bw[x, 18] = -BIG
        if not single[x]:
            for ii in range(gstart[x], gstart[x + 1]):
                g = pgeoms[ii]
                _world_row(R, p, glocal, g, gw, g, 0.0)
    for i in range(planes.shape[0]):
        _plane_world(planes[i], body_pos, body_rot, geom_bid, gplane, plw, i)
    # 2. subtree AABBs: one reverse sweep, children before parents.
    saabb[:, :] = baabb
    for x in range(L - 1, 0, -1):
        q = parent_pos[x]
        for i in range(3):
            if saabb[x, i] < saabb[q, i]:
                saabb[q, i] = saabb[x, i]
            if saabb[x, 3 + i] > saabb[q, 3 + i]:
                saabb[q, 3 + i] = saabb[x, 3 + i]
    st = (order, parent_pos, weld, filter_parent, ctor, caor, excl, gstart, pgeoms, single, pairflag,
          pair_keys, gct, gca, gmargin, G, L)
    ws = (bw, gw)
    k = 0
    # 3-4. every body pair at its lowest common ancestor n.
    for n in range(L):
        if hasb[n] and end[n] > n + 1:
            k = _body_vs_subtree(n, n + 1, end, baabb, saabb, hasb, st, ws, keys, k, stats)
            # n + 1 is n's first child; the remaining children follow their siblings' ranges.
            c = end[n + 1]
            while c < end[n]:
                k = _body_vs_subtree(n, c, end, baabb, saabb, hasb, st, ws, keys, k, stats)
                c = end[c]
        if nchild[n] >= 2:
            k = _children_pairs(n, nchild, child_start, children, sap, saabb, end, baabb, hasb, st, ws,
                                keys, k, stats)
    # 5a. planes against the tree.
    for i in range(planes.shape[0]):
        qg = planes[i]
        qx = plane_pos[i]
        mq = gmargin[qg]
        x = 0
        while x < L:
            stats[ST_PLANE] += 1
            if not _aabb_plane_hit(saabb, x, plw, i, mq):
                x = end[x]
                continue
            if hasb[x] and x != qx and _body_rules(x, qx, order, parent_pos, weld, filter_parent, excl, L):
                if (gct[qg] & caor[x]) != 0 or (ctor[x] & gca[qg]) != 0:
                    stats[ST_PLANE] += 1
                    if _plane_hit(plw, i, mq, bw, x, 0.0):
                        for ii in range(gstart[x], gstart[x + 1]):
                            g = pgeoms[ii]
                            if (gct[g] & gca[qg]) == 0 and (gct[qg] & gca[g]) == 0:
                                continue
                            if pair_keys.shape[0] > 0:
                                key = g * G + qg if g < qg else qg * G + g
                                if _in_sorted(pair_keys, key):
                                    continue
                            if not single[x]:
                                stats[ST_PLANE] += 1
                                if not _plane_hit(plw, i, mq, gw, g, gmargin[g]):
                                    continue
                            k = _emit(keys, k, g, qg, G)
            x += 1
    # 5b. explicit pairs: only the bounds test, with the pair's own inflation if given.
    for i in range(pair_g.shape[0]):
        g1 = pair_g[i, 0]
        g2 = pair_g[i, 1]
        m1 = gmargin[g1] if np.isnan(pair_m[i]) else pair_m[i]
        m2 = gmargin[g2] if np.isnan(pair_m[i]) else pair_m[i]
        p1 = gplane[g1, 0] != 0.0 or gplane[g1, 1] != 0.0 or gplane[g1, 2] != 0.0
        p2 = gplane[g2, 0] != 0.0 or gplane[g2, 1] != 0.0 or gplane[g2, 2] != 0.0
        if p1 and p2:
            continue  # two halfspaces: never a pair
        if p1 or p2:
            gp, gs, mp, ms = (g1, g2, m1, m2) if p1 else (g2, g1, m2, m1)
            _plane_world(gp, body_pos, body_rot, geom_bid, gplane, tmp, 0)
            _geom_world(gs, body_pos, body_rot, geom_bid, glocal, tmp, 1)
            stats[ST_PLANE] += 1
            if _plane_hit(tmp, 0, mp, tmp, 1, ms):
                k = _emit(keys, k, g1, g2, G)
            continue
        _geom_world(g1, body_pos, body_rot, geom_bid, glocal, tmp, 0)
        _geom_world(g2, body_pos, body_rot, geom_bid, glocal, tmp, 1)
        stats[ST_GEOM_SPHERE] += 1
        if not _sphere_hit(tmp, 0, m1, tmp, 1, m2):
            continue
        stats[ST_GEOM_OBB] += 1
        if obb_hit(tmp, 0, m1, tmp, 1, m2):
            k = _emit(keys, k, g1, g2, G)
    stats[ST_OUT] = k
    if k <= keys.shape[0]:
        keys[:k].sort()
    return k


@nb.njit(cache=True)
def step(body_pos, body_rot, order, pos_of, end, parent_pos, weld, filter_parent, nchild, child_start,
         children, gstart, pgeoms, single, hasb, pairflag, ctor, caor, excl, planes, plane_pos, geom_bid,
         gct, gca, gmargin, blocal, glocal, gplane, pair_g, pair_m, pair_keys, bw, gw, baabb, saabb, plw,
         tmp, sap, keys, stats, info):
    """One world, one call: returns the ``(K, 2) int32`` pairs, or an empty array with
    ``info = (status, body, K)`` when a pose is bad (status > 0) or ``keys`` overflowed (K > cap)."""
    info[0] = OK
    k = _world(body_pos, body_rot, order, pos_of, end, parent_pos, weld, filter_parent, nchild,
               child_start, children, gstart, pgeoms, single, hasb, pairflag, ctor, caor, excl,
               planes, plane_pos, geom_bid, gct, gca, gmargin, blocal, glocal, gplane, pair_g,
               pair_m, pair_keys, bw, gw, baabb, saabb, plw, tmp, sap, keys, stats, info)
    info[2] = k
    if k < 0 or k > keys.shape[0]:
        return np.empty((0, 2), np.int32)
    G = gct.shape[0]
    out = np.empty((k, 2), np.int32)
    for i in range(k):
        out[i, 0] = keys[i] // G
        out[i, 1] = keys[i] % G
    return out


@nb.njit(cache=True, parallel=True)
def step_batch(body_pos, body_rot, order, pos_of, end, parent_pos, weld, filter_parent, nchild,
               child_start, children, gstart, pgeoms, single, hasb, pairflag, ctor, caor, excl, planes,
               plane_pos, geom_bid, gct, gca, gmargin, blocal, glocal, gplane, pair_g, pair_m, pair_keys,
               bw, gw, baabb, saabb, plw, tmp, sap, keys, stats, world_count, world_info, chunk_total):
    """Worlds split into ``C = bw.shape[0]`` contiguous chunks, one per thread (prange), each with
    its own workspace (leading axis C). World ``w``'s sorted keys follow the previous worlds of its
    chunk in ``keys[c]``; ``world_count[w]`` is its pair count (-1 with ``world_info[w]`` = (status,
    body) on a bad pose); ``chunk_total[c]`` may exceed the capacity (then the caller reruns)."""
    B = body_pos.shape[0]
    C = bw.shape[0]
    cap = keys.shape[1]
    for c in nb.prange(C):
        w0 = (B * c) // C
        w1 = (B * (c + 1)) // C
        off = 0
        st = stats[c]
        for w in range(w0, w1):
            # Beyond capacity, keep counting (on a zero-length tail) so the caller learns the size.
            start = off if off < cap else cap
            kw = _world(body_pos[w], body_rot[w], order, pos_of, end, parent_pos, weld, filter_parent,
                        nchild, child_start, children, gstart, pgeoms, single, hasb, pairflag, ctor, caor,
                        excl, planes, plane_pos, geom_bid, gct, gca, gmargin, blocal, glocal, gplane,
                        pair_g, pair_m, pair_keys, bw[c], gw[c], baabb[c], saabb[c], plw[c], tmp[c],
                        sap[c], keys[c, start:], st, world_info[w])
            world_count[w] = kw
            if kw > 0:
                off += kw
            for s in range(N_STATS):
                stats[c, N_STATS + s] += st[s]
        chunk_total[c] = off
    return 0


@nb.njit(cache=True)
def gather_batch(keys, world_count, chunk_total, G, C):
    """Rows ``(world, g1, g2)`` int32 from the chunks' keys, world by world."""
    B = world_count.shape[0]
    K = 0
    for c in range(C):
        K += chunk_total[c]
    out = np.empty((K, 3), np.int32)
    r = 0
    for c in range(C):
        w0 = (B * c) // C
        w1 = (B * (c + 1)) // C
        i = 0
        for w in range(w0, w1):
            for _ in range(world_count[w]):
                out[r, 0] = w
                out[r, 1] = keys[c, i] // G
                out[r, 2] = keys[c, i] % G
                r += 1
                i += 1
    return out
