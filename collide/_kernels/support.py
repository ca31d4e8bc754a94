"""Support functions of convex cores, posed in the world (numba): ``s(d) = argmax_x d . x``.

A *shape* here is a flat tuple the narrow-phase kernels pass around unchanged (DESIGN.md, Wave 2):

``(kind, prm, pts, nbr_start, nbr, rot, pos)``

- ``kind`` : int64, one of `POINTS`, `CYLINDER`, `CONE`, `ELLIPSOID`;
- ``prm`` : ``(4,) float64``: the primitive's parameters (cylinder ``radius, half_height``; cone
  ``radius, height``; ellipsoid ``rx, ry, rz``) and, last, the ball radius added to the core
  (``prm[3]``: the `PointCloud` radius; an ellipsoid's rolling radius, `collide.support.rolling_radius`);
- ``pts`` : ``(n, 3) float64``: the core's points in the shape frame (``POINTS`` only; ``(0, 3)``
  otherwise);
- ``nbr_start`` : ``(n + 1,) int32`` and ``nbr`` : ``(m,) int32``: the hull's vertex adjacency in
  CSR form (``nbr[nbr_start[i]:nbr_start[i + 1]]`` are the neighbours of vertex ``i``), used for
  hill-climbing; a ``nbr_start`` of length below 2 means "scan every point";
- ``rot`` : ``(3, 3) float64`` and ``pos`` : ``(3,) float64``: the pose, world = ``rot @ x + pos``.

The core is ``hull(pts)``, the cylinder's or cone's solid, or the ellipsoid's inner parallel body at
distance ``prm[3]`` (the ellipsoid is that core ⊕ ball(``prm[3]``): `collide.support.rolling_radius`);
the full set is the core ⊕ ball(``prm[3]``) (Box2D's proxy form), whose radius the distance kernels
add after GJK/EPA ran on the cores. Only the ellipsoid's support reads ``prm[3]``.

The support of ``rot @ K + pos`` is ``rot @ s_K(rot^T d) + pos`` for *any* linear ``rot``
(``h_{RK}(d) = h_K(R^T d)``), so a rotation off by rounding still gives the exact support of the
set its points describe.

Hill-climbing (the simplex method on the hull's edge graph): a vertex no neighbour of which is
higher along ``d`` is the global maximum of a linear function over a convex polytope, and
Qhull's triangulated facets only add edges (coplanar diagonals), so the climb is exact; it starts
from a hint (the previous support), which makes warm queries a few steps (van den Bergen 2003,
"Collision Detection in Interactive 3D Environments", §4.3.4).
"""

from __future__ import annotations

import math

from numba import njit

from ._ptr import NO_NRT

# Shape kinds (the ``kind`` slot of a shape tuple).
POINTS, CYLINDER, CONE, ELLIPSOID = 0, 1, 2, 3


@njit(**NO_NRT)
def _scan(pts, l0, l1, l2):
    # The point of pts with the largest l . x (first of equals).
    best = -math.inf
    ib = 0
    for i in range(pts.shape[0]):
        s = pts[i, 0] * l0 + pts[i, 1] * l1 + pts[i, 2] * l2
        if s > best:
            best = s
            ib = i
    return ib


# Vertices a cold climb (no hint) starts from: `collide.support` puts the hull's extreme vertices
# along -x, +x, -y, +y, -z, +z first, and the climb starts from the best of them.
SEEDS = 6


@njit(**NO_NRT)
def _climb(pts, nbr_start, nbr, l0, l1, l2, hint):
    # Steepest ascent over the vertex graph from ``hint``; strictly increasing, so it stops.
    if 0 <= hint < pts.shape[0]:
        i = hint
        best = pts[i, 0] * l0 + pts[i, 1] * l1 + pts[i, 2] * l2
    else:
        i = 0
        best = -math.inf
        for j in range(min(SEEDS, pts.shape[0])):
            s = pts[j, 0] * l0 + pts[j, 1] * l1 + pts[j, 2] * l2
            if s > best:
                best = s
                i = j
    while True:
        jb = -1
        for e in range(nbr_start[i], nbr_start[i + 1]):
            j = nbr[e]
            s = pts[j, 0] * l0 + pts[j, 1] * l1 + pts[j, 2] * l2
            if s > best:
                best = s
                jb = j
        if jb < 0:
            return i
        i = jb


@njit(cache=True, inline="always")
def support(shape, d0, d1, d2, hint, out):
    """World support point of a shape's core in direction ``d`` (any length, non-zero).

    Parameters
    ----------
    shape : tuple
        ``(kind, prm, pts, nbr_start, nbr, rot, pos)`` (module docstring).
    d0, d1, d2 : float
        The direction, world frame.
    hint : int
        Start vertex of the hill-climb (``POINTS`` with adjacency); out of range (-1): the best of
        the first `SEEDS` vertices. Ignored otherwise.
    out : (3,) float64
        Receives the support point, world frame.

    Returns
    -------
    index : int
        The vertex of ``pts`` chosen (``POINTS``), ``-1`` for a primitive.
    """
    kind, prm, pts, nbr_start, nbr, rot, pos = shape
    # Direction in the shape frame: rot^T d.
    l0 = rot[0, 0] * d0 + rot[1, 0] * d1 + rot[2, 0] * d2
    l1 = rot[0, 1] * d0 + rot[1, 1] * d1 + rot[2, 1] * d2
    l2 = rot[0, 2] * d0 + rot[1, 2] * d1 + rot[2, 2] * d2
    idx = -1
    if kind == POINTS:
        if nbr_start.shape[0] > 1:
            idx = _climb(pts, nbr_start, nbr, l0, l1, l2, hint)
        else:
            idx = _scan(pts, l0, l1, l2)
        x = pts[idx, 0]
        y = pts[idx, 1]
        z = pts[idx, 2]
    elif kind == CYLINDER:
        # Rim point of the cap facing d (the axis point when d is along the axis).
        r = prm[0]
        h = prm[1]
        q = math.sqrt(l0 * l0 + l1 * l1)
        x = r * l0 / q if q > 0.0 else 0.0
        y = r * l1 / q if q > 0.0 else 0.0
        z = h if l2 >= 0.0 else -h
    elif kind == CONE:
        # Apex (0, 0, height) or the base rim point facing d, whichever is higher along d.
        r = prm[0]
        h = prm[1]
        q = math.sqrt(l0 * l0 + l1 * l1)
        if h * l2 >= r * q:
            x = 0.0
            y = 0.0
            z = h
        elif q > 0.0:
            x = r * l0 / q
            y = r * l1 / q
            z = 0.0
        else:  # d straight down the axis: the base's centre is one of its maxima
            x = 0.0
            y = 0.0
            z = 0.0
    else:  # ELLIPSOID less its rolling ball: D^2 l / |D l| - rho l / |l|, D = diag(radii), rho = prm[3]
        a = prm[0]
        b = prm[1]
        c = prm[2]
        rho = prm[3]
        q = math.sqrt((a * l0) ** 2 + (b * l1) ** 2 + (c * l2) ** 2)
        if q > 0.0:
            ll = rho / math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
            x = a * a * l0 / q - ll * l0
            y = b * b * l1 / q - ll * l1
            z = c * c * l2 / q - ll * l2
        else:
            x = 0.0
            y = 0.0
            z = c - rho
    for k in range(3):
        out[k] = rot[k, 0] * x + rot[k, 1] * y + rot[k, 2] * z + pos[k]
    return idx
