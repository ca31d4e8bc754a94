"""CSG graph nodes: primitives (`Leaf` and its constructors), `Transform`, `Union`,
`Intersection`, `Difference`, `Instances`, and the recursive pair `Recursive` / `Ref`.

Nodes are immutable and may be shared by many parents; what is computed from a graph (clouds,
leaves, BVHs, rays) lives in the modules above this one.
"""

from __future__ import annotations

import inspect

import numpy as np

from .. import shapes as _shapes
from .._kernels import ray_primitives as _prim
from .._validate import as_affine, as_array, as_count, as_points
from ..pointcloud import PointCloud

__all__ = [
    "Difference", "Instances", "Intersection", "Leaf", "Node", "Recursive", "Ref", "Transform", "Union",
    "box", "capsule", "cone", "cylinder", "ellipsoid", "mesh", "sphere",
]

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
        from ._unrolling import _cloud, _Context, _deep_recursion  # that module imports this one

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
                return _prim.P_BOX, p, local  # flat: zero volume, never entered
            return _prim.P_BOX, prm["half_extents"].copy(), local
        if kind == "mesh":
            return _prim.P_MESH, p, local
        if kind == "sphere":
            p[0] = prm["radius"]
            return _prim.P_SPHERE, p, local
        if kind == "ellipsoid":
            radii = prm["radii"]
            if np.any(radii <= 0):
                return _prim.P_BOX, p, local
            local[:3, :3] = np.diag(radii)
            p[0] = 1.0
            return _prim.P_SPHERE, p, local
        p[0] = prm["radius"]
        p[1] = prm["half_length"] if kind in ("capsule", "cylinder") else prm["height"]
        if p[0] <= 0 or (kind == "cone" and p[1] <= 0):
            # no volume (a capsule or cylinder of radius 0 is a segment: an axis ray "hit" it)
            return _prim.P_BOX, np.zeros(3), local
        return {"capsule": _prim.P_CAPSULE, "cylinder": _prim.P_CYLINDER, "cone": _prim.P_CONE}[kind], p, local

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
