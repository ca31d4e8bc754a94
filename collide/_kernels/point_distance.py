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
  hyperellipsoid"), found by Newton's method kept inside a bracket.

The answer is then certified as `collide._kernels.distance.segment_distance` certifies its own,
in the world frame and for the sets as the support functions define them (``rot @ K + pos``,
whatever the rounding of ``rot``):

* lower: the support values along the normal ``n`` found (``min n.B - max n.A``, the separating
  axis bound, valid for every ``n``, penetrating or not);
* upper, apart: the distance between the point and the foot, a point of the primitive;
* upper, overlapping: a ball about the point inside the primitive. For a cylinder or cone, the
  ball of the depth (an interior point's nearest face is at that depth); for an ellipsoid, the
  rolling ball: a ball of radius ``rho <= c^2 / a`` (its rolling radius,
  `collide.support.rolling_radius`) touching the surface at the foot from inside lies inside
  it (Blaschke's rolling theorem), which certifies a depth up to ``rho``. The ball is carried to
  the world through ``rot``, shrunk by ``rot``'s least singular value and the point's rounding.

Where the two bounds are farther apart than the tolerance (a deep ellipsoid overlap, a point on
a cylinder's edge where the normal is poorly known, a flat ellipsoid, a rotation far from
orthonormal), nothing is written and the caller runs GJK/EPA, as for two segments.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .gjk import _FLOOR
from .support import CONE, CYLINDER, ELLIPSOID, support

_EPS = float(np.finfo(np.float64).eps)

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


@njit(cache=True)
def _sigma(rot):
    # (a lower bound of rot's least singular value, rot's defect e: its R^T R's largest entry
    # off the identity); R^T R's eigenvalues lie within 3 e of 1 (Gershgorin).
    e = 0.0
    for i in range(3):
        for j in range(3):
            s = rot[0, i] * rot[0, j] + rot[1, i] * rot[1, j] + rot[2, i] * rot[2, j]
            e = max(e, abs(s - (1.0 if i == j else 0.0)))
    return math.sqrt(max(0.0, 1.0 - 3.0 * e)) * (1.0 - 4.0 * _EPS), e


@njit(cache=True)
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


@njit(cache=True)
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
    if ds <= 0.0 and db <= 0.0:  # inside
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
    t = ((rho - r) * (-r) + l2 * h) / (ln * ln)  # along the slant from (r, 0) to (0, h)
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
    # same). +inf, -inf where a denominator is not positive (F's pole).
    e0, e1, e2 = c0 + u, c1 + u, c2 + u
    if not (e0 > 0.0 and e1 > 0.0 and e2 > 0.0):
        return math.inf, -math.inf
    s = q0 / (e0 * e0) + q1 / (e1 * e1) + q2 / (e2 * e2)
    return s, -2.0 * (q0 / (e0 * e0 * e0) + q1 / (e1 * e1 * e1) + q2 / (e2 * e2 * e2))


# Relative rounding of F + 1 as `_secular` computes it (each term's few roundings): F's sign
# beyond it is certain.
_F_MARGIN = 64.0 * _EPS


@njit(cache=True)
def _ellipsoid(a, l0, l1, l2, foot, nrm):
    # Foot on the ellipsoid (semi-axes a (3,)) and its outward normal; returns (signed distance,
    # inside, found, depth): not found for a flat ellipsoid or a root that does not settle (an
    # interior point on the plane of a shortest axis, near the centre: Eberly's degenerate case);
    # ``depth`` a certified lower bound of an interior point's depth (0 when none), from the
    # root's bracket: F decreases on t > -b_m and the depth |t| |p_i / (b_i + t)| grows as t
    # decreases there, so F(t_hi) < 0 < F(t_lo) puts the root, and the depth, between them.
    a0, a1, a2 = a[0], a[1], a[2]
    if not (a0 > 0.0 and a1 > 0.0 and a2 > 0.0):
        return 0.0, False, False, 0.0
    am = min(a0, a1, a2)
    bm = am * am
    c0, c1, c2 = (a0 - am) * (a0 + am), (a1 - am) * (a1 + am), (a2 - am) * (a2 + am)
    s = (l0 / a0) ** 2 + (l1 / a1) ** 2 + (l2 / a2) ** 2
    inside = s < 1.0
    q0, q1, q2 = (a0 * l0) ** 2, (a1 * l1) ** 2, (a2 * l2) ** 2
    if inside:  # the root's u in (0, b_m)
        lo, hi = 0.0, bm
    else:  # in (b_m, b_m + a_max |p|): there every term is at most a_max^2 |p|^2 / t^2
        lo, hi = bm, bm + max(a0, a1, a2) * math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
    rooted = False  # a u with F certainly > 0 seen: the root is in the interval
    u = bm  # t = 0
    for _ in range(100):
        f1, fp = _secular(q0, q1, q2, c0, c1, c2, u)
        f = f1 - 1.0
        if f == 0.0:
            break
        if f > 0.0:
            lo = u
            rooted = rooted or f > _F_MARGIN * f1
        else:
            hi = u
        un = u - f / fp if fp < 0.0 and math.isfinite(fp) and math.isfinite(f) else 0.5 * (lo + hi)
        if not lo < un < hi:
            un = 0.5 * (lo + hi)
            if not lo < un < hi:
                break
        if abs(un - u) <= 4.0 * _EPS * u:
            u = un
            break
        u = un
    e0, e1, e2 = c0 + u, c1 + u, c2 + u
    if not (e0 > 0.0 and e1 > 0.0 and e2 > 0.0):
        return 0.0, inside, False, 0.0
    x0, x1, x2 = a0 * a0 * l0 / e0, a1 * a1 * l1 / e1, a2 * a2 * l2 / e2
    sx = (x0 / a0) ** 2 + (x1 / a1) ** 2 + (x2 / a2) ** 2
    if not abs(sx - 1.0) <= 1e-6:
        return 0.0, inside, False, 0.0
    k = 1.0 / math.sqrt(sx)  # onto the surface
    foot[0], foot[1], foot[2] = x0 * k, x1 * k, x2 * k
    g0, g1, g2 = foot[0] / (a0 * a0), foot[1] / (a1 * a1), foot[2] / (a2 * a2)
    gl = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    nrm[0], nrm[1], nrm[2] = g0 / gl, g1 / gl, g2 / gl
    d = math.sqrt((l0 - foot[0]) ** 2 + (l1 - foot[1]) ** 2 + (l2 - foot[2]) ** 2)
    if not inside:
        return d, False, True, 0.0
    depth = 0.0
    if rooted:
        step = 16.0 * _EPS * u
        for _ in range(40):  # u_hi: the nearest u above the root found with F certainly < 0
            uh = min(u + step, bm)
            f1, _ = _secular(q0, q1, q2, c0, c1, c2, uh)
            if f1 < 1.0 - _F_MARGIN:
                e0, e1, e2 = c0 + uh, c1 + uh, c2 + uh
                el = math.sqrt((l0 / e0) ** 2 + (l1 / e1) ** 2 + (l2 / e2) ** 2)
                depth = (bm - uh) * el * (1.0 - _F_MARGIN)  # |t| |p_i / (b_i + t)|
                break
            step *= 4.0
    return -d, True, True, depth


@njit(cache=True)
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
    res : (9,) float64
        Receives, on success, the primitive's witness point (3), the ball's (3), and the unit
        normal from the primitive to the ball (3), world frame.

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
    buf = np.empty(9)
    foot = buf[0:3]
    nl = buf[3:6]
    w = buf[6:9]
    depth = 0.0
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
    lower = (n0 * p0 + n1 * p1 + n2 * p2) - (n0 * w[0] + n1 * w[1] + n2 * w[2]) - rk - rp
    if not inside:  # upper: the distance between the two witnesses' centres less the radii
        upper = math.sqrt((p0 - k0) ** 2 + (p1 - k1) ** 2 + (p2 - k2) ** 2) - rp
    else:
        # upper: a ball about the point inside the primitive (module docstring)
        x0, x1, x2 = _world(rot, pos, l0, l1, l2)
        e = math.sqrt((x0 - p0) ** 2 + (x1 - p1) ** 2 + (x2 - p2) ** 2)  # the point's round trip
        smin, defect = _sigma(rot)
        if kind == ELLIPSOID:
            # the rolling ball about the core's foot, in the world; then the root's depth, in
            # the ellipsoid shrunk by what rot's scale takes from its ball
            inner = rk - math.sqrt((p0 - c0) ** 2 + (p1 - c1) ** 2 + (p2 - c2) ** 2)
            if depth > 0.0:
                inner = max(inner, smin * (depth - 4.0 * defect * rk) - e)
        else:
            inner = smin * -(sd + rk) - e + rk  # the core's depth, carried; then its ball
        upper = -inner - rp
    slack = rounding * _EPS * (scale + rk + rp)
    lower -= slack
    upper += slack
    if not upper - lower <= max(tol, _FLOOR * scale):
        return False, 0.0, 0.0, 0.0, False
    res[0], res[1], res[2] = k0, k1, k2
    res[3], res[4], res[5] = p0 - rp * n0, p1 - rp * n1, p2 - rp * n2
    res[6], res[7], res[8] = n0, n1, n2
    return True, min(max(sd - rp, lower), upper), lower, upper, inside and kind != ELLIPSOID
