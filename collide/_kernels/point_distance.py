"""Signed distance of a ball and a cylinder, cone or ellipsoid, in closed form (numba).

A sphere (a one-point core plus its radius) against a curved primitive is the query robotics
users make most (robots approximated by spheres, obstacles by primitives), and the one GJK and
EPA handle worst: the primitive's curved surface makes GJK converge linearly, and a ball deep in
a cylinder or an ellipsoid has a circle or a whole family of nearest directions, which EPA's
polytope cannot resolve before its cap. The point's signed distance to the primitive has a
closed form, computed here in the primitive's frame:

* cylinder and cone (solids of revolution): the 2-D distance from ``(hypot(x, y), z)`` to their
  meridian section, a rectangle or a right triangle (the foot on an edge, or inside, the nearest
  edge: the perpendicular foot of an interior point lies on it);
* ellipsoid: the foot ``x_i = a_i^2 p_i / (a_i^2 + t)`` at the root ``t`` of
  ``F(t) = sum (a_i p_i / (a_i^2 + t))^2 - 1``, decreasing and convex on ``(-min a_i^2, inf)``,
  where it has one root (Eberly 2013, "Distance from a point to an ellipse, an ellipsoid, or a
  hyperellipsoid"), found by Newton's method kept inside a bracket; an interior point on the
  plane of the shortest axes near the centre, where F has no root there, takes Eberly's
  degenerate foot.

The answer is then certified as `collide._kernels.distance.segment_distance` certifies its own,
in the world frame and for the sets as the support functions define them (``rot @ core + pos``
plus the core's ball, whatever the rounding of ``rot``):

* lower: the support values along the normal ``n`` found (``min n.B - max n.A``, the separating
  axis bound, valid for every ``n``, penetrating or not);
* upper, apart: the distance between the point and the foot, a point of the primitive;
* upper, overlapping: a ball about the point inside the primitive. For a cylinder or cone, the
  ball of the depth (an interior point's nearest face is at that depth). For an ellipsoid, the
  larger of two: the rolling ball, of radius ``rho <= c^2 / a`` (its rolling radius,
  `collide.support.rolling_radius`), touching the surface at the foot from inside, lies inside
  it (Blaschke's rolling theorem); and the S-lemma's bound, for one quadratic constraint an
  exact duality: every multiplier ``mu`` in ``(-min a_i^2, 0]`` gives
  ``depth^2 >= |mu| (1 - sum p_i^2 / (a_i^2 + mu))``, the depth itself at the root's ``mu``.
  The ball is carried to the world through ``rot``, shrunk by ``rot``'s least singular value
  and the point's rounding.

Where the two bounds are farther apart than the tolerance (a point on a cylinder's rim where
the normal is poorly known, a flat ellipsoid, a rotation far from orthonormal) or cross,
nothing is written and the caller runs GJK/EPA, as for two segments; so do primitives below
``1e-100``, whose squared sizes underflow.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._ptr import NO_NRT
from .gjk import _FLOOR
from .support import CONE, CYLINDER, ELLIPSOID, support

_EPS = float(np.finfo(np.float64).eps)

# Primitives no larger than this (1e-100) are left to GJK/EPA: their squared dimensions
# underflow (the ellipsoid's support function squares its radii).
_TINY = 1e-100


@njit(cache=True, inline="always")
def _norm(x, y, z):
    # |(x, y, z)| without the squares' underflow (a distance of 1e-300 is not 0) or overflow
    return math.hypot(math.hypot(x, y), z)


@njit(cache=True, inline="always")
def _local(rot, pos, p0, p1, p2):
    # rot^T (p - pos): the point in the primitive's frame
    d0, d1, d2 = p0 - pos[0], p1 - pos[1], p2 - pos[2]
    return (rot[0, 0] * d0 + rot[1, 0] * d1 + rot[2, 0] * d2,
            rot[0, 1] * d0 + rot[1, 1] * d1 + rot[2, 1] * d2,
            rot[0, 2] * d0 + rot[1, 2] * d1 + rot[2, 2] * d2)


@njit(cache=True, inline="always")
def _world(rot, pos, x0, x1, x2):
    return (rot[0, 0] * x0 + rot[0, 1] * x1 + rot[0, 2] * x2 + pos[0],
            rot[1, 0] * x0 + rot[1, 1] * x1 + rot[1, 2] * x2 + pos[1],
            rot[2, 0] * x0 + rot[2, 1] * x1 + rot[2, 2] * x2 + pos[2])


@njit(**NO_NRT)
def _sigma(rot):
    # (a lower bound of rot's least singular value, rot's defect e: its R^T R's largest entry
    # off the identity). Gershgorin on G = R^T R: its least eigenvalue is at least
    # min_i (G_ii - sum_{j != i} |G_ij|), tight for a rotation scaled by rounding.
    lam = math.inf
    e = 0.0
    for i in range(3):
        row = 0.0
        for j in range(3):
            g = rot[0, i] * rot[0, j] + rot[1, i] * rot[1, j] + rot[2, i] * rot[2, j]
            e = max(e, abs(g - (1.0 if i == j else 0.0)))
            if i == j:
                row += g
            else:
                row -= abs(g)
        lam = min(lam, row)
    return math.sqrt(max(0.0, lam * (1.0 - 8.0 * _EPS))) * (1.0 - 4.0 * _EPS), e


@njit(**NO_NRT)
def _cylinder(r, h, l0, l1, l2, foot, nrm):
    # Foot on the solid cylinder (radius r, half height h) and the outward normal there; returns
    # (signed distance, inside, well conditioned).
    rho = math.hypot(l0, l1)
    u0, u1 = (l0 / rho, l1 / rho) if rho > 0.0 else (1.0, 0.0)
    sz = 1.0 if l2 >= 0.0 else -1.0
    dr = rho - r
    dz = abs(l2) - h
    if dr <= 0.0 and dz <= 0.0:  # inside: the nearer of the side and the cap facing the point
        if -dz <= -dr:
            foot[0], foot[1], foot[2] = l0, l1, sz * h
            nrm[0], nrm[1], nrm[2] = 0.0, 0.0, sz
            return dz, True, True
        foot[0], foot[1], foot[2] = r * u0, r * u1, l2
        nrm[0], nrm[1], nrm[2] = u0, u1, 0.0
        return dr, True, True
    fr = min(rho, r)
    fz = min(max(l2, -h), h)
    foot[0], foot[1], foot[2] = fr * u0, fr * u1, fz
    if dz <= 0.0:  # beside the side
        nrm[0], nrm[1], nrm[2] = u0, u1, 0.0
        return dr, False, True
    if dr <= 0.0:  # above or below a cap
        nrm[0], nrm[1], nrm[2] = 0.0, 0.0, sz
        return dz, False, True
    d = math.hypot(dr, dz)  # beyond the rim: along the point's offset from the rim
    nrm[0], nrm[1], nrm[2] = u0 * dr / d, u1 * dr / d, sz * dz / d
    return d, False, True


@njit(**NO_NRT)
def _cone(r, h, l0, l1, l2, foot, nrm):
    # Foot on the solid cone (base radius r at z = 0, apex at z = h) and the outward normal
    # there, in the meridian half-plane (rho, z): the triangle (0, 0), (r, 0), (0, h).
    rho = math.hypot(l0, l1)
    u0, u1 = (l0 / rho, l1 / rho) if rho > 0.0 else (1.0, 0.0)
    ln = math.hypot(r, h)
    if not ln > 0.0:
        return 0.0, False, False
    # the slant edge from (r, 0) to (0, h): outward normal (h, r) / ln, offset r h / ln
    sn0, sn1 = h / ln, r / ln
    ds = sn0 * rho + sn1 * l2 - r * h / ln
    db = -l2  # the base's plane, outward normal (0, -1)
    if ds <= 0.0 and db <= 0.0 and rho <= r:  # inside (rho <= r: implied unless the cone is flat)
        if -db <= -ds:
            foot[0], foot[1], foot[2] = l0, l1, 0.0
            nrm[0], nrm[1], nrm[2] = 0.0, 0.0, -1.0
            return db, True, True
        fr, fz = rho - ds * sn0, l2 - ds * sn1
        foot[0], foot[1], foot[2] = fr * u0, fr * u1, fz
        nrm[0], nrm[1], nrm[2] = sn0 * u0, sn0 * u1, sn1
        return ds, True, True
    # outside: the nearer of the base segment and the slant segment
    bq = min(max(rho, 0.0), r)
    b2 = (rho - bq) ** 2 + l2 * l2
    t = (l2 * sn0 - (rho - r) * sn1) / ln  # along the slant from (r, 0) to (0, h) (ln * ln may underflow)
    t = min(max(t, 0.0), 1.0)
    sr, sz = r - t * r, t * h
    s2 = (rho - sr) ** 2 + (l2 - sz) ** 2
    if b2 <= s2:
        fr, fz = bq, 0.0
    else:
        fr, fz = sr, sz
    foot[0], foot[1], foot[2] = fr * u0, fr * u1, fz
    e0, e1 = rho - fr, l2 - fz
    d = math.hypot(e0, e1)
    if b2 <= s2 and rho <= r:  # below the base
        nrm[0], nrm[1], nrm[2] = 0.0, 0.0, -1.0
        return d, False, True
    if b2 > s2 and 0.0 < t < 1.0:  # off the slant face
        nrm[0], nrm[1], nrm[2] = sn0 * u0, sn0 * u1, sn1
        return d, False, True
    if not d > 0.0:
        return 0.0, False, False
    nrm[0], nrm[1], nrm[2] = u0 * e0 / d, u1 * e0 / d, e1 / d  # off the rim or the apex
    return d, False, True


@njit(cache=True, inline="always")
def _secular(q0, q1, q2, c0, c1, c2, u):
    # F(t) + 1 = sum q_i / (b_i + t)^2 (q_i = (a_i p_i)^2, b_i = a_i^2) and F'(t), at
    # u = t + b_m (b_m the least b_i) with b_i + t = c_i + u, c_i = b_i - b_m computed as
    # (a_i - a_m)(a_i + a_m): exact where a_i is a_m, and no digit lost near a near-sphere's
    # centre, where t is -b_m to within the point's offset (collide.testing's oracle does the
    # same). +inf, -inf where a denominator is not positive or its cube underflows (F's pole).
    e0, e1, e2 = c0 + u, c1 + u, c2 + u
    g0, g1, g2 = e0 * e0 * e0, e1 * e1 * e1, e2 * e2 * e2
    if not (g0 > 0.0 and g1 > 0.0 and g2 > 0.0):
        return math.inf, -math.inf
    s = q0 / (e0 * e0) + q1 / (e1 * e1) + q2 / (e2 * e2)
    return s, -2.0 * (q0 / g0 + q1 / g1 + q2 / g2)


@njit(**NO_NRT)
def _ellipsoid(a, l0, l1, l2, foot, nrm):
    # Foot on the ellipsoid (semi-axes a (3,)) and its outward normal; returns (signed distance,
    # inside, found, depth): not found for a flat ellipsoid (or one too thin for the solve's
    # floats) or a root that does not settle; ``depth`` a certified lower bound of an interior
    # point's depth (0 when none). Solved on the ellipsoid divided by its longest axis (no
    # underflow of a small one's powers), the answers scaled back.
    amax = max(a[0], a[1], a[2])
    if not (min(a[0], a[1], a[2]) > 0.0 and _TINY < amax < math.inf):
        return 0.0, False, False, 0.0
    a0, a1, a2 = a[0] / amax, a[1] / amax, a[2] / amax
    m0, m1, m2 = l0 / amax, l1 / amax, l2 / amax
    am = min(a0, a1, a2)
    bm = am * am
    if not bm > 0.0:
        return 0.0, False, False, 0.0
    c0, c1, c2 = (a0 - am) * (a0 + am), (a1 - am) * (a1 + am), (a2 - am) * (a2 + am)
    s = (m0 / a0) ** 2 + (m1 / a1) ** 2 + (m2 / a2) ** 2
    inside = s < 1.0
    q0, q1, q2 = (a0 * m0) ** 2, (a1 * m1) ** 2, (a2 * m2) ** 2
    if inside:  # the root's u = t + b_m in (0, b_m)
        lo, hi = 0.0, bm
    else:  # in (b_m, b_m + a_max |p|): there every term is at most a_max^2 |p|^2 / t^2
        lo, hi = bm, bm + math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
    u = bm  # t = 0
    for _ in range(200):
        f1, fp = _secular(q0, q1, q2, c0, c1, c2, u)
        f = f1 - 1.0
        if f == 0.0:
            break
        if f > 0.0:
            lo = u
        else:
            hi = u
        un = u - f / fp if fp < 0.0 and math.isfinite(fp) and math.isfinite(f) else lo
        if not lo < un < hi:
            # bisected, geometrically while lo is 0 or far below hi (a root near 0: a point
            # near a near-sphere's centre, where halving would take a step per bit)
            un = hi * 1e-3 if lo == 0.0 else (math.sqrt(lo * hi) if lo < 0.25 * hi else 0.5 * (lo + hi))
            if not lo < un < hi:
                break
        if abs(un - u) <= 4.0 * _EPS * u:
            u = un
            break
        u = un
    e0, e1, e2 = c0 + u, c1 + u, c2 + u
    if not (e0 > 0.0 and e1 > 0.0 and e2 > 0.0):
        return 0.0, inside, False, 0.0
    x0, x1, x2 = a0 * a0 * m0 / e0, a1 * a1 * m1 / e1, a2 * a2 * m2 / e2
    sx = (x0 / a0) ** 2 + (x1 / a1) ** 2 + (x2 / a2) ** 2
    # Eberly's degenerate case: an interior point on the plane of the shortest axes (those
    # coordinates 0), near the centre: F's limit at the pole, the other axes' sum, at most 0
    # (no root beyond the pole: the iteration's u is none). Decided by that limit, not by the
    # foot's residue, which a u next to the pole leaves small.
    degenerate = False
    if inside:
        pole = 0.0
        for ci, qi in ((c0, q0), (c1, q1), (c2, q2)):
            if ci > 0.0:
                pole += qi / (ci * ci)
            elif qi != 0.0:
                pole = math.inf  # a shortest axis' coordinate not 0: its term has the pole
        degenerate = pole <= 1.0
    if degenerate:
        # the other axes' x_i = b_i p_i / c_i, the rest of the unit sum on a shortest axis
        x0, x1, x2 = (a0 * a0 * m0 / c0 if c0 > 0.0 else 0.0, a1 * a1 * m1 / c1 if c1 > 0.0 else 0.0,
                      a2 * a2 * m2 / c2 if c2 > 0.0 else 0.0)
        rest = 1.0 - ((x0 / a0) ** 2 + (x1 / a1) ** 2 + (x2 / a2) ** 2)
        if not rest >= 0.0:
            return 0.0, inside, False, 0.0
        if c0 == 0.0:
            x0 = math.copysign(a0 * math.sqrt(rest), m0)
        elif c1 == 0.0:
            x1 = math.copysign(a1 * math.sqrt(rest), m1)
        else:
            x2 = math.copysign(a2 * math.sqrt(rest), m2)
        sx = (x0 / a0) ** 2 + (x1 / a1) ** 2 + (x2 / a2) ** 2
    if not abs(sx - 1.0) <= 1e-6:
        return 0.0, inside, False, 0.0
    k = 1.0 / math.sqrt(sx)  # onto the surface
    x0, x1, x2 = x0 * k, x1 * k, x2 * k
    g0, g1, g2 = x0 / (a0 * a0), x1 / (a1 * a1), x2 / (a2 * a2)
    gl = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    if not gl > 0.0:
        return 0.0, inside, False, 0.0
    nrm[0], nrm[1], nrm[2] = g0 / gl, g1 / gl, g2 / gl
    foot[0], foot[1], foot[2] = x0 * amax, x1 * amax, x2 * amax
    d = _norm(m0 - x0, m1 - x1, m2 - x2) * amax
    if not inside:
        return d, False, True, 0.0
    # The depth's certified lower bound, by the S-lemma (one quadratic constraint: exact
    # duality): every multiplier mu in (-b_m, 0] gives depth^2 >= |mu| (1 - sum p_i^2 / (b_i + mu)),
    # the minimum over x of |x - p|^2 + mu (x^T D^-2 x - 1), whose matrix I + mu D^-2 is then
    # positive definite; at the root's mu (and as mu -> -b_m in the degenerate case, a
    # shortest axis' term 0/0 then 0) it is the depth itself. Here mu = u - b_m, b_i + mu = e_i,
    # with the rounding of |mu|, of each term and of 1 - S allowed for.
    e0, e1, e2 = c0 + u, c1 + u, c2 + u
    t0 = m0 * m0 / e0 if m0 != 0.0 else 0.0
    t1 = m1 * m1 / e1 if m1 != 0.0 else 0.0
    t2 = m2 * m2 / e2 if m2 != 0.0 else 0.0
    ssum = t0 + t1 + t2
    f_mu = bm - u - 2.0 * _EPS * bm  # |mu|, less its rounding
    f_s = 1.0 - ssum - 16.0 * _EPS * (1.0 + ssum)
    # both factors positive (near the surface each may round below 0, and two negatives would
    # multiply to a positive bound)
    depth = math.sqrt(f_mu * f_s) * (1.0 - 4.0 * _EPS) * amax if f_mu > 0.0 and f_s > 0.0 else 0.0
    return -d, True, True, depth


@njit(**NO_NRT)
def point_distance(sk, sp, tol, rounding, res):
    """`collide._kernels.distance.pair_distance`'s answer for a ball and a cylinder, cone or
    ellipsoid, in closed form (module docstring), when it is certified within ``tol``.

    Parameters
    ----------
    sk : tuple
        The primitive's shape tuple (``CYLINDER``, ``CONE`` or ``ELLIPSOID``).
    sp : tuple
        The ball's: ``POINTS`` with one point, its radius ``prm[3]``.
    tol : float
        Absolute tolerance on the bracket's width (below `collide._kernels.gjk`'s floor times
        the coordinates' scale, that floor).
    rounding : float
        `collide._kernels.distance.ROUNDING`: the bounds' rounding allowance, in eps times the
        largest coordinate.
    res : (18,) float64
        Receives, on success, the primitive's witness point (3), the ball's (3), and the unit
        normal from the primitive to the ball (3), world frame; the rest is scratch (the
        caller's one allocation).

    Returns
    -------
    found : bool
        Whether the answer is certified within ``tol``; False: the caller runs GJK/EPA (``res``
        and the rest meaningless).
    distance, lower, upper : float
        The signed distance of the two full sets and its certified bracket.
    cores : bool
        Whether the cores overlap (the ball's centre inside a cylinder's or cone's core).
    """
    kind, prm, _, _, _, rot, pos = sk
    pts, prot, ppos = sp[2], sp[5], sp[6]
    rp = sp[1][3]
    rk = prm[3]  # the primitive core's ball (an ellipsoid's rolling ball)
    # the ball's centre, as `collide._kernels.support.support` poses a point
    p0, p1, p2 = _world(prot, ppos, pts[0, 0], pts[0, 1], pts[0, 2])
    l0, l1, l2 = _local(rot, pos, p0, p1, p2)
    foot = res[9:12]
    nl = res[12:15]
    w = res[15:18]
    depth = 0.0
    if not max(prm[0], prm[1], prm[2]) > _TINY:
        return False, 0.0, 0.0, 0.0, False  # a primitive whose support squares underflow: GJK/EPA
    if kind == CYLINDER:
        sd, inside, ok = _cylinder(prm[0], prm[1], l0, l1, l2, foot, nl)
        sd -= rk  # of the core: the full set is the core and its ball
    elif kind == CONE:
        sd, inside, ok = _cone(prm[0], prm[1], l0, l1, l2, foot, nl)
        sd -= rk
    elif kind == ELLIPSOID:
        # the foot on the ellipsoid itself, its core's foot rk below it along the normal
        sd, inside, ok, depth = _ellipsoid(prm[0:3], l0, l1, l2, foot, nl)
        for q in range(3):
            foot[q] -= rk * nl[q]
    else:
        ok = inside = False
        sd = 0.0
    if not ok:
        return False, 0.0, 0.0, 0.0, False
    # The sets are rot @ core + pos plus a ball (the support functions'), whatever rot's
    # rounding: the normal carried to the world and made unit, the core's foot carried as a
    # point of the core, the primitive's witness the foot plus its ball along the normal.
    n0, n1, n2 = (rot[0, 0] * nl[0] + rot[0, 1] * nl[1] + rot[0, 2] * nl[2],
                  rot[1, 0] * nl[0] + rot[1, 1] * nl[1] + rot[1, 2] * nl[2],
                  rot[2, 0] * nl[0] + rot[2, 1] * nl[1] + rot[2, 2] * nl[2])
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if not nn > 0.0:
        return False, 0.0, 0.0, 0.0, False
    n0, n1, n2 = n0 / nn, n1 / nn, n2 / nn
    c0, c1, c2 = _world(rot, pos, foot[0], foot[1], foot[2])
    k0, k1, k2 = c0 + rk * n0, c1 + rk * n1, c2 + rk * n2
    scale = max(abs(p0), abs(p1), abs(p2), abs(k0), abs(k1), abs(k2), abs(pos[0]), abs(pos[1]), abs(pos[2]))
    # lower: the separating-axis bound along n (from the primitive to the ball), the support
    # values of the primitive's core plus its ball and of the ball
    support(sk, n0, n1, n2, -1, w)
    scale = max(scale, abs(w[0]), abs(w[1]), abs(w[2]))  # n . w rounds at w's size
    lower = (n0 * p0 + n1 * p1 + n2 * p2) - (n0 * w[0] + n1 * w[1] + n2 * w[2]) - rk - rp
    if not inside:  # upper: the distance between the two witnesses' centres less the radii
        upper = _norm(p0 - k0, p1 - k1, p2 - k2) - rp
    else:
        # upper: a ball about the point inside the primitive (module docstring)
        x0, x1, x2 = _world(rot, pos, l0, l1, l2)
        e = _norm(x0 - p0, x1 - p1, x2 - p2)  # the point's round trip
        smin, defect = _sigma(rot)
        if kind == ELLIPSOID:
            # the rolling ball about the core's foot, in the world; then the root's depth, in
            # the ellipsoid shrunk by what rot's scale takes from its ball
            inner = rk - _norm(p0 - c0, p1 - c1, p2 - c2)
            if depth > 0.0:
                inner = max(inner, smin * (depth - 4.0 * defect * rk) - e)
        else:
            inner = smin * -(sd + rk) - e + rk  # the core's depth, carried; then its ball
        upper = -inner - rp
    # converged as GJK/EPA's test has it (before the rounding allowance both then add)
    if not upper - lower <= max(tol, _FLOOR * scale):
        return False, 0.0, 0.0, 0.0, False
    slack = rounding * _EPS * (scale + rk + rp)
    lower -= slack
    upper += slack
    if not lower <= upper:  # bounds crossed beyond the rounding allowance: no certificate here
        return False, 0.0, 0.0, 0.0, False
    res[0], res[1], res[2] = k0, k1, k2
    res[3], res[4], res[5] = p0 - rp * n0, p1 - rp * n1, p2 - rp * n2
    res[6], res[7], res[8] = n0, n1, n2
    return True, min(max(sd - rp, lower), upper), lower, upper, inside and kind != ELLIPSOID
