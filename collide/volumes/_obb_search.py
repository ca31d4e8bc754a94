"""Branch and bound on t over the edge-pair families (`collide.volumes._obb_families`), for
`collide.volumes._obb_exact`: the least box volume of each family to a relative ``TOL``, with
certified lower bounds (see `_interval`).

The box of family ``(e1, e2)`` at ``t`` has axes ``a(t)``, ``b(t) = a x d2 / |a x d2|`` and
``c = a x b``; its volume is measured by hill climbing on the hull's vertex graph (a vertex with
no better neighbour is the support of a convex polytope), warm-started from the last supports.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._obb_families import cross3, dot3, families

# Relative gap at which the branch and bound stops: a family is dropped once its lower bound
# is within TOL of the best box found.
TOL = 1e-12
# Intervals of t (radians) narrower than this are not split further (their midpoint is taken):
# where the bounds blow up (a family through a = +-d2, where b(t) has no formula) the true
# volume is still continuous, and such an interval moves the box by less than rounding.
_H_MIN = 1e-13


@nb.njit(cache=True)
def _climb(P, start, adj, v, u, sign):
    # Support vertex of the polytope in direction sign * u by hill climbing from vertex v.
    best = sign * (P[v, 0] * u[0] + P[v, 1] * u[1] + P[v, 2] * u[2])
    while True:
        nxt = -1
        for k in range(start[v], start[v + 1]):
            w = adj[k]
            f = sign * (P[w, 0] * u[0] + P[w, 1] * u[1] + P[w, 2] * u[2])
            if f > best:
                best = f
                nxt = w
        if nxt < 0:
            return v
        v = nxt


@nb.njit(cache=True)
def _family(s, q, e1, e2, fam):
    # The constants of family (e1, e2): s1 q1 d1 s2 q2 d2 (18), then A1 B1 A2 B2 D p0 qc rs.
    # With alpha = a . q2 = A1 cos t + B1 sin t and beta = -a . s2 = A2 cos t + B2 sin t,
    # a x d2 = alpha s2 + beta q2, so b turns along its circle at psi' = D / |a x d2|^2
    # (D = A1 B2 - A2 B1), and |a x d2|^2 = p0 + qc cos 2t + rs sin 2t. fam[26] is b's sign.
    for k in range(3):
        fam[k] = s[e1, k]
        fam[3 + k] = q[e1, k]
        fam[9 + k] = s[e2, k]
        fam[12 + k] = q[e2, k]
    cross3(fam[0:3], fam[3:6], fam[6:9])
    cross3(fam[9:12], fam[12:15], fam[15:18])
    a1, b1 = dot3(fam[0:3], fam[12:15]), dot3(fam[3:6], fam[12:15])
    a2, b2 = -dot3(fam[0:3], fam[9:12]), -dot3(fam[3:6], fam[9:12])
    fam[18], fam[19], fam[20], fam[21] = a1, b1, a2, b2
    fam[22] = a1 * b2 - a2 * b1
    fam[23] = 0.5 * (a1 * a1 + b1 * b1 + a2 * a2 + b2 * b2)
    fam[24] = 0.5 * (a1 * a1 - b1 * b1 + a2 * a2 - b2 * b2)
    fam[25] = a1 * b1 + a2 * b2
    fam[26] = 1.0


@nb.njit(cache=True)
def _axes(t, fam, ax):
    # The box of the family at t: rows ax[0:3] = a, b, c and ax[3:6] = a', b', c' (d/dt).
    # Returns psi' (b's angular speed). a' = d1 x a; b' = psi' (d2 x b); c' = a' x b + a x b'.
    ct, st = np.cos(t), np.sin(t)
    a, b, c, ap, bp, cp = ax[0], ax[1], ax[2], ax[3], ax[4], ax[5]
    for k in range(3):
        a[k] = ct * fam[k] + st * fam[3 + k]
    al = fam[18] * ct + fam[19] * st
    be = fam[20] * ct + fam[21] * st
    ss = al * al + be * be
    if ss > 1e-28:
        r = fam[26] / np.sqrt(ss)
        for k in range(3):
            b[k] = (al * fam[9 + k] + be * fam[12 + k]) * r
        psi1 = fam[22] / ss
    else:  # a = +-d2 (so d2 is orthogonal to d1 and D = 0): the limit of b is +-d1
        for k in range(3):
            b[k] = fam[26] * fam[6 + k]
        psi1 = 0.0
    cross3(a, b, c)
    cross3(fam[6:9], a, ap)
    cross3(fam[15:18], b, bp)
    for k in range(3):
        bp[k] *= psi1
    cross3(ap, b, cp)
    cross3(a, bp, ax[6])
    for k in range(3):
        cp[k] += ax[6, k]
    return psi1


@nb.njit(cache=True)
def _measure(P, start, adj, ax, sup, radius):
    # Volume of the box with axes ax[0:3] around the polytope; its supports sup (6,) (the
    # highest and lowest vertex along each axis) are found by climbing from the given ones.
    vol = 1.0
    for i in range(3):
        u = ax[i]
        sup[2 * i] = _climb(P, start, adj, sup[2 * i], u, 1.0)
        sup[2 * i + 1] = _climb(P, start, adj, sup[2 * i + 1], u, -1.0)
        hv, lv = sup[2 * i], sup[2 * i + 1]
        w = ((P[hv, 0] - P[lv, 0]) * u[0] + (P[hv, 1] - P[lv, 1]) * u[1]
             + (P[hv, 2] - P[lv, 2]) * u[2])
        vol *= max(w, 0.0) + 2.0 * radius
    return vol


@nb.njit(cache=True)
def _fixed(P, sup, ax, radius, out):
    # The lower-bound function of the supports sup at the axes ax: out[0] = G_i = g_i + 2r with
    # g_i = (p_i - q_i) . u_i (never above the true width at any t), out[1] = g_i', out[2] =
    # |p_i - q_i|. Returns prod(G_i).
    vol = 1.0
    for i in range(3):
        hv, lv = sup[2 * i], sup[2 * i + 1]
        dx, dy, dz = P[hv, 0] - P[lv, 0], P[hv, 1] - P[lv, 1], P[hv, 2] - P[lv, 2]
        out[0, i] = dx * ax[i, 0] + dy * ax[i, 1] + dz * ax[i, 2] + 2.0 * radius
        out[1, i] = dx * ax[3 + i, 0] + dy * ax[3 + i, 1] + dz * ax[3 + i, 2]
        out[2, i] = np.sqrt(dx * dx + dy * dy + dz * dz)
        vol *= out[0, i]
    return vol


@nb.njit(cache=True)
def _s2_min(fam, lo, hi):
    # Minimum over t in [lo, hi] of |a(t) x d2|^2 = alpha^2 + beta^2 = p0 + qc cos 2t + rs sin 2t.
    # Without cancellation: at the ends from alpha and beta themselves, and at the trough (if
    # inside) as D^2 / (p0 + k), the product of the squared singular values of (alpha, beta)'s
    # 2 x 2 map over its largest, rather than p0 - k.
    m = np.inf
    for t in (lo, hi):
        ct, st = np.cos(t), np.sin(t)
        al = fam[18] * ct + fam[19] * st
        be = fam[20] * ct + fam[21] * st
        m = min(m, al * al + be * be)
    p0, qc, rs = fam[23], fam[24], fam[25]
    k = np.sqrt(qc * qc + rs * rs)
    if k > 0.0:
        trough = 0.5 * (np.arctan2(rs, qc) + np.pi)  # 2t - atan2(rs, qc) = pi
        trough = lo + (trough - lo) % np.pi
        if trough <= hi:
            m = fam[22] * fam[22] / (p0 + k)
    return m


@nb.njit(cache=True)
def _speeds(fam, lo, hi, spd):
    # Bounds over [lo, hi] of |u_i'| (spd[0]) and |u_i''| (spd[1]) for the axes a, b, c:
    # |a'| = |a''| = 1; |b'| = |psi'| and |b''| <= psi'^2 + |psi''| with psi' = D / s2 and
    # psi'' = -D s2' / s2^2, s2 = |a x d2|^2 (|s2'| <= 2 sqrt(qc^2 + rs^2)); c = a x b.
    # False where they are unbounded (s2 reaches 0 with D != 0).
    dd = abs(fam[22])
    if dd == 0.0:
        p1, p2 = 0.0, 0.0
    else:
        s2m = _s2_min(fam, lo, hi)
        if s2m <= 0.0:
            return False
        p1 = dd / s2m
        p2 = dd * 2.0 * np.sqrt(fam[24] * fam[24] + fam[25] * fam[25]) / (s2m * s2m)
    bdd = p1 * p1 + p2
    spd[0, 0], spd[1, 0] = 1.0, 1.0
    spd[0, 1], spd[1, 1] = p1, bdd
    spd[0, 2], spd[1, 2] = 1.0 + p1, 1.0 + 2.0 * p1 + bdd
    return np.isfinite(spd[1, 2])


@nb.njit(cache=True)
def _taylor(g, spd, h):
    # For a lower-bound function G = prod(G_i) known at an interval's midpoint (g = _fixed's
    # out) and the axes' speed bounds spd over the interval (width h): returns (lb, slope,
    # m2): lb bounds G over the interval from below (the larger of the product of the factors'
    # own bounds and G(t) - |G'(t)| h/2 - M2 h^2/8), slope = G'(t), m2 >= |G''| there; lb = -1
    # where a factor can reach a negative value (G is then no bound of the volume).
    lb1 = 1.0
    gd0, gd1, gd2 = g[2, 0] * spd[0, 0], g[2, 1] * spd[0, 1], g[2, 2] * spd[0, 2]
    for i in range(3):
        low = g[0, i] - g[2, i] * spd[0, i] * 0.5 * h
        if not low >= 0.0:  # also catches nan
            return -1.0, 0.0, np.inf
        lb1 *= low
    x0 = g[0, 0] + gd0 * 0.5 * h
    x1 = g[0, 1] + gd1 * 0.5 * h
    x2 = g[0, 2] + gd2 * 0.5 * h
    m2 = (g[2, 0] * spd[1, 0] * x1 * x2 + g[2, 1] * spd[1, 1] * x0 * x2 + g[2, 2] * spd[1, 2] * x0 * x1
          + 2.0 * (gd0 * gd1 * x2 + gd0 * gd2 * x1 + gd1 * gd2 * x0))
    v = g[0, 0] * g[0, 1] * g[0, 2]
    slope = g[1, 0] * g[0, 1] * g[0, 2] + g[0, 0] * g[1, 1] * g[0, 2] + g[0, 0] * g[0, 1] * g[1, 2]
    return max(lb1, v - abs(slope) * 0.5 * h - m2 * h * h / 8.0), slope, m2


@nb.njit(cache=True)
def _fixed_at(t, fam, P, sup, radius, ax, g):
    _axes(t, fam, ax)
    return _fixed(P, sup, ax, radius, g)


@nb.njit(cache=True)
def _crossing(lo, hi, fam, P, sup_l, sup_h, radius, ax, g):
    # Least value on [lo, hi] of max(G_L, G_H) for G_L decreasing and G_H increasing there:
    # the bracket [ta, tb] of their crossing is narrowed (regula falsi, Illinois), then for
    # t <= ta max >= G_L(ta), for t >= tb max >= G_H(tb), between max >= max(G_L(tb), G_H(ta)),
    # the least of which is the latter. Returns (bound, a point of the bracket).
    ta, tb = lo, hi
    fa = _fixed_at(ta, fam, P, sup_l, radius, ax, g) - _fixed_at(ta, fam, P, sup_h, radius, ax, g)
    fb = _fixed_at(tb, fam, P, sup_l, radius, ax, g) - _fixed_at(tb, fam, P, sup_h, radius, ax, g)
    if not (fa >= 0.0 and fb <= 0.0):
        return -1.0, 0.5 * (lo + hi)
    side = 0
    for _ in range(40):
        if tb - ta <= 1e-15 * (1.0 + abs(ta)) or fa == fb:
            break
        tc = (ta * fb - tb * fa) / (fb - fa)
        if not ta < tc < tb:
            tc = 0.5 * (ta + tb)
        fc = _fixed_at(tc, fam, P, sup_l, radius, ax, g) - _fixed_at(tc, fam, P, sup_h, radius, ax, g)
        if fc >= 0.0:
            ta, fa = tc, fc
            if side == 1:
                fb *= 0.5
            side = 1
        else:
            tb, fb = tc, fc
            if side == -1:
                fa *= 0.5
            side = -1
    lb = max(_fixed_at(tb, fam, P, sup_l, radius, ax, g), _fixed_at(ta, fam, P, sup_h, radius, ax, g))
    return lb, 0.5 * (ta + tb)


@nb.njit(cache=True)
def _frozen(P, sup, ax, ax_lo, ax_hi, radius, h, tmp):
    # Lower bound over [lo, hi] (width h) of the bound function of the supports sup, taking b's
    # motion as a displacement: b(x) stays within beta = max |b(end) - b(t)| of b = b(t) (it
    # turns one way along its circle), so g_b >= g_b(t) - |d_b| beta and, as c = a x b,
    # g_c(x) >= d_c . (a(x) x b) - |d_c| beta. What is left, F = G_a(x) (d_c . (a(x) x b) + 2r -
    # |d_c| beta), has |a'| = |a''| = 1 only: its Taylor bound stays sharp where b's speed
    # bounds blow up (near a = +-d2, where b hardly moves), and where F cannot turn on the
    # interval its least value is at an end. tmp: (3,) scratch.
    a, b = ax[0], ax[1]
    beta = 0.0
    for e in range(2):
        x = ax_lo[1] if e == 0 else ax_hi[1]
        beta = max(beta, np.sqrt((x[0] - b[0]) ** 2 + (x[1] - b[1]) ** 2 + (x[2] - b[2]) ** 2))
    ha, la, hb, lb_, hc, lc = sup[0], sup[1], sup[2], sup[3], sup[4], sup[5]
    da0, da1, da2 = P[ha, 0] - P[la, 0], P[ha, 1] - P[la, 1], P[ha, 2] - P[la, 2]
    db0, db1, db2 = P[hb, 0] - P[lb_, 0], P[hb, 1] - P[lb_, 1], P[hb, 2] - P[lb_, 2]
    dc0, dc1, dc2 = P[hc, 0] - P[lc, 0], P[hc, 1] - P[lc, 1], P[hc, 2] - P[lc, 2]
    na = np.sqrt(da0 * da0 + da1 * da1 + da2 * da2)
    nb_ = np.sqrt(db0 * db0 + db1 * db1 + db2 * db2)
    nc = np.sqrt(dc0 * dc0 + dc1 * dc1 + dc2 * dc2)
    gb = db0 * b[0] + db1 * b[1] + db2 * b[2] + 2.0 * radius - nb_ * beta
    ga = da0 * a[0] + da1 * a[1] + da2 * a[2] + 2.0 * radius
    c = ax[2]
    hh = dc0 * c[0] + dc1 * c[1] + dc2 * c[2] + 2.0 * radius - nc * beta
    low_a, low_h = ga - na * 0.5 * h, hh - nc * 0.5 * h
    if not (gb >= 0.0 and low_a >= 0.0 and low_h >= 0.0):
        return 0.0
    cross3(ax[3], b, tmp)  # a' x b
    f = ga * hh
    ap = ax[3]
    fp = (da0 * ap[0] + da1 * ap[1] + da2 * ap[2]) * hh + ga * (dc0 * tmp[0] + dc1 * tmp[1] + dc2 * tmp[2])
    m2 = na * (hh + nc * 0.5 * h) + 2.0 * na * nc + (ga + na * 0.5 * h) * nc
    lb = max(low_a * low_h, f - abs(fp) * 0.5 * h - m2 * h * h / 8.0)
    if abs(fp) > m2 * 0.5 * h:
        end = ax_lo if fp > 0.0 else ax_hi
        cross3(end[0], b, tmp)
        e0 = end[0]
        fe = ((da0 * e0[0] + da1 * e0[1] + da2 * e0[2] + 2.0 * radius)
              * (dc0 * tmp[0] + dc1 * tmp[1] + dc2 * tmp[2] + 2.0 * radius - nc * beta))
        lb = max(lb, fe)
    return gb * lb


@nb.njit(cache=True)
def _interval(lo, hi, fam, P, start, adj, radius, sup_l, sup_h, v_lo, v_hi, sup_m, best, tol, wk):
    # One branch-and-bound step on [lo, hi], whose ends have the supports sup_l, sup_h and
    # volumes v_lo, v_hi: measures the midpoint (supports into sup_m) and bounds the volume on
    # the interval from below by the best of, for the supports of the midpoint and the ends,
    # * their Taylor bound (_taylor) and the bound with b's motion as a displacement (_frozen);
    # * monotonicity: where a bound function's slope cannot change sign on the interval
    #   (|G'(t)| > M2 h/2), its least value is at an end; for the ends' own supports that is
    #   the measured volume there;
    # * a kink: the low end's function decreasing and the high end's increasing, the volume is
    #   at least their crossing (_crossing), and where that beats the best box the crossing
    #   itself is measured (a box flush with three edges, or the like).
    # Returns (volume at the midpoint, bound, best volume measured here, its t).
    h = hi - lo
    mid = 0.5 * (lo + hi)
    thr = best * (1.0 - tol)  # a bound this high drops the interval: the cheap ones first
    ax, ax_lo, ax_hi, g, spd = wk[0:7], wk[7:14], wk[14:21], wk[21:24], wk[24:26]
    _axes(mid, fam, ax)
    sup_m[:] = sup_l
    v_mid = _measure(P, start, adj, ax, sup_m, radius)
    found, t_found = v_mid, mid
    _axes(lo, fam, ax_lo)
    _axes(hi, fam, ax_hi)
    lb = _frozen(P, sup_m, ax, ax_lo, ax_hi, radius, h, wk[26])
    if lb >= thr:
        return v_mid, lb, found, t_found
    speeds = _speeds(fam, lo, hi, spd)
    rise_m, rise_l, rise_h = 0, 0, 0  # +1: increasing on the interval, -1: decreasing
    for x in range(3):
        sup = sup_m if x == 0 else (sup_l if x == 1 else sup_h)
        if x > 0:
            lb = max(lb, _frozen(P, sup, ax, ax_lo, ax_hi, radius, h, wk[26]))
        if speeds:
            _fixed(P, sup, ax, radius, g)
            b, slope, m2 = _taylor(g, spd, h)
            lb = max(lb, b)
            if b >= 0.0 and abs(slope) > m2 * 0.5 * h:
                rise = 1 if slope > 0.0 else -1
                if x == 0:
                    rise_m = rise
                elif x == 1:
                    rise_l = rise
                else:
                    rise_h = rise
        if lb >= thr:
            return v_mid, lb, found, t_found
    if rise_l == 1:
        lb = max(lb, v_lo)
    if rise_h == -1:
        lb = max(lb, v_hi)
    if rise_m != 0:
        lb = max(lb, _fixed(P, sup_m, ax_lo if rise_m == 1 else ax_hi, radius, g))
    if rise_l == -1 and rise_h == 1 and lb < thr:
        cross, tc = _crossing(lo, hi, fam, P, sup_l, sup_h, radius, ax, g)
        lb = max(lb, cross)
        if cross >= 0.0 and cross < thr:
            _axes(tc, fam, ax)
            sup = sup_m.copy()
            v = _measure(P, start, adj, ax, sup, radius)
            if v < found:
                found, t_found = v, tc
    return v_mid, lb, found, t_found


@nb.njit(cache=True)
def _search(P, start, adj, s, q, ids, span, radius, best, best_frame, tol, budget):
    # Branch and bound over every family; best / best_frame: the incumbent (volume, axes as
    # columns), improved in place. Returns (best volume, evaluations).
    k = ids.shape[0]
    fam = np.empty(27)
    wk = np.zeros((32, 3))
    ax, g, spd = wk[0:7], wk[21:24], wk[24:26]
    sup = np.zeros(6, dtype=np.int64)
    sups = np.empty((k, 6), dtype=np.int64)
    sign = np.empty(k)
    v_mid = np.empty(k)
    lb_root = np.empty(k)
    last_b = np.zeros(3)
    evals = 0
    # Pass 1: the midpoint of every family, for an incumbent that prunes most families at once.
    for f in range(k):
        _family(s, q, ids[f, 0], ids[f, 1], fam)
        lo, hi = span[f, 0], span[f, 1]
        mid = 0.5 * (lo + hi)
        _axes(mid, fam, ax)
        if dot3(ax[1], last_b) < 0.0:  # b's sign is free: keep the last one's, for warm climbs
            fam[26] = -1.0
            _axes(mid, fam, ax)
        last_b[:] = ax[1]
        sign[f] = fam[26]
        vol = _measure(P, start, adj, ax, sup, radius)
        evals += 1
        if vol < best:
            best = vol
            best_frame[:, :] = ax[0:3].T
        lb = 0.0
        if _speeds(fam, lo, hi, spd):
            _fixed(P, sup, ax, radius, g)
            lb = _taylor(g, spd, hi - lo)[0]
        v_mid[f] = vol
        lb_root[f] = lb
        sups[f] = sup
    # Pass 2: branch and bound, most promising families first. A stack entry: lo, hi and the
    # volumes there (st_f), the supports there (st_i).
    depth = 256
    st_f = np.empty((depth, 4))
    st_i = np.empty((depth, 12), dtype=np.int64)
    sup_m = np.empty(6, dtype=np.int64)
    for f in np.argsort(v_mid):
        if evals > budget:  # out of budget: the best so far, not certified (the caller sees evals)
            break
        if lb_root[f] >= best * (1.0 - tol) or span[f, 1] - span[f, 0] <= _H_MIN:
            continue
        _family(s, q, ids[f, 0], ids[f, 1], fam)
        fam[26] = sign[f]
        lo, hi = span[f, 0], span[f, 1]
        top = 0
        st_f[0, 0], st_f[0, 1] = lo, hi
        for e in range(2):
            _axes(lo if e == 0 else hi, fam, ax)
            sup[:] = sups[f]
            vol = _measure(P, start, adj, ax, sup, radius)
            evals += 1
            if vol < best:
                best = vol
                best_frame[:, :] = ax[0:3].T
            st_f[0, 2 + e] = vol
            st_i[0, 6 * e:6 * e + 6] = sup
        top = 1
        while top > 0 and evals <= budget:
            top -= 1
            lo, hi, v_lo, v_hi = st_f[top, 0], st_f[top, 1], st_f[top, 2], st_f[top, 3]
            v_m, lb, found, t_found = _interval(lo, hi, fam, P, start, adj, radius, st_i[top, 0:6],
                                                st_i[top, 6:12], v_lo, v_hi, sup_m, best, tol, wk)
            evals += 1
            if found < best:
                best = found
                _axes(t_found, fam, ax)
                best_frame[:, :] = ax[0:3].T
            if lb >= best * (1.0 - tol) or hi - lo <= _H_MIN or top + 2 > depth:
                continue
            mid = 0.5 * (lo + hi)
            # children: [mid, hi] below [lo, mid], which is taken first
            st_f[top + 1, 0], st_f[top + 1, 1], st_f[top + 1, 2], st_f[top + 1, 3] = lo, mid, v_lo, v_m
            st_i[top + 1, 0:6] = st_i[top, 0:6]
            st_i[top + 1, 6:12] = sup_m
            st_f[top, 0], st_f[top, 1], st_f[top, 2], st_f[top, 3] = mid, hi, v_m, v_hi
            st_i[top, 0:6] = sup_m
            top += 2
    return best, evals


def min_volume_axes(P, start, adj, s, q, phi, radius: float, rotation: np.ndarray, tol: float = TOL,
                    budget: int = -1):
    """Axes of the minimum-volume box of ``hull(P) ⊕ ball(radius)``, given the Gauss map of
    the hull (`solid_graph` or `flat_graph`) and a starting rotation (its box is the first
    incumbent), to a relative ``tol``.

    Returns ``(rotation (3, 3) float64, volume, families, evaluations)``; columns of rotation
    are the axes, right-handed. ``P`` should be centred and of unit size (the tolerances are
    absolute in angle and relative in volume). ``budget`` (> 0): stop after about that many
    evaluations with the best box so far (then ``evaluations > budget``: not certified).
    """
    ids, span = families(s, q, phi)
    proj = P @ rotation
    best = float(np.prod(np.ptp(proj, axis=0) + 2.0 * radius))
    frame = np.ascontiguousarray(rotation, dtype=np.float64).copy()
    cap = int(budget) if budget > 0 else np.iinfo(np.int64).max
    best, evals = _search(P, start, adj, s, q, ids, span, float(radius), best, frame, float(tol), cap)
    return frame, best, len(ids), evals
