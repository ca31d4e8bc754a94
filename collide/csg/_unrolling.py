"""Unrolling CSG graphs: recursion states, leaf counts, the nodes' point clouds (Stürzlinger 1996,
§3.1-§3.3, memoized per (node, recursion level)), box-of-box bounds and the list of leaves.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from .. import pointcloud as _pc
from ..pointcloud import PointCloud
from ..volumes import aabb_corners
from ._graph import Difference, Instances, Intersection, Leaf, Node, Recursive, Ref, Transform, Union, _check_node

__all__ = ["MAX_LEAVES", "leaves", "unrolled_leaf_count"]

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
# far more than can be unrolled; review, 2026-11-22). The flower demo has 6641.
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
