"""Brute-force twins of the face-contact kernels (`collide._kernels.faces`, `.manifold`).

Plain numpy, written another way: every separating axis from the corners' projections, clipped
polygons as the vertex sets of convex polygon intersections (corners inside the other polygon
plus edge crossings), the largest quadrilateral by trying every 4-subset.
"""

from __future__ import annotations

import itertools

import numpy as np

__all__ = ["box_box_contacts", "box_corners", "convex_polygon_intersection", "max_area_quad", "polytope_faces_loop"]


def box_corners(p: np.ndarray, r: np.ndarray, h: np.ndarray) -> np.ndarray:
    """The 8 corners ``(8, 3)`` of a box (centre ``p``, rotation ``r``, half sizes ``h``), world frame."""
    s = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
    return p + (s * h) @ r.T


def _inside(poly2: np.ndarray, x: np.ndarray, eps: float) -> bool:
    # x inside the counter-clockwise 2D polygon poly2 (within eps)
    n = len(poly2)
    for i in range(n):
        a, b = poly2[i], poly2[(i + 1) % n]
        if (b[0] - a[0]) * (x[1] - a[1]) - (b[1] - a[1]) * (x[0] - a[0]) < -eps:
            return False
    return True


def convex_polygon_intersection(a: np.ndarray, b: np.ndarray, eps: float = 1e-12) -> np.ndarray:
    """Vertices ``(m, 2)`` of the intersection of two convex 2D polygons (counter-clockwise),
    unordered, duplicates merged: the corners of each inside the other and the edge crossings."""
    pts = [x for x in a if _inside(b, x, eps)] + [x for x in b if _inside(a, x, eps)]
    for i in range(len(a)):
        p, q = a[i], a[(i + 1) % len(a)]
        for j in range(len(b)):
            r, s = b[j], b[(j + 1) % len(b)]
            m = np.array([q - p, r - s]).T
            if abs(np.linalg.det(m)) < 1e-300:
                continue
            t, u = np.linalg.solve(m, r - p)
            if -1e-12 <= t <= 1 + 1e-12 and -1e-12 <= u <= 1 + 1e-12:
                pts.append(p + t * (q - p))
    out: list = []
    for x in pts:
        if all(np.linalg.norm(x - y) > 1e-9 for y in out):
            out.append(np.asarray(x, float))
    return np.array(out).reshape(-1, 2)


def max_area_quad(pts: np.ndarray) -> float:
    """The largest area of a quadrilateral on 4 of the (convex-position) points ``(n, 3)``."""
    best = 0.0
    for c in itertools.combinations(range(len(pts)), 4):
        q = pts[list(c)]
        ctr = q.mean(axis=0)
        n = np.cross(q[1] - q[0], q[2] - q[0])
        if np.linalg.norm(n) == 0:
            n = np.cross(q[1] - q[0], q[3] - q[0])
        n = n / (np.linalg.norm(n) or 1.0)
        u = q[0] - ctr
        u = u / (np.linalg.norm(u) or 1.0)
        w = np.cross(n, u)
        order = np.argsort(np.arctan2((q - ctr) @ w, (q - ctr) @ u))
        q = q[order]
        area = 0.5 * np.linalg.norm(sum(np.cross(q[i], q[(i + 1) % 4]) for i in range(4)))
        best = max(best, area)
    return best


def box_box_contacts(p1, r1, h1, p2, r2, h2, thr: float):
    """Box-box contacts by brute force: ``(dist (k,), pos (k, 3), normal (3,))`` or None.

    The 15 axes' separations from the projections of all 16 corners; the same choice of axis as
    `collide._kernels.faces.box_box` (a face wins ties, an edge axis near the best face axis that
    is not 5 % deeper gives way); a face axis: the incident face (the other box's face most
    opposed) intersected with the reference face as 2D polygons, each vertex's height above the
    reference face from the incident face's plane; an edge axis: one contact at the closest
    points of the two edges that support it, found among all 12 x 12 edge pairs.
    """
    c1, c2 = box_corners(p1, r1, h1), box_corners(p2, r2, h2)
    d = p2 - p1
    axes, kinds = [], []
    for i in range(3):
        axes.append(r1[:, i]), kinds.append(("f1", i))
    for j in range(3):
        axes.append(r2[:, j]), kinds.append(("f2", j))
    for i in range(3):
        for j in range(3):
            a = np.cross(r1[:, i], r2[:, j])
            if np.dot(a, a) < 1e-16:
                axes.append(None), kinds.append(("e", i, j))
                continue
            axes.append(a / np.linalg.norm(a)), kinds.append(("e", i, j))
    tol = thr + 1e-13 * (np.sum(h1) + np.sum(h2))
    seps = []
    for a in axes:
        if a is None:
            seps.append(-np.inf)
            continue
        a = a if np.dot(a, d) >= 0 else -a
        seps.append(float(np.min(c2 @ a) - np.max(c1 @ a)))
    if max(seps) > tol:
        return None
    face = int(np.argmax(seps[:6]))
    best, code = seps[face], face
    for k in range(6, 15):
        s = seps[k]
        if s - 1e-6 * abs(s) > best and s > seps[face]:
            best, code = s, k
    if code >= 6:
        a = axes[code]
        if abs(np.dot(a, axes[face])) > 0.99 and best < seps[face] + 0.05 * abs(seps[face]) + 1e-15:
            code = face
    if code >= 6:
        a = axes[code]
        a = a if np.dot(a, d) >= 0 else -a
        best_pair, best_gap = None, np.inf
        e1 = _edges(c1, h1, r1)
        e2 = _edges(c2, h2, r2)
        i, j = kinds[code][1], kinds[code][2]
        for (u0, u1, di) in e1:
            if di != i:
                continue
            for (v0, v1, dj) in e2:
                if dj != j:
                    continue
                x, y = _segment_closest(u0, u1, v0, v1)
                # the supporting edges: extreme along the axis
                if np.dot(u0, a) < np.max(c1 @ a) - 1e-9 or np.dot(v0, a) > np.min(c2 @ a) + 1e-9:
                    continue
                g = np.linalg.norm(y - x)
                if g < best_gap:
                    best_gap, best_pair = g, (x, y)
        x, y = best_pair
        dist = float(np.dot(y - x, a))
        if dist > tol:
            return None
        return np.array([dist]), 0.5 * (x + y)[None], a
    ref1 = code < 3
    pr, rr, hr = (p1, r1, h1) if ref1 else (p2, r2, h2)
    pi, ri, hi = (p2, r2, h2) if ref1 else (p1, r1, h1)
    ax = code if ref1 else code - 3
    nref = rr[:, ax] * (1.0 if np.dot(rr[:, ax], pi - pr) >= 0 else -1.0)
    # incident face: the most opposed of the other box's 6
    k = int(np.argmax(np.abs(ri.T @ nref)))
    ninc = ri[:, k] * (-1.0 if np.dot(ri[:, k], nref) > 0 else 1.0)
    cinc = pi + ninc * hi[k]
    u, v = [q for q in range(3) if q != k]
    inc = np.array([cinc + su * hi[u] * ri[:, u] + sv * hi[v] * ri[:, v]
                    for su, sv in ((1, 1), (-1, 1), (-1, -1), (1, -1))])
    # 2D frame of the reference face: its two axes
    au, av = [q for q in range(3) if q != ax]
    e_u, e_v = rr[:, au], rr[:, av]
    cref = pr + nref * hr[ax]

    def to2(x):
        return np.array([np.dot(x - cref, e_u), np.dot(x - cref, e_v)])

    inc2 = np.array([to2(x) for x in inc])
    if np.cross(np.r_[inc2[1] - inc2[0], 0], np.r_[inc2[2] - inc2[0], 0])[2] < 0:
        inc2 = inc2[::-1]
    rect = np.array([[hr[au], hr[av]], [-hr[au], hr[av]], [-hr[au], -hr[av]], [hr[au], -hr[av]]])
    if np.cross(np.r_[rect[1] - rect[0], 0], np.r_[rect[2] - rect[0], 0])[2] < 0:
        rect = rect[::-1]
    verts = convex_polygon_intersection(inc2, rect)
    dists, poss = [], []
    for x2 in verts:
        x = cref + x2[0] * e_u + x2[1] * e_v
        # the incident face's plane over x, along nref
        hgt = np.dot(cinc - x, ninc) / np.dot(nref, ninc)
        if hgt > thr:
            continue
        dists.append(hgt)
        poss.append(x + 0.5 * hgt * nref)
    if not dists:
        return None
    normal = nref if ref1 else -nref
    return np.array(dists), np.array(poss), normal


def _edges(c, h, r):
    # the 12 edges of a box from its corners (index bits = signs), with their axis
    out = []
    for a in range(8):
        for ax in range(3):
            b = a | (1 << (2 - ax))
            if b != a:
                out.append((c[a], c[b], ax))
    return out


def _segment_closest(p0, p1, q0, q1):
    # closest points of two segments, on a fine search refined by projection (brute force)
    best = (np.inf, p0, q0)
    ts = np.linspace(0.0, 1.0, 201)
    P = p0 + ts[:, None] * (p1 - p0)
    for x in P:
        dq = q1 - q0
        t = np.clip(np.dot(x - q0, dq) / np.dot(dq, dq), 0.0, 1.0)
        y = q0 + t * dq
        g = np.linalg.norm(y - x)
        if g < best[0]:
            best = (g, x, y)
    # polish: alternate projections from the best grid point
    x, y = best[1], best[2]
    dp, dq = p1 - p0, q1 - q0
    for _ in range(200):
        s = np.clip(np.dot(y - p0, dp) / np.dot(dp, dp), 0.0, 1.0)
        x = p0 + s * dp
        t = np.clip(np.dot(x - q0, dq) / np.dot(dq, dq), 0.0, 1.0)
        y = q0 + t * dq
    return x, y


def polytope_faces_loop(points):
    """`collide.faces.polytope_faces`, one face at a time (its twin): the same planes (Qhull's
    triangles grouped by `collide.faces._hull_planes`), each face's vertices found and ordered
    counter-clockwise about its normal by a loop over the faces."""
    from ..faces import PolytopeFaces, _empty, _hull_planes

    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    planes = _hull_planes(pts)
    if planes is None:
        return _empty(pts)
    verts, tri, group, normal = planes
    vlists = []
    for g in range(len(normal)):
        ids = np.unique(tri[group == g])
        p = verts[ids]
        ctr = p.mean(axis=0)
        n = normal[g]
        u = p[0] - ctr
        u -= n * np.dot(u, n)
        u /= np.linalg.norm(u) or 1.0
        w = np.cross(n, u)
        ang = np.arctan2((p - ctr) @ w, (p - ctr) @ u)
        vlists.append(ids[np.argsort(ang, kind="stable")])
    offset = np.array([float(np.mean(verts[v] @ normal[g])) for g, v in enumerate(vlists)])
    vnum = np.array([len(v) for v in vlists], np.int64)
    vadr = np.concatenate([[0], np.cumsum(vnum)[:-1]]).astype(np.int64)
    return PolytopeFaces(verts, normal, offset, vadr, vnum, np.concatenate(vlists).astype(np.int32))
