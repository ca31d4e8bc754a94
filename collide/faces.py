"""Faces of convex polytopes, flat, for face contacts (`collide._kernels.faces`).

`polytope_faces` turns a point set into its hull's faces (coplanar triangles of Qhull merged
into one polygon each, its vertices in counter-clockwise order about the outward normal). Built
once per geom; the narrow phase reads the concatenation (`FaceTable`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

__all__ = ["FaceTable", "PolytopeFaces", "polytope_faces"]

# Two hull facets are one face when their unit normals and their offsets (relative to the hull's
# size) agree on a grid of this step.
_COPLANAR = 1e-9


@dataclass(frozen=True)
class PolytopeFaces:
    """The hull of a point set as faces.

    Attributes
    ----------
    verts : (H, 3) float64
        Hull vertices.
    normal : (F, 3) float64
        Outward unit normals.
    offset : (F,) float64
        ``normal . x = offset`` on the face.
    vadr, vnum : (F,) int64
        Each face's vertex list in ``vidx``: ``vidx[vadr[f]:vadr[f] + vnum[f]]``.
    vidx : (V,) int32
        Indices into ``verts``, counter-clockwise about the face's normal.
    """

    verts: np.ndarray
    normal: np.ndarray
    offset: np.ndarray
    vadr: np.ndarray
    vnum: np.ndarray
    vidx: np.ndarray


def _empty(points: np.ndarray) -> PolytopeFaces:
    z = np.zeros(0, np.int64)
    return PolytopeFaces(np.asarray(points, float).reshape(-1, 3), np.zeros((0, 3)), np.zeros(0), z, z,
                         np.zeros(0, np.int32))


def _hull_planes(pts: np.ndarray):
    """Qhull's triangles of the hull of ``pts`` ``(n, 3)`` grouped by plane, or None (no volume).

    Returns ``verts`` (H, 3) (the hull's vertices), ``tri`` (T, 3) (indices into ``verts``),
    ``group`` (T,) (each triangle's plane, 0..F-1, ordered as the planes' grid keys sort) and
    ``normal`` (F, 3) (outward unit normals).
    """
    if len(pts) < 4 or not np.all(np.isfinite(pts)):
        return None
    try:
        hull = ConvexHull(pts)
    except (QhullError, ValueError):
        return None
    used = np.unique(hull.simplices)
    remap = np.full(len(pts), -1, np.int64)
    remap[used] = np.arange(len(used))
    verts = pts[used]
    tri = remap[hull.simplices]
    eq = hull.equations  # (T, 4): n . x + c <= 0 inside
    size = float(np.max(np.ptp(verts, axis=0))) or 1.0
    # group the triangles by plane: equations on a grid of _COPLANAR (Qhull's facets of one planar
    # face agree to rounding; a value straddling a grid line splits a face in two, which only
    # shrinks a face manifold, never makes a wrong contact)
    q = np.c_[np.round(eq[:, :3] / _COPLANAR), np.round(eq[:, 3] / (_COPLANAR * size))].astype(np.int64)
    _, first, group = np.unique(q, axis=0, return_index=True, return_inverse=True)
    normal = eq[first, :3].astype(np.float64)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    return verts, tri, group.ravel(), normal


def polytope_faces(points) -> PolytopeFaces:
    """Faces of the convex hull of ``points`` ``(n, 3)``.

    A flat, collinear or single-point set has no faces (a hull of no volume): the result then
    has no faces and no adjacency, its ``verts`` the input.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    planes = _hull_planes(pts)
    if planes is None:
        return _empty(pts)
    verts, tri, group, normal = planes
    # Each face's distinct vertices, sorted by face then vertex id, all faces at once (a mesh of
    # thousands of triangles has thousands of faces: a Python loop per face was the Collider's
    # set-up time). `collide.testing.manifold.polytope_faces_loop` is the per-face twin.
    H = len(verts)
    key = np.unique(np.repeat(group, 3) * H + tri.ravel())
    fid, vid = key // H, key % H
    start = np.flatnonzero(np.r_[True, fid[1:] != fid[:-1]])
    count = np.diff(np.r_[start, len(key)])
    p = verts[vid]
    ctr = np.add.reduceat(p, start, axis=0) / count[:, None]
    # angles about the centre in the face's plane, from its lowest-numbered vertex
    u = p[start] - ctr
    u -= normal * np.einsum("ij,ij->i", u, normal)[:, None]
    un = np.linalg.norm(u, axis=1)
    u /= np.where(un > 0, un, 1.0)[:, None]
    w = np.cross(normal, u)
    d = p - ctr[fid]
    ang = np.arctan2(np.einsum("ij,ij->i", d, w[fid]), np.einsum("ij,ij->i", d, u[fid]))
    order = np.lexsort((ang, fid))
    offset = np.add.reduceat(np.einsum("ij,ij->i", p, normal[fid]), start) / count
    return PolytopeFaces(verts, normal, offset, start.astype(np.int64), count.astype(np.int64),
                         vid[order].astype(np.int32))


class FaceTable:
    """`PolytopeFaces` of several geoms, concatenated (`collide._kernels.faces` reads them).

    Parameters
    ----------
    faces : list of PolytopeFaces or None
        One per geom; None for a geom without faces.

    Attributes
    ----------
    hv_adr, hv_num, f_adr, f_num : (G,) int64
        Each geom's rows in ``hv`` (hull vertices) and in the face arrays.
    hv : (H, 3) float64
    f_normal : (F, 3) float64
    f_offset : (F,) float64
    f_vadr, f_vnum : (F,) int64
        Into ``f_vidx`` (indices local to the geom's ``hv`` rows).
    f_vidx : (V,) int32
    """

    def __init__(self, faces: list):
        G = len(faces)
        self.hv_adr, self.hv_num = np.zeros(G, np.int64), np.zeros(G, np.int64)
        self.f_adr, self.f_num = np.zeros(G, np.int64), np.zeros(G, np.int64)
        hv, fn, fo, fva, fvn, fvi = [], [], [], [], [], []
        h = f = v = 0
        for g, pf in enumerate(faces):
            if pf is None:
                continue
            self.hv_adr[g], self.hv_num[g] = h, len(pf.verts)
            self.f_adr[g], self.f_num[g] = f, len(pf.normal)
            hv.append(pf.verts)
            fn.append(pf.normal)
            fo.append(pf.offset)
            fva.append(pf.vadr + v)
            fvn.append(pf.vnum)
            fvi.append(pf.vidx)
            h += len(pf.verts)
            f += len(pf.normal)
            v += len(pf.vidx)

        def cat(parts, shape, dtype):
            return np.ascontiguousarray(np.concatenate(parts) if parts else np.zeros(shape), dtype=dtype)

        self.hv = cat(hv, (0, 3), np.float64)
        self.f_normal = cat(fn, (0, 3), np.float64)
        self.f_offset = cat(fo, 0, np.float64)
        self.f_vadr = cat(fva, 0, np.int64)
        self.f_vnum = cat(fvn, 0, np.int64)
        self.f_vidx = cat(fvi, 0, np.int32)
        self.max_face = int(self.f_vnum.max()) if len(self.f_vnum) else 0

    def kernel_args(self) -> tuple:
        """The arrays in `collide._kernels.manifold.collide_pairs`' order."""
        return (self.hv_adr, self.hv_num, self.hv, self.f_adr, self.f_num, self.f_normal, self.f_offset, self.f_vadr,
                self.f_vnum, self.f_vidx)
