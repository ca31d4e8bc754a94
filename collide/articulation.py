"""The kinematic tree: bodies, geoms, collision filters, depth-first layout, local bounds (once).

An `Articulation` is built from arrays in MuJoCo's layout (body 0 is the world,
``body_parent[0] == 0``). Set-up, done once per model and tuned for tightness rather than speed,
computes everything the per-step broad phase (`collide.broadphase`) needs:

- each geom's cloud in its body's frame, its local OBB, enclosing sphere and capsule;
- each body's hull-reduced cloud (union of its geoms, Stürzlinger 1996 §3.3) and local bounds
  that contain its geoms' bounds (inflated by their margins), so culling a body never culls a
  geom pair whose own bounds overlap;
- the depth-first layout: every subtree is one contiguous range of positions;
- the static filter: weld groups, parent-child rule, excluded body pairs, explicit geom pairs.

Bounds semantics (what "two geoms' bounds overlap" means everywhere in `collide`): the geoms'
spheres overlap, their OBBs overlap (separating-axis test on all 15 axes) *and* their world AABBs
overlap, each volume inflated by the geom's margin (radius + margin, half extents + margin). A
geom's world AABB is the intersection of its OBB's world AABB and its capsule's: each geom also
keeps a local capsule (a segment centred on its OBB's centre, along the OBB's longest axis, plus
a radius) containing its cloud, whose world AABB is exact for a capsule geom at any angle (the AABB
of a limb's OBB at 45 degrees is larger by ~(sqrt(2) - 1) r a side across it: on 22 humanoids a
third fewer candidate pairs). A plane is the halfspace
``{x : normal . x <= offset + margin}``; it overlaps a geom when all three of the geom's volumes
reach it (the AABB: its corner deepest along the normal). Explicit pairs are tested on their
spheres and OBBs only, inflated by the pair's own margin.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from . import hull as _hull
from . import shapes as _shapes
from . import volumes as _volumes
from ._kernels.bounds import ORTHO_TOL as _KERNEL_ORTHO_TOL
from ._validate import as_array
from .pointcloud import PointCloud, union

__all__ = [
    "Articulation", "BOUND_GUARD", "MARGIN_SLACK", "MIN_GEOM_SIZE", "ORTHO_TOL", "POSE_ORTHO_TOL",
    "ROTATION_SLACK", "fit_capsule", "fit_local_obb", "fit_local_sphere", "not_rotations",
]

# Relative guard added to every local bound so that the rounding of the fitters (extents measured
# as differences of rotated coordinates) can never leave a cloud point outside its volume.
BOUND_GUARD = 1e-10

# Rotations (geom placement) that deviate from orthonormal by more than this are rejected.
ORTHO_TOL = 1e-6


def _is_plane(obj) -> bool:
    # shapes.Plane only: its constructor checks the normal and the offset (another object with a
    # normal and an offset could carry a zero normal or a NaN, and the plane would never pair).
    return isinstance(obj, _shapes.Plane)


def fit_local_obb(cloud: PointCloud) -> _volumes.OBB:
    """Near-minimal OBB of ``cloud`` (``volumes``' "optimal" fitter)."""
    return cloud.obb("optimal")


def fit_local_sphere(cloud: PointCloud) -> _volumes.Sphere:
    """Minimal enclosing sphere of ``cloud`` (``volumes``' "exact" fitter)."""
    return cloud.sphere("exact")


# Body rotations are accepted per step when |R^T R - I| <= POSE_ORTHO_TOL entrywise (float32
# poses carry ~1e-7 of error). The kernel moves a local box by R and then treats its axes R a_i as
# orthonormal; the true image is the parallelepiped spanned by h_i R a_i, whose support in any
# direction differs from the box's by at most ~4 tol (h_0 + h_1 + h_2), and ||R|| <= 1 + 1.5 tol
# grows spheres. Every local bound carries that slack (8 tol sum(h), and 2 tol r), so a pair that
# a slightly scaled rotation brings into contact is never culled (found 2026-11-21: a 4.5e-7
# scaled rotation missed touching boxes 4e-7 apart). The tolerance is the per-step kernel's.
POSE_ORTHO_TOL = _KERNEL_ORTHO_TOL
ROTATION_SLACK = 8.0 * POSE_ORTHO_TOL
# Margins are added to the half extents and radii the kernel moves with the same rotations, so
# they need the same cover: a margin-1 point under R = (1 - 4.9e-7) I reached 1 - 4.9e-7 along
# the axes and lost a touching pair (review, 2026-11-22). Under R with |R^T R - I| <= tol, the
# axes' support in any unit direction is at least 1 - 1.5 tol, and treating skewed axes as
# orthonormal costs up to 4 tol of the three half extents summed (12 tol m from a margin m):
# every bound carries its margin grown by MARGIN_SLACK (32 tol) relative.
MARGIN_SLACK = 4.0 * ROTATION_SLACK
# Geoms whose extent (points' spread or radius) is below this, but not zero, are refused: the
# kernels compare squared distances, which underflow below ~1.5e-154 (the square root of float64's
# smallest normal number), so two touching 1e-162 boxes could be culled. `collide.hull.MIN_EXTENT`.
MIN_GEOM_SIZE = _hull.MIN_EXTENT


def _guarded(obb: _volumes.OBB, sphere: _volumes.Sphere):
    scale = max(float(np.abs(obb.center).max()), float(obb.half_extents.max()),
                float(np.abs(sphere.center).max()), sphere.radius, 1e-300)
    pad = BOUND_GUARD * scale
    half = obb.half_extents + pad + ROTATION_SLACK * float(np.sum(obb.half_extents))
    radius = (sphere.radius + pad) * (1.0 + 2.0 * POSE_ORTHO_TOL)
    return obb.center.copy(), obb.rotation.copy(), half, sphere.center.copy(), radius


def fit_capsule(centers: np.ndarray, radii: np.ndarray, center: np.ndarray, axis: np.ndarray):
    """A capsule centred on ``center`` along the unit ``axis`` that contains every ball
    ``(centers[k], radii[k])``, guarded like the other local bounds.

    The half-length ``h`` minimises ``h / 2 + r(h)``, the mean half-width of the capsule's world
    AABB over rotations (``h |u_i| + r``, ``E|u_i| = 1/2``), where ``r(h)`` is the smallest radius
    that holds every ball: a convex function of ``h`` (each ball's distance to the segment is
    ``sqrt(max(|t| - h, 0)^2 + p^2)``, convex and non-increasing in ``h``), found by golden-section
    search on ``[0, max |t|]`` in O(n) per step. For the two end points of a capsule geom this is
    the capsule itself (up to the search's ~1e-15 relative).

    Returns
    -------
    d : (3,) float64
        Half segment, ``h * axis``: the capsule is ``{center + s d : |s| <= 1}`` grown by ``r``.
    r : float
    """
    v = np.asarray(centers, np.float64) - center
    t = v @ axis
    perp = np.linalg.norm(v - t[:, None] * axis, axis=1)
    at = np.abs(t)

    def radius(h: float) -> float:
        # the smallest radius around the segment of half-length h that holds every ball (exact
        # for any h: the capsule contains the balls whichever h the search ends on)
        return float(np.max(np.sqrt(np.maximum(at - h, 0.0) ** 2 + perp ** 2) + radii))

    lo, hi = 0.0, float(at.max())
    g = (np.sqrt(5.0) - 1.0) / 2.0
    a, b = hi - g * (hi - lo), lo + g * (hi - lo)
    fa, fb = a / 2 + radius(a), b / 2 + radius(b)
    for _ in range(80):  # the bracket shrinks by 0.618 a step: 80 steps, ~1e-17 of max |t|
        if fa <= fb:
            hi, b, fb = b, a, fa
            a = hi - g * (hi - lo)
            fa = a / 2 + radius(a)
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = b / 2 + radius(b)
    # the ends of the bracket too: a cloud on the axis or a ball at the centre ends at 0 or max |t|
    h = min((0.0, a, float(at.max())), key=lambda x: x / 2 + radius(x))
    r = radius(h)
    # The fit's rounding (BOUND_GUARD, as `_guarded`), and rotations accepted within
    # POSE_ORTHO_TOL of orthonormal: the kernel moves the segment by the same R as the shape's
    # points, so only distances to it grow, by ||R|| <= 1 + 1.5 tol.
    scale = max(float(np.abs(center).max()), h, r, 1e-300)
    r = (r + BOUND_GUARD * scale) * (1.0 + 2.0 * POSE_ORTHO_TOL)
    return h * np.asarray(axis, np.float64), r


def _depth_first(body_parent: np.ndarray):
    # Children lists in id order, then an explicit-stack DFS from the world: positions, ranges.
    L = len(body_parent)
    order = np.argsort(body_parent[1:], kind="stable") + 1
    counts = np.bincount(body_parent[1:], minlength=L)
    start = np.concatenate([[0], np.cumsum(counts)])
    dfs_order = np.empty(L, np.int64)
    subtree_end = np.empty(L, np.int64)  # by position
    pos = np.full(L, -1, np.int64)
    n = 0
    stack = [(0, False)]
    while stack:
        b, done = stack.pop()
        if done:
            subtree_end[pos[b]] = n
            continue
        pos[b] = n
        dfs_order[n] = b
        n += 1
        stack.append((b, True))
        kids = order[start[b]:start[b + 1]]
        stack.extend((int(k), False) for k in kids[::-1])
    if n != L:
        bad = int(np.flatnonzero(pos < 0)[0])
        raise ValueError(f"body_parent: body {bad} is not connected to the world (body 0): "
                         "the parent links form a cycle")
    return dfs_order, pos, subtree_end


def not_rotations(rot: np.ndarray) -> np.ndarray:
    """Indices of the matrices of ``rot (N, 3, 3)`` that are not proper rotations: an entry of
    ``R^T R - I`` above `ORTHO_TOL`, or a determinant not positive (NaN included)."""
    if len(rot) == 0:
        return np.zeros(0, np.int64)
    err = np.abs(np.einsum("gji,gjk->gik", rot, rot) - np.eye(3)).max(axis=(1, 2))
    return np.flatnonzero(~((err <= ORTHO_TOL) & (np.linalg.det(rot) > 0)))


class Articulation:
    """A kinematic tree of bodies carrying convex geoms, with collision filters.

    Parameters
    ----------
    body_parent : (L,) int array_like
        Parent of each body; body 0 is the world and ``body_parent[0] == 0``. Every other body
        must reach the world through its parents (no cycle), parents in ``[0, L)``.
    geom_body : (G,) int array_like
        Body of each geom, in ``[0, L)``.
    geom_cloud : sequence of G PointCloud or shapes.Plane
        Each geom's shape in its own frame (non-empty clouds). A plane is the halfspace
        ``{x : normal . x <= offset}`` of its frame; planes never pair with planes.
    geom_pos : (G, 3) float64, optional
        Position of each geom frame in its body frame (zero by default).
    geom_rot : (G, 3, 3) float64, optional
        Rotation of each geom frame in its body frame (identity by default), orthonormal.
    geom_contype, geom_conaffinity : (G,) int, optional
        Collision bit masks (1 by default); a pair passes when
        ``(ct1 & ca2) or (ct2 & ca1)``.
    geom_margin : (G,) float64, optional
        Inflation of each geom's bounds (0 by default, ``>= 0``).
    exclude : (E, 2) int array_like or sequence of pairs, optional
        Body pairs never reported.
    pairs : (P, 2) int array_like or sequence of pairs, optional
        Geom pairs always tested: they bypass every filter but the bounds test (and are then not
        tested again by the dynamic path). Duplicates are merged.
    filter_parent : bool, default True
        A body never pairs with its parent unless the parent is the world.
    pair_margin : (P,) float64, optional
        Inflation applied to both geoms of each explicit pair instead of the geoms' margins.
    body_weld : (L,) int array_like, optional
        Weld group of each body: bodies with equal value never pair (MuJoCo's weld rule).
        Default: every body its own group.

    Attributes
    ----------
    body_count, geom_count : int
    body_parent : (L,) int64
    body_weld : (L,) int64
    body_dfs_order : (L,) int64
        ``body_dfs_order[p]`` is the body at depth-first position ``p``.
    body_dfs_pos : (L,) int64
        Depth-first position of each body (inverse of ``body_dfs_order``).
    body_subtree_end : (L,) int64
        By body: the subtree of body ``b`` is positions ``[body_dfs_pos[b], body_subtree_end[b])``.
    body_cloud : list of L PointCloud
        Hull-reduced union of the body's (non-plane) geom clouds, in the body frame.
    body_has_bounds : (L,) bool
        Whether the body carries a non-plane geom.
    body_obb_center, body_obb_rot, body_obb_half : (L, 3), (L, 3, 3), (L, 3) float64
        Local OBB of the body (contains its geoms' OBBs inflated by their margins).
    body_sphere_center, body_sphere_radius : (L, 3), (L,) float64
        Local sphere of the body (contains its geoms' spheres inflated by their margins).
    body_capsule_half, body_capsule_radius : (L, 3), (L,) float64
        Local capsule of the body, centred on its OBB's centre (`fit_capsule`): contains its
        geoms' capsules inflated by their margins (a single geom's: that one, inflated).
    geom_body, geom_contype, geom_conaffinity : (G,) int64
    geom_pos, geom_rot, geom_margin : (G, 3), (G, 3, 3), (G,) float64
    geom_bound_margin : (G,) float64
        The margin as the bounds carry it: ``geom_margin * (1 + MARGIN_SLACK)``, so that rotations
        accepted within ``POSE_ORTHO_TOL`` of orthonormal still cover the margin.
    geom_is_plane : (G,) bool
    geom_plane : (G, 4) float64
        For planes: unit normal and offset in the body frame (zeros for other geoms).
    geom_local_cloud : list of G (PointCloud or None)
        Each geom's cloud in its body's frame (None for planes).
    geom_obb_center, geom_obb_rot, geom_obb_half : (G, 3), (G, 3, 3), (G, 3) float64
        Local OBB of each geom in its body frame, not inflated by the margin.
    geom_sphere_center, geom_sphere_radius : (G, 3), (G,) float64
        Local enclosing sphere of each geom in its body frame, not inflated.
    geom_capsule_half, geom_capsule_radius : (G, 3), (G,) float64
        Local capsule of each geom, ``{geom_obb_center + s half : |s| <= 1}`` grown by the radius,
        along the OBB's longest axis (`fit_capsule`), not inflated; for the world AABB.
    exclude : (E, 2) int64
        Excluded body pairs, lower id first, sorted, unique.
    pairs : (P, 2) int64
        Explicit geom pairs, lower id first, sorted, unique.
    pair_margin : (P,) float64
        Inflation for each explicit pair (NaN where the geoms' own margins apply).
    pair_bound_margin : (P,) float64
        ``pair_margin * (1 + MARGIN_SLACK)``, as ``geom_bound_margin``.
    filter_parent : bool
    """

    def __init__(self, body_parent, geom_body, geom_cloud: Sequence, geom_pos=None, geom_rot=None,
                 geom_contype=None, geom_conaffinity=None, geom_margin=None, exclude=(), pairs=(),
                 filter_parent: bool = True, pair_margin=None, body_weld=None):
        parent = self._int_array(body_parent, "body_parent", (None,))
        L = len(parent)
        if L == 0:
            raise ValueError("body_parent: need at least the world body (body 0)")
        if np.any((parent < 0) | (parent >= L)):
            bad = int(np.flatnonzero((parent < 0) | (parent >= L))[0])
            raise ValueError(f"body_parent: parent {int(parent[bad])} of body {bad} is out of range [0, {L})")
        if parent[0] != 0:
            raise ValueError(f"body_parent: body 0 is the world and must be its own parent, got {int(parent[0])}")
        gbody = self._int_array(geom_body, "geom_body", (None,))
        G = len(gbody)
        if np.any((gbody < 0) | (gbody >= L)):
            bad = int(np.flatnonzero((gbody < 0) | (gbody >= L))[0])
            raise ValueError(f"geom_body: geom {bad} is on body {int(gbody[bad])}, which does not exist "
                             f"(bodies are 0..{L - 1})")
        try:
            clouds = list(geom_cloud)
        except TypeError:
            raise ValueError(f"geom_cloud: expected a list of PointCloud or shapes.Plane, got "
                             f"{type(geom_cloud).__name__}") from None
        if len(clouds) != G:
            raise ValueError(f"geom_cloud: expected {G} shapes (one per geom), got {len(clouds)}")
        is_plane = np.zeros(G, bool)
        for g, c in enumerate(clouds):
            if _is_plane(c):
                is_plane[g] = True
            elif not isinstance(c, PointCloud):
                raise ValueError(f"geom_cloud[{g}]: expected a PointCloud or shapes.Plane, got {type(c).__name__}")
            elif c.is_empty:
                raise ValueError(f"geom_cloud[{g}]: the cloud is empty")
            else:
                size = _hull.extent(c.points, c.radius)
                if 0.0 < size < MIN_GEOM_SIZE:
                    raise ValueError(f"geom_cloud[{g}]: size {size:.3g} is below {MIN_GEOM_SIZE:g}, the smallest "
                                     "non-zero geom the broad phase supports (its squared distances would "
                                     "underflow); scale the model up, or give a single point of radius 0")
        gpos = np.zeros((G, 3)) if geom_pos is None else as_array(geom_pos, "geom_pos", (G, 3))
        grot = np.tile(np.eye(3), (G, 1, 1)) if geom_rot is None else as_array(geom_rot, "geom_rot", (G, 3, 3))
        if G:
            bad = not_rotations(grot)
            if len(bad):
                raise ValueError(f"geom_rot: rotation of geom {int(bad[0])} is not a proper orthonormal matrix")
        ct = np.ones(G, np.int64) if geom_contype is None else self._int_array(geom_contype, "geom_contype", (G,))
        ca = (np.ones(G, np.int64) if geom_conaffinity is None
              else self._int_array(geom_conaffinity, "geom_conaffinity", (G,)))
        margin = np.zeros(G) if geom_margin is None else as_array(geom_margin, "geom_margin", (G,))
        if np.any(margin < 0):
            raise ValueError(f"geom_margin: margin of geom {int(np.flatnonzero(margin < 0)[0])} is negative")
        weld = np.arange(L, dtype=np.int64) if body_weld is None else self._int_array(body_weld, "body_weld", (L,))

        # Own copies: the caller's arrays may change after this (a broad phase built from this
        # articulation packs its values once, and must agree with it).
        parent, weld, gbody, ct, ca, gpos, grot, margin = (
            np.array(v) for v in (parent, weld, gbody, ct, ca, gpos, grot, margin))
        self.body_count, self.geom_count = L, G
        self.body_parent, self.body_weld = parent, weld
        self.geom_body, self.geom_contype, self.geom_conaffinity = gbody, ct, ca
        self.geom_pos, self.geom_rot, self.geom_margin = gpos, grot, margin
        self.geom_is_plane = is_plane
        self.geom_cloud = clouds
        if not isinstance(filter_parent, (bool, np.bool_)):
            raise ValueError(f"filter_parent: expected True or False, got {filter_parent!r}")
        self.filter_parent = bool(filter_parent)
        self.exclude = self._pair_list(exclude, "exclude", L, "body")
        self.pairs, self.pair_margin = self._explicit(pairs, pair_margin, G)
        self.geom_bound_margin = margin * (1.0 + MARGIN_SLACK)
        self.pair_bound_margin = self.pair_margin * (1.0 + MARGIN_SLACK)
        self.body_dfs_order, self.body_dfs_pos, end_by_pos = _depth_first(parent)
        self.body_subtree_end = end_by_pos[self.body_dfs_pos]
        self._fit_geoms()
        self._fit_bodies()

    # ----------------------------------------------------------------------------- validation
    @staticmethod
    def _read(value, name):
        try:
            return np.asarray(value)
        except ValueError as exc:  # ragged rows
            raise ValueError(f"{name}: cannot be read as an integer array ({exc})") from None

    @classmethod
    def _int_array(cls, value, name, shape):
        arr = cls._read(value, name)
        if arr.size == 0 and len(shape) == 1 and shape[0] in (None, 0):
            return np.zeros(0, np.int64)
        if arr.dtype.kind not in "iub":
            raise ValueError(f"{name}: expected integers, got dtype {arr.dtype}")
        if arr.dtype.kind == "u" and arr.size and int(arr.max()) > np.iinfo(np.int64).max:
            raise ValueError(f"{name}: value {int(arr.max())} is out of range")  # would wrap to negative
        arr = as_array(arr, name, shape, np.int64)
        return arr

    @classmethod
    def _pair_list(cls, value, name, n, what):
        arr = cls._read(value, name)
        if arr.size == 0:
            return np.zeros((0, 2), np.int64)
        arr = cls._int_array(arr, name, (None, 2))
        if np.any((arr < 0) | (arr >= n)):
            bad = int(np.flatnonzero(np.any((arr < 0) | (arr >= n), axis=1))[0])
            raise ValueError(f"{name}: row {bad} names a {what} outside [0, {n}): {arr[bad].tolist()}")
        arr = np.sort(arr, axis=1)
        return np.unique(arr, axis=0)

    @classmethod
    def _explicit(cls, pairs, pair_margin, G):
        arr = cls._read(pairs, "pairs")
        if arr.size == 0:
            if pair_margin is not None and np.asarray(pair_margin).size:
                raise ValueError("pair_margin: given without explicit pairs")
            return np.zeros((0, 2), np.int64), np.zeros(0)
        arr = cls._int_array(arr, "pairs", (None, 2))
        P = len(arr)
        if np.any((arr < 0) | (arr >= G)):
            bad = int(np.flatnonzero(np.any((arr < 0) | (arr >= G), axis=1))[0])
            raise ValueError(f"pairs: row {bad} names a geom outside [0, {G}): {arr[bad].tolist()}")
        if np.any(arr[:, 0] == arr[:, 1]):
            bad = int(np.flatnonzero(arr[:, 0] == arr[:, 1])[0])
            raise ValueError(f"pairs: row {bad} pairs geom {int(arr[bad, 0])} with itself")
        pm = np.full(P, np.nan) if pair_margin is None else as_array(pair_margin, "pair_margin", (P,))
        if np.any(pm < 0):
            raise ValueError(f"pair_margin: margin of pair {int(np.flatnonzero(pm < 0)[0])} is negative")
        arr = np.sort(arr, axis=1)
        # Merge duplicates: keep the largest inflation (conservative).
        key = arr[:, 0] * G + arr[:, 1]
        uk, inv = np.unique(key, return_inverse=True)
        out_m = np.full(len(uk), -np.inf)
        np.maximum.at(out_m, inv, np.where(np.isnan(pm), np.inf, pm))
        out_m[np.isinf(out_m)] = np.nan
        return np.stack([uk // G, uk % G], axis=1).astype(np.int64), out_m

    # ----------------------------------------------------------------------------- local bounds
    def _fit_geoms(self):
        G = self.geom_count
        self.geom_local_cloud = [None] * G
        self.geom_obb_center = np.zeros((G, 3))
        self.geom_obb_rot = np.tile(np.eye(3), (G, 1, 1))
        self.geom_obb_half = np.zeros((G, 3))
        self.geom_sphere_center = np.zeros((G, 3))
        self.geom_sphere_radius = np.zeros(G)
        self.geom_plane = np.zeros((G, 4))
        self.geom_capsule_half = np.zeros((G, 3))
        self.geom_capsule_radius = np.zeros(G)
        for g, c in enumerate(self.geom_cloud):
            R, t = self.geom_rot[g], self.geom_pos[g]
            if self.geom_is_plane[g]:
                # The image of {y : n . y <= offset} under x = R y + t is {x : m . x <= offset + m . t}
                # with m = R^-T n. R is orthonormal only within ORTHO_TOL: R n tilted the plane by
                # that much, and a sphere 100 away sinking 1e-7 into it was missed (review, 2026-11-22).
                n = np.asarray(c.normal, float)
                m = np.linalg.solve(R.T, n / np.linalg.norm(n))
                k = float(np.linalg.norm(m))
                self.geom_plane[g, :3] = m / k
                self.geom_plane[g, 3] = (float(c.offset) + float(m @ t)) / k
                continue
            try:
                local = c.transform(R, t)
                self.geom_local_cloud[g] = local
                (self.geom_obb_center[g], self.geom_obb_rot[g], self.geom_obb_half[g],
                 self.geom_sphere_center[g], self.geom_sphere_radius[g]) = _guarded(
                    fit_local_obb(local), fit_local_sphere(local))
                axis = self.geom_obb_rot[g][:, int(np.argmax(self.geom_obb_half[g]))]
                pts = local.points
                self.geom_capsule_half[g], self.geom_capsule_radius[g] = fit_capsule(
                    pts, np.full(len(pts), float(local.radius)), self.geom_obb_center[g], axis)
            except ValueError as exc:  # name the geom (a fit refusing coordinates beyond its range)
                raise ValueError(f"geom_cloud[{g}]: {exc}") from None

    def _fit_bodies(self):
        L = self.body_count
        self.body_cloud = [PointCloud.empty() for _ in range(L)]
        self.body_has_bounds = np.zeros(L, bool)
        self.body_obb_center = np.zeros((L, 3))
        self.body_obb_rot = np.tile(np.eye(3), (L, 1, 1))
        self.body_obb_half = np.zeros((L, 3))
        self.body_sphere_center = np.zeros((L, 3))
        self.body_sphere_radius = np.zeros(L)
        self.body_capsule_half = np.zeros((L, 3))
        self.body_capsule_radius = np.zeros(L)
        solid = np.flatnonzero(~self.geom_is_plane)
        by_body = np.argsort(self.geom_body[solid], kind="stable")
        solid = solid[by_body]
        cuts = np.searchsorted(self.geom_body[solid], np.arange(L + 1))
        for b in range(L):
            gs = solid[cuts[b]:cuts[b + 1]]
            if len(gs) == 0:
                continue
            self.body_has_bounds[b] = True
            m = self.geom_bound_margin[gs]
            self.body_cloud[b] = union([self.geom_local_cloud[g] for g in gs], threshold=1).reduced()
            if len(gs) == 1:
                # One geom: the body's bounds are that geom's inflated bounds, bit for bit, so
                # the body test decides the geom test (the kernel skips the repeat).
                g = gs[0]
                self.body_obb_center[b] = self.geom_obb_center[g]
                self.body_obb_rot[b] = self.geom_obb_rot[g]
                self.body_obb_half[b] = self.geom_obb_half[g] + m[0]
                self.body_sphere_center[b] = self.geom_sphere_center[g]
                self.body_sphere_radius[b] = self.geom_sphere_radius[g] + m[0]
                self.body_capsule_half[b] = self.geom_capsule_half[g]
                self.body_capsule_radius[b] = self.geom_capsule_radius[g] + m[0]
                continue
            # The body's OBB must contain its geoms' inflated OBBs (the kernel culls with it
            # before the geom tests): fit to their corners, one level only.
            corners = np.concatenate([_volumes.obb_corners(self.geom_obb_center[g], self.geom_obb_rot[g],
                                                   self.geom_obb_half[g] + m[i]) for i, g in enumerate(gs)])
            try:
                obb = fit_local_obb(PointCloud(corners))
            except ValueError as exc:  # the inflated geoms' corners beyond the fits' range
                raise ValueError(f"body {b}: the bounds of its geoms {gs.tolist()}, inflated by geom_margin "
                                 f"(largest {float(m.max()):.3g}), cannot be fitted: {exc}") from None
            # Its sphere must contain the geoms' inflated spheres: try the body hull's centre and
            # the geom spheres' centres' centre, keep the smaller enclosing radius.
            cs, rs = self.geom_sphere_center[gs], self.geom_sphere_radius[gs] + m
            best = None
            for cand in (fit_local_sphere(self.body_cloud[b]).center,
                         fit_local_sphere(PointCloud(cs)).center):
                r = float(np.max(np.linalg.norm(cs - cand, axis=1) + rs))
                if best is None or r < best[1]:
                    best = (cand, r)
            sph = _volumes.Sphere(np.asarray(best[0], float), best[1])
            (self.body_obb_center[b], self.body_obb_rot[b], self.body_obb_half[b],
             self.body_sphere_center[b], self.body_sphere_radius[b]) = _guarded(obb, sph)
            # Its capsule must contain its geoms' inflated capsules: the balls at their ends.
            ends = np.concatenate([self.geom_obb_center[gs] + self.geom_capsule_half[gs],
                                   self.geom_obb_center[gs] - self.geom_capsule_half[gs]])
            rads = np.tile(self.geom_capsule_radius[gs] + m, 2)
            axis = self.body_obb_rot[b][:, int(np.argmax(self.body_obb_half[b]))]
            self.body_capsule_half[b], self.body_capsule_radius[b] = fit_capsule(
                ends, rads, self.body_obb_center[b], axis)

    def __repr__(self) -> str:
        return (f"Articulation({self.body_count} bodies, {self.geom_count} geoms, "
                f"{len(self.exclude)} excluded body pairs, {len(self.pairs)} explicit pairs)")
