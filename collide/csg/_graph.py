"""CSG graphs, cyclic (recursive) graphs of plants, their point clouds, BVHs and ray queries.

Stürzlinger 1996, "Bounding Volume Construction using Point Clouds":
- §3.1-§3.3: a node's cloud comes from its primitives, moved by transforms, appended by unions
  (hull-reduced past ``threshold``), intersected exactly (or by boxes), and a difference keeps its
  left operand. `Node.point_cloud` does this, memoized per (node, recursion level): a shared
  subgraph's cloud is computed once in its own frame and only transformed for each instance.
- §3.5: every node of the CSG tree gets a bounding volume from its cloud; a top-down pass clips
  each child's box to its parent's (an intersection clips both operands, a difference its right
  one; an empty clip removes a difference's right subtree and empties an intersection).
  `build_bvh(..., method="box_of_box")` builds the classical hierarchy (each node's box from its
  children's transformed boxes) for comparison.
- §4: recursive graphs (a node referring back to itself through a transform: `Recursive` and
  `Ref`) unrolled to a depth; the flower experiment is `demos/flower.py`.

Ray queries (`raycast`) run in numba (`collide._kernels.ray`) with exact primitive tests and span
arithmetic (Roth 1982); the brute-force twin is `collide.testing.csg.brute_force_raycast`.

Example
-------
>>> import numpy as np
>>> from collide import csg
>>> lift = np.eye(4); lift[2, 3] = 1.0
>>> tower = csg.Recursive("t", csg.Union(csg.box([1, 1, 0.5]), csg.Transform(lift, csg.Ref("t"))), 3)
>>> tower.point_cloud().aabb().hi
array([1. , 1. , 2.5])
"""

from __future__ import annotations

import inspect
import sys
from dataclasses import dataclass, field

import numpy as np

from . import pointcloud as _pc
from . import shapes as _shapes
from ._kernels import ray as _ray
from ._validate import as_affine, as_array, as_count, as_points, as_positive, as_radius
from .pointcloud import PointCloud
from .volumes import AABB, aabb_corners

__all__ = [
    "BVH", "Difference", "Instances", "Intersection", "Leaf", "Node", "RayHits", "Recursive", "Ref",
    "Transform", "Union", "box", "build_bvh", "capsule", "cone", "cylinder", "ellipsoid",
    "leaves", "mesh", "pinhole_rays", "raycast", "sphere", "unrolled_leaf_count",
]

# Relative inflation of every BVH box: rounding in the slab test must never miss a leaf that
# the exact primitive test hits (DESIGN.md: prefer a tiny conservative inflation).
BOX_PAD = 1e-9


def _matrix(value, name: str = "matrix") -> np.ndarray:
    # Any accepted affine form -> (4, 4) float64.
    linear, t = as_affine(value, name=name)
    m = np.eye(4)
    m[:3, :3] = linear
    m[:3, 3] = t
    return m


class Node:
    """Base class of CSG graph nodes. Nodes are immutable; a node may be shared by many parents."""

    __slots__ = ()

    def __setattr__(self, name, value):
        # Set once (in __init__, by copy or pickle), never again: rewiring a built node could
        # tie its graph into a cycle of objects, and memoised clouds would go stale.
        try:
            object.__getattribute__(self, name)
        except AttributeError:
            object.__setattr__(self, name, value)
            return
        raise AttributeError(f"{type(self).__name__}.{name}: nodes are immutable; build a new node")

    def children(self) -> tuple["Node", ...]:
        """The node's direct children (a `Ref` has none: it is resolved when unrolled)."""
        return ()

    def point_cloud(self, threshold: int = 256, exact_intersection: bool = True,
                    cache: dict | None = None) -> PointCloud:
        """A cloud bounding the node's solid in its own frame (paper §3.3).

        Parameters
        ----------
        threshold : int, default 256
            Unions are hull-reduced once they pass this many points.
        exact_intersection : bool, default True
            True: intersections are the exact hull intersections (manifold3d); False: the
            corners of the intersection of the two boxes.
        cache : dict, optional
            Memo of clouds per (node, recursion state, settings); pass the same dict to share the
            work between calls (its size is the number of distinct clouds computed).

        Returns
        -------
        PointCloud
        """
        if not isinstance(exact_intersection, (bool, np.bool_)):
            raise ValueError(f"exact_intersection: expected True or False, got {exact_intersection!r}")
        if cache is not None and not isinstance(cache, dict):
            raise ValueError(f"cache: expected a dict (or None), got {type(cache).__name__}")
        ctx = _Context(as_count(threshold, "threshold", 1), bool(exact_intersection),
                       {} if cache is None else cache)
        with _deep_recursion():
            return _cloud(self, (), ctx)


def _check_node(value, name: str) -> Node:
    if not isinstance(value, Node):
        raise ValueError(f"{name}: expected a csg Node, got {type(value).__name__}")
    return value


class Leaf(Node):
    """A primitive with its exact geometry kept (for ray tests) and its cloud from `collide.shapes`.

    Parameters
    ----------
    kind : {"box", "sphere", "capsule", "cylinder", "cone", "ellipsoid", "mesh"}
    *args, **kwargs
        The parameters of the matching `collide.shapes` constructor: ``box(half_extents)``,
        ``sphere(radius)``, ``capsule(radius, half_length)`` (z axis),
        ``cylinder(radius, half_length, planes=16)`` (z in ``[-h, h]``),
        ``cone(radius, height, planes=16)`` (base at z = 0, apex at z = height),
        ``ellipsoid(radii, planes=16)``; ``mesh(mesh)`` takes a closed ``trimesh.Trimesh`` or a
        ``(vertices (n, 3), faces (m, 3) int)`` pair (ray tests need the faces; a mesh's inside
        is between odd and even crossings, so it should be closed and consistently wound). Rays
        meet triangles by a watertight test (Woop, Benthin & Wald 2013): a crossing on an edge
        or a vertex shared by several triangles counts once. A ray running along the surface
        (grazing a face, or along an edge) enters no volume; whether it reports a touch there
        depends on the triangulation.
    """

    __slots__ = ("kind", "params", "_cloud", "_vertices", "_faces")

    KINDS = ("box", "sphere", "capsule", "cylinder", "cone", "ellipsoid", "mesh")

    def __init__(self, kind: str, *args, **kwargs):
        if kind not in self.KINDS:
            raise ValueError(f"kind: expected one of {self.KINDS}, got {kind!r}")
        self.kind = kind
        if kind == "mesh":
            if len(args) + len(kwargs) != 1:
                raise ValueError("mesh: expected one argument, a trimesh.Trimesh or (vertices, faces)")
            m = args[0] if args else next(iter(kwargs.values()))
            if hasattr(m, "vertices") and hasattr(m, "faces"):
                verts, faces = m.vertices, m.faces
            elif isinstance(m, (tuple, list)) and len(m) == 2:
                verts, faces = m
            else:
                raise ValueError("mesh: expected a trimesh.Trimesh or a (vertices, faces) pair")
            v = as_points(verts, "vertices")
            raw = np.asarray(faces)
            if raw.dtype.kind not in "iu" and not (raw.dtype.kind == "f" and np.all(raw == np.round(raw))):
                raise ValueError(f"faces: expected integer vertex indices, got dtype {raw.dtype}")
            f = as_array(raw, "faces", (None, 3), dtype=np.int64)
            if len(v) == 0 or len(f) == 0:
                raise ValueError("mesh: the mesh is empty (no vertices or no faces)")
            if f.min() < 0 or f.max() >= len(v):
                raise ValueError(f"faces: indices must lie in [0, {len(v)}), got [{f.min()}, {f.max()}]")
            self._vertices, self._faces = v, f
            self.params = {}
            self._cloud = _shapes.mesh(v)
        else:
            # shapes validates and raises ValueError naming the bad parameter; a wrong number or
            # name of arguments is a TypeError there, told here with the signature.
            ctor = getattr(_shapes, kind)
            try:
                inspect.signature(ctor).bind(*args, **kwargs)
            except TypeError as exc:
                raise ValueError(f"Leaf({kind!r}, ...): {exc}; expected the arguments of "
                                 f"collide.shapes.{kind}{inspect.signature(ctor)}") from None
            self._cloud = ctor(*args, **kwargs)
            self.params = self._normalise(kind, args, kwargs)
            self._vertices = self._faces = None

    @staticmethod
    def _normalise(kind, args, kwargs) -> dict:
        names = {"box": ("half_extents",), "sphere": ("radius",),
                 "capsule": ("radius", "half_length"),
                 "cylinder": ("radius", "half_length", "planes"),
                 "cone": ("radius", "height", "planes"), "ellipsoid": ("radii", "planes", "bands")}[kind]
        params = dict(zip(names, args))
        params.update(kwargs)
        for key in ("half_extents", "radii"):
            if key in params:
                params[key] = np.asarray(params[key], dtype=np.float64).copy()
        return params

    def cloud(self) -> PointCloud:
        """The primitive's cloud in its own frame (from `collide.shapes`)."""
        return self._cloud

    @property
    def vertices(self) -> np.ndarray | None:
        """``(n, 3) float64``: a mesh leaf's vertices (local frame); None for other kinds."""
        return self._vertices

    @property
    def faces(self) -> np.ndarray | None:
        """``(m, 3) int64``: a mesh leaf's triangles as vertex indices; None for other kinds."""
        return self._faces

    def triangles(self) -> np.ndarray:
        """``(m, 3, 3) float64``: a mesh leaf's triangles (local frame); ``(0, 3, 3)`` otherwise."""
        if self._faces is None:
            return np.zeros((0, 3, 3))
        return self._vertices[self._faces]

    def kernel_form(self) -> tuple[int, np.ndarray, np.ndarray]:
        """(primitive code, parameters ``(3,) float64``, local map ``(4, 4)``) for the ray kernel.

        Ellipsoids become unit spheres under ``diag(radii)``. Zero-volume primitives (a zero
        radius or height, a flat ellipsoid) become a point-sized box that no ray enters.
        """
        p = np.zeros(3)
        local = np.eye(4)
        kind, prm = self.kind, self.params
        if kind == "box":
            if np.any(prm["half_extents"] <= 0):
                return _ray.P_BOX, p, local  # flat: zero volume, never entered
            return _ray.P_BOX, prm["half_extents"].copy(), local
        if kind == "mesh":
            return _ray.P_MESH, p, local
        if kind == "sphere":
            p[0] = prm["radius"]
            return _ray.P_SPHERE, p, local
        if kind == "ellipsoid":
            radii = prm["radii"]
            if np.any(radii <= 0):
                return _ray.P_BOX, p, local
            local[:3, :3] = np.diag(radii)
            p[0] = 1.0
            return _ray.P_SPHERE, p, local
        p[0] = prm["radius"]
        p[1] = prm["half_length"] if kind in ("capsule", "cylinder") else prm["height"]
        if p[0] <= 0 or (kind == "cone" and p[1] <= 0):
            # no volume (a capsule or cylinder of radius 0 is a segment: an axis ray "hit" it)
            return _ray.P_BOX, np.zeros(3), local
        return {"capsule": _ray.P_CAPSULE, "cylinder": _ray.P_CYLINDER, "cone": _ray.P_CONE}[kind], p, local

    def __repr__(self) -> str:
        if self.kind == "mesh":
            return f"Leaf('mesh', {len(self._vertices)} vertices, {len(self._faces)} faces)"
        args = ", ".join(f"{k}={np.round(v, 6).tolist() if isinstance(v, np.ndarray) else v}"
                         for k, v in self.params.items())
        return f"Leaf({self.kind!r}, {args})"


def box(half_extents) -> Leaf:
    """A box leaf centred at the origin, ``half_extents (3,)``."""
    return Leaf("box", half_extents)


def sphere(radius: float) -> Leaf:
    """A sphere leaf about the origin."""
    return Leaf("sphere", radius)


def capsule(radius: float, half_length: float) -> Leaf:
    """A capsule leaf along z (segment ``z`` in ``[-half_length, half_length]``)."""
    return Leaf("capsule", radius, half_length)


def cylinder(radius: float, half_length: float, planes: int = 16) -> Leaf:
    """A solid cylinder leaf along z, ``z`` in ``[-half_length, half_length]``."""
    return Leaf("cylinder", radius, half_length, planes)


def cone(radius: float, height: float, planes: int = 16) -> Leaf:
    """A solid cone leaf: base of ``radius`` at z = 0, apex at z = ``height``."""
    return Leaf("cone", radius, height, planes)


def ellipsoid(radii, planes: int = 16) -> Leaf:
    """A solid ellipsoid leaf with semi-axes ``radii (3,)``."""
    return Leaf("ellipsoid", radii, planes)


def mesh(mesh_or_pair) -> Leaf:
    """A closed triangle-mesh leaf: a ``trimesh.Trimesh`` or ``(vertices (n, 3), faces (m, 3))``."""
    return Leaf("mesh", mesh_or_pair)


class Transform(Node):
    """``child`` under an affine map: a ``(4, 4)`` matrix or a ``(rotation, translation)`` pair."""

    __slots__ = ("matrix", "child")

    def __init__(self, matrix, child: Node):
        self.matrix = _matrix(matrix)
        self.matrix.setflags(write=False)
        self.child = _check_node(child, "child")

    def children(self):
        return (self.child,)

    def __repr__(self) -> str:
        return f"Transform({self.child!r})"


class Union(Node):
    """The union of any number of children (none: the empty set)."""

    __slots__ = ("items",)

    def __init__(self, *children: Node):
        self.items = tuple(_check_node(c, f"children[{i}]") for i, c in enumerate(children))

    def children(self):
        return self.items

    def __repr__(self) -> str:
        return f"Union({len(self.items)} children)"


class _Binary(Node):
    """A node with two ordered operands ``a`` and ``b``."""

    __slots__ = ("a", "b")

    def __init__(self, a: Node, b: Node):
        self.a = _check_node(a, "a")
        self.b = _check_node(b, "b")

    def children(self):
        return (self.a, self.b)


class Intersection(_Binary):
    """``a ∩ b``."""

    __slots__ = ()


class Difference(_Binary):
    """``a \\ b``."""

    __slots__ = ()


class Instances(Node):
    """One child under many transforms (the paper's CT node): the union of ``matrices[i] @ child``.

    Parameters
    ----------
    child : Node
    matrices : (k, 4, 4) array_like of float
        Affine matrices (last rows ``[0, 0, 0, 1]``); ``k`` may be zero (the empty set).
    """

    __slots__ = ("child", "matrices")

    def __init__(self, child: Node, matrices):
        self.child = _check_node(child, "child")
        try:
            mats = np.asarray(matrices, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"matrices: cannot be read as a float64 array ({exc})") from None
        if mats.size == 0:
            mats = np.zeros((0, 4, 4))
        mats = as_array(mats, "matrices", (None, 4, 4))
        for i, m in enumerate(mats):
            _matrix(m, f"matrices[{i}]")
        mats.setflags(write=False)
        self.matrices = mats

    def children(self):
        return (self.child,)

    def __repr__(self) -> str:
        return f"Instances({self.child!r}, {len(self.matrices)} matrices)"


class Recursive(Node):
    """A cyclic graph unrolled to ``depth``: ``body`` with every ``Ref(name)`` inside it standing
    for the whole node again, one level down; at level 0 a `Ref` is ``base`` (default: empty).

    ``depth = 1`` is ``body`` with its references replaced by ``base``; ``depth = 30`` nests 30
    copies. A reference normally sits under a `Transform` or `Instances` (a plant's branches).

    Parameters
    ----------
    name : str
    body : Node
    depth : int
        ``>= 0``; 0 gives ``base``.
    base : Node, optional
    """

    __slots__ = ("name", "body", "depth", "base")

    def __init__(self, name: str, body: Node, depth: int, base: Node | None = None):
        if not isinstance(name, str) or not name:
            raise ValueError(f"name: expected a non-empty string, got {name!r}")
        self.name = name
        self.body = _check_node(body, "body")
        self.depth = as_count(depth, "depth", 0)
        self.base = None if base is None else _check_node(base, "base")

    def children(self):
        return (self.body,) if self.base is None else (self.body, self.base)

    def __repr__(self) -> str:
        return f"Recursive({self.name!r}, depth={self.depth})"


class Ref(Node):
    """A reference to the enclosing `Recursive` of the same ``name`` (innermost first)."""

    __slots__ = ("name",)

    def __init__(self, name: str):
        if not isinstance(name, str) or not name:
            raise ValueError(f"name: expected a non-empty string, got {name!r}")
        self.name = name

    def __repr__(self) -> str:
        return f"Ref({self.name!r})"


# ---------------------------------------------------------------------------------------------
# Unrolling. A recursion state ``env`` is a tuple of bindings ``(name, recursive, level, outer)``
# (innermost first); ``outer`` is the env in which the Recursive node itself appeared.

_EMPTY = Union()


def _resolve(node, env):
    """Step through Recursive and Ref nodes: (the node they stand for, its env)."""
    while True:
        if isinstance(node, Recursive):
            if node.depth == 0:
                node, env = (node.base or _EMPTY), env
                continue
            node, env = node.body, ((node.name, node, node.depth, env),) + env
            continue
        if isinstance(node, Ref):
            for name, rec, level, outer in env:
                if name == node.name:
                    if level - 1 == 0:
                        node, env = (rec.base or _EMPTY), outer
                    else:
                        node, env = rec.body, ((name, rec, level - 1, outer),) + outer
                    break
            else:
                raise ValueError(f"Ref({node.name!r}) is not inside a Recursive named {node.name!r}")
            continue
        return node, env


def _free_refs(node, memo: dict) -> frozenset:
    """Names of the `Ref` s in ``node`` that no `Recursive` inside ``node`` binds."""
    got = memo.get(node)
    if got is not None:
        return got
    if isinstance(node, Ref):
        out = frozenset([node.name])
    elif isinstance(node, Recursive):
        out = _free_refs(node.body, memo) - {node.name}
        if node.base is not None:
            out |= _free_refs(node.base, memo)
    else:
        out = frozenset().union(*(_free_refs(c, memo) for c in node.children()))
    memo[node] = out
    return out


def _key_env(node, env, ctx):
    # A subgraph without free references is the same at every recursion level: drop the
    # recursion state, so its cloud and boxes are computed once for all levels and instances.
    return env if env and _free_refs(node, ctx.free) else ()


# The most leaves `leaves` and `build_bvh` unroll: a graph past it is refused before unrolling
# (a Recursive whose body refers to itself twice doubles per level: 40 levels are 2^40 leaves,
# which unrolled for hours; review, 2026-11-22). The flower demo has 6641.
MAX_LEAVES = 1_000_000


def unrolled_leaf_count(node: "Node") -> int:
    """Leaves of the unrolled graph (the length of `leaves` ``(node)``), counted without unrolling.

    Each distinct (node, recursion state) is counted once and reused, so a graph of exponential
    size is counted in time linear in its depth.
    """
    _check_node(node, "node")
    memo: dict = {}
    sigs: dict = {}

    def sig(env):
        # A hashable form of a recursion state (the envs themselves hold nodes by identity).
        got = sigs.get(id(env))
        if got is None:
            got = (tuple((name, id(rec), level, sig(outer)) for name, rec, level, outer in env), env)
            sigs[id(env)] = got  # env kept alive with it: its id is not reused during the count
        return got[0]

    def count(n, env):
        n, env = _resolve(n, env)
        key = (id(n), sig(env))
        got = memo.get(key)
        if got is None:
            if isinstance(n, Leaf):
                got = 1
            elif isinstance(n, Transform):
                got = count(n.child, env)
            elif isinstance(n, Instances):
                got = len(n.matrices) * count(n.child, env)
            else:
                got = sum(count(c, env) for c in n.children())
            memo[key] = (got, n)
            return got
        return got[0]

    with _deep_recursion():
        return count(node, ())


def _check_leaf_count(node) -> None:
    n = unrolled_leaf_count(node)
    if n > MAX_LEAVES:
        raise ValueError(f"node: the unrolled graph has {n:.4g} leaves, more than MAX_LEAVES = {MAX_LEAVES:,} "
                         "(a Recursive whose body holds several Refs multiplies per level); lower its depth")


class _deep_recursion:
    # Unrolling recurses once per graph level; deep recursive graphs need more than Python's
    # default 1000 frames.
    def __enter__(self):
        self.old = sys.getrecursionlimit()
        sys.setrecursionlimit(max(self.old, 20000))

    def __exit__(self, exc_type, exc, tb):
        sys.setrecursionlimit(self.old)
        if exc_type is RecursionError:
            # A bare RecursionError named no cause (review, 2026-11-21).
            raise ValueError(
                "node: the unrolled graph nests deeper than the 20000 Python frames allowed here (about "
                "6000 levels of recursion, or of directly nested transforms and unions), or its node "
                "objects form a cycle; lower the Recursive depth or flatten the nesting") from exc


@dataclass
class _Context:
    threshold: int
    exact: bool
    cache: dict
    bob: dict = field(default_factory=dict)
    fits: dict = field(default_factory=dict)
    free: dict = field(default_factory=dict)


def _cloud(node, env, ctx: _Context) -> PointCloud:
    node, env = _resolve(node, env)
    env = _key_env(node, env, ctx)
    # The settings are part of the key: a cache shared between calls with other settings must not
    # hand back a cloud built with them.
    key = (node, env, ctx.threshold, ctx.exact)
    got = ctx.cache.get(key)
    if got is not None:
        return got
    if isinstance(node, Leaf):
        out = node.cloud()
    elif isinstance(node, Transform):
        out = _cloud(node.child, env, ctx).transform(node.matrix)
    elif isinstance(node, Union):
        out = _pc.union([_cloud(c, env, ctx) for c in node.items], ctx.threshold)
    elif isinstance(node, Instances):
        child = _cloud(node.child, env, ctx)
        out = _pc.union([child.transform(m) for m in node.matrices], ctx.threshold)
    elif isinstance(node, Intersection):
        out = _pc.intersection(_cloud(node.a, env, ctx), _cloud(node.b, env, ctx), ctx.exact)
    elif isinstance(node, Difference):
        out = _pc.difference(_cloud(node.a, env, ctx), PointCloud.empty())  # paper §3.3: keep a
    else:
        raise ValueError(f"unknown node type {type(node).__name__}")
    if len(out) > ctx.threshold:
        out = out.reduced()
    ctx.cache[key] = out
    return out


def _box_under(lo, hi, m) -> tuple[np.ndarray, np.ndarray]:
    # The box of a transformed box (the box-of-box step that grows under rotation).
    if np.any(lo > hi):
        return lo, hi
    c = aabb_corners(lo, hi) @ m[:3, :3].T + m[:3, 3]
    return c.min(axis=0), c.max(axis=0)


_NO_BOX = (np.full(3, np.inf), np.full(3, -np.inf))


def _bob(node, env, ctx: _Context):
    """Box-of-box bound in the node's own frame: (lo, hi), from its children's boxes only."""
    node, env = _resolve(node, env)
    env = _key_env(node, env, ctx)
    key = (node, env)
    got = ctx.bob.get(key)
    if got is not None:
        return got
    if isinstance(node, Leaf):
        box_ = node.cloud().aabb()
        out = (box_.lo, box_.hi)
    elif isinstance(node, Transform):
        out = _box_under(*_bob(node.child, env, ctx), node.matrix)
    elif isinstance(node, (Union, Instances)):
        if isinstance(node, Union):
            boxes = [_bob(c, env, ctx) for c in node.items]
        else:
            child = _bob(node.child, env, ctx)
            boxes = [_box_under(*child, m) for m in node.matrices]
        out = _NO_BOX
        for lo, hi in boxes:
            out = (np.minimum(out[0], lo), np.maximum(out[1], hi))
    elif isinstance(node, Intersection):
        (la, ha), (lb, hb) = _bob(node.a, env, ctx), _bob(node.b, env, ctx)
        out = (np.maximum(la, lb), np.minimum(ha, hb))
        if np.any(out[0] > out[1]):
            out = _NO_BOX
    elif isinstance(node, Difference):
        out = _bob(node.a, env, ctx)
    else:
        raise ValueError(f"unknown node type {type(node).__name__}")
    ctx.bob[key] = out
    return out


def leaves(node: Node, stop_at: tuple = ()) -> list[tuple[Node, np.ndarray]]:
    """Every leaf of the unrolled graph with its world matrix, in depth-first order.

    The position in this list is the leaf id that `raycast` reports.

    Parameters
    ----------
    node : Node
    stop_at : tuple of Node subclasses, optional
        Node types reported as a whole instead of descended into (for example
        ``(Intersection,)``: each intersection with its world matrix; its cloud in its own frame
        is ``n.point_cloud()``, valid when it holds no `Ref` to an enclosing recursion). With
        ``stop_at`` the positions are no longer leaf ids.

    Returns
    -------
    list of (Leaf or stop_at node, (4, 4) float64)
    """
    _check_node(node, "node")
    if isinstance(stop_at, type):
        stop_at = (stop_at,)
    if (isinstance(stop_at, (str, bytes)) or not hasattr(stop_at, "__iter__")
            or not all(isinstance(t, type) and issubclass(t, Node) for t in stop_at)):
        raise ValueError(f"stop_at: expected a tuple of Node subclasses (e.g. (csg.Intersection,)), got {stop_at!r}")
    stop_at = tuple(stop_at)
    _check_leaf_count(node)
    out = []

    def walk(n, env, w):
        n, env = _resolve(n, env)
        if isinstance(n, Leaf) or (stop_at and isinstance(n, stop_at)):
            out.append((n, w))
        elif isinstance(n, Transform):
            walk(n.child, env, w @ n.matrix)
        elif isinstance(n, Instances):
            for m in n.matrices:
                walk(n.child, env, w @ m)
        else:
            for c in n.children():
                walk(c, env, w)

    with _deep_recursion():
        walk(node, (), np.eye(4))
    return out


# ---------------------------------------------------------------------------------------------
# BVH: the unrolled tree in world coordinates (transforms folded into the leaves).

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
            code, p, mi = _ray.P_BOX, np.zeros(3), np.eye(4)
        prim[i], param[i], inv[i] = code, p, mi[:3]
        if code == _ray.P_MESH:
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
            span_max[i] = int(tcount[lf]) // 2 + 1 if prim[lf] == _ray.P_MESH else 1
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


# ---------------------------------------------------------------------------------------------
# Ray queries.

@dataclass(frozen=True)
class RayHits:
    """First hits of a batch of rays.

    Attributes
    ----------
    distance : (R,) float64
        Ray parameter ``t >= 0`` of the first boundary point (in units of ``|direction|``);
        ``inf`` on a miss.
    leaf : (R,) int32
        Unrolled leaf id (see `leaves`, `BVH.leaf_source`) whose surface was hit; -1 on a miss.
    normal : (R, 3) float64
        Unit outward normal of the solid at the hit (facing the ray at an entry); zero on a miss.
    bound_tests, primitive_tests : (R,) int64
        Ray-box tests and exact primitive tests spent on each ray.
    """

    distance: np.ndarray
    leaf: np.ndarray
    normal: np.ndarray
    bound_tests: np.ndarray
    primitive_tests: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """``(R,) bool``: rays that hit."""
        return self.leaf >= 0


def _rays(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    o = as_array(origins, "origins", (None, 3))
    d = as_array(directions, "directions", (None, 3))
    if len(o) != len(d):
        raise ValueError(f"origins and directions: different counts ({len(o)} vs {len(d)})")
    if len(d) and np.any(np.all(d == 0.0, axis=1)):
        raise ValueError(f"directions: zero vector at row {int(np.argmax(np.all(d == 0.0, axis=1)))}")
    return o, d


def _two_prod(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # a * b = p + e exactly (Dekker 1971, Veltkamp's split; no overflow below ~1e290).
    p = a * b
    sa, sb = 134217729.0 * a, 134217729.0 * b  # 2**27 + 1
    ah = sa - (sa - a)
    bh = sb - (sb - b)
    al, bl = a - ah, b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def _two_sum(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # a + b = s + e exactly (Knuth, TAOCP vol. 2, 4.2.2).
    s = a + b
    v = s - a
    return s, (a - (s - v)) + (b - v)


def _reorigin(bvh: BVH, o: np.ndarray, d: np.ndarray):
    # A ray that starts far from the scene (1e16 away from a unit box) has its entry and exit
    # parameters rounded to one value, and misses. Such a ray's origin is moved along it to just
    # before the root bound, o' = o + t0 d computed in double-double (`_two_prod`, `_two_sum`) so
    # that o' is the point of the given ray to within an ulp of o', and the t0s are added back to
    # the distances. t0 is a float: from 1e100 away one step lands within ~1e85 of the scene, so
    # the step is repeated (each gains ~15 digits). Rays starting within 64 radii of the scene
    # are left bit for bit as they are.
    if bvh.volume == "aabb":
        c = 0.5 * (bvh.node_lo[0] + bvh.node_hi[0])
        rad = 0.5 * float(np.linalg.norm(bvh.node_hi[0] - bvh.node_lo[0]))
    elif bvh.volume == "obb":
        c, rad = bvh.node_center[0], float(np.linalg.norm(bvh.node_hi[0]))
    else:
        c, rad = bvh.node_center[0], float(bvh.node_radius[0])
    if not (np.all(np.isfinite(c)) and np.isfinite(rad)):
        return o, None
    dd = np.einsum("ij,ij->i", d, d)
    total = np.zeros(len(o))
    for _ in range(32):
        # The closest approach to the bound's centre, less its radius, less 8 ulps of itself:
        # rounding t0 (1e17: an ulp is 16, the box's radius 0.9) must not carry the new origin
        # into the bound or past it. A ray is moved while that leaves it 64 radii nearer.
        with np.errstate(over="ignore", invalid="ignore"):
            t0 = np.einsum("ij,ij->i", c - o, d) / dd - 2.0 * rad / np.sqrt(dd)
            t0 = t0 - 8.0 * np.spacing(np.abs(t0))
            far = (t0 > 0) & np.isfinite(t0) & (t0 * np.sqrt(dd) > 64.0 * max(rad, 1e-300))
        if not np.any(far):
            break
        t0 = np.where(far, t0, 0.0)
        with np.errstate(over="ignore", invalid="ignore"):
            p, pe = _two_prod(t0[:, None], d)
            s, se = _two_sum(o, p)
            moved = s + (se + pe)
        far &= np.all(np.isfinite(moved), axis=1)  # the split overflows past ~1e290: left as given
        if not np.any(far):
            break
        o = np.where(far[:, None], moved, o)
        total = total + np.where(far, t0, 0.0)
    return o, (total if np.any(total) else None)


def raycast(bvh: BVH, origins, directions) -> RayHits:
    """First hits of rays ``origins + t * directions``, ``t >= 0``, through a CSG hierarchy.

    The hit is the first point where the ray crosses the boundary of the whole solid (an entry
    for a ray from outside; the exit for a ray that starts inside).

    Parameters
    ----------
    bvh : BVH
        From `build_bvh`.
    origins, directions : (R, 3) array_like of float
        Directions need not be unit (``distance`` is then in units of their length), but must be
        non-zero.

    Returns
    -------
    RayHits

    Notes
    -----
    Rays may start at any distance: one that starts far away is first moved along itself to the
    scene (exactly, to an ulp of the new origin). A scene part smaller than the spacing of float64
    at its own coordinates (a 1000-wide box at 1e20, where that spacing is 16384) is not
    representable and may be missed.
    """
    if not isinstance(bvh, BVH):
        raise ValueError(f"bvh: expected a BVH from build_bvh, got {type(bvh).__name__}")
    o, d = _rays(origins, directions)
    r = len(o)
    # Directions of extreme length (|d|^2 under- or overflows in the kernel: a direction of
    # length 1e-200 gave t = 2.4e200 instead of 4e200) are scaled by a power of two, exactly,
    # and their distances scaled back; ordinary directions pass through bit for bit.
    _, expo = np.frexp(np.abs(d).max(axis=1)) if r else (None, np.zeros(0, int))
    expo = np.where(np.abs(expo) > 100, expo, 0)
    if np.any(expo):
        d = np.ldexp(d, -expo[:, None])
    o, t0 = _reorigin(bvh, o, d) if (bvh.n_nodes and r) else (o, None)
    out_t = np.full(r, np.inf)
    out_leaf = np.full(r, -1, dtype=np.int32)
    out_n = np.zeros((r, 3))
    out_b = np.zeros(r, dtype=np.int64)
    out_p = np.zeros(r, dtype=np.int64)
    if bvh.n_nodes and r:
        bound = {"aabb": 0, "obb": 1, "sphere": 2}[bvh.volume]
        _ray.raycast_kernel(o, d, bvh.node_kind, bvh.node_first, bvh.node_count, bvh.node_child,
                            bound, bvh.node_lo, bvh.node_hi, bvh.node_rot, bvh.node_center,
                            bvh.node_radius, bvh.node_leaf, bvh.leaf_prim, bvh.leaf_param,
                            bvh.leaf_inv, bvh.leaf_tri_first, bvh.leaf_tri_count, bvh.tri,
                            bvh.span_capacity, bvh.height, bvh.max_children, bvh.max_tri,
                            out_t, out_leaf, out_n, out_b, out_p)
    if t0 is not None:
        out_t = out_t + t0  # inf stays inf: a miss
    if np.any(expo):
        with np.errstate(over="ignore"):
            out_t = np.ldexp(out_t, -expo)  # inf past the float range (a direction of length 1e-320)
        lost = (out_leaf >= 0) & ~np.isfinite(out_t)
        # A hit farther than the largest float along the direction given is a miss, as `RayHits`
        # says inf is (it was leaf 0 at distance inf; review, 2026-11-22).
        out_leaf[lost] = -1
        out_n[lost] = 0.0
    return RayHits(out_t, out_leaf, out_n, out_b, out_p)


def pinhole_rays(eye, target, width: int, height: int, fov_deg: float = 40.0,
                 up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Rays of a pinhole camera, one per pixel, row-major from the top-left pixel.

    Parameters
    ----------
    eye, target : (3,) array_like of float
        Camera position and the point it looks at.
    width, height : int
        Image size in pixels.
    fov_deg : float
        Vertical field of view, in (0, 180) degrees.
    up : (3,) array_like of float
        Approximate up direction (not parallel to ``target - eye``).

    Returns
    -------
    origins : (height * width, 3) float64
    directions : (height * width, 3) float64
        Unit vectors.
    """
    eye = as_array(eye, "eye", (3,))
    fwd = as_array(target, "target", (3,)) - eye
    w = as_count(width, "width", 1)
    h = as_count(height, "height", 1)
    fov = as_positive(fov_deg, "fov_deg")
    if not fov < 180.0:
        raise ValueError(f"fov_deg: a pinhole camera's field of view must be below 180 degrees, got {fov:g}")
    if not np.linalg.norm(fwd) > 0:
        raise ValueError("target: must differ from eye")
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, as_array(up, "up", (3,)))
    if not np.linalg.norm(right) > 1e-12:
        raise ValueError("up: must not be parallel to the viewing direction")
    right /= np.linalg.norm(right)
    true_up = np.cross(right, fwd)
    s = np.tan(np.radians(fov) / 2)
    ys = (1 - 2 * (np.arange(h) + 0.5) / h) * s
    xs = (2 * (np.arange(w) + 0.5) / w - 1) * s * w / h
    d = fwd + xs[None, :, None] * right + ys[:, None, None] * true_up
    d = d.reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1)[:, None]
    return np.repeat(eye[None], len(d), axis=0), d
