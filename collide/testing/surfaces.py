"""Analytic true-surface samplers for every primitive of `collide.shapes`, and random maps.

The samplers evaluate each shape's own definition (implicit or parametric surface, patch
evaluation, polygon edges), never the clouds built by `collide.shapes`, so a test that checks
"these points lie inside the cloud's bounding volumes" checks the constructors themselves.

``sample_surface(kind, n, rng, **params)`` takes the same keyword parameters as
``collide.shapes.<kind>(**params)`` (construction-only ones such as ``planes`` are accepted and
ignored), so a test can build both from one parameter dict; `random_shape_params` draws such
dicts.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import BSpline
from scipy.special import comb

__all__ = [
    "SHAPE_KINDS", "apply_affine", "random_affine", "random_polygon", "random_rigid", "random_rotation",
    "random_shape_params", "random_similarity", "sample_surface",
]

# Every kind `sample_surface` knows; each is also the name of its constructor in collide.shapes.
SHAPE_KINDS = (
    "box", "sphere", "capsule", "cylinder", "cone", "ellipsoid", "torus", "superquadric",
    "mesh", "bezier_patch", "bspline_patch", "nurbs_patch", "extrude", "cone_sweep", "revolve",
)

# Construction parameters of collide.shapes that do not change the true shape.
_CONSTRUCTION_ONLY = ("planes", "bands", "steps", "tube_planes", "reduce")


# --------------------------------------------------------------------------------------------
# maps


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation, ``(3, 3) float64`` with determinant +1 (QR of a Gaussian)."""
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def random_rigid(rng: np.random.Generator, translation_scale: float = 1.0) -> np.ndarray:
    """A random rigid map as a ``(4, 4) float64`` homogeneous matrix."""
    m = np.eye(4)
    m[:3, :3] = random_rotation(rng)
    m[:3, 3] = rng.normal(scale=translation_scale, size=3)
    return m


def random_affine(rng: np.random.Generator, max_stretch: float = 5.0,
                  translation_scale: float = 1.0, reflect: bool | None = None) -> np.ndarray:
    """A random general (non-similar) affine map, ``(4, 4) float64``.

    The linear part is ``Q1 diag(s) Q2`` with random rotations and singular values ``s`` drawn
    log-uniformly in ``[1 / max_stretch, max_stretch]`` (so almost never a similarity: radii
    must become points), with a reflection half of the time unless ``reflect`` says.
    """
    s = np.exp(rng.uniform(-np.log(max_stretch), np.log(max_stretch), size=3))
    if reflect is None:
        reflect = bool(rng.random() < 0.5)
    if reflect:
        s[0] = -s[0]
    m = np.eye(4)
    m[:3, :3] = random_rotation(rng) @ np.diag(s) @ random_rotation(rng)
    m[:3, 3] = rng.normal(scale=translation_scale, size=3)
    return m


def random_similarity(rng: np.random.Generator, translation_scale: float = 1.0) -> np.ndarray:
    """A random rotation times a uniform scale in ``[0.2, 5]``, ``(4, 4) float64``."""
    m = random_rigid(rng, translation_scale)
    m[:3, :3] *= np.exp(rng.uniform(np.log(0.2), np.log(5.0)))
    return m


def apply_affine(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points`` ``(n, 3)`` mapped by the ``(4, 4)`` affine ``matrix``: ``(n, 3) float64``."""
    return np.asarray(points, dtype=np.float64) @ matrix[:3, :3].T + matrix[:3, 3]


# --------------------------------------------------------------------------------------------
# small helpers


def _unit_vectors(n: int, rng: np.random.Generator) -> np.ndarray:
    v = rng.standard_normal((n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    return v


def _disk(n: int, radius: float, rng: np.random.Generator) -> np.ndarray:
    # (n, 2) uniform on the disk.
    r = radius * np.sqrt(rng.random(n))
    a = rng.uniform(0.0, 2.0 * np.pi, n)
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


def _circle(n: int, radius: float, rng: np.random.Generator) -> np.ndarray:
    a = rng.uniform(0.0, 2.0 * np.pi, n)
    return np.column_stack([radius * np.cos(a), radius * np.sin(a)])


def _polygon_boundary(contour: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    # (n, 2) uniform on the closed polygon's edges (by length).
    a, b = contour, np.roll(contour, -1, axis=0)
    length = np.linalg.norm(b - a, axis=1)
    if length.sum() == 0.0:
        return np.repeat(contour[:1], n, axis=0)
    edge = rng.choice(len(a), size=n, p=length / length.sum())
    t = rng.random(n)[:, None]
    return a[edge] + t * (b[edge] - a[edge])


def _inside_polygon(contour: np.ndarray, pts: np.ndarray) -> np.ndarray:
    # Even-odd rule: count crossings of a ray towards +x (Shimrat 1962 / the classic PNPOLY).
    x, y = pts[:, 0:1], pts[:, 1:2]
    a, b = contour[None, :, :], np.roll(contour, -1, axis=0)[None, :, :]
    straddle = (a[..., 1] > y) != (b[..., 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[..., 0] + (y - a[..., 1]) * (b[..., 0] - a[..., 0]) / (b[..., 1] - a[..., 1])
    return (np.sum(straddle & (x < xc), axis=1) % 2) == 1


def _polygon_region(contour: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    # (n, 2) uniform in the closed polygon's region (rejection sampling in its bounding box);
    # a polygon without area gives boundary points instead.
    lo, hi = contour.min(axis=0), contour.max(axis=0)
    area = 0.5 * abs(np.sum(contour[:, 0] * np.roll(contour[:, 1], -1)
                            - np.roll(contour[:, 0], -1) * contour[:, 1]))
    if area <= 1e-12 * max(float(np.prod(hi - lo)), 1e-300) or len(contour) < 3:
        return _polygon_boundary(contour, n, rng)
    out = []
    got = 0
    for _ in range(200):
        cand = lo + rng.random((max(4 * n, 64), 2)) * (hi - lo)
        keep = cand[_inside_polygon(contour, cand)]
        out.append(keep)
        got += len(keep)
        if got >= n:
            break
    pts = np.concatenate(out)
    if len(pts) < n:  # a sliver polygon: top up from the boundary
        pts = np.concatenate([pts, _polygon_boundary(contour, n - len(pts), rng)])
    return pts[:n]


def _split(n: int, weights, rng: np.random.Generator) -> np.ndarray:
    # How many of n samples go to each part, proportional to weights (all parts if all zero).
    w = np.asarray(weights, dtype=float)
    w = np.ones_like(w) if w.sum() == 0 else w
    return rng.multinomial(n, w / w.sum())


def _signed_pow(x: np.ndarray, e: float) -> np.ndarray:
    return np.sign(x) * np.abs(x) ** e


def _default_knots(count: int, degree: int) -> np.ndarray:
    # Clamped uniform knot vector on [0, 1].
    inner = np.linspace(0.0, 1.0, count - degree + 1)[1:-1]
    return np.concatenate([np.zeros(degree + 1), inner, np.ones(degree + 1)])


def _bspline_basis(params: np.ndarray, count: int, degree, knots) -> np.ndarray:
    # (n, count) B-spline basis values at params in [0, 1] mapped onto the knot domain.
    p = min(3, count - 1) if degree is None else int(degree)
    t = _default_knots(count, p) if knots is None else np.asarray(knots, dtype=float)
    lo, hi = t[p], t[count]
    x = lo + params * (hi - lo)
    return BSpline.design_matrix(np.clip(x, lo, hi), t, p).toarray()


def _bernstein(params: np.ndarray, count: int) -> np.ndarray:
    deg = count - 1
    i = np.arange(count)
    return comb(deg, i)[None, :] * params[:, None] ** i * (1.0 - params[:, None]) ** (deg - i)


# --------------------------------------------------------------------------------------------
# per-kind samplers (each: n points on the true surface, (n, 3) float64)


def _box(n, rng, half_extents):
    h = np.asarray(half_extents, dtype=float)
    face_area = np.array([h[1] * h[2], h[0] * h[2], h[0] * h[1]])
    pts = rng.uniform(-1.0, 1.0, (n, 3)) * h
    axis = rng.choice(3, size=n, p=face_area / face_area.sum()) if face_area.sum() > 0 else \
        np.argmax(h) * np.ones(n, dtype=int)
    side = rng.choice([-1.0, 1.0], size=n)
    pts[np.arange(n), axis] = side * h[axis]
    return pts


def _sphere(n, rng, radius):
    return radius * _unit_vectors(n, rng)


def _capsule(n, rng, radius, half_length):
    n_side, n_caps = _split(n, [4 * np.pi * radius * half_length, 4 * np.pi * radius**2], rng)
    side = np.column_stack([_circle(n_side, radius, rng), rng.uniform(-half_length, half_length, n_side)])
    caps = radius * _unit_vectors(n_caps, rng)
    caps[:, 2] += np.where(caps[:, 2] >= 0, half_length, -half_length)
    return np.concatenate([side, caps])


def _cylinder(n, rng, radius, half_length):
    n_side, n_caps = _split(n, [2 * radius * half_length, radius**2], rng)
    side = np.column_stack([_circle(n_side, radius, rng), rng.uniform(-half_length, half_length, n_side)])
    caps = np.column_stack([_disk(n_caps, radius, rng), rng.choice([-half_length, half_length], n_caps)])
    return np.concatenate([side, caps])


def _cone(n, rng, radius, height):
    n_side, n_base = _split(n, [np.pi * radius * np.hypot(radius, height), np.pi * radius**2], rng)
    t = np.sqrt(rng.random(n_side))[:, None]  # area grows linearly with the distance from the apex
    apex = np.array([0.0, 0.0, height])
    rim = np.column_stack([_circle(n_side, radius, rng), np.zeros(n_side)])
    side = apex + t * (rim - apex)
    base = np.column_stack([_disk(n_base, radius, rng), np.zeros(n_base)])
    return np.concatenate([side, base])


def _ellipsoid(n, rng, radii):
    return _unit_vectors(n, rng) * np.asarray(radii, dtype=float)


def _torus(n, rng, major_radius, minor_radius):
    u = rng.uniform(0.0, 2.0 * np.pi, n)
    v = rng.uniform(0.0, 2.0 * np.pi, n)
    r = major_radius + minor_radius * np.cos(v)
    return np.column_stack([r * np.cos(u), r * np.sin(u), minor_radius * np.sin(v)])


def _superquadric(n, rng, radii, e1, e2):
    # Barr's parametric form: x = a c(η)^e1 c(ω)^e2, y = b c(η)^e1 s(ω)^e2, z = c s(η)^e1.
    # The six tips are always included: they are where the hull is decided for e > 2.
    eta = rng.uniform(-np.pi / 2, np.pi / 2, n)
    om = rng.uniform(-np.pi, np.pi, n)
    ce = _signed_pow(np.cos(eta), e1)
    pts = np.column_stack([ce * _signed_pow(np.cos(om), e2), ce * _signed_pow(np.sin(om), e2),
                           _signed_pow(np.sin(eta), e1)])
    k = min(6, n)
    pts[:k] = np.concatenate([np.eye(3), -np.eye(3)])[:k]
    return pts * np.asarray(radii, dtype=float)


def _mesh(n, rng, vertices_or_trimesh):
    if hasattr(vertices_or_trimesh, "faces") and len(vertices_or_trimesh.faces):
        import trimesh

        pts, _ = trimesh.sample.sample_surface(vertices_or_trimesh, n, seed=rng)
        return np.asarray(pts, dtype=np.float64)
    verts = np.asarray(getattr(vertices_or_trimesh, "vertices", vertices_or_trimesh), dtype=float)
    return verts[rng.integers(0, len(verts), n)]


def _bezier_patch(n, rng, control_points):
    net = np.asarray(control_points, dtype=float)
    bu = _bernstein(rng.random(n), net.shape[0])
    bv = _bernstein(rng.random(n), net.shape[1])
    return np.einsum("si,sj,ijk->sk", bu, bv, net)


def _bspline_patch(n, rng, control_points, degree_u=None, degree_v=None, knots_u=None, knots_v=None):
    net = np.asarray(control_points, dtype=float)
    bu = _bspline_basis(rng.random(n), net.shape[0], degree_u, knots_u)
    bv = _bspline_basis(rng.random(n), net.shape[1], degree_v, knots_v)
    return np.einsum("si,sj,ijk->sk", bu, bv, net)


def _nurbs_patch(n, rng, control_points, weights, degree_u=None, degree_v=None, knots_u=None,
                 knots_v=None):
    net = np.asarray(control_points, dtype=float)
    w = np.asarray(weights, dtype=float)
    bu = _bspline_basis(rng.random(n), net.shape[0], degree_u, knots_u)
    bv = _bspline_basis(rng.random(n), net.shape[1], degree_v, knots_v)
    num = np.einsum("si,sj,ij,ijk->sk", bu, bv, w, net)
    den = np.einsum("si,sj,ij->s", bu, bv, w)
    return num / den[:, None]


def _extrude(n, rng, contour, height):
    c = np.asarray(contour, dtype=float)
    n_side, n_caps = _split(n, [1.0, 1.0], rng)
    side = np.column_stack([_polygon_boundary(c, n_side, rng), rng.uniform(0.0, height, n_side)])
    caps = np.column_stack([_polygon_region(c, n_caps, rng), rng.choice([0.0, height], n_caps)])
    return np.concatenate([side, caps])


def _cone_sweep(n, rng, contour, height, apex=(0.0, 0.0)):
    c = np.asarray(contour, dtype=float)
    top = np.array([apex[0], apex[1], height], dtype=float)
    n_side, n_base = _split(n, [1.0, 1.0], rng)
    rim = np.column_stack([_polygon_boundary(c, n_side, rng), np.zeros(n_side)])
    t = rng.random(n_side)[:, None]
    side = rim + t * (top - rim)
    base = np.column_stack([_polygon_region(c, n_base, rng), np.zeros(n_base)])
    return np.concatenate([side, base])


def _revolve(n, rng, contour):
    # The contour as a closed polygon in the (r, z) half-plane, rotated by a uniform angle.
    rz = _polygon_boundary(np.asarray(contour, dtype=float), n, rng)
    a = rng.uniform(0.0, 2.0 * np.pi, n)
    return np.column_stack([rz[:, 0] * np.cos(a), rz[:, 0] * np.sin(a), rz[:, 1]])


_SAMPLERS = {
    "box": _box, "sphere": _sphere, "capsule": _capsule, "cylinder": _cylinder, "cone": _cone,
    "ellipsoid": _ellipsoid, "torus": _torus, "superquadric": _superquadric, "mesh": _mesh,
    "bezier_patch": _bezier_patch, "bspline_patch": _bspline_patch, "nurbs_patch": _nurbs_patch,
    "extrude": _extrude, "cone_sweep": _cone_sweep, "revolve": _revolve,
}


def sample_surface(kind: str, n: int, rng: np.random.Generator, **params) -> np.ndarray:
    """``n`` points on the true surface of a primitive (analytic, not from its cloud).

    Parameters
    ----------
    kind : str
        One of `SHAPE_KINDS` (the name of the constructor in ``collide.shapes``).
    n : int
        Number of points.
    rng : numpy.random.Generator
    **params
        The constructor's keyword parameters (``radius``, ``half_extents``, ``contour``, ...);
        ``planes``, ``bands``, ``steps``, ``tube_planes`` and ``reduce`` are ignored.

    Returns
    -------
    points : (n, 3) float64
        Solids include their caps (cylinder ends, cone base, extrusion caps); surfaces of
        revolution and sweeps treat the contour as a closed polygon; a mesh is sampled on its
        faces (trimesh), a bare vertex array at its vertices.
    """
    if kind not in _SAMPLERS:
        raise ValueError(f"kind: expected one of {SHAPE_KINDS}, got {kind!r}")
    for key in _CONSTRUCTION_ONLY:
        params.pop(key, None)
    pts = _SAMPLERS[kind](int(n), rng, **params)
    return np.ascontiguousarray(pts, dtype=np.float64).reshape(-1, 3)


# --------------------------------------------------------------------------------------------
# random parameters


def random_polygon(rng: np.random.Generator, k: int | None = None, scale: float = 1.0) -> np.ndarray:
    """A random star-shaped (usually non-convex) closed polygon, ``(k, 2) float64``."""
    k = int(rng.integers(3, 12)) if k is None else k
    a = np.sort(rng.uniform(0.0, 2.0 * np.pi, k))
    r = scale * rng.uniform(0.2, 1.0, k)
    return np.column_stack([r * np.cos(a), r * np.sin(a)]) + rng.normal(scale=0.3 * scale, size=2)


def random_shape_params(kind: str, rng: np.random.Generator) -> dict:
    """Random valid keyword parameters for ``collide.shapes.<kind>`` and `sample_surface`.

    Sizes are drawn over about two orders of magnitude; construction parameters (``planes``,
    ``steps``) vary too, including small odd counts.
    """
    size = lambda lo=0.05, hi=3.0: float(np.exp(rng.uniform(np.log(lo), np.log(hi))))  # noqa: E731
    planes = int(rng.choice([3, 4, 5, 7, 8, 12, 16, 32]))
    if kind == "box":
        return {"half_extents": [size(), size(), size()]}
    if kind == "sphere":
        return {"radius": size()}
    if kind == "capsule":
        return {"radius": size(), "half_length": size()}
    if kind == "cylinder":
        return {"radius": size(), "half_length": size(), "planes": planes}
    if kind == "cone":
        return {"radius": size(), "height": size(), "planes": planes}
    if kind == "ellipsoid":
        return {"radii": [size(), size(), size()], "planes": planes}
    if kind == "torus":
        return {"major_radius": size(), "minor_radius": size(), "planes": planes,
                "tube_planes": int(rng.choice([3, 4, 6, 8, 16]))}
    if kind == "superquadric":
        e = lambda: float(np.exp(rng.uniform(np.log(0.1), np.log(4.0))))  # noqa: E731
        return {"radii": [size(), size(), size()], "e1": e(), "e2": e(), "planes": planes}
    if kind == "mesh":
        import trimesh

        m = trimesh.creation.icosphere(subdivisions=1, radius=size())
        m.vertices = m.vertices * rng.uniform(0.3, 2.0, 3) + rng.normal(scale=0.1, size=m.vertices.shape)
        return {"vertices_or_trimesh": m}
    if kind in ("bezier_patch", "bspline_patch", "nurbs_patch"):
        m, n = int(rng.integers(2, 6)), int(rng.integers(2, 6))
        grid = np.stack(np.meshgrid(np.arange(m), np.arange(n), indexing="ij"), axis=-1) * 1.0
        net = np.concatenate([grid, np.zeros((m, n, 1))], axis=-1) + rng.normal(scale=0.7, size=(m, n, 3))
        out = {"control_points": net * size(0.1, 2.0)}
        if kind == "nurbs_patch":
            out["weights"] = np.exp(rng.uniform(np.log(0.05), np.log(20.0), size=(m, n)))
        if kind != "bezier_patch":
            out["degree_u"] = int(rng.integers(1, m))
            out["degree_v"] = int(rng.integers(1, n))
        return out
    if kind == "extrude":
        return {"contour": random_polygon(rng, scale=size()), "height": size()}
    if kind == "cone_sweep":
        return {"contour": random_polygon(rng, scale=size()), "height": size(),
                "apex": rng.normal(size=2)}
    if kind == "revolve":
        c = random_polygon(rng, scale=size())
        c[:, 0] = np.abs(c[:, 0])  # into the r >= 0 half-plane
        if rng.random() < 0.3:
            c[0, 0] = 0.0  # a point on the axis
        return {"contour": c, "steps": planes}
    raise ValueError(f"kind: expected one of {SHAPE_KINDS}, got {kind!r}")
