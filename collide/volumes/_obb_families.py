"""O'Rourke's edge-pair families of box orientations, enumerated for `collide.volumes._obb_exact`.

A family is an ordered pair of hull edges ``(e1, e2)`` and an interval of ``t``: the axis
``a(t) = cos t s1 + sin t q1`` runs along the arc of ``e1`` in the hull's Gauss map (from the
normal of one of its faces towards the other's, orthogonal to the edge), the axis
``b = a x d2 / |a x d2|`` is orthogonal to ``a`` and to ``e2``'s direction ``d2``, and the
interval keeps ``b`` (or ``-b``) on the arc of ``e2``: there ``e1`` is flush with a face of the
box and ``e2`` with an adjacent one. Each pair of edges is taken in one order only, unless the
edges are orthogonal (see `_pieces`).
"""

from __future__ import annotations

import numba as nb
import numpy as np

# Slack (radians) of the edge-pair screening and the arc membership tests: generous, since a
# wider search only costs time, while a narrower one could miss a face-flush end point.
ARC_SLACK = 1e-9


@nb.njit(cache=True)
def cross3(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@nb.njit(cache=True)
def dot3(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@nb.njit(cache=True)
def _screen_pairs(s, q, phi):
    # Unordered edge pairs (i <= j) whose arcs can hold orthogonal points: a in arc i, b in
    # arc j with a . b = 0 needs the arcs' mid points c_i, c_j within rho_i + rho_j (half the
    # arcs' lengths) of a right angle, |c_i . c_j| <= sin(rho_i + rho_j).
    m = s.shape[0]
    c = np.empty((m, 3))
    rho = np.empty(m)
    sr = np.empty(m)
    cr = np.empty(m)
    for i in range(m):
        h = 0.5 * phi[i]
        for k in range(3):
            c[i, k] = np.cos(h) * s[i, k] + np.sin(h) * q[i, k]
        rho[i] = h + ARC_SLACK
        sr[i], cr[i] = np.sin(rho[i]), np.cos(rho[i])
    cap = 1024
    out = np.empty((cap, 2), dtype=np.int64)
    count = 0
    for i in range(m):
        for j in range(i, m):
            # sin(rho_i + rho_j), when rho_i + rho_j < pi / 2 (else every pair passes)
            if rho[i] + rho[j] < 0.5 * np.pi:
                cc = c[i, 0] * c[j, 0] + c[i, 1] * c[j, 1] + c[i, 2] * c[j, 2]
                if abs(cc) > sr[i] * cr[j] + cr[i] * sr[j]:
                    continue
            if count == cap:
                cap *= 2
                grown = np.empty((cap, 2), dtype=np.int64)
                grown[:count] = out[:count]
                out = grown
            out[count, 0] = i
            out[count, 1] = j
            count += 1
    return out[:count]


@nb.njit(cache=True)
def _pieces(pairs, s, q, phi):
    # The families: for each ordered pair (e1, e2) of a screened pair, the t-intervals of
    # [0, phi1] on which b(t) = a(t) x d2 / |a(t) x d2| (or -b) lies on the arc of e2. b meets
    # the arc's ends where a . s2 = 0 and a . end2 = 0; between those cuts membership is
    # constant (b moves monotonically along its circle), so each sub-interval's midpoint
    # decides: b (or -b) is at angle psi in [0, phi2] from s2 towards q2, i.e. b . q2 >= 0 and
    # b . s2 >= cos(phi2) (phi2 <= pi), with slack. Returns the edge ids (K, 2) int64, the
    # intervals (K, 2) float64 and a sort key (K,): where b sits on the circle orthogonal to a
    # at the midpoint (its angle from d1, which lies on that circle for every a of e1's arc).
    m = s.shape[0]
    d = np.empty((m, 3))
    end = np.empty((m, 3))
    cos_end = np.empty(m)
    for e in range(m):
        cross3(s[e], q[e], d[e])
        for k in range(3):
            end[e, k] = np.cos(phi[e]) * s[e, k] + np.sin(phi[e]) * q[e, k]
        cos_end[e] = np.cos(phi[e] + ARC_SLACK) if phi[e] + ARC_SLACK < np.pi else -1.0
    cap = 2 * pairs.shape[0] + 16
    ids = np.empty((cap, 2), dtype=np.int64)
    span = np.empty((cap, 2))
    key = np.empty(cap)
    count = 0
    cuts = np.empty(8)
    for p in range(pairs.shape[0]):
        for order in range(2):
            e1, e2 = pairs[p, order], pairs[p, 1 - order]
            # Unless d1 is orthogonal to d2, the pair's curve {a on C1, b on C2, a . b = 0} is
            # a x d2 / |a x d2| over a on C1 and also b x d1 / |b x d1| over b on C2: one order
            # covers it. Orthogonal edges give two branches (b = +-d1 with a on C1, and a = +-d2
            # with b on C2), one per order.
            if order == 1 and (e1 == e2 or abs(dot3(d[e1], d[e2])) > ARC_SLACK):
                break
            n = 2
            cuts[0] = 0.0
            cuts[1] = phi[e1]
            for w in range(2):
                x = s[e2] if w == 0 else end[e2]
                A = s[e1, 0] * x[0] + s[e1, 1] * x[1] + s[e1, 2] * x[2]
                B = q[e1, 0] * x[0] + q[e1, 1] * x[1] + q[e1, 2] * x[2]
                if abs(A) + abs(B) < 1e-15:
                    continue  # a . x = 0 for every t: no cut
                tt = np.arctan2(-A, B) % np.pi  # A cos t + B sin t = 0
                while tt < phi[e1]:
                    if tt > 0.0:
                        # insertion into the sorted cuts
                        j = n
                        while j > 0 and cuts[j - 1] > tt:
                            cuts[j] = cuts[j - 1]
                            j -= 1
                        cuts[j] = tt
                        n += 1
                    tt += np.pi
            for k in range(n - 1):
                lo, hi = cuts[k], cuts[k + 1]
                if k > 0 and hi == lo:
                    continue
                tm = 0.5 * (lo + hi)
                ct, st = np.cos(tm), np.sin(tm)
                a0 = ct * s[e1, 0] + st * q[e1, 0]
                a1 = ct * s[e1, 1] + st * q[e1, 1]
                a2 = ct * s[e1, 2] + st * q[e1, 2]
                v0 = a1 * d[e2, 2] - a2 * d[e2, 1]
                v1 = a2 * d[e2, 0] - a0 * d[e2, 2]
                v2 = a0 * d[e2, 1] - a1 * d[e2, 0]
                nv = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
                if nv < 1e-12:
                    # a = +-d2: every b orthogonal to a and d2 is the limit b = d1
                    v0, v1, v2, nv = d[e1, 0], d[e1, 1], d[e1, 2], 1.0
                v0, v1, v2 = v0 / nv, v1 / nv, v2 / nv
                xs = v0 * s[e2, 0] + v1 * s[e2, 1] + v2 * s[e2, 2]
                xq = v0 * q[e2, 0] + v1 * q[e2, 1] + v2 * q[e2, 2]
                if not ((xq >= -ARC_SLACK and xs >= cos_end[e2])
                        or (-xq >= -ARC_SLACK and -xs >= cos_end[e2])):
                    continue
                if count == cap:
                    cap *= 2
                    g1 = np.empty((cap, 2), dtype=np.int64)
                    g1[:count] = ids[:count]
                    ids = g1
                    g2 = np.empty((cap, 2))
                    g2[:count] = span[:count]
                    span = g2
                    g3 = np.empty(cap)
                    g3[:count] = key[:count]
                    key = g3
                # b's angle from d1 on the circle orthogonal to a (basis d1, a x d1)
                y0 = a1 * d[e1, 2] - a2 * d[e1, 1]
                y1 = a2 * d[e1, 0] - a0 * d[e1, 2]
                y2 = a0 * d[e1, 1] - a1 * d[e1, 0]
                ids[count, 0] = e1
                ids[count, 1] = e2
                span[count, 0] = lo
                span[count, 1] = hi
                key[count] = np.arctan2(v0 * y0 + v1 * y1 + v2 * y2,
                                        v0 * d[e1, 0] + v1 * d[e1, 1] + v2 * d[e1, 2]) % np.pi
                count += 1
    return ids[:count], span[:count], key[:count]


@nb.njit(cache=True)
def _order(ids, key, m):
    # Families grouped by e1 (a counting sort over the m edges) and, within a group, by key:
    # consecutive evaluations are then close, and the hill climbs warm.
    k = ids.shape[0]
    start = np.zeros(m + 1, dtype=np.int64)
    for f in range(k):
        start[ids[f, 0] + 1] += 1
    for e in range(m):
        start[e + 1] += start[e]
    fill = start[:-1].copy()
    out = np.empty(k, dtype=np.int64)
    for f in range(k):
        e = ids[f, 0]
        out[fill[e]] = f
        fill[e] += 1
    for e in range(m):
        group = out[start[e]:start[e + 1]]
        out[start[e]:start[e + 1]] = group[np.argsort(key[group])]
    return out


def families(s: np.ndarray, q: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The edge-pair families of a Gauss map (edge arcs ``s, q (E, 3)``, ``phi (E,)``).

    Returns ``ids (K, 2) int64`` (e1, e2) and ``span (K, 2) float64`` (the interval of t),
    grouped by e1 and ordered along b within a group.
    """
    ids, span, key = _pieces(_screen_pairs(s, q, phi), s, q, phi)
    order = _order(ids, key, len(phi))
    return ids[order], span[order]
