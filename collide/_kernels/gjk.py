"""GJK on the Minkowski difference ``C = A - B`` of two cores, with the signed-volume subalgorithm.

GJK (Gilbert, Johnson & Keerthi 1988) walks a simplex of support points of ``C`` towards the
origin; its closest point ``v`` is a point of ``C`` (an upper bound ``|v|`` on the distance) and
each support ``w = s_C(d)`` gives the lower bound ``-h_C(d / |d|)`` of the *signed* distance:
``sd(A, B) = max over unit u of -h_C(u)`` holds for separated and overlapping sets alike (the
separating-axis form of the distance, and of the penetration depth). The loop stops when the
two meet within ``tol``.

The closest point of a simplex to the origin is found with the signed-volume subalgorithm of
Montanari, Petrinic & Barbieri (2017, "Improving the GJK algorithm for faster and more reliable
distance queries between convex objects", ACM TOG 36(3), §3): barycentric coordinates come from
signed areas/volumes of sub-simplices, projected onto the coordinate plane (or axis) where the
simplex is largest, and a sub-face is examined only when the origin lies on its far side. It has
no tolerance for degeneracy: a flat tetrahedron or a collinear triangle has a zero signed
measure, which compares as "not same sign", so every face is examined instead (their §3.2).

Kernels take flat arrays (the shape tuples of `collide._kernels.support`), ``cache=True``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._ptr import NO_NRT
from .support import support

# Rounding floor of the tolerances, in units of the largest world coordinate seen.
_FLOOR = 16.0 * float(np.finfo(np.float64).eps)

# Outcome of `gjk`.
SEPARATED, OVERLAP, STALLED = 0, 1, 2


@njit(**NO_NRT)
def _same_sign(a, b):
    return (a > 0.0 and b > 0.0) or (a < 0.0 and b < 0.0)


@njit(**NO_NRT)
def _s1d(W, i, j):
    # Closest point of segment W[i] W[j] to the origin: (lambda_i, lambda_j, squared distance).
    t0 = W[j, 0] - W[i, 0]
    t1 = W[j, 1] - W[i, 1]
    t2 = W[j, 2] - W[i, 2]
    tt = t0 * t0 + t1 * t1 + t2 * t2
    mu = 0.0
    if tt > 0.0:
        mu = -(W[i, 0] * t0 + W[i, 1] * t1 + W[i, 2] * t2) / tt
        mu = min(max(mu, 0.0), 1.0)
    p0 = W[i, 0] + mu * t0
    p1 = W[i, 1] + mu * t1
    p2 = W[i, 2] + mu * t2
    return 1.0 - mu, mu, p0 * p0 + p1 * p1 + p2 * p2


@njit(**NO_NRT)
def _area2(W, i, j, k, u, v, p_u, p_v, which):
    # Signed doubled area, in the (u, v) coordinate plane, of triangle (W[i], W[j], W[k]) with
    # vertex ``which`` (0, 1, 2) replaced by the point (p_u, p_v).
    au, av = W[i, u], W[i, v]
    bu, bv = W[j, u], W[j, v]
    cu, cv = W[k, u], W[k, v]
    if which == 0:
        au, av = p_u, p_v
    elif which == 1:
        bu, bv = p_u, p_v
    else:
        cu, cv = p_u, p_v
    return (bu - au) * (cv - av) - (bv - av) * (cu - au)


@njit(**NO_NRT)
def s2d(W, i, j, k):
    """Closest point of triangle ``(W[i], W[j], W[k])`` to the origin (Montanari et al. S2D).

    Returns
    -------
    lam_i, lam_j, lam_k : float
        Barycentric weights (non-negative, summing to one).
    dist2 : float
        Squared distance of that point to the origin.
    """
    e0, e1, e2 = W[j, 0] - W[i, 0], W[j, 1] - W[i, 1], W[j, 2] - W[i, 2]
    f0, f1, f2 = W[k, 0] - W[i, 0], W[k, 1] - W[i, 1], W[k, 2] - W[i, 2]
    n0 = e1 * f2 - e2 * f1
    n1 = e2 * f0 - e0 * f2
    n2 = e0 * f1 - e1 * f0
    nn = n0 * n0 + n1 * n1 + n2 * n2
    if nn > 0.0:
        # Projection of the origin onto the triangle's plane.
        s = (n0 * W[i, 0] + n1 * W[i, 1] + n2 * W[i, 2]) / nn
        p = (n0 * s, n1 * s, n2 * s)
        # Drop the axis where the normal is largest; (u, v) in cyclic order so that the
        # projected area has the sign of that normal component.
        a0, a1, a2 = abs(n0), abs(n1), abs(n2)
        if a0 >= a1 and a0 >= a2:
            u, v, mu_max = 1, 2, n0
        elif a1 >= a2:
            u, v, mu_max = 2, 0, n1
        else:
            u, v, mu_max = 0, 1, n2
        c0 = _area2(W, i, j, k, u, v, p[u], p[v], 0)
        c1 = _area2(W, i, j, k, u, v, p[u], p[v], 1)
        c2 = _area2(W, i, j, k, u, v, p[u], p[v], 2)
        if _same_sign(mu_max, c0) and _same_sign(mu_max, c1) and _same_sign(mu_max, c2):
            # Divided by their sum, not by mu_max: the areas through the projected point sum
            # to the triangle's only up to rounding, and weights off 1 by 1e-12 moved the
            # witnesses by that times their distance from the origin.
            tot = c0 + c1 + c2
            l0, l1, l2 = c0 / tot, c1 / tot, c2 / tot
            x0 = l0 * W[i, 0] + l1 * W[j, 0] + l2 * W[k, 0]
            x1 = l0 * W[i, 1] + l1 * W[j, 1] + l2 * W[k, 1]
            x2 = l0 * W[i, 2] + l1 * W[j, 2] + l2 * W[k, 2]
            return l0, l1, l2, x0 * x0 + x1 * x1 + x2 * x2
        out_i, out_j, out_k = not _same_sign(mu_max, c0), not _same_sign(mu_max, c1), not _same_sign(mu_max, c2)
    else:  # degenerate (collinear or repeated points): every edge is a candidate
        out_i, out_j, out_k = True, True, True
    best = math.inf
    b0 = b1 = b2 = 0.0
    if out_i:  # the origin beyond the edge opposite i
        la, lb, d2 = _s1d(W, j, k)
        if d2 < best:
            best, b0, b1, b2 = d2, 0.0, la, lb
    if out_j:
        la, lb, d2 = _s1d(W, i, k)
        if d2 < best:
            best, b0, b1, b2 = d2, la, 0.0, lb
    if out_k:
        la, lb, d2 = _s1d(W, i, j)
        if d2 < best:
            best, b0, b1, b2 = d2, la, lb, 0.0
    return b0, b1, b2, best


@njit(**NO_NRT)
def _det3(W, i, j, k):
    # W[i] . (W[j] x W[k])
    return (W[i, 0] * (W[j, 1] * W[k, 2] - W[j, 2] * W[k, 1])
            + W[i, 1] * (W[j, 2] * W[k, 0] - W[j, 0] * W[k, 2])
            + W[i, 2] * (W[j, 0] * W[k, 1] - W[j, 1] * W[k, 0]))


@njit(**NO_NRT)
def _s3d(W, lam):
    # Closest point of tetrahedron W[0..3] to the origin (Montanari et al. S3D); fills lam[0:4]
    # and returns the squared distance (0 when the origin is inside).
    # Barycentric coordinates of the origin: the signed volume with vertex x replaced by it.
    c0 = -_det3(W, 1, 2, 3)
    c1 = _det3(W, 0, 2, 3)
    c2 = -_det3(W, 0, 1, 3)
    c3 = _det3(W, 0, 1, 2)
    mu = c0 + c1 + c2 + c3
    if _same_sign(mu, c0) and _same_sign(mu, c1) and _same_sign(mu, c2) and _same_sign(mu, c3):
        lam[0], lam[1], lam[2], lam[3] = c0 / mu, c1 / mu, c2 / mu, c3 / mu
        return 0.0
    best = math.inf
    cs = (c0, c1, c2, c3)
    for x in range(4):
        if _same_sign(mu, cs[x]):
            continue  # the origin is on this vertex's side of the opposite facet
        i, j, k = (x + 1) % 4, (x + 2) % 4, (x + 3) % 4
        li, lj, lk, d2 = s2d(W, i, j, k)
        if d2 < best:
            best = d2
            lam[x] = 0.0
            lam[i], lam[j], lam[k] = li, lj, lk
    return best


@njit(**NO_NRT)
def closest(W, n, lam):
    """Closest point of the simplex ``W[:n]`` to the origin (signed volumes).

    Parameters
    ----------
    W : (4, 3) float64
        Simplex vertices in the first ``n`` rows.
    n : int
        1 to 4.
    lam : (4,) float64
        Receives the barycentric weights of the closest point (zero for unused vertices).

    Returns
    -------
    dist2 : float
        Its squared distance to the origin.
    """
    if n == 1:
        lam[0] = 1.0
        return W[0, 0] ** 2 + W[0, 1] ** 2 + W[0, 2] ** 2
    if n == 2:
        lam[0], lam[1], d2 = _s1d(W, 0, 1)
        return d2
    if n == 3:
        lam[0], lam[1], lam[2], d2 = s2d(W, 0, 1, 2)
        return d2
    return _s3d(W, lam)


@njit(**NO_NRT)
def _push(W, WA, WB, n, pa, pb):
    for k in range(3):
        WA[n, k] = pa[k]
        WB[n, k] = pb[k]
        W[n, k] = pa[k] - pb[k]


@njit(**NO_NRT)
def _compact(W, WA, WB, lam, n):
    # Keep the vertices with positive weight (the face the closest point lies on).
    m = 0
    for i in range(n):
        if lam[i] > 0.0:
            if m != i:
                for k in range(3):
                    W[m, k] = W[i, k]
                    WA[m, k] = WA[i, k]
                    WB[m, k] = WB[i, k]
                lam[m] = lam[i]
            m += 1
    return m


@njit(**NO_NRT)
def _direction(W, n, v):
    # Next search direction, -v, taken from the simplex's feature where that is more precise,
    # and its conditioning c (its angle is known to about c times the coordinates' rounding).
    # Near touching, v is tiny and its direction is only known to eps * size / |v|; a support
    # along a direction tilted by that much loses the tilt times the feature's extent in the
    # lower bound (1e-7 of the size at a 1e-9 gap). A triangle's normal (from its edges) and v
    # made exactly perpendicular to an edge only rotate within the feature's normal cone, which
    # costs the bound second-order terms only.
    if n == 3:
        e0, e1, e2 = W[1, 0] - W[0, 0], W[1, 1] - W[0, 1], W[1, 2] - W[0, 2]
        f0, f1, f2 = W[2, 0] - W[0, 0], W[2, 1] - W[0, 1], W[2, 2] - W[0, 2]
        m0, m1, m2 = e1 * f2 - e2 * f1, e2 * f0 - e0 * f2, e0 * f1 - e1 * f0
        s = m0 * v[0] + m1 * v[1] + m2 * v[2]
        lm = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
        if lm > 0.0:
            c = (math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) + math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)) / lm
            if s > 0.0:
                return -m0, -m1, -m2, c
            if s < 0.0:
                return m0, m1, m2, c
    elif n == 2:
        e0, e1, e2 = W[1, 0] - W[0, 0], W[1, 1] - W[0, 1], W[1, 2] - W[0, 2]
        ee = e0 * e0 + e1 * e1 + e2 * e2
        if ee > 0.0:
            t = (v[0] * e0 + v[1] * e1 + v[2] * e2) / ee
            d0, d1, d2 = -(v[0] - t * e0), -(v[1] - t * e1), -(v[2] - t * e2)
            ld = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            if ld > 0.0:
                return d0, d1, d2, 1.0 / ld
    lv = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return -v[0], -v[1], -v[2], 1.0 / lv if lv > 0.0 else math.inf


@njit(**NO_NRT)
def gjk(sa, sb, d0, hints, tol, max_iter, W, WA, WB, lam, v, dirn, pa, pb):
    """GJK distance of the cores of two posed shapes, with a certified lower bound: `gjk_within`
    with no cutoff (parameters and returns as there)."""
    return gjk_within(sa, sb, d0, hints, tol, math.inf, max_iter, W, WA, WB, lam, v, dirn, pa, pb)


@njit(**NO_NRT)
def gjk_within(sa, sb, d0, hints, tol, cutoff, max_iter, W, WA, WB, lam, v, dirn, pa, pb, idx=None):
    """GJK distance of the cores of two posed shapes, with a certified lower bound.

    Parameters
    ----------
    sa, sb : tuple
        Shape tuples (`collide._kernels.support`).
    d0 : (3,) float64
        First search direction in ``C = A - B`` space (from A towards B); zero: ``pos_b - pos_a``.
    hints : (2,) int64
        Hill-climb start vertices of A and B; updated in place with the last supports.
    tol : float
        Absolute tolerance: stop when ``|v| - lower <= tol``, or call the sets overlapping when
        ``|v| <= tol``.
    cutoff : float
        Stop, `SEPARATED`, as soon as the certified lower bound exceeds it (``inf``: never): a
        contact's caller needs no distance beyond its contact distance, as MuJoCo's GJK stops at
        its ``dist_cutoff`` (engine_collision_gjk.c, ``gjk``). The simplex then holds at least
        one vertex and ``|v| >= lower``, so the distance it reports exceeds ``cutoff`` too.
    max_iter : int
        Iteration cap (the bounds stay valid when it is reached).
    W, WA, WB : (4, 3) float64
        Receive the final simplex: ``W = WA - WB``, with ``WA`` / ``WB`` the supports of A / B.
    lam : (4,) float64
        Receives the barycentric weights of the closest point.
    v : (3,) float64
        Receives the closest point of the simplex, ``sum lam W``.
    dirn : (4,) float64
        Receives the last search direction (from A towards B; any length) and its conditioning
        (its angle is known to about that times the coordinates' rounding): see `_direction`.
    pa, pb : (3,) float64
        Scratch for the support points (no allocation here: see `collide._kernels.distance`).
    idx : (8,) int64, optional
        Receives the vertex indices of A and B of the final simplex's row ``i`` in
        ``idx[2 i]``, ``idx[2 i + 1]`` (the supports' own, `collide._kernels.support.support`),
        which EPA carries into its polytope for a warm start across calls
        (`collide._kernels.epa`). Omitted: none kept (numba compiles that call without it).

    Returns
    -------
    status : int
        `SEPARATED` (bounds met within ``tol``), `OVERLAP` (the simplex holds the origin within
        ``tol``: run EPA) or `STALLED` (cap, or no progress left at rounding level).
    n : int
        Number of simplex vertices.
    lower : float
        Certified lower bound on the cores' signed distance (``-inf`` if none found).
    scale : float
        Largest absolute world coordinate of any support point seen (for rounding bounds).
    iterations : int
    """
    dx, dy, dz = d0[0], d0[1], d0[2]
    if dx == 0.0 and dy == 0.0 and dz == 0.0:
        dx, dy, dz = sb[6][0] - sa[6][0], sb[6][1] - sa[6][1], sb[6][2] - sa[6][2]
    # Scaled up where its squared length would underflow (positions 1e-160 apart, a tiny warm
    # normal): its length divides the first lower bound. The direction is what counts.
    m = max(abs(dx), abs(dy), abs(dz))
    if m == 0.0:
        dx = 1.0
    elif m < 1e-100:
        dx, dy, dz = dx / m, dy / m, dz / m
    n = 0
    lower = -math.inf
    scale = 0.0
    vv = math.inf
    cond = math.inf
    status = STALLED
    it = 0
    while it < max_iter:
        it += 1
        hints[0] = support(sa, dx, dy, dz, hints[0], pa)
        hints[1] = support(sb, -dx, -dy, -dz, hints[1], pb)
        for k in range(3):
            scale = max(scale, abs(pa[k]), abs(pb[k]))
        w0, w1, w2 = pa[0] - pb[0], pa[1] - pb[1], pa[2] - pb[2]
        dn = math.sqrt(dx * dx + dy * dy + dz * dz)
        lower = max(lower, -(dx * w0 + dy * w1 + dz * w2) / dn)  # sd >= -h_C(d / |d|)
        if lower > cutoff:
            status = SEPARATED
            if n == 0:  # the support alone: a point of C, so |v| >= lower
                _push(W, WA, WB, 0, pa, pb)
                if idx is not None:
                    idx[0], idx[1] = hints[0], hints[1]
                n = 1
                lam[0] = 1.0
                lam[1] = lam[2] = lam[3] = 0.0
                v[0], v[1], v[2] = w0, w1, w2
            break
        if n > 0 and math.sqrt(vv) - lower <= max(tol, _FLOOR * scale):
            status = SEPARATED
            break
        dup = False
        for i in range(n):
            if W[i, 0] == w0 and W[i, 1] == w1 and W[i, 2] == w2:
                dup = True
        if dup:  # the support is already a vertex: no progress is possible
            break
        _push(W, WA, WB, n, pa, pb)
        if idx is not None:
            idx[2 * n], idx[2 * n + 1] = hints[0], hints[1]
        n += 1
        for i in range(n, 4):
            lam[i] = 0.0
        vv_new = closest(W, n, lam)
        for k in range(3):
            v[k] = lam[0] * W[0, k] + lam[1] * W[1, k] + lam[2] * W[2, k] + lam[3] * W[3, k]
        if n == 4 and vv_new == 0.0:
            status = OVERLAP
            break
        if idx is not None:  # the rows `_compact` keeps, in its order
            m = 0
            for i in range(n):
                if lam[i] > 0.0:
                    idx[2 * m], idx[2 * m + 1] = idx[2 * i], idx[2 * i + 1]
                    m += 1
        n = _compact(W, WA, WB, lam, n)
        if vv_new <= tol * tol:
            status = OVERLAP
            break
        if vv_new >= vv:  # rounding level reached: |v| no longer decreases
            vv = vv_new
            break
        vv = vv_new
        dx, dy, dz, cond = _direction(W, n, v)
    dirn[0], dirn[1], dirn[2], dirn[3] = dx, dy, dz, cond
    return status, n, lower, scale, it
