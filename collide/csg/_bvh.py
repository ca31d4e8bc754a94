"""The BVH of a CSG graph: the unrolled tree in world coordinates (transforms folded into the
leaves), each node bounded by a box (or OBB, or sphere) fitted from its point cloud, with the
paper's top-down tightening (Stürzlinger 1996, §3.5), flattened into arrays for the ray kernels;
``method="box_of_box"`` builds the classical hierarchy for comparison.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._kernels import ray as _ray
from .._kernels import ray_primitives as _prim
from .._validate import as_count
from ..volumes import AABB
from ._graph import Instances, Intersection, Leaf, Node, Transform, Union, _check_node
from ._unrolling import _NO_BOX, _bob, _box_under, _check_leaf_count, _cloud, _Context, _deep_recursion, _resolve

__all__ = ["BOX_PAD", "BVH", "build_bvh"]

# Relative inflation of every BVH box: rounding in the slab test must never miss a leaf that
# the exact primitive test hits (DESIGN.md: prefer a tiny conservative inflation).
BOX_PAD = 1e-9

class _P:
    # A node of the unrolled world tree: kind, children, leaf id, world box, and the world OBB
    # (centre, rotation, half extents) or sphere (centre, radius) when those are the volume.
    __slots__ = ("kind", "kids", "leaf", "lo", "hi", "vol")

    def __init__(self, kind, kids, leaf, lo, hi, vol=None):
        self.kind, self.kids, self.leaf, self.lo, self.hi, self.vol = kind, kids, leaf, lo, hi, vol


def _world_volume(node, env, w, ctx, volume):
    """World OBB ``(center, rotation, half)`` or sphere ``(center, radius)`` of a node's cloud.

    Fitted once per distinct cloud in its own frame, then moved by ``w``: a similarity keeps an
    OBB an OBB and a sphere a sphere; a general affine map turns the OBB into a parallelepiped,
    bounded by the box along its polar-decomposition axes, and the sphere into an ellipsoid,
    bounded by the sphere of the largest singular value (no refit per instance).
    """
    if volume == "aabb":
        return None
    cloud = _cloud(node, env, ctx)
    local = ctx.fits.get((id(cloud), volume))
    if local is None:
        local = cloud.obb() if volume == "obb" else cloud.sphere()
        ctx.fits[(id(cloud), volume)] = local  # the cloud lives in ctx.cache: ids stay unique
    lin = w[:3, :3]
    center = lin @ local.center + w[:3, 3]
    u, sv, vt = np.linalg.svd(lin @ local.rotation if volume == "obb" else lin)
    if volume == "sphere":
        return center, local.radius * float(sv[0])
    m = lin @ local.rotation
    rot = u @ vt  # the orthonormal factor of m (polar decomposition): m's own axes
    half = np.abs(rot.T @ m) @ local.half_extents
    return center, rot, half * (1.0 + 1e-12)


def _world_box(node, env, w, ctx, method):
    if method == "pointcloud":
        c = _cloud(node, env, ctx)
        if c.is_empty:
            return _NO_BOX
        # Exact AABB of hull(P) ⊕ ball(r) under x -> L x + t: the ball maps to an ellipsoid whose
        # half-extent along axis i is r * |row i of L|.
        pts = c.points @ w[:3, :3].T + w[:3, 3]
        ext = c.radius * np.linalg.norm(w[:3, :3], axis=1)
        return pts.min(axis=0) - ext, pts.max(axis=0) + ext
    return _box_under(*_bob(node, env, ctx), w)


def _unroll(node, env, w, ctx, method, leaf_list, volume="aabb"):
    """World tree of ``node`` (None where empty); appends (Leaf, world) to ``leaf_list`` in DFS order."""
    node, env = _resolve(node, env)
    if isinstance(node, Transform):
        return _unroll(node.child, env, w @ node.matrix, ctx, method, leaf_list, volume)
    if isinstance(node, Leaf):
        leaf_list.append((node, w))
        lo, hi = _world_box(node, env, w, ctx, method)
        return _P(_ray.LEAF, [], len(leaf_list) - 1, lo, hi, _world_volume(node, env, w, ctx, volume))
    if isinstance(node, Instances):
        kids = [_unroll(node.child, env, w @ m, ctx, method, leaf_list, volume) for m in node.matrices]
    else:
        kids = [_unroll(c, env, w, ctx, method, leaf_list, volume) for c in node.children()]
    if isinstance(node, (Union, Instances)):
        kids = [k for k in kids if k is not None]
        if not kids:
            return None
        kind = _ray.UNION
    elif isinstance(node, Intersection):
        if kids[0] is None or kids[1] is None:
            return None
        kind = _ray.INTERSECTION
    else:
        if kids[0] is None:
            return None
        if kids[1] is None:
            return kids[0]
        kind = _ray.DIFFERENCE
    lo, hi = _world_box(node, env, w, ctx, method)
    if np.any(lo > hi):
        return None  # e.g. an intersection whose operands' hulls are disjoint
    return _P(kind, kids, -1, lo, hi, _world_volume(node, env, w, ctx, volume))


def _clip(p: _P, lo, hi):
    """Top-down pass (§3.5): clip ``p``'s box to its parent's clipped box; None when emptied."""
    lo = np.maximum(p.lo, lo)
    hi = np.minimum(p.hi, hi)
    if np.any(lo > hi):
        return None
    p.lo, p.hi = lo, hi
    if p.kind == _ray.LEAF:
        return p
    kids = [_clip(k, lo, hi) for k in p.kids]
    if p.kind == _ray.UNION:
        p.kids = [k for k in kids if k is not None]
        return p if p.kids else None
    if p.kind == _ray.INTERSECTION:
        if kids[0] is None or kids[1] is None:
            return None  # an empty clip empties an intersection
        p.kids = kids
        return p
    if kids[0] is None:
        return None
    if kids[1] is None:
        return kids[0]  # an empty clip removes a difference's right subtree
    p.kids = kids
    return p


@dataclass(repr=False)
class BVH:
    """A flattened CSG hierarchy ready for `raycast`; node 0 is the root.

    Attributes
    ----------
    node_kind : (N,) int8
        0 leaf, 1 union, 2 intersection, 3 difference.
    node_first, node_count : (N,) int32
        Each node's children are ``node_child[node_first : node_first + node_count]``.
    node_child : (M,) int32
    node_lo, node_hi : (N, 3) float64
        World boxes (after the top-down pass when ``tightened``); for ``volume="obb"``,
        ``node_hi`` holds the OBB half extents.
    node_center : (N, 3) float64
        OBB or sphere centres (``volume`` "obb" or "sphere"; zero for "aabb").
    node_rot : (N, 3, 3) float64
        OBB rotations, columns are the box axes (identity otherwise).
    node_radius : (N,) float64
        Sphere radii (``volume="sphere"``; zero otherwise).
    node_leaf : (N,) int32
        Leaf id of a leaf node, -1 otherwise.
    leaf_prim : (L,) int8
        Kernel primitive code of each unrolled leaf (``collide._kernels.ray.P_*``).
    leaf_param : (L, 3) float64
    leaf_inv : (L, 3, 4) float64
        World -> local affine maps (identity rows for singular maps, which get a null primitive).
    leaf_tri_first, leaf_tri_count : (L,) int32
        Mesh leaves: their triangles in ``tri``.
    tri : (T, 3, 3) float64
        Triangles of all mesh leaves, in their leaf's local frame.
    leaf_source : list of Leaf
        The Leaf node of each unrolled leaf id.
    leaf_world : (L, 4, 4) float64
        Local -> world matrix of each leaf.
    volume : str
        ``"aabb"``, ``"obb"`` or ``"sphere"``.
    method : str
        ``"pointcloud"`` or ``"box_of_box"``.
    tightened : bool
        Whether the top-down pass ran.
    """

    node_kind: np.ndarray
    node_first: np.ndarray
    node_count: np.ndarray
    node_child: np.ndarray
    node_lo: np.ndarray
    node_hi: np.ndarray
    node_leaf: np.ndarray
    node_center: np.ndarray
    node_rot: np.ndarray
    node_radius: np.ndarray
    leaf_prim: np.ndarray
    leaf_param: np.ndarray
    leaf_inv: np.ndarray
    leaf_tri_first: np.ndarray
    leaf_tri_count: np.ndarray
    tri: np.ndarray
    leaf_source: list
    leaf_world: np.ndarray
    volume: str
    method: str
    tightened: bool
    root_unclipped: AABB
    span_capacity: int
    height: int
    max_children: int
    max_tri: int

    @property
    def n_nodes(self) -> int:
        """Number of nodes in the flattened tree (empty and removed subtrees excluded)."""
        return len(self.node_kind)

    @property
    def n_leaves(self) -> int:
        """Number of unrolled leaves (ids ``0 .. n_leaves - 1``), including removed ones."""
        return len(self.leaf_prim)

    def root_aabb(self) -> AABB:
        """The root's box as constructed (before the top-down pass and the padding)."""
        return self.root_unclipped

    def __repr__(self) -> str:
        return (f"BVH({self.n_nodes} nodes, {self.n_leaves} leaves, volume={self.volume!r}, "
                f"method={self.method!r}, tightened={self.tightened})")


def _leaf_arrays(leaf_list):
    n = len(leaf_list)
    prim = np.zeros(n, dtype=np.int8)
    param = np.zeros((n, 3))
    inv = np.zeros((n, 3, 4))
    tfirst = np.zeros(n, dtype=np.int32)
    tcount = np.zeros(n, dtype=np.int32)
    tris = []
    ntri = 0
    for i, (leaf, w) in enumerate(leaf_list):
        code, p, local = leaf.kernel_form()
        m = w @ local
        try:
            mi = np.linalg.inv(m)
            ok = np.all(np.isfinite(mi)) and np.linalg.cond(m[:3, :3]) < 1e12
        except np.linalg.LinAlgError:
            ok = False
        if not ok:
            # A singular map flattens the solid: zero volume, no ray enters it.
            code, p, mi = _prim.P_BOX, np.zeros(3), np.eye(4)
        prim[i], param[i], inv[i] = code, p, mi[:3]
        if code == _prim.P_MESH:
            t = leaf.triangles()
            tfirst[i], tcount[i] = ntri, len(t)
            tris.append(t)
            ntri += len(t)
    tri = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
    return prim, param, inv, tfirst, tcount, np.ascontiguousarray(tri)


def build_bvh(node: Node, volume: str = "aabb", method: str = "pointcloud", tighten: bool = True,
              threshold: int = 256, exact_intersection: bool = True) -> BVH:
    """Bounding-volume hierarchy of a CSG graph for ray queries (paper §3.5).

    Parameters
    ----------
    node : Node
        The root; recursive parts are unrolled to their depth.
    volume : {"aabb", "obb", "sphere"}
        The bounding volume tested by the rays at each node: the world box, a near-minimal
        oriented box or the minimal sphere of the node's cloud (``cloud.obb()``,
        ``cloud.sphere()``), fitted once per shared subgraph in its own frame and moved into
        the world (exact for similarity maps, conservatively enlarged by other affine maps).
    method : {"pointcloud", "box_of_box"}
        ``"pointcloud"``: each node's box is the exact box of its cloud (memoized per shared
        subgraph, moved into the world frame). ``"box_of_box"``: each node's box comes from its
        children's transformed boxes, as in a classical CSG ray tracer (for comparison).
    tighten : bool, default True
        Run the top-down pass: every child's box is clipped to its parent's clipped box (an
        intersection clips both operands, a difference its right one); an empty clip removes a
        difference's right subtree, an intersection or a union child. With ``"obb"`` and
        ``"sphere"`` the boxes still decide the removals; the tested volumes are not clipped.
    threshold, exact_intersection
        Passed to the cloud construction (see `Node.point_cloud`).

    Returns
    -------
    BVH
    """
    _check_node(node, "node")
    if volume not in ("aabb", "obb", "sphere"):
        raise ValueError(f"volume: expected 'aabb', 'obb' or 'sphere', got {volume!r}")
    if method not in ("pointcloud", "box_of_box"):
        raise ValueError(f"method: expected 'pointcloud' or 'box_of_box', got {method!r}")
    if method == "box_of_box" and volume != "aabb":
        raise ValueError("method: 'box_of_box' is the classical construction of axis-aligned "
                         f"boxes; use volume='aabb' with it, got volume={volume!r}")
    for flag, value in (("tighten", tighten), ("exact_intersection", exact_intersection)):
        if not isinstance(value, (bool, np.bool_)):
            raise ValueError(f"{flag}: expected True or False, got {value!r}")
    _check_leaf_count(node)
    ctx = _Context(as_count(threshold, "threshold", 1), bool(exact_intersection), {})
    leaf_list: list = []
    with _deep_recursion():
        root = _unroll(node, (), np.eye(4), ctx, method, leaf_list, volume)
        root_box = AABB(*_NO_BOX) if root is None else AABB(root.lo.copy(), root.hi.copy())
        if root is not None and tighten:
            root = _clip(root, root.lo, root.hi)
        return _flatten(root, leaf_list, volume, method, bool(tighten), root_box)


def _flatten(root, leaf_list, volume, method, tightened, root_box) -> BVH:
    kinds, firsts, counts, lows, highs, leafs, child = [], [], [], [], [], [], []
    centers, rots, radii = [], [], []
    span_max, caps, heights = [], [], []

    # Pre-order numbering with an explicit stack; children lists filled when a node is numbered.
    order = []
    if root is not None:
        stack = [root]
        ids = {}
        while stack:
            p = stack.pop()
            ids[id(p)] = len(order)
            order.append(p)
            stack.extend(reversed(p.kids))
        for p in order:
            kinds.append(p.kind)
            firsts.append(len(child))
            counts.append(len(p.kids))
            child.extend(ids[id(k)] for k in p.kids)
            scale = max(float(np.abs(p.lo).max()), float(np.abs(p.hi).max()), 1e-300)
            leafs.append(p.leaf)
            if volume == "aabb":
                lows.append(p.lo - BOX_PAD * scale)
                highs.append(p.hi + BOX_PAD * scale)
                centers.append(np.zeros(3))
                rots.append(np.eye(3))
                radii.append(0.0)
            elif volume == "obb":
                center, rot, half = p.vol
                lows.append(-half)
                highs.append(half + BOX_PAD * scale)
                centers.append(center)
                rots.append(rot)
                radii.append(0.0)
            else:
                center, radius = p.vol
                lows.append(p.lo)
                highs.append(p.hi)
                centers.append(center)
                rots.append(np.eye(3))
                radii.append(radius + BOX_PAD * scale)
    n = len(order)
    prim, param, inv, tfirst, tcount, tri = _leaf_arrays(leaf_list)
    # Span-buffer capacity: S(node) bounds a node's span count, W(node) the buffer an evaluation
    # needs (acc + child evaluation + merge output; see _kernels.ray._eval_node).
    span_max = [0] * n
    caps = [0] * n
    heights = [1] * n
    for i in range(n - 1, -1, -1):
        if kinds[i] == _ray.LEAF:
            lf = leafs[i]
            span_max[i] = int(tcount[lf]) // 2 + 1 if prim[lf] == _prim.P_MESH else 1
            caps[i] = span_max[i]
            continue
        kids = child[firsts[i]:firsts[i] + counts[i]]
        s = sum(span_max[k] for k in kids)
        span_max[i] = s
        caps[i] = max([2 * s] + [s - span_max[k] + caps[k] for k in kids])
        heights[i] = 1 + max(heights[k] for k in kids)
    return BVH(
        node_kind=np.array(kinds, dtype=np.int8), node_first=np.array(firsts, dtype=np.int32),
        node_count=np.array(counts, dtype=np.int32), node_child=np.array(child, dtype=np.int32),
        node_lo=np.array(lows, dtype=np.float64).reshape(n, 3),
        node_hi=np.array(highs, dtype=np.float64).reshape(n, 3),
        node_leaf=np.array(leafs, dtype=np.int32),
        node_center=np.array(centers, dtype=np.float64).reshape(n, 3),
        node_rot=np.array(rots, dtype=np.float64).reshape(n, 3, 3),
        node_radius=np.array(radii, dtype=np.float64), leaf_prim=prim, leaf_param=param, leaf_inv=inv,
        leaf_tri_first=tfirst, leaf_tri_count=tcount, tri=tri,
        leaf_source=[lf for lf, _ in leaf_list],
        leaf_world=np.array([w for _, w in leaf_list]).reshape(-1, 4, 4),
        volume=volume, method=method, tightened=tightened, root_unclipped=root_box,
        span_capacity=int(2 * caps[0] + 4) if n else 4, height=int(heights[0]) if n else 1,
        max_children=max(counts, default=0), max_tri=int(tcount.max(initial=0)))
