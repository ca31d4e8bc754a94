"""Brute-force twins of `collide.deform` and `collide.swept`: dense samples of the true sets.

- `sample_cloud`: points of a cloud's set ``hull(points) ⊕ ball(radius)``, on its boundary (facets
  pushed out by the radius, vertex caps, edges) and inside it;
- `deformed_sample`: ``f`` of such points (the true deformed set, densely sampled);
- `swept_sample`: positions of points at many times of the motion ``R(s) x + t(s)``,
  ``R(s) = exp(s log(R1 R0ᵀ)) R0``, evaluated independently (a quaternion slerp);
- `signed_excess`: exact signed distance of points to ``hull(P)`` minus the radius (positive
  outside the cloud's set): containment checks with it are exact up to rounding;
- `cloud_volume`: the volume of ``hull(P) ⊕ ball(r)`` by Steiner's formula
  ``V + A r + (r² / 2) Σ_edges ℓ ψ + (4/3) π r³`` (``ψ`` the exterior dihedral angle).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation, Slerp

from ..hull import affine_basis
from ..pointcloud import PointCloud

__all__ = ["cloud_volume", "deformed_sample", "sample_cloud", "signed_excess", "swept_sample"]


def _seg(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    # Distances (c, t) of points p (c, 1, 3) to segments a b (t, 3).
    ab = b - a
    ll = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.einsum("cij,ij->ci", p - a, ab) / np.where(ll > 0, ll, 1.0), 0.0, 1.0)
    return np.linalg.norm(a + t[..., None] * ab - p, axis=2)


def _tri_distance(X: np.ndarray, tris: np.ndarray, chunk: int = 256) -> np.ndarray:
    # Distance (m,) of points X (m, 3) to the union of triangles (t, 3, 3), in chunks.
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    ok = nn > 0
    out = np.empty(len(X))
    for i in range(0, len(X), chunk):
        p = X[i:i + chunk, None, :]
        s = np.where(ok, np.einsum("cij,ij->ci", p - a, n) / np.where(ok, nn, 1.0), 0.0)
        foot = p - s[..., None] * n
        inside = np.broadcast_to(ok, s.shape).copy()
        for u, v in ((a, b), (b, c), (c, a)):
            inside &= np.einsum("cij,ij->ci", np.cross(v - u, foot - u), n) >= 0
        edge = np.minimum(np.minimum(_seg(p, a, b), _seg(p, b, c)), _seg(p, c, a))
        out[i:i + chunk] = np.where(inside, np.abs(s) * np.sqrt(nn), edge).min(axis=1)
    return out


def _tri_distance_paired(X: np.ndarray, tris: np.ndarray) -> np.ndarray:
    # Distance (m,) of each point X[i] (m, 3) to its own triangle tris[i] (m, 3, 3).
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    ok = nn > 0
    s = np.where(ok, np.einsum("ij,ij->i", X - a, n) / np.where(ok, nn, 1.0), 0.0)
    foot = X - s[:, None] * n
    inside = ok.copy()
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(v - u, foot - u), n) >= 0

    def seg(u, v):
        uv = v - u
        ll = np.einsum("ij,ij->i", uv, uv)
        t = np.clip(np.einsum("ij,ij->i", X - u, uv) / np.where(ll > 0, ll, 1.0), 0.0, 1.0)
        return np.linalg.norm(u + t[:, None] * uv - X, axis=1)

    edge = np.minimum(np.minimum(seg(a, b), seg(b, c)), seg(c, a))
    return np.where(inside, np.abs(s) * np.sqrt(nn), edge)


def _frame(points: np.ndarray):
    center, axes, rank = affine_basis(points)
    return center, axes, rank, (points - center) @ axes.T


def _hull_triangles(points: np.ndarray) -> tuple[np.ndarray, int]:
    # Triangles (t, 3, 3) covering the boundary of a solid hull (rank 3) or the whole of a flat one.
    center, axes, rank, local = _frame(points)
    if rank == 3:
        return points[ConvexHull(local).simplices], 3
    if rank == 2:
        order = ConvexHull(local[:, :2]).vertices
        fan = np.stack([np.full(len(order) - 2, order[0]), order[1:-1], order[2:]], axis=1)
        return points[fan], 2
    return np.zeros((0, 3, 3)), rank


def sample_cloud(cloud: PointCloud, n: int, rng: np.random.Generator, interior: float = 0.3) -> np.ndarray:
    """``(n, 3) float64`` points of ``cloud``'s set: ``1 - interior`` of them on its boundary.

    Boundary points: uniform points of the hull's facets pushed out by ``radius`` along the facet
    normal, and support points ``argmax d.p + radius d`` for random unit ``d`` (the vertex caps and
    edges); interior points: random convex combinations of the hull's vertices plus a random
    vector of length below the radius.
    """
    P = np.asarray(cloud.points, float)
    r = cloud.radius
    n_in = int(round(interior * n))
    n_b = n - n_in
    tris, rank = _hull_triangles(P) if len(P) > 2 else (np.zeros((0, 3, 3)), 0)
    out = []
    n_face = n_b // 2 if rank == 3 else 0
    if n_face:
        area = np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
        pick = rng.choice(len(tris), n_face, p=area / area.sum())
        u = rng.random((n_face, 2))
        flip = u.sum(axis=1) > 1
        u[flip] = 1 - u[flip]
        t = tris[pick]
        pts = t[:, 0] + u[:, :1] * (t[:, 1] - t[:, 0]) + u[:, 1:] * (t[:, 2] - t[:, 0])
        normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        inward = np.einsum("ij,ij->i", normal, P.mean(axis=0) - pts) > 0
        normal[inward] *= -1
        out.append(pts + r * normal)
    d = rng.normal(size=(n_b - n_face, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out.append(P[np.argmax(d @ P.T, axis=1)] + r * d)
    w = rng.exponential(size=(n_in, len(P))) ** 3
    w /= w.sum(axis=1, keepdims=True)
    v = rng.normal(size=(n_in, 3))
    v *= (r * rng.random((n_in, 1)) ** (1 / 3)) / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-300)
    out.append(w @ P + v)
    return np.concatenate(out)


def deformed_sample(cloud: PointCloud, f, n: int, rng: np.random.Generator, interior: float = 0.3) -> np.ndarray:
    """``f`` of `sample_cloud` points: ``(n, 3) float64`` points of the true deformed set."""
    return np.asarray(f(sample_cloud(cloud, n, rng, interior)), dtype=np.float64)


def swept_sample(points, pose0, pose1, times) -> np.ndarray:
    """Positions ``R(s) x + t(s)`` of ``points`` ``(n, 3)`` at ``times`` ``(k,)``: ``(k, n, 3) float64``.

    ``R(s)`` is the slerp from ``R0`` to ``R1`` (the constant-rate turn about the axis of
    ``R1 R0ᵀ``, the shorter way round), ``t(s)`` linear; poses are ``(R, t)`` pairs.
    """
    (R0, t0), (R1, t1) = pose0, pose1
    R0, R1 = np.asarray(R0, float), np.asarray(R1, float)
    t0, t1 = np.asarray(t0, float), np.asarray(t1, float)
    times = np.asarray(times, float)
    slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([R0, R1])))
    Rs = slerp(times).as_matrix()  # (k, 3, 3)
    ts = (1.0 - times)[:, None] * t0 + times[:, None] * t1
    return np.einsum("kij,nj->kni", Rs, np.asarray(points, float)) + ts[:, None, :]


def signed_excess(points, cloud: PointCloud) -> np.ndarray:
    """Signed distance of each of ``points`` ``(m, 3)`` to ``hull(cloud.points)``, minus the radius.

    Returns
    -------
    (m,) float64
        Positive outside ``cloud``'s set. Inside a solid hull the distance is minus the nearest
        facet plane's (exact for a convex polytope); outside, the nearest facet triangle's (or
        segment's, or point's, for flat, collinear and single-point hulls).
    """
    X = np.asarray(points, float).reshape(-1, 3)
    P = np.asarray(cloud.points, float)
    out = np.empty(len(X))
    center, axes, rank, local = _frame(P)
    if rank == 3:
        h = ConvexHull(local)
        Xl = (X - center) @ axes.T  # in the hull's frame, as its equations are
        tris = P[h.simplices]
        # Each triangle's bounding sphere: |p - centre| - radius is at most p's distance to it.
        cen = tris.mean(axis=1)
        rad = np.sqrt(np.einsum("tkj,tkj->tk", tris - cen[:, None], tris - cen[:, None]).max(axis=1))
        # Points in chunks: a (chunk, facets) block of plane values stays small on big hulls.
        step = int(np.clip(2_000_000 // len(tris), 16, 256))
        for s in range(0, len(X), step):
            plane = Xl[s:s + step] @ h.equations[:, :3].T + h.equations[:, 3]  # (c, f)
            out[s:s + step] = plane.max(axis=1)
            o = np.flatnonzero(out[s:s + step] > 0)
            if len(o) == 0:
                continue
            # Outside, the distance is the nearest triangle's. The triangle of the facet the point
            # is farthest outside of gives an upper bound d; a triangle can be nearer only if its
            # bounding sphere comes nearer than d (|p - centre| - radius is at most p's distance
            # to it), so those candidates, all measured, give the all-triangle minimum. (Qhull's
            # planes are rounded, and a sliver facet's -- near-duplicate points -- may be far off:
            # the planes only choose the first bound, never exclude a triangle;
            # tests/test_adversary_oracles.py checks the all-triangle formula on clustered clouds.)
            x = X[s + o]
            d = _tri_distance_paired(x, tris[np.argmax(plane[o], axis=1)])
            dc = np.sqrt(np.maximum(np.einsum("ij,ij->i", x, x)[:, None] - 2 * x @ cen.T
                                    + np.einsum("ij,ij->i", cen, cen)[None, :], 0.0))
            # slack for the rounding of the bound (the expanded square loses ~1e-8 of |x| + |cen|)
            slack = 1e-7 * (np.abs(x).max(axis=1)[:, None] + np.abs(cen).max(axis=1)[None, :] + rad[None, :])
            pi, ti = np.nonzero(dc - rad[None, :] - slack < d[:, None])
            for k in range(0, len(pi), 65536):  # candidate pairs in blocks: memory stays small
                np.minimum.at(d, pi[k:k + 65536], _tri_distance_paired(x[pi[k:k + 65536]], tris[ti[k:k + 65536]]))
            out[s + o] = d
    elif rank == 2:
        out[:] = _tri_distance(X, _hull_triangles(P)[0])
    elif rank == 1:
        a = P[np.argmin(local[:, 0])][None]
        b = P[np.argmax(local[:, 0])][None]
        out[:] = _seg(X[:, None, :], a, b)[:, 0]
    else:
        out[:] = np.linalg.norm(X - P[0], axis=1)
    return out - cloud.radius


def cloud_volume(cloud: PointCloud) -> float:
    """Volume of ``hull(points) ⊕ ball(radius)`` (Steiner's formula; 0 for a flat cloud of radius 0)."""
    P = np.asarray(cloud.points, float)
    r = cloud.radius
    ball = 4.0 / 3.0 * np.pi * r**3
    center, axes, rank, local = _frame(P)
    if rank == 3:
        h = ConvexHull(P)
        normals = h.equations[:, :3]
        psi_len = 0.0
        for i, (tri, nbrs) in enumerate(zip(h.simplices, h.neighbors)):
            for j, nb in enumerate(nbrs):  # neighbour j is opposite vertex j
                edge = np.delete(tri, j)
                cosang = np.clip(normals[i] @ normals[nb], -1.0, 1.0)
                psi_len += np.linalg.norm(P[edge[0]] - P[edge[1]]) * np.arccos(cosang)
        return float(h.volume + h.area * r + 0.5 * r * r * psi_len / 2.0 + ball)
    if rank == 2:
        h2 = ConvexHull(local[:, :2])
        # area A (both sides: 2 A r), perimeter L (half cylinders: pi r² L / 2... exact: π r² L / 2)
        return float(2.0 * h2.volume * r + 0.5 * np.pi * r * r * h2.area + ball)
    if rank == 1:
        return float(np.pi * r * r * np.ptp(local[:, 0]) + ball)
    return float(ball)
