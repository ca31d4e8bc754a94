"""Random articulated scenes with a fixed seed: chains, branching trees, many robots, free hulls.

Every generator returns a `Scene`: an `Articulation` plus the kinematics to pose it (each body
sits at a fixed offset in its parent's frame and turns about one hinge axis; children of the
world may instead be free bodies). ``scene.poses(rng)`` draws a random configuration and returns
``(body_pos (L, 3), body_rot (L, 3, 3))``; ``scene.poses(rng, worlds=B)`` returns ``(B, L, ...)``.
Shapes are built as `PointCloud` directly (box corners, sphere and capsule radius forms, random
convex meshes), so the generators only depend on the core representation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import shapes as _shapes
from ..articulation import Articulation
from ..pointcloud import PointCloud

__all__ = [
    "Scene", "axis_angle", "branching_tree", "chain", "free_hulls", "hull_motion", "make_plane",
    "many_robots", "quat_to_mat", "random_hull", "random_rotation", "random_shape", "scene_motion",
]


@dataclass(frozen=True)
class _Plane:
    # Stand-in with the shape of shapes.Plane, used only while shapes.plane is not available.
    normal: np.ndarray
    offset: float


def make_plane(normal=(0.0, 0.0, 1.0), offset: float = 0.0):
    """A halfspace ``{x : normal . x <= offset}``: ``shapes.plane`` when available."""
    if hasattr(_shapes, "plane"):
        return _shapes.plane(normal=normal, offset=offset)
    n = np.asarray(normal, float)
    return _Plane(n / np.linalg.norm(n), float(offset))


def random_rotation(rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """Uniform random rotation(s): ``(3, 3)`` or ``(n, 3, 3) float64`` (from unit quaternions)."""
    q = rng.normal(size=(1 if n is None else n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    R = quat_to_mat(q)
    return R[0] if n is None else R


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """``(n, 4)`` unit quaternions (w, x, y, z) -> ``(n, 3, 3)`` rotation matrices."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], axis=1)


def axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations about unit ``axis`` ``(..., 3)`` by ``angle`` ``(...)``: ``(..., 3, 3)`` (Rodrigues)."""
    angle = np.asarray(angle, float)[..., None, None]
    k = np.asarray(axis, float)
    K = np.zeros(k.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
    K = K - np.swapaxes(K, -1, -2)
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * (K @ K)


def random_hull(rng: np.random.Generator, size: float = 1.0, n: int = 30) -> PointCloud:
    """A random convex mesh: ``n`` points on a random ellipsoid-ish blob of diameter ~``size``."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    axes = rng.uniform(0.4, 1.0, 3) * size / 2
    return PointCloud(d * axes * rng.uniform(0.85, 1.0, (n, 1)))


def random_shape(rng: np.random.Generator, size: float = 1.0) -> PointCloud:
    """A box, sphere, capsule or convex mesh of size ~``size`` (radius forms included)."""
    kind = rng.integers(4)
    if kind == 0:
        h = rng.uniform(0.2, 0.5, 3) * size
        return PointCloud(np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * h)
    if kind == 1:
        return PointCloud(np.zeros((1, 3)), rng.uniform(0.2, 0.5) * size)
    if kind == 2:
        hl = rng.uniform(0.2, 0.5) * size
        return PointCloud([[0, 0, -hl], [0, 0, hl]], rng.uniform(0.1, 0.3) * size)
    return random_hull(rng, size, int(rng.integers(8, 40)))


@dataclass
class Scene:
    """An articulation and its kinematics.

    Attributes
    ----------
    articulation : Articulation
    body_offset_pos : (L, 3) float64
        Body origin in the parent's frame at the zero configuration.
    body_offset_rot : (L, 3, 3) float64
    body_axis : (L, 3) float64
        Hinge axis in the body frame (unit).
    body_range : (L,) float64
        Joint angles are drawn in ``[-range, range]``.
    body_free : (L,) bool
        Free bodies (children of the world): pose drawn in a box of half size ``free_extent``.
    free_extent : float
    name : str
    """

    articulation: Articulation
    body_offset_pos: np.ndarray
    body_offset_rot: np.ndarray
    body_axis: np.ndarray
    body_range: np.ndarray
    body_free: np.ndarray
    free_extent: float = 1.0
    name: str = ""
    meta: dict = field(default_factory=dict)

    def forward(self, angle: np.ndarray, free_pos=None, free_rot=None):
        """Body poses from joint angles ``(B, L)`` (free bodies from ``free_pos``/``free_rot``).

        Returns
        -------
        body_pos : (B, L, 3) float64
        body_rot : (B, L, 3, 3) float64
        """
        a = self.articulation
        B, L = angle.shape
        pos = np.zeros((B, L, 3))
        rot = np.zeros((B, L, 3, 3))
        rot[:, 0] = np.eye(3)
        joint = axis_angle(np.broadcast_to(self.body_axis, (B, L, 3)), angle)
        local = self.body_offset_rot @ joint  # (B, L, 3, 3)
        for b in a.body_dfs_order[1:]:
            if self.body_free[b]:
                pos[:, b] = free_pos[:, b]
                rot[:, b] = free_rot[:, b]
                continue
            p = a.body_parent[b]
            rot[:, b] = rot[:, p] @ local[:, b]
            pos[:, b] = pos[:, p] + np.einsum("bij,j->bi", rot[:, p], self.body_offset_pos[b])
        return pos, rot

    def poses(self, rng: np.random.Generator, worlds: int | None = None):
        """A random configuration: ``(L, 3), (L, 3, 3)``, or ``(B, L, 3), (B, L, 3, 3)``."""
        L = self.articulation.body_count
        B = 1 if worlds is None else worlds
        angle = rng.uniform(-1, 1, (B, L)) * self.body_range
        free_pos = rng.uniform(-self.free_extent, self.free_extent, (B, L, 3))
        free_rot = random_rotation(rng, B * L).reshape(B, L, 3, 3)
        pos, rot = self.forward(angle, free_pos, free_rot)
        return (pos[0], rot[0]) if worlds is None else (pos, rot)


def _scene(parent, geom_body, clouds, off_pos, off_rot, axis, rng_, free, rng, name, free_extent=1.0,
           filters=True, planes=0, **kw):
    G = len(geom_body)
    L = len(parent)
    opts = dict(kw)
    if filters and G:
        # Random filter data so every rule is exercised: masks, margins, welds, excludes, pairs.
        opts.setdefault("geom_contype", np.where(rng.random(G) < 0.85, 1, rng.integers(0, 4, G)))
        opts.setdefault("geom_conaffinity", np.where(rng.random(G) < 0.85, 1, rng.integers(0, 4, G)))
        opts.setdefault("geom_margin", np.where(rng.random(G) < 0.7, 0.0, rng.uniform(0, 0.05, G)))
        weld = np.arange(L)
        fused = rng.random(L) < 0.05
        weld[fused] = parent[fused]  # an approximation of MuJoCo's weld: share the parent's group
        opts.setdefault("body_weld", weld)
        E = max(1, L // 10)
        opts.setdefault("exclude", rng.integers(0, L, (E, 2)))
        P = max(1, G // 20)
        pr = rng.integers(0, G, (P, 2))
        pr = pr[pr[:, 0] != pr[:, 1]]
        opts.setdefault("pairs", pr)
        opts.setdefault("pair_margin", rng.uniform(0, 0.05, len(pr)))
    for _ in range(planes):
        geom_body = np.append(geom_body, 0)
        n = rng.normal(size=3) * [0.2, 0.2, 1.0]
        clouds = list(clouds) + [make_plane(n, float(rng.uniform(-1.0, -0.2)))]
        for key, fill in (("geom_contype", 1), ("geom_conaffinity", 1), ("geom_margin", 0.01)):
            if key in opts:
                opts[key] = np.append(opts[key], fill)
        if "geom_pos" in opts:
            opts["geom_pos"] = np.concatenate([opts["geom_pos"], np.zeros((1, 3))])
            opts["geom_rot"] = np.concatenate([opts["geom_rot"], np.eye(3)[None]])
    art = Articulation(parent, geom_body, clouds, **opts)
    return Scene(art, off_pos, off_rot, axis, rng_, free, free_extent, name)


def chain(n_links: int = 64, seed: int = 0, radius: float = 0.05, half_length: float = 0.15,
          filters: bool = True, planes: int = 0, joint_range: float = 1.2) -> Scene:
    """A serial chain of capsules (z axis) end to end, random hinge axes, hinge at each link's base."""
    rng = np.random.default_rng(seed)
    L = n_links + 1
    parent = np.maximum(np.arange(L) - 1, 0)
    off_pos = np.zeros((L, 3))
    off_pos[2:, 2] = 2 * half_length
    off_rot = np.tile(np.eye(3), (L, 1, 1))
    axis = rng.normal(size=(L, 3)) * [1, 1, 0.2]
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    clouds = [PointCloud([[0, 0, 0], [0, 0, 2 * half_length]], radius) for _ in range(n_links)]
    return _scene(parent, np.arange(1, L), clouds, off_pos, off_rot, axis, np.full(L, joint_range),
                  np.zeros(L, bool), rng, f"chain{n_links}", filters=filters, planes=planes)


def branching_tree(n_bodies: int = 60, seed: int = 0, size: float = 0.3, filters: bool = True,
                   planes: int = 1, geoms_per_body=(0, 3)) -> Scene:
    """A random branching tree: parent of body i drawn from the recent bodies, mixed shapes,
    0 to 3 geoms per body (some bodies bare), random hinge axes."""
    rng = np.random.default_rng(seed)
    L = n_bodies + 1
    parent = np.zeros(L, np.int64)
    for i in range(2, L):
        parent[i] = rng.integers(max(0, i - 6), i)
    off_pos = rng.normal(size=(L, 3)) * size
    off_pos[parent == 0] = rng.uniform(-1, 1, (int(np.sum(parent == 0)), 3)) * 0.3
    off_rot = random_rotation(rng, L)
    axis = rng.normal(size=(L, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    geom_body, clouds, gpos, grot = [], [], [], []
    for b in range(1, L):
        for _ in range(int(rng.integers(geoms_per_body[0], geoms_per_body[1] + 1))):
            geom_body.append(b)
            clouds.append(random_shape(rng, size))
            gpos.append(rng.normal(size=3) * size * 0.3)
            grot.append(random_rotation(rng))
    return _scene(parent, np.array(geom_body, np.int64), clouds, off_pos, off_rot, axis, np.full(L, 1.5),
                  np.zeros(L, bool), rng, f"tree{n_bodies}", filters=filters, planes=planes,
                  geom_pos=np.array(gpos).reshape(-1, 3), geom_rot=np.array(grot).reshape(-1, 3, 3))


def many_robots(n_robots: int = 12, links: int = 6, seed: int = 0, size: float = 0.25, spread: float = 1.2,
                filters: bool = True, planes: int = 1) -> Scene:
    """Many small branching robots rooted at free bodies scattered in a box of half size ``spread``."""
    rng = np.random.default_rng(seed)
    parent = [0]
    free = [False]
    for _ in range(n_robots):
        root = len(parent)
        parent.append(0)
        free.append(True)
        for i in range(1, links):
            parent.append(root + int(rng.integers(max(0, i - 3), i)))
            free.append(False)
    parent = np.array(parent, np.int64)
    L = len(parent)
    off_pos = rng.normal(size=(L, 3)) * size * 0.8
    off_rot = random_rotation(rng, L)
    axis = rng.normal(size=(L, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    geom_body, clouds = [], []
    for b in range(1, L):
        for _ in range(int(rng.integers(1, 3))):
            geom_body.append(b)
            clouds.append(random_shape(rng, size).transform(random_rotation(rng), rng.normal(size=3) * size * 0.2))
    return _scene(parent, np.array(geom_body, np.int64), clouds, off_pos, off_rot, axis, np.full(L, 1.5),
                  np.array(free), rng, f"robots{n_robots}x{links}", free_extent=spread, filters=filters,
                  planes=planes)


def free_hulls(n: int = 64, seed: int = 0, size: float = 1.0, points: int = 30, filters: bool = False,
               planes: int = 0) -> Scene:
    """``n`` free bodies with random convex hulls (~``points`` points each) on a jittered grid whose
    spacing makes each body touch about 1 to 3 neighbours (the benchmark's hull scene, issue 3):
    truly touching (`brute_force_pairs`) under `hull_motion`: 1.0 a body at 16, 1.5 at 64, 1.7 at 256.
    (The spacing was 0.78 ``size`` until 2026-11-22, which gave 0.3-0.4: found by a review.)

    ``scene.meta["home_pos"]`` ``(L, 3)`` and ``["home_rot"]`` hold the grid poses; use
    `hull_motion` for a small random rigid motion per step.
    """
    rng = np.random.default_rng(seed)
    L = n + 1
    side = int(np.ceil(n ** (1 / 3)))
    grid = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3)[:n]
    spacing = 0.62 * size
    home_pos = np.zeros((L, 3))
    home_pos[1:] = grid * spacing + rng.normal(size=(n, 3)) * 0.08 * size
    home_rot = np.tile(np.eye(3), (L, 1, 1))
    home_rot[1:] = random_rotation(rng, n)
    clouds = [random_hull(rng, size, points) for _ in range(n)]
    sc = _scene(np.zeros(L, np.int64), np.arange(1, L), clouds, np.zeros((L, 3)), np.tile(np.eye(3), (L, 1, 1)),
                np.tile([0.0, 0.0, 1.0], (L, 1)), np.zeros(L), np.r_[False, np.ones(n, bool)], rng,
                f"hulls{n}", filters=filters, planes=planes)
    sc.meta.update(home_pos=home_pos, home_rot=home_rot, size=size)
    return sc


def hull_motion(scene: Scene, rng: np.random.Generator, steps: int, step_size: float = 0.01):
    """Poses of `free_hulls` bodies under a small random rigid motion per step (a random walk
    about the grid poses): ``(steps, L, 3)`` and ``(steps, L, 3, 3)`` float64."""
    home_pos, home_rot = scene.meta["home_pos"], scene.meta["home_rot"]
    size = scene.meta["size"]
    L = len(home_pos)
    dp = rng.normal(size=(steps, L, 3)) * step_size * size
    dp[:, 0] = 0
    pos = home_pos + np.cumsum(dp, axis=0)
    w = rng.normal(size=(steps, L, 3)) * step_size
    w[:, 0] = 0
    ang = np.linalg.norm(w, axis=-1)
    ax = w / np.maximum(ang, 1e-300)[..., None]
    ax[ang == 0] = [0, 0, 1]
    rot = np.empty((steps, L, 3, 3))
    cur = home_rot.copy()
    inc = axis_angle(ax, ang)
    for s in range(steps):
        cur = inc[s] @ cur
        rot[s] = cur
    return pos, rot


def scene_motion(scene: Scene, rng: np.random.Generator, steps: int, step_size: float = 0.01):
    """Poses of any `Scene` along a smooth random motion: joint angles and free bodies on random
    walks from a random configuration (angles by ``step_size`` of their range a step, free bodies
    by ``step_size`` of ``free_extent`` and ``step_size`` radians), as a simulation moves them.

    Returns
    -------
    body_pos : (steps, L, 3) float64
    body_rot : (steps, L, 3, 3) float64
    """
    L = scene.articulation.body_count
    r = np.asarray(scene.body_range, float)
    angle = rng.uniform(-1, 1, L) * r + np.cumsum(rng.normal(size=(steps, L)) * step_size * r, axis=0)
    free_pos = rng.uniform(-1, 1, (1, L, 3)) * scene.free_extent
    free_pos = free_pos + np.cumsum(rng.normal(size=(steps, L, 3)) * step_size * scene.free_extent, axis=0)
    w = rng.normal(size=(steps, L, 3)) * step_size
    ang = np.linalg.norm(w, axis=-1)
    ax = w / np.maximum(ang, 1e-300)[..., None]
    ax[ang == 0] = [0, 0, 1]
    inc = axis_angle(ax, ang)
    free_rot = np.empty((steps, L, 3, 3))
    cur = random_rotation(rng, L)
    for s in range(steps):
        cur = inc[s] @ cur
        free_rot[s] = cur
    return scene.forward(angle, free_pos, free_rot)
