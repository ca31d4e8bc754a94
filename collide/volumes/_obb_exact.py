"""The minimum-volume box of ``hull(points) ⊕ ball(radius)``, exactly (up to rounding).

The guarantee is O'Rourke's (1985, "Finding minimal enclosing boxes", Int. J. Comput. Inf. Sci.
14): a minimal box has two adjacent faces flush with edges of the hull. It carries over to a
radius, the objective being ``prod(w_i + 2 r)`` with ``w_i`` the hull's widths along the axes:

* Rotating a box about one of its own axes moves each of the other two widths as
  ``|d| cos(t - f)`` for fixed support vertices (positive there, so concave) and leaves the
  third, and a product of positive concave functions (plus constants ``2 r``) is log-concave;
  strictly so while the widths are positive. A minimum of a strictly log-concave function can
  only sit where the supports change (a convex kink), i.e. where a face of one of the other
  two axes holds a hull edge not parallel to the axis of rotation. (A width of zero, a flat
  hull's normal as an axis, is a kink itself: that face holds the whole polygon.)
* Asking that for all three axes leaves edges flush with faces of at least two axes, and for
  an axis ``a`` with a flush edge ``e1``, one of the other axes' faces holds an edge ``e2`` not
  parallel to ``a``. So ``a`` lies on ``e1``'s arc of the Gauss map (orthogonal to ``e1``,
  between its two faces' normals) and ``b = a x d2 / |a x d2|`` (``d2`` along ``e2``; defined,
  as ``a`` is not parallel to ``d2``) on ``e2``'s.

Every ordered edge pair is thus a one-parameter family of orientations (`_obb_families`), and
the least volume on each is found to a relative ``TOL`` by branch and bound on its parameter
with certified lower bounds (`_obb_search`); the face-flush boxes (rotating calipers) are the
families' end points. Large hulls are searched through subsets of their vertices first, with a
certificate of optimality (`exact_axes`).

Cost, for a hull of ``n`` vertices and ``E`` edges: ``O(E^2)`` to screen the edge pairs, then
one evaluation per family, and branch and bound on the families whose lower bound does not
clear the best box. There are ``K = O(E^2)`` families (O'Rourke's), about ``E^1.5`` when the
hull's face normals are spread evenly (as Jylänki 2015 counts for the same enumeration); an
evaluation is six hill climbs on the hull's vertex graph, ``O(1)`` steps when warm and ``O(n)``
at worst. The bounds are second order and resolve kinks at their crossing, so a family that
reaches the best box takes ``O(log(1 / TOL))`` steps (seen in the tests and benchmarks; the
splitting stops at intervals of 1e-13 rad in any case); with that, ``O(n^3 log(1 / TOL))`` at
worst, as O'Rourke's ``O(n^3)``, and ``O(n^1.5)`` evaluations for round hulls. The subset rounds add a
bounded factor (see `exact_axes`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from ._obb_search import TOL, min_volume_axes

# ----------------------------------------------------------------------------------------------
# The hull's Gauss map: vertices, vertex graph, edges with their arcs


def _edge_arcs(P, ev, nf, ng):
    # Arc of each edge (m, 2) between its faces' unit normals nf, ng (m, 3): start s (= nf
    # projected orthogonal to the edge), unit q with the arc a(t) = cos t s + sin t q, t in
    # [0, phi]; d = s x q is the edge's direction.
    d0 = P[ev[:, 1]] - P[ev[:, 0]]
    d0 /= np.linalg.norm(d0, axis=1)[:, None]
    s = nf - np.sum(nf * d0, axis=1)[:, None] * d0
    s /= np.linalg.norm(s, axis=1)[:, None]
    q = np.cross(d0, s)
    flip = np.sum(ng * q, axis=1) < 0.0
    q[flip] = -q[flip]
    phi = np.arctan2(np.maximum(np.sum(ng * q, axis=1), 0.0), np.sum(ng * s, axis=1))
    return s, q, phi


def _adjacency(n, ev):
    # CSR vertex graph of the edges ev (m, 2).
    both = np.concatenate([ev, ev[:, ::-1]])
    order = np.lexsort((both[:, 1], both[:, 0]))
    both = both[order]
    start = np.zeros(n + 1, dtype=np.int64)
    np.add.at(start, both[:, 0] + 1, 1)
    return np.cumsum(start), np.ascontiguousarray(both[:, 1])


def solid_graph(P: np.ndarray):
    """Gauss map of the hull of ``P`` ``(n, 3)`` (full rank, every point a hull vertex).

    Returns ``(P, start, adj, s, q, phi)``: the hull's vertices ``(m, 3)``, its vertex graph
    (CSR ``start (m + 1,) int64``, ``adj int64``) and each edge's arc (``s, q (E, 3)``,
    ``phi (E,)``, see `_edge_arcs`). Qhull runs on whitened coordinates (each principal spread
    scaled to one), so a thin hull is as well conditioned as a round one; its facet normals are
    mapped back (by the inverse transpose). Triangles of one merged facet share its normal, so
    their diagonals get empty arcs: they are dropped (the facet's normal is an end point of its
    boundary edges' arcs).
    """
    c = P.mean(axis=0)
    _, sv, vt = np.linalg.svd(P - c, full_matrices=False)
    white = ((P - c) @ vt.T) / sv
    try:
        hull = ConvexHull(white)
    except (QhullError, ValueError):
        hull = ConvexHull(white, qhull_options="QJ")  # joggled: a valid graph of nearly this hull
    keep = np.unique(hull.simplices)
    remap = np.full(len(P), -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    simp = remap[hull.simplices]
    normal = hull.equations[:, :3] @ (vt / sv[:, None])  # rows: n_w^T M, M = diag(1/sv) vt
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    f = np.repeat(np.arange(len(simp)), 3)
    g = hull.neighbors.ravel()
    j = np.tile(np.arange(3), len(simp))
    own = f < g
    f, g, j = f[own], g[own], j[own]
    ev = np.stack([simp[f, (j + 1) % 3], simp[f, (j + 2) % 3]], axis=1)
    P = np.ascontiguousarray(P[keep])
    start, adj = _adjacency(len(P), ev)
    s, q, phi = _edge_arcs(P, ev, normal[f], normal[g])
    real = phi > 0.0
    return P, start, adj, np.ascontiguousarray(s[real]), np.ascontiguousarray(q[real]), phi[real]


def flat_graph(P: np.ndarray, axes: np.ndarray):
    """Gauss map of a flat convex polygon: ``P`` ``(n, 3)`` in the plane spanned by ``axes[0]``
    and ``axes[1]`` (rows, orthonormal). Its two faces have normals ``+-n`` and each edge's arc
    is the half circle from ``n`` through the edge's outward normal to ``-n``. Returns what
    `solid_graph` returns."""
    u, v = axes[0], axes[1]
    n = np.cross(u, v)
    xy = np.stack([P @ u, P @ v], axis=1)
    order = ConvexHull(xy).vertices  # counter-clockwise
    P = np.ascontiguousarray(P[order])
    xy = xy[order]
    m = len(P)
    nxt = (np.arange(m) + 1) % m
    ev = np.stack([np.arange(m), nxt], axis=1)
    dxy = xy[nxt] - xy
    out = dxy[:, 1:2] * u - dxy[:, 0:1] * v  # (dy, -dx): outward for a counter-clockwise polygon
    out /= np.linalg.norm(out, axis=1)[:, None]
    s = np.tile(n, (m, 1))
    start, adj = _adjacency(m, ev)
    return P, start, adj, s, np.ascontiguousarray(out), np.full(m, np.pi)


# ----------------------------------------------------------------------------------------------
# The driver: the search on a growing subset of the hull's vertices (a certificate of optimality)

# Hulls up to this many vertices are searched whole; larger ones start from a subset.
DIRECT = 64
# Directions whose extreme vertices seed the subset: the 13 axes of a 26-DOP.
_SEED_DIRECTIONS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, -1, 0], [1, 0, 1],
                             [1, 0, -1], [0, 1, 1], [0, 1, -1], [1, 1, 1], [1, 1, -1], [1, -1, 1],
                             [1, -1, -1]], dtype=np.float64)


def box_volume(P: np.ndarray, radius: float, rotation: np.ndarray) -> float:
    """Volume of the box with axes ``rotation`` (columns) around ``P`` ``(n, 3)``, plus radius."""
    proj = P @ rotation
    return float(np.prod(np.ptp(proj, axis=0) + 2.0 * radius))


def _supports(P: np.ndarray, rotation: np.ndarray, k: int = 1) -> np.ndarray:
    # The k highest and k lowest vertices along each axis (columns of rotation).
    proj = P @ rotation
    k = min(k, len(P))
    if k == 1:
        return np.concatenate([np.argmax(proj, axis=0), np.argmin(proj, axis=0)])
    return np.concatenate([np.argpartition(-proj, k - 1, axis=0)[:k].ravel(),
                           np.argpartition(proj, k - 1, axis=0)[:k].ravel()])


def exact_axes(P: np.ndarray, radius: float, rotation: np.ndarray, graph, rounds: int | None = None,
               direct: int = DIRECT, tol: float = TOL, seeds=(), seed_k: int = 1, budget: int = -1):
    """Axes of the minimum-volume box of ``hull(P) ⊕ ball(radius)``.

    Parameters
    ----------
    P : (m, 3) float64
        The hull's vertices, centred and of unit size (the tolerances are relative to it).
    radius : float
        In P's units.
    rotation : (3, 3) float64
        A first guess (its box is the first incumbent); columns are axes.
    graph : callable
        Builds the Gauss map of the hull of a subset of ``P`` (`solid_graph`, or `flat_graph`
        with the polygon's axes bound).
    rounds : int, optional
        At most this many subset rounds (see below), then stop with the best box found, not
        certified, however large the subset grows (``None``: until certified, the whole hull
        at worst).
    direct : int
        Hulls of up to this many vertices are searched whole (no subset rounds).
    tol : float
        Relative tolerance of the searches (and of the certificate).
    seeds : sequence of (3, 3) float64
        Rotations whose boxes' ``seed_k`` most extreme vertices along each axis join the first
        subset (good boxes found otherwise: their supports are likely the optimum's).
    budget : int
        > 0: a search of the whole hull stops after about this many box evaluations with the
        best box so far, not certified (near-flat hulls cost in proportion to 1 / thickness).

    Returns
    -------
    rotation : (3, 3) float64
        Right-handed, columns are axes.
    volume : float
        Its box's volume (in P's units).
    certified : bool
        Whether the volume is the minimum (within ``tol``).

    Notes
    -----
    A subset ``S`` of the vertices has, in every orientation, a box no larger than the hull's,
    so its minimum ``v_S`` bounds the hull's from below. If the hull's box in ``S``'s optimal
    orientation has the volume ``v_S`` (its supports are in ``S``), that orientation is optimal
    for the hull too; otherwise those supports join ``S`` and ``S`` is searched again. Hulls of
    up to ``direct`` vertices are searched whole at once, and so is any hull once ``S`` holds a
    third of its vertices. ``S`` grows by half each round (the supports, then the next most
    extreme vertices along the box's axes), so there are ``O(log m)`` rounds, and the subset
    searches together cost a bounded multiple of the last (the worst case stays that of one
    search of the whole hull).
    """
    m = len(P)
    best_rot = np.ascontiguousarray(rotation, dtype=np.float64)
    best = box_volume(P, radius, best_rot)
    if m > direct:
        keep = np.zeros(m, dtype=bool)
        proj = P @ _SEED_DIRECTIONS.T
        keep[np.argmax(proj, axis=0)] = True
        keep[np.argmin(proj, axis=0)] = True
        keep[_supports(P, best_rot)] = True
        for seed in seeds:
            keep[_supports(P, seed, seed_k)] = True
        done = 0
        limit = m // 3 if rounds is None else m
        while keep.sum() <= limit and (rounds is None or done < rounds):
            sub = P[keep]
            try:
                rot, low = min_volume_axes(*graph(sub), radius, best_rot, tol)[:2]
            except (QhullError, ValueError):
                break  # a subset without full rank: search the whole hull
            done += 1
            vol = box_volume(P, radius, rot)
            if vol < best:
                best, best_rot = vol, rot
            if vol <= low * (1.0 + tol):
                return rot, vol, True
            grown = keep.copy()
            grown[_supports(P, rot)] = True
            if grown.sum() == keep.sum():  # rounding: the supports are in S already
                return rot, vol, True
            # ... and the next most extreme vertices along its axes, half as many as S has:
            # S grows geometrically, so the rounds together cost a bounded multiple of the last
            grown[_supports(P, rot, -(-int(keep.sum()) // 12))] = True
            keep = grown
        if rounds is not None:
            return best_rot, best, False
    rot, vol, _, evals = min_volume_axes(*graph(P), radius, best_rot, tol, budget)
    return rot, vol, not (budget > 0 and evals > budget)
