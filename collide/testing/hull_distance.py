"""Distance between two convex hulls, exactly, for the brute-force twins (`collide.testing.brute`).

- `gjk_distance`: GJK (Gilbert, Johnson and Keerthi 1988) on two point sets, with a brute-force
  Johnson sub-algorithm (every subset of the simplex tried, weights from signed volumes) and van
  den Bergen's termination; it returns bounds that meet at convergence. Independent of the
  library's `collide._kernels.gjk`.
- `hulls_intersect_lp`: whether two hulls meet, by a feasibility linear program (scipy's HiGHS):
  the slow, independent twin of ``gjk_distance(P, Q)[0] == 0``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["gjk_distance", "hulls_intersect_lp"]


@nb.njit(cache=True)
def _closest_on_simplex(W, n, lam_out):
    # Closest point to the origin of hull(W[:n]) (n <= 4, unit-size coordinates): every
    # non-empty subset's projection of the origin with non-negative weights is a point of the
    # simplex; the smallest is the answer (brute-force Johnson). The weights come from signed
    # lengths, areas and volumes (Montanari et al. 2017), linear in the subset's size: the
    # bordered Gram system used before has a determinant quadratic in it, so a tetrahedron
    # 1e-7 thin was rejected as singular and a point inside it reported 5e-8 away (review,
    # 2026-11-21). A subset thinner than 1e-13 of its edges (rounding) is skipped.
    best = np.inf
    bestmask = 0
    v = np.zeros(3)
    lam = np.zeros(4)
    idx = np.empty(4, np.int64)
    p = np.zeros(3)
    for mask in range(1, 1 << n):
        m = 0
        for i in range(n):
            if mask & (1 << i):
                idx[m] = i
                m += 1
        if not _subset_weights(W, idx, m, lam, p):
            continue
        d2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
        if d2 < best:
            best = d2
            bestmask = mask
            v[:] = p
            lam_out[:] = 0.0
            for a in range(m):
                lam_out[idx[a]] = lam[a]
    return v, bestmask


@nb.njit(cache=True)
def _det3(a, b, c):
    return (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0]))


@nb.njit(cache=True)
def _subset_weights(W, idx, m, lam, p):
    # Barycentric weights (into lam[:m]) of the origin's projection p onto the affine hull of
    # W[idx[:m]]; False when the subset is degenerate or a weight is negative (the projection
    # lies outside the subset: a smaller subset holds the closest point). p is computed
    # directly, not as sum(lam * w): that sum carries the weights' rounding times |w| (1e-9 for
    # a tetrahedron 1e-7 thin), more than the distance it should show.
    w0 = W[idx[0]]
    if m == 1:
        lam[0] = 1.0
        p[:] = w0
        return True
    if m == 2:
        e = W[idx[1]] - w0
        ee = e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
        if ee == 0.0:
            return False
        t = -(w0[0] * e[0] + w0[1] * e[1] + w0[2] * e[2]) / ee
        lam[0] = 1.0 - t
        lam[1] = t
        p[:] = w0 + t * e
        return 0.0 <= t <= 1.0
    e1 = W[idx[1]] - w0
    e2 = W[idx[2]] - w0
    l1 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]
    l2 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2]
    if m == 3:
        nrm = np.cross(e1, e2)
        nn = nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]
        if not nn > (1e-13 * max(l1, l2)) ** 2:
            return False
        # the projection p of the origin on the plane, then each weight = signed sub-area / area
        p[:] = nrm * ((nrm[0] * w0[0] + nrm[1] * w0[1] + nrm[2] * w0[2]) / nn)
        for a in range(3):
            b = W[idx[(a + 1) % 3]] - p
            c = W[idx[(a + 2) % 3]] - p
            lam[a] = np.dot(nrm, np.cross(b, c)) / nn
        return lam[0] >= 0.0 and lam[1] >= 0.0 and lam[2] >= 0.0
    e3 = W[idx[3]] - w0
    d = _det3(e1, e2, e3)
    l3 = e3[0] * e3[0] + e3[1] * e3[1] + e3[2] * e3[2]
    if not abs(d) > 1e-13 * max(l1, l2, l3) ** 1.5:
        return False
    # origin = w0 + mu . (e1, e2, e3), by Cramer's rule; inside when every weight is >= 0
    mw = -w0
    lam[1] = _det3(mw, e2, e3) / d
    lam[2] = _det3(e1, mw, e3) / d
    lam[3] = _det3(e1, e2, mw) / d
    lam[0] = 1.0 - lam[1] - lam[2] - lam[3]
    p[:] = 0.0  # the origin is its own projection onto a 3-dimensional hull
    return lam[0] >= 0.0 and lam[1] >= 0.0 and lam[2] >= 0.0 and lam[3] >= 0.0


@nb.njit(cache=True)
def gjk_distance(P, Q):
    """Euclidean distance between ``hull(P)`` and ``hull(Q)`` (``(n, 3)``, ``(m, 3)`` float64).

    Returns ``(upper, lower)``: bounds on the distance that meet at convergence (GJK, Gilbert,
    Johnson & Keerthi 1988; van den Bergen's termination, relative gap 1e-14).

    Both sets are first centred on their common mean and scaled to unit size: the simplex
    solver's singularity test is not scale-free, and on micrometre-sized shapes it accepted a
    degenerate tetrahedron and reported distance 0 for hulls 3e-7 apart (0.08 of their size).
    """
    c = np.zeros(3)
    for i in range(P.shape[0]):
        c += P[i]
    for i in range(Q.shape[0]):
        c += Q[i]
    c /= P.shape[0] + Q.shape[0]
    s = 0.0
    for i in range(P.shape[0]):
        for k in range(3):
            s = max(s, abs(P[i, k] - c[k]))
    for i in range(Q.shape[0]):
        for k in range(3):
            s = max(s, abs(Q[i, k] - c[k]))
    if s == 0.0:
        return 0.0, 0.0
    upper, lower = _gjk_unit((P - c) / s, (Q - c) / s)
    if upper <= 8.0 * np.finfo(np.float64).eps:
        # Rounding level of unit-size coordinates: the origin is inside (touching).
        return 0.0, 0.0
    return upper * s, lower * s


@nb.njit(cache=True)
def _gjk_unit(P, Q):
    # GJK proper, on sets of unit size (see gjk_distance).
    W = np.zeros((4, 3))
    lam = np.zeros(4)
    W[0] = P[0] - Q[0]
    n = 1
    v = W[0].copy()
    lower = 0.0
    for _ in range(200):
        vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
        if vv == 0.0:
            return 0.0, 0.0
        # support of P - Q in direction -v
        ip = 0
        best = np.inf
        for i in range(P.shape[0]):
            s = P[i, 0] * v[0] + P[i, 1] * v[1] + P[i, 2] * v[2]
            if s < best:
                best = s
                ip = i
        iq = 0
        best = -np.inf
        for i in range(Q.shape[0]):
            s = Q[i, 0] * v[0] + Q[i, 1] * v[1] + Q[i, 2] * v[2]
            if s > best:
                best = s
                iq = i
        w = P[ip] - Q[iq]
        vw = v[0] * w[0] + v[1] * w[1] + v[2] * w[2]
        nv = np.sqrt(vv)
        lower = max(lower, vw / nv)
        if vv - vw <= 1e-14 * vv:
            break
        dup = False
        for i in range(n):
            if W[i, 0] == w[0] and W[i, 1] == w[1] and W[i, 2] == w[2]:
                dup = True
        if dup:
            break
        W[n] = w
        n += 1
        v, mask = _closest_on_simplex(W, n, lam)
        # keep only the support subset
        m = 0
        for i in range(n):
            if mask & (1 << i):
                W[m] = W[i]
                m += 1
        n = m
        if n == 4:
            return 0.0, 0.0
    return np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), max(lower, 0.0)


def hulls_intersect_lp(P: np.ndarray, Q: np.ndarray) -> bool:
    """Whether ``hull(P)`` and ``hull(Q)`` intersect, by a feasibility linear program.

    The slow, independent twin of `gjk_distance` (``== 0``): the hulls meet iff convex weights
    ``a``, ``b`` exist with ``P^T a = Q^T b``.

    Parameters
    ----------
    P, Q : (n, 3), (m, 3) float64
    """
    from scipy.optimize import linprog

    n, m = len(P), len(Q)
    A = np.zeros((5, n + m))
    A[:3, :n], A[:3, n:] = np.asarray(P).T, -np.asarray(Q).T
    A[3, :n] = 1
    A[4, n:] = 1
    res = linprog(np.zeros(n + m), A_eq=A, b_eq=[0, 0, 0, 1, 1], bounds=(0, None), method="highs")
    return res.status == 0
