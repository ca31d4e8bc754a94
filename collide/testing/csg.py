"""Brute-force twin of `collide.csg.raycast`: every leaf, no hierarchy, point classification.

Independent of the fast path on purpose: it unrolls the CSG graph with its own walker, tests
every leaf with numpy (a primitive's ray interval is found by classifying the gaps between the
roots of its bounding surfaces, not by the kernel's case analysis; a mesh ray passing near an
edge or a vertex by the winding number of its gaps, not by a tie rule), and finds the first
boundary of the whole solid by classifying the gaps between all candidate surface points with a
boolean evaluation of the CSG tree (Requicha's membership classification), instead of span
arithmetic. Slow (fine for a 128 x 128 image of a few dozen leaves), never used by the library.
"""

from __future__ import annotations

import numpy as np

from .. import csg

__all__ = [
    "brute_force_raycast", "leaf_spans", "random_leaf", "random_scene", "winding_number",
]

_BIG = 1e300


def _walk(node, env, w, leaves):
    # -> expression tree of tuples; appends (Leaf, world (4, 4)) in depth-first order.
    if isinstance(node, csg.Recursive):
        if node.depth == 0:
            return _walk(node.base, env, w, leaves) if node.base is not None else ("union", [])
        return _walk(node.body, {**env, node.name: (node, node.depth, env)}, w, leaves)
    if isinstance(node, csg.Ref):
        if node.name not in env:
            raise ValueError(f"unbound Ref({node.name!r})")
        rec, level, outer = env[node.name]
        if level == 1:
            return _walk(rec.base, outer, w, leaves) if rec.base is not None else ("union", [])
        return _walk(rec.body, {**outer, rec.name: (rec, level - 1, outer)}, w, leaves)
    if isinstance(node, csg.Leaf):
        leaves.append((node, w))
        return ("leaf", len(leaves) - 1)
    if isinstance(node, csg.Transform):
        return _walk(node.child, env, w @ node.matrix, leaves)
    if isinstance(node, csg.Instances):
        return ("union", [_walk(node.child, env, w @ m, leaves) for m in node.matrices])
    if isinstance(node, csg.Union):
        return ("union", [_walk(c, env, w, leaves) for c in node.items])
    if isinstance(node, csg.Intersection):
        return ("inter", _walk(node.a, env, w, leaves), _walk(node.b, env, w, leaves))
    if isinstance(node, csg.Difference):
        return ("diff", _walk(node.a, env, w, leaves), _walk(node.b, env, w, leaves))
    raise ValueError(f"unknown node {node!r}")


def _roots(a, b, c):
    # Real roots of a t^2 + b t + c (nan where none); a linear fallback where a == 0.
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = b * b - 4 * a * c
        s = np.sqrt(np.where(disc > 0, disc, np.nan))
        r0 = (-b - s) / (2 * a)
        r1 = (-b + s) / (2 * a)
        lin = -c / b
    r0 = np.where(a == 0, lin, r0)
    r1 = np.where(a == 0, np.nan, r1)
    return r0, r1


def _plane_hits(o, d, lo, hi):
    with np.errstate(divide="ignore", invalid="ignore"):
        return (lo - o) / d, (hi - o) / d


def _convex_interval(breaks, inside_at):
    # The interval between consecutive break points whose midpoint is inside (the solid is
    # convex: at most one such gap of positive length). breaks: (R, k) with nan for none.
    r = len(breaks)
    b = np.where(np.isfinite(breaks), breaks, np.nan)
    b = np.concatenate([b, np.full((r, 1), -_BIG), np.full((r, 1), _BIG)], axis=1)
    b = np.sort(b, axis=1)  # nan last
    mids = 0.5 * (b[:, :-1] + b[:, 1:])
    inside = inside_at(mids) & (b[:, 1:] > b[:, :-1])
    t0 = np.full(r, np.nan)
    t1 = np.full(r, np.nan)
    for j in range(mids.shape[1] - 1, -1, -1):
        t0 = np.where(inside[:, j], b[:, j], t0)
        t1 = np.where(inside[:, j], b[:, j + 1], t1)
    # Adjacent inside gaps (a break point inside the solid, e.g. a capsule seam) merge.
    for j in range(mids.shape[1]):
        grow = inside[:, j] & (b[:, j] == t1)
        t1 = np.where(grow, b[:, j + 1], t1)
    return t0[:, None], t1[:, None]


def leaf_spans(leaf: "csg.Leaf", world: np.ndarray, origins: np.ndarray, directions: np.ndarray):
    """Spans of one leaf along every ray: ``(t0, t1)``, each ``(R, k) float64``, nan-padded.

    Quadric leaves are solved from each ray's point closest to the leaf's origin (``t = tc``),
    then shifted back: from far away the quadratic's coefficients cancel catastrophically.
    """
    tc = np.zeros(len(origins))
    if leaf.kind not in ("box", "mesh"):
        a = np.sum(directions * directions, axis=1)
        rel = origins - world[:3, 3]
        tc = np.where(a > 0, -np.sum(rel * directions, axis=1) / np.where(a > 0, a, 1.0), 0.0)
        origins = origins + tc[:, None] * directions
    t0, t1 = _local_spans(leaf, world, origins, directions)
    return t0 + tc[:, None], t1 + tc[:, None]


def winding_number(tri: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Generalised winding number of a closed triangle mesh at each point, and which points lie on it.

    Parameters
    ----------
    tri : (T, 3, 3) float64
        The triangles' vertices.
    points : (n, 3) float64

    Returns
    -------
    winding : (n,) float64
        The solid angles the triangles subtend, summed, over 4 pi (van Oosterom & Strackee 1983):
        +-1 inside a closed mesh, 0 outside; independent of any ray.
    on_surface : (n,) bool
        The point lies on a triangle, within rounding (its solid angle there, +-2 pi or a part of
        it, is a branch cut: the winding number means nothing).
    """
    w = np.zeros(len(points))
    on = np.zeros(len(points), bool)
    for c0 in range(0, len(points), 256):
        a, b, c = (tri[None, :, i, :] - points[c0:c0 + 256, None, :] for i in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        num = np.einsum("ntk,ntk->nt", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ntk,ntk->nt", a, b) * lc + np.einsum("ntk,ntk->nt", b, c) * la
               + np.einsum("ntk,ntk->nt", c, a) * lb)
        w[c0:c0 + 256] = 2.0 * np.arctan2(num, den).sum(axis=1) / (4.0 * np.pi)
        tol = 1e-9 * la * lb * lc
        on[c0:c0 + 256] = ((np.abs(num) <= tol) & (den <= tol)).any(axis=1)
    return w, on


def _mesh_spans(tri: np.ndarray, o: np.ndarray, d: np.ndarray):
    # A closed mesh's spans along each ray (`_mesh_spans_all`), computed only for the rays whose
    # line meets the mesh's box padded by 1e-6 of its diagonal (a line crossing a triangle, or
    # passing within TOL of one, meets it; the rest have no span), with as many columns as the
    # most spans of a ray: every ray against every triangle made (R, T) blocks before.
    r = len(o)
    lo, hi = tri.min(axis=(0, 1)), tri.max(axis=(0, 1))
    pad = 1e-6 * float(np.linalg.norm(hi - lo)) + 1e-300
    lo, hi = lo - pad, hi + pad
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = (lo - o) / d, (hi - o) / d
    flat = d == 0  # a line parallel to a slab: inside it or not, for every t
    inslab = (o >= lo) & (o <= hi)
    tmin = np.where(flat, np.where(inslab, -np.inf, np.inf), np.minimum(ta, tb)).max(axis=1)
    tmax = np.where(flat, np.where(inslab, np.inf, -np.inf), np.maximum(ta, tb)).min(axis=1)
    sel = np.flatnonzero(tmin <= tmax)
    t0s, t1s = _mesh_spans_all(tri, o[sel], d[sel])
    # Columns up to the last finite one of any ray: a ray's spans may have a gap of NaN
    # columns (two crossings at one t, a doubled sheet inside a closed mesh, pair as an empty
    # span), so the count of finite columns would drop the spans after it.
    fin = np.isfinite(t0s)
    n = int((fin * np.arange(1, fin.shape[1] + 1)).max(initial=0))
    t0, t1 = np.full((r, max(n, 1)), np.nan), np.full((r, max(n, 1)), np.nan)
    t0[sel, :n], t1[sel, :n] = t0s[:, :n], t1s[:, :n]
    return t0, t1


def _mesh_spans_all(tri: np.ndarray, o: np.ndarray, d: np.ndarray):
    # A closed mesh's spans along each ray. Every triangle's crossing by Cramer's rule on
    # o + t d = v0 + u e1 + v e2 (scalar triple products; the kernel shears instead, Woop et al.
    # 2013). A ray that crosses every triangle it meets well inside (barycentric coordinates
    # above TOL) is inside between its odd and even crossings. A ray passing within TOL of an
    # edge or a vertex (where two or more triangles may both count one crossing, or neither),
    # or meeting a triangle nearly edge-on, is classified instead: its crossings, near ones
    # included, merged where closer than TOL, bound gaps whose midpoints are classified by the
    # winding number, which no tie between triangles can flip.
    TOL = 1e-9
    r = len(o)
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    nrm = np.cross(e1, e2)
    hits = np.full((r, len(tri)), np.nan)
    near_t = np.full((r, len(tri)), np.nan)
    for c0 in range(0, r, 2048):
        oc, dc = o[c0:c0 + 2048], d[c0:c0 + 2048]
        s = oc[:, None, :] - v0[None]
        det = -np.einsum("rk,tk->rt", dc, nrm)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            t = np.einsum("rtk,tk->rt", s, nrm) / det
            u = -np.einsum("rk,rtk->rt", dc, np.cross(s, e2[None])) / det
            v = -np.einsum("rk,rtk->rt", dc, np.cross(e1[None], s)) / det
            edge_on = np.abs(det) <= TOL * np.linalg.norm(dc, axis=1)[:, None] * np.linalg.norm(nrm, axis=1)[None]
            low = np.minimum(np.minimum(u, v), 1.0 - u - v)
        ok = (det != 0) & np.isfinite(t)
        hits[c0:c0 + 2048] = np.where(ok & (low > TOL) & ~edge_on, t, np.nan)
        near_t[c0:c0 + 2048] = np.where(ok & (low >= -TOL) & ((low <= TOL) | edge_on), t, np.nan)
    hits_sorted = np.sort(hits, axis=1)
    k = hits.shape[1] // 2
    t0, t1 = hits_sorted[:, 0:2 * k:2], hits_sorted[:, 1:2 * k:2]
    t0, t1 = np.where(t0 < t1, t0, np.nan), np.where(t0 < t1, t1, np.nan)
    for i in np.flatnonzero(np.isfinite(near_t).any(axis=1)):
        cand = np.sort(np.concatenate([hits[i][np.isfinite(hits[i])], near_t[i][np.isfinite(near_t[i])]]))
        keep = np.concatenate([[True], np.diff(cand) > TOL * (1.0 + np.abs(cand[1:]))])
        cand = cand[keep]
        t0[i] = t1[i] = np.nan
        if len(cand) < 2:
            continue
        mids = 0.5 * (cand[:-1] + cand[1:])
        # A gap on the surface (a ray grazing a face or along an edge) enters no volume: outside,
        # as the kernel finds.
        wn, on = winding_number(tri, o[i] + mids[:, None] * d[i])
        inside = (np.abs(wn) > 0.5) & ~on
        spans = []
        for j in np.flatnonzero(inside):
            if spans and spans[-1][1] == cand[j]:
                spans[-1][1] = cand[j + 1]  # adjacent inside gaps: one span
            else:
                spans.append([cand[j], cand[j + 1]])
        if len(spans) > t0.shape[1]:
            grow = len(spans) - t0.shape[1]
            t0 = np.concatenate([t0, np.full((r, grow), np.nan)], axis=1)
            t1 = np.concatenate([t1, np.full((r, grow), np.nan)], axis=1)
        for j, (a, b) in enumerate(spans):
            t0[i, j], t1[i, j] = a, b
    return t0, t1


def _local_spans(leaf: "csg.Leaf", world: np.ndarray, origins: np.ndarray, directions: np.ndarray):
    m = world.copy()
    kind, p = leaf.kind, leaf.params
    if kind == "ellipsoid":
        m = m @ np.diag(list(p["radii"]) + [1.0])
    r = len(origins)
    none = (np.full((r, 1), np.nan), np.full((r, 1), np.nan))
    if abs(np.linalg.det(m[:3, :3])) < 1e-300 or np.linalg.cond(m[:3, :3]) >= 1e12:
        return none
    inv = np.linalg.inv(m)
    o = origins @ inv[:3, :3].T + inv[:3, 3]
    d = directions @ inv[:3, :3].T
    at = lambda t, i: o[:, i, None] + t * d[:, i, None]  # noqa: E731

    if kind == "mesh":
        return _mesh_spans(leaf.triangles(), o, d)
    if kind == "box":
        h = p["half_extents"]
        if np.any(h <= 0):
            return none
        breaks = np.concatenate([np.stack(_plane_hits(o[:, i], d[:, i], -h[i], h[i]), 1)
                                 for i in range(3)], axis=1)
        return _convex_interval(breaks, lambda t: np.all(
            [np.abs(at(t, i)) <= h[i] for i in range(3)], axis=0))
    if kind in ("sphere", "ellipsoid"):
        rad = 1.0 if kind == "ellipsoid" else p["radius"]
        if rad <= 0 or (kind == "ellipsoid" and np.any(p["radii"] <= 0)):
            return none
        breaks = np.stack(_roots((d * d).sum(1), 2 * (o * d).sum(1), (o * o).sum(1) - rad**2), 1)
        return _convex_interval(breaks, lambda t: at(t, 0)**2 + at(t, 1)**2 + at(t, 2)**2 <= rad**2)
    if kind in ("cylinder", "capsule"):
        rad, h = p["radius"], p["half_length"]
        if rad <= 0:
            return none
        parts = [np.stack(_roots(d[:, 0]**2 + d[:, 1]**2, 2 * (o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1]),
                                 o[:, 0]**2 + o[:, 1]**2 - rad**2), 1),
                 np.stack(_plane_hits(o[:, 2], d[:, 2], -h, h), 1)]

        def in_cyl(t):
            return (at(t, 0)**2 + at(t, 1)**2 <= rad**2) & (np.abs(at(t, 2)) <= h)

        if kind == "cylinder":
            return _convex_interval(np.concatenate(parts, 1), in_cyl)
        for zc in (-h, h):
            oz = o[:, 2] - zc
            parts.append(np.stack(_roots((d * d).sum(1), 2 * (o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1]
                                                              + oz * d[:, 2]),
                                         o[:, 0]**2 + o[:, 1]**2 + oz**2 - rad**2), 1))

        def in_caps(t):
            xy = at(t, 0)**2 + at(t, 1)**2
            z = at(t, 2)
            return in_cyl(t) | (xy + (z + h)**2 <= rad**2) | (xy + (z - h)**2 <= rad**2)

        return _convex_interval(np.concatenate(parts, 1), in_caps)
    if kind == "cone":
        rad, hh = p["radius"], p["height"]
        if rad <= 0 or hh <= 0:
            return none
        k2 = (rad / hh) ** 2
        u0 = hh - o[:, 2]
        breaks = np.concatenate([
            np.stack(_roots(d[:, 0]**2 + d[:, 1]**2 - k2 * d[:, 2]**2,
                            2 * (o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1] + k2 * u0 * d[:, 2]),
                            o[:, 0]**2 + o[:, 1]**2 - k2 * u0**2), 1),
            np.stack(_plane_hits(o[:, 2], d[:, 2], 0.0, hh), 1)], axis=1)
        return _convex_interval(breaks, lambda t: (at(t, 0)**2 + at(t, 1)**2 <= k2 * (hh - at(t, 2))**2)
                                & (at(t, 2) >= 0) & (at(t, 2) <= hh))
    raise ValueError(f"unknown leaf kind {kind!r}")


def _member(expr, spans, t):
    kind = expr[0]
    if kind == "leaf":
        t0, t1 = spans[expr[1]]
        out = np.zeros(t.shape, dtype=bool)
        for j in range(t0.shape[1]):
            out |= (t0[:, j, None] < t) & (t < t1[:, j, None])
        return out
    if kind == "union":
        out = np.zeros(t.shape, dtype=bool)
        for c in expr[1]:
            out |= _member(c, spans, t)
        return out
    a = _member(expr[1], spans, t)
    b = _member(expr[2], spans, t)
    return a & b if kind == "inter" else a & ~b


def brute_force_raycast(node: "csg.Node", origins, directions) -> tuple[np.ndarray, np.ndarray]:
    """First boundary point ``t >= 0`` of the whole solid along each ray, and the leaf it is on.

    Parameters
    ----------
    node : csg.Node
    origins, directions : (R, 3) array_like of float

    Returns
    -------
    distance : (R,) float64
        ``inf`` on a miss.
    leaf : (R,) int32
        Depth-first leaf id (as `collide.csg.leaves`); -1 on a miss.
    """
    o = np.asarray(origins, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64)
    leaves: list = []
    expr = _walk(node, {}, np.eye(4), leaves)
    with np.errstate(over="ignore", invalid="ignore"):
        spans = [leaf_spans(lf, w, o, d) for lf, w in leaves]
    r = len(o)
    if not spans:
        return np.full(r, np.inf), np.full(r, -1, dtype=np.int32)
    cand = np.concatenate([np.concatenate([t0, t1], 1) for t0, t1 in spans], axis=1)
    label = np.concatenate([np.full(2 * t0.shape[1], i) for i, (t0, _) in enumerate(spans)])
    cand = np.where(np.isfinite(cand), cand, np.inf)
    order = np.argsort(cand, axis=1, kind="stable")
    cand = np.take_along_axis(cand, order, axis=1)
    lab = label[order]
    k = int(np.max(np.sum(np.isfinite(cand), axis=1)))
    dist = np.full(r, np.inf)
    leaf = np.full(r, -1, dtype=np.int32)
    if k == 0:
        return dist, leaf
    cand, lab = cand[:, :k], lab[:, :k]
    # Gap j lies between candidates j - 1 and j (gap 0 before the first); each is sampled at its
    # midpoint. Gaps past a ray's last finite candidate repeat its last gap (no change there).
    count = np.sum(np.isfinite(cand), axis=1)
    left = np.concatenate([cand[:, :1] - 1.0, cand], axis=1)
    right = np.concatenate([cand, np.full((r, 1), np.inf)], axis=1)
    idx = np.minimum(np.arange(k + 1)[None, :], count[:, None])
    left = np.take_along_axis(left, idx, axis=1)
    right = np.take_along_axis(right, idx, axis=1)
    left = np.where(np.isfinite(left), left, 0.0)
    right = np.where(np.isfinite(right), right, left + 1.0)
    inside = _member(expr, spans, 0.5 * (left + right))
    change = inside[:, :-1] != inside[:, 1:]
    valid = np.isfinite(cand) & (cand >= 0) & change
    first = np.argmax(valid, axis=1)
    got = valid[np.arange(r), first]
    dist[got] = cand[got, first[got]]
    leaf[got] = lab[got, first[got]]
    return dist, leaf


# --------------------------------------------------------------------------------------------
# Random scenes with every node kind (for the twin tests).

def _pose(rng, spread: float, stretch: bool = True) -> np.ndarray:
    from .surfaces import random_rotation

    m = np.eye(4)
    lin = random_rotation(rng)
    if stretch:
        lin = lin @ np.diag(rng.uniform(0.7, 1.4, 3))  # mild non-uniform scale: general affine
    m[:3, :3] = lin
    m[:3, 3] = rng.uniform(-spread, spread, 3)
    return m


def random_leaf(kind: str, rng: np.random.Generator) -> "csg.Leaf":
    """A leaf of ``kind`` (any of `csg.Leaf.KINDS`) with random parameters of size about 0.3-1."""
    import trimesh

    u = lambda lo=0.3, hi=0.9: float(rng.uniform(lo, hi))  # noqa: E731
    if kind == "box":
        return csg.box(rng.uniform(0.2, 0.8, 3))
    if kind == "sphere":
        return csg.sphere(u())
    if kind == "capsule":
        return csg.capsule(u(0.2, 0.5), u(0.2, 0.8))
    if kind == "cylinder":
        return csg.cylinder(u(0.2, 0.7), u(0.2, 0.8))
    if kind == "cone":
        return csg.cone(u(0.3, 0.8), u(0.5, 1.5))
    if kind == "ellipsoid":
        return csg.ellipsoid(rng.uniform(0.2, 0.9, 3))
    if kind == "mesh":
        if rng.random() < 0.5:
            return csg.mesh(trimesh.creation.icosphere(1, radius=u(0.4, 0.9)))
        return csg.mesh(trimesh.creation.torus(u(0.5, 0.8), u(0.15, 0.3), major_sections=12,
                                               minor_sections=8))
    raise ValueError(f"unknown leaf kind {kind!r}")


def random_scene(seed: int, n_items: int = 10, spread: float = 1.5,
                 max_leaves: int = 80) -> "csg.Node":
    """A random CSG graph with every node kind, every leaf kind and shared subgraphs.

    Items (transformed leaves) are combined pairwise by unions, intersections (with a primitive
    placed over the operand, so the result is rarely empty), differences (a primitive cut out of
    the operand), instancing (2-3 copies) and a small recursion (the item plus a shrunken,
    rotated copy of the whole, 3 levels). Some items are reused under a second transform (a
    shared subgraph). The multiplying operations are skipped (a union instead) once the
    unrolled scene would pass ``max_leaves``. Mostly inside ``[-4, 4]^3``.
    """
    rng = np.random.default_rng(seed)
    kinds = csg.Leaf.KINDS
    pool = [csg.Transform(_pose(rng, spread), random_leaf(kinds[i % len(kinds)], rng))
            for i in range(n_items)]
    rec = 0
    size = {id(p): 1 for p in pool}
    while len(pool) > 1:
        rng.shuffle(pool)
        a = pool.pop()
        op = str(rng.choice(["union", "inter", "diff", "instances", "recursive", "share"]))
        total = sum(size[id(p)] for p in pool) + size[id(a)]
        grow = {"inter": 1, "diff": 1, "instances": 3, "recursive": 3, "share": 2}.get(op, 0)
        if total + (grow - 1) * size[id(a)] > max_leaves and grow > 1:
            op = "union"
        if op in ("inter", "diff") and size[id(a)] > 6:
            op = "union"  # a cut through a large group would leave little of the scene
        n = size[id(a)] * max(grow, 1) + (1 if op in ("inter", "diff") else 0)
        if op == "union":
            n += size[id(pool[-1])]
            out = csg.Union(a, pool.pop())
        elif op in ("inter", "diff"):
            c = a.point_cloud()
            box_ = c.aabb()
            center = 0.5 * (box_.lo + box_.hi) + (0 if op == "inter" else 0.4 * (box_.hi - box_.lo)
                                                   * rng.uniform(-1, 1, 3))
            cutter = random_leaf(kinds[int(rng.integers(len(kinds)))], rng)
            m = _pose(rng, 0.0)
            m[:3, 3] = center
            if op == "inter":
                m[:3, :3] *= 1.5
                out = csg.Intersection(a, csg.Transform(m, cutter))
            else:
                out = csg.Difference(a, csg.Transform(m, cutter))
        elif op == "instances":
            out = csg.Instances(a, [_pose(rng, 1.0, stretch=False) for _ in range(int(rng.integers(2, 4)))])
        elif op == "recursive":
            name = f"r{rec}"
            rec += 1
            m = _pose(rng, 0.8, stretch=False)
            m[:3, :3] *= 0.7
            out = csg.Recursive(name, csg.Union(a, csg.Transform(m, csg.Ref(name))), 3)
        else:
            out = csg.Union(a, csg.Transform(_pose(rng, 1.5), a))
        size[id(out)] = n
        pool.append(out)
    return pool[0]
