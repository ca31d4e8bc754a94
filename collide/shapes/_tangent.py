"""Primitive -> PointCloud constructors (Stürzlinger 1996, §3.1, plus the radius forms).

Every constructor returns a `PointCloud` in the shape's own frame whose set
``hull(points) ⊕ ball(radius)`` contains the true shape (conservative, up to a relative
inflation of ``TANGENT_INFLATE`` that absorbs rounding):

- exact forms: ``box`` (8 corners), ``sphere`` (1 point + radius), ``capsule`` (2 points +
  radius, MuJoCo's convention), ``mesh`` (its vertices), the free-form patches (their control
  points: the convex-hull property of Bezier, B-spline and positive-weight NURBS surfaces) and
  the sweeps of polygonal contours (``extrude``, ``cone_sweep``);
- tangent-plane forms (paper §3.1): ``cylinder``, ``cone``, ``ellipsoid``, ``torus``,
  ``superquadric`` and ``revolve`` give the vertices of a polytope circumscribed about the
  curved shape; ``planes`` trades size for tightness (more planes, a tighter cloud).

Orientation convention: a circumscribed regular k-gon has its vertices at azimuths
``(j + 1/2) 2π/k``, so its edges touch the circle at azimuths ``j 2π/k``; when ``k`` is a
multiple of 4 the tangent lines include ``x = ±r`` and ``y = ±r`` and the shape's own AABB is
exact.

`plane` is the exception: a halfspace is unbounded, so it returns a `Plane`, not a cloud.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import HalfspaceIntersection, QhullError

from . import hull as _hull
from ._validate import as_array, as_count, as_points, as_positive, as_radius
from .pointcloud import PointCloud

__all__ = [
    "MAX_POINTS", "Plane", "TANGENT_INFLATE", "bezier_patch", "box", "bspline_patch", "capsule", "cone",
    "cone_sweep", "cylinder", "ellipsoid", "extrude", "mesh", "nurbs_patch", "plane", "revolve", "sphere",
    "sphere_polytope_circumradius", "superquadric", "superquadric_support", "torus",
]

# Relative outward inflation of every tangent-plane construction: the polytope vertices are
# computed in floating point (cos, sin, divisions), so an edge can sit an ulp inside the curve it
# should touch. 1e-12 is far above that rounding and far below any tolerance a user sees
# (hull.ball_polytope uses the same margin).
TANGENT_INFLATE = 1.0 + 1e-12


# --------------------------------------------------------------------------------------------
# circumscribed polygons and revolutions


def _azimuths(k: int) -> np.ndarray:
    # Vertex azimuths of the circumscribed k-gon (edges tangent at azimuths j 2π/k).
    return (np.arange(k) + 0.5) * (2.0 * np.pi / k)


def _ring(r: float, z: float, k: int) -> np.ndarray:
    # (k, 3) vertices of the regular k-gon at height z circumscribed about the circle of radius
    # r (circumradius r / cos(π/k)): the tangent-plane construction of a circle.
    a = _azimuths(k)
    rr = r / math.cos(math.pi / k) * TANGENT_INFLATE
    return np.stack([rr * np.cos(a), rr * np.sin(a), np.full(k, float(z))], axis=1)


# Most points a shape builder makes (tessellation counts multiply: a torus has planes x
# tube_planes): 2**24 points are 400 MB; more is a typo, refused before numpy's allocation fails.
MAX_POINTS = 2**24


def _budget(n: int, what: str) -> None:
    if n > MAX_POINTS:
        raise ValueError(f"{what}: would make {n} points, more than MAX_POINTS = {MAX_POINTS}")


def _revolve_points(rz: np.ndarray, steps: int) -> np.ndarray:
    # Each (r, z) becomes a circumscribed `steps`-gon of radius |r| at height z; r == 0 stays one
    # point on the axis. Why this bounds the solid of revolution of hull(rz): a point at
    # azimuth φ of the solid is (ρ cos φ, ρ sin φ, z) with (ρ, z) = Σ λ_i (r_i, z_i), a convex
    # combination of the points, so it equals Σ λ_i (r_i cos φ, r_i sin φ, z_i), a convex
    # combination of points on the circles of radius |r_i| at heights z_i, each inside its ring.
    # (The same argument allows r_i < 0, which the torus uses.)
    _budget(len(rz) * steps, "planes (or steps) x contour points")
    out = []
    for r, z in rz:
        if r == 0.0:
            out.append(np.array([[0.0, 0.0, z]]))
        else:
            out.append(_ring(abs(float(r)), float(z), steps))
    return np.concatenate(out, axis=0)


def _circle_polygon(center: tuple[float, float], radius: float, k: int) -> np.ndarray:
    # (k, 2) vertices of the regular k-gon circumscribed about a 2D circle.
    a = _azimuths(k)
    rr = radius / math.cos(math.pi / k) * TANGENT_INFLATE
    return np.stack([center[0] + rr * np.cos(a), center[1] + rr * np.sin(a)], axis=1)


# --------------------------------------------------------------------------------------------
# exact forms


def box(half_extents) -> PointCloud:
    """The 8 corners of a box centred at the origin (exact).

    Parameters
    ----------
    half_extents : (3,) array_like of float
        Half side lengths along x, y, z, each ``>= 0`` (zero gives a flat or thinner box).

    Returns
    -------
    PointCloud
        8 points, radius 0.
    """
    h = as_array(half_extents, "half_extents", (3,))
    if np.any(h < 0):
        raise ValueError(f"half_extents: must be >= 0, got {h}")
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    return PointCloud(signs * h)


def sphere(radius: float) -> PointCloud:
    """A ball of ``radius`` about the origin: one point plus the radius (exact).

    Parameters
    ----------
    radius : float
        ``>= 0``.
    """
    return PointCloud(np.zeros((1, 3)), as_radius(radius, "radius"))


def capsule(radius: float, half_length: float) -> PointCloud:
    """A capsule along z (MuJoCo's convention): two points at ``z = ±half_length`` plus the radius.

    Parameters
    ----------
    radius : float
        ``>= 0``.
    half_length : float
        Half length of the segment between the two cap centres, ``>= 0``.
    """
    r = as_radius(radius, "radius")
    h = as_radius(half_length, "half_length")
    return PointCloud(np.array([[0.0, 0.0, -h], [0.0, 0.0, h]]), r)


def mesh(vertices_or_trimesh, reduce: bool = True) -> PointCloud:
    """The vertices of a mesh (its hull is the hull of the mesh).

    Parameters
    ----------
    vertices_or_trimesh : (n, 3) array_like of float, or trimesh.Trimesh
        Vertices, or any object with a ``vertices`` attribute (a ``trimesh.Trimesh``).
    reduce : bool, default True
        Keep only the hull vertices.

    Returns
    -------
    PointCloud
        Radius 0.

    Raises
    ------
    ValueError
        An empty mesh (it would bound nothing), non-finite or wrongly shaped vertices.
    """
    if not isinstance(reduce, (bool, np.bool_)):
        raise ValueError(f"reduce: expected True or False, got {reduce!r}")
    verts = getattr(vertices_or_trimesh, "vertices", vertices_or_trimesh)
    pts = as_points(verts, "vertices")
    if len(pts) == 0:
        raise ValueError("vertices: the mesh is empty (no vertices), it bounds nothing")
    if reduce:
        pts = _hull.hull_vertices(pts)
    return PointCloud(pts)


def _control_net(control_points) -> np.ndarray:
    net = as_array(control_points, "control_points", (None, None, 3))
    if net.shape[0] == 0 or net.shape[1] == 0:
        raise ValueError(f"control_points: the net is empty, shape {net.shape}")
    return net


def _degree_and_knots(count: int, degree, knots, axis: str) -> None:
    # Validate a B-spline direction: degree < count, knots non-decreasing of length count+degree+1.
    p = min(3, count - 1) if degree is None else as_count(degree, f"degree_{axis}", 0)
    if p > count - 1:
        raise ValueError(f"degree_{axis}: {p} needs at least {p + 1} control points along {axis}, "
                         f"got {count}")
    if knots is not None:
        t = as_array(knots, f"knots_{axis}", (None,))
        if len(t) != count + p + 1:
            raise ValueError(f"knots_{axis}: expected {count + p + 1} knots (control points + "
                             f"degree + 1), got {len(t)}")
        if np.any(np.diff(t) < 0):
            raise ValueError(f"knots_{axis}: must be non-decreasing")
        if t[count] <= t[p]:
            raise ValueError(f"knots_{axis}: the domain [t[{p}], t[{count}]] is empty")


def bezier_patch(control_points) -> PointCloud:
    """A Bezier surface patch: its control points (convex-hull property).

    Parameters
    ----------
    control_points : (m, n, 3) array_like of float
        The control net, degree ``(m - 1, n - 1)``.

    Returns
    -------
    PointCloud
        The ``m * n`` control points; the Bernstein weights are non-negative and sum to 1, so
        every surface point is a convex combination of them.
    """
    return PointCloud(_control_net(control_points).reshape(-1, 3))


def bspline_patch(control_points, degree_u: int | None = None, degree_v: int | None = None,
                  knots_u=None, knots_v=None) -> PointCloud:
    """A tensor-product B-spline surface patch: its control points (convex-hull property).

    Parameters
    ----------
    control_points : (m, n, 3) array_like of float
    degree_u, degree_v : int, optional
        Degrees; default ``min(3, m - 1)`` and ``min(3, n - 1)``.
    knots_u, knots_v : (m + degree_u + 1,), (n + degree_v + 1,) array_like of float, optional
        Non-decreasing knot vectors (validated only: the convex-hull property holds on the
        valid domain for every knot vector).

    Returns
    -------
    PointCloud
        The ``m * n`` control points.
    """
    net = _control_net(control_points)
    _degree_and_knots(net.shape[0], degree_u, knots_u, "u")
    _degree_and_knots(net.shape[1], degree_v, knots_v, "v")
    return PointCloud(net.reshape(-1, 3))


def nurbs_patch(control_points, weights, degree_u: int | None = None, degree_v: int | None = None,
                knots_u=None, knots_v=None) -> PointCloud:
    """A NURBS surface patch: its control points (convex-hull property for positive weights).

    Parameters
    ----------
    control_points : (m, n, 3) array_like of float
    weights : (m, n) array_like of float
        Strictly positive. With positive weights the rational basis functions
        ``w_ij N_i M_j / Σ w N M`` are non-negative and sum to 1, so the surface lies in the hull
        of the control points; a zero or negative weight breaks that property (the surface can
        leave the hull, or run to infinity), so it is rejected.
    degree_u, degree_v, knots_u, knots_v
        As in `bspline_patch`.

    Returns
    -------
    PointCloud
        The ``m * n`` control points.
    """
    net = _control_net(control_points)
    w = as_array(weights, "weights", net.shape[:2])
    if np.any(w <= 0):
        bad = tuple(int(i) for i in np.argwhere(w <= 0)[0])
        raise ValueError(f"weights: must be > 0 (a non-positive weight breaks the convex-hull "
                         f"property of the NURBS surface), got {w[bad]} at index {bad}")
    _degree_and_knots(net.shape[0], degree_u, knots_u, "u")
    _degree_and_knots(net.shape[1], degree_v, knots_v, "v")
    return PointCloud(net.reshape(-1, 3))


def _contour(contour, name: str = "contour") -> np.ndarray:
    c = as_array(contour, name, (None, 2))
    if len(c) == 0:
        raise ValueError(f"{name}: needs at least one point")
    return c


def extrude(contour, height: float) -> PointCloud:
    """Translational sweep of a closed planar polygon from ``z = 0`` to ``z = height`` (exact hull).

    Parameters
    ----------
    contour : (k, 2) array_like of float
        Polygon vertices in the xy plane (closed implicitly; any orientation, may be non-convex).
    height : float
        ``>= 0``.

    Returns
    -------
    PointCloud
        ``2k`` points: the contour at ``z = 0`` and at ``z = height``.
    """
    c = _contour(contour)
    h = as_radius(height, "height")
    k = len(c)
    return PointCloud(np.concatenate([np.column_stack([c, np.zeros(k)]),
                                      np.column_stack([c, np.full(k, h)])]))


def cone_sweep(contour, height: float, apex=(0.0, 0.0)) -> PointCloud:
    """The cone over a closed planar polygon: every segment from the polygon region to an apex.

    The base is the region bounded by ``contour`` in the plane ``z = 0``; the apex is the point
    ``(apex[0], apex[1], height)``. (A pyramid for a polygonal contour; a cone of a circle when
    the contour is a circumscribed polygon of it.)

    Parameters
    ----------
    contour : (k, 2) array_like of float
        Polygon vertices in the xy plane.
    height : float
        ``>= 0``: the apex height.
    apex : (2,) array_like of float, default (0, 0)
        The apex's x and y.

    Returns
    -------
    PointCloud
        ``k + 1`` points (exact hull).
    """
    c = _contour(contour)
    h = as_radius(height, "height")
    a = as_array(apex, "apex", (2,))
    return PointCloud(np.concatenate([np.column_stack([c, np.zeros(len(c))]), [[a[0], a[1], h]]]))


def revolve(contour, steps: int = 16) -> PointCloud:
    """Rotational sweep of a contour in the ``(r, z)`` half-plane about the z axis (§3.1).

    Each contour point ``(r, z)`` is rotated in ``steps`` steps with ``r`` scaled outward by
    ``1 / cos(π / steps)``: the regular ``steps``-gon circumscribed about its circle, so the
    polygonal sweep contains the solid of revolution of the contour's hull.

    Parameters
    ----------
    contour : (k, 2) array_like of float
        ``(r, z)`` points with ``r >= 0`` (a closed polygon, or an open profile).
    steps : int, default 16
        ``>= 3``; the circumradius over the true radius is ``1 / cos(π / steps)``.

    Returns
    -------
    PointCloud
        ``steps`` points per contour point off the axis, one per point on it.
    """
    c = _contour(contour)
    if np.any(c[:, 0] < 0):
        raise ValueError(f"contour: r (column 0) must be >= 0 in the (r, z) half-plane, "
                         f"got {c[:, 0].min()}")
    steps = as_count(steps, "steps", 3)
    return PointCloud(_revolve_points(c, steps))


# --------------------------------------------------------------------------------------------
# tangent-plane forms


def cylinder(radius: float, half_length: float, planes: int = 16) -> PointCloud:
    """A solid cylinder along z, ``z`` in ``[-half_length, half_length]`` (tangent planes, §3.1).

    Parameters
    ----------
    radius, half_length : float
        ``>= 0``.
    planes : int, default 16
        ``>= 3`` tangent planes around the axis: the ends become regular ``planes``-gons of
        circumradius ``radius / cos(π / planes)``.

    Returns
    -------
    PointCloud
        ``2 * planes`` points (2 when ``radius`` is 0).
    """
    r = as_radius(radius, "radius")
    h = as_radius(half_length, "half_length")
    k = as_count(planes, "planes", 3)
    return PointCloud(_revolve_points(np.array([[r, -h], [r, h]]), k))


def cone(radius: float, height: float, planes: int = 16) -> PointCloud:
    """A solid cone: base disk of ``radius`` at ``z = 0``, apex at ``(0, 0, height)``.

    Parameters
    ----------
    radius, height : float
        ``>= 0``.
    planes : int, default 16
        ``>= 3``; the base becomes the regular ``planes``-gon of circumradius
        ``radius / cos(π / planes)``.

    Returns
    -------
    PointCloud
        ``planes + 1`` points.
    """
    r = as_radius(radius, "radius")
    h = as_radius(height, "height")
    k = as_count(planes, "planes", 3)
    return PointCloud(_revolve_points(np.array([[r, 0.0], [0.0, h]]), k))


def _bands(planes: int, bands) -> int:
    # Latitude bands matched to the longitudinal planes: tangent points every π/m in latitude
    # versus every 2π/k in azimuth, so m = k/2 balances the two angular errors.
    m = max(2, math.ceil(planes / 2)) if bands is None else as_count(bands, "bands", 2)
    _budget(planes * (m + 1), "planes x bands")
    return m


def _vertex_latitudes(m: int) -> np.ndarray:
    # Latitudes of the vertices of the circumscribed half-polygon of the meridian semicircle with
    # tangent points at -π/2 + iπ/m, i = 0..m: midway between consecutive tangent points.
    return -np.pi / 2 + (2 * np.arange(m) + 1) * np.pi / (2 * m)


def sphere_polytope_circumradius(planes: int = 16, bands: int | None = None) -> float:
    """Analytic circumradius of the unit-sphere tangent polytope used by `ellipsoid`.

    The polytope is the lat-long tangent-plane construction: tangent planes at azimuths
    ``j 2π/k`` (``k = planes``) and latitudes ``-π/2 + iπ/m`` (``m = bands``). In a meridian
    plane its vertices lie at latitudes ``ψ_i = -π/2 + (2i + 1)π/(2m)`` at distance
    ``1 / cos(π/(2m))`` (the circumscribed half-polygon), and revolving scales their ``r`` by
    ``1 / cos(π/k)``, so a vertex's distance from the centre is
    ``sqrt(cos²ψ / cos²(π/k) + sin²ψ) / cos(π/(2m))``, largest at the ``ψ`` nearest the equator:

    - ``m`` odd (a vertex ring on the equator): ``1 / (cos(π/k) cos(π/(2m)))``;
    - ``m`` even (a tangent ring on the equator): ``sqrt(1 / cos²(π/k) + tan²(π/(2m)))``.

    Parameters
    ----------
    planes : int
        ``k >= 3``.
    bands : int, optional
        ``m >= 2``; default ``max(2, ceil(k / 2))``.

    Returns
    -------
    float
        Without the ``TANGENT_INFLATE`` rounding margin.
    """
    k = as_count(planes, "planes", 3)
    m = _bands(k, bands)
    ck, cm = math.cos(math.pi / k), math.cos(math.pi / (2 * m))
    if m % 2:
        return 1.0 / (ck * cm)
    return math.sqrt(1.0 / ck**2 + math.tan(math.pi / (2 * m)) ** 2)


def ellipsoid(radii, planes: int = 16, bands: int | None = None) -> PointCloud:
    """A solid ellipsoid with semi-axes ``radii`` along x, y, z (tangent planes, §3.1).

    The unit sphere gets the lat-long tangent-plane polytope (see
    `sphere_polytope_circumradius`), which is then scaled by ``radii``: the affine image of a
    polytope circumscribed about the ball circumscribes the ellipsoid. With ``planes`` a
    multiple of 4 and ``bands`` even (the default for such ``planes``) the polytope has
    tangent planes at ``±x, ±y, ±z``, so the ellipsoid's own AABB is exact.

    Parameters
    ----------
    radii : (3,) array_like of float
        ``>= 0`` each (zero gives a flat ellipse or a segment).
    planes : int, default 16
        Longitudinal tangent planes, ``>= 3``.
    bands : int, optional
        Latitude bands, ``>= 2``; default ``max(2, ceil(planes / 2))``.

    Returns
    -------
    PointCloud
        ``planes * bands`` points.
    """
    rad = as_array(radii, "radii", (3,))
    if np.any(rad < 0):
        raise ValueError(f"radii: must be >= 0, got {rad}")
    k = as_count(planes, "planes", 3)
    m = _bands(k, bands)
    psi = _vertex_latitudes(m)
    rz = np.stack([np.cos(psi), np.sin(psi)], axis=1) / math.cos(math.pi / (2 * m))
    # The outermost rings have z = ±1 exactly in exact arithmetic (they lie on the pole tangent
    # planes); the inflation below keeps them there or beyond after rounding.
    rz[:, 1] *= TANGENT_INFLATE
    return PointCloud(_revolve_points(rz, k) * rad)


def torus(major_radius: float, minor_radius: float, planes: int = 16,
          tube_planes: int | None = None) -> PointCloud:
    """A solid torus about the z axis (tangent planes, §3.1).

    The tube's cross-section, the disk of ``minor_radius`` about ``(major_radius, 0)`` in the
    ``(r, z)`` half-plane, is replaced by its circumscribed regular ``tube_planes``-gon, which is
    then revolved (see `revolve`) in ``planes`` steps. A self-intersecting (spindle) torus,
    ``minor_radius > major_radius``, is fine: polygon vertices with ``r < 0`` are revolved at
    ``|r|``, which still bounds the solid.

    Parameters
    ----------
    major_radius, minor_radius : float
        ``>= 0``.
    planes : int, default 16
        Steps around the z axis, ``>= 3``.
    tube_planes : int, optional
        Sides of the cross-section polygon, ``>= 3``; default ``planes``. With both multiples
        of 4 the AABB is exact: ``[-(R + a), R + a]² x [-a, a]``.

    Returns
    -------
    PointCloud
        ``planes * tube_planes`` points at most.
    """
    big = as_radius(major_radius, "major_radius")
    small = as_radius(minor_radius, "minor_radius")
    k = as_count(planes, "planes", 3)
    p = k if tube_planes is None else as_count(tube_planes, "tube_planes", 3)
    _budget(k * p, "planes x tube_planes")  # before the tube's polygon is built
    return PointCloud(_revolve_points(_circle_polygon((big, 0.0), small, p), k))


def _lp_norm(v: np.ndarray, s: float) -> np.ndarray:
    # ||v||_s along the last axis for s in [1, inf], scaled by the max to avoid over/underflow.
    a = np.abs(v)
    big = a.max(axis=-1)
    if math.isinf(s):
        return big
    safe = np.where(big > 0, big, 1.0)
    return big * np.sum((a / safe[..., None]) ** s, axis=-1) ** (1.0 / s)


def _dual_exponent(p: float) -> float:
    return math.inf if p == 1.0 else p / (p - 1.0)


def superquadric_support(directions, e1: float, e2: float) -> np.ndarray:
    """Support function of the convex hull of the unit superellipsoid with exponents ``e1, e2``.

    The unit superellipsoid is ``{x : N(x) <= 1}`` with the nested "norm"
    ``N(x) = || (|| (x, y) ||_p, z) ||_q``, ``p = 2/e2``, ``q = 2/e1``. For ``p, q >= 1``
    (``e1, e2 <= 2``, the convex case) ``N`` is a norm with a monotone outer part, so its dual
    norm, the support function, is the same nesting of the dual exponents:
    ``h(u) = || (|| (u_x, u_y) ||_p*, u_z) ||_q*`` with ``1/p + 1/p* = 1``. For ``e > 2`` the
    exponent is clamped to 2 first: that gives exactly the convex hull (see `superquadric`).

    Parameters
    ----------
    directions : (n, 3) float64
    e1, e2 : float
        ``> 0``.

    Returns
    -------
    h : (n,) float64
        ``max_{x in hull} u . x`` for each direction ``u``.
    """
    u = as_array(directions, "directions", (None, 3))
    e1 = as_positive(e1, "e1")
    e2 = as_positive(e2, "e2")
    p_star = _dual_exponent(2.0 / min(e2, 2.0))
    q_star = _dual_exponent(2.0 / min(e1, 2.0))
    inner = _lp_norm(u[:, :2], p_star)
    return _lp_norm(np.stack([inner, u[:, 2]], axis=1), q_star)


def _tangent_directions(k: int, m: int) -> np.ndarray:
    # Unit normals of the lat-long tangent planes (azimuths j 2π/k, latitudes -π/2 + iπ/m, the
    # poles once), plus the six axis directions so the shape's own AABB is always exact.
    az = np.arange(k) * (2.0 * np.pi / k)
    lat = -np.pi / 2 + np.arange(1, m) * (np.pi / m)
    A, L = np.meshgrid(az, lat, indexing="ij")
    ring = np.stack([np.cos(L) * np.cos(A), np.cos(L) * np.sin(A), np.sin(L)], axis=-1).reshape(-1, 3)
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    return np.concatenate([ring, axes])


def superquadric(radii, e1: float, e2: float, planes: int = 16, bands: int | None = None) -> PointCloud:
    """A solid superellipsoid (Barr 1981) with semi-axes ``radii`` (tangent planes, §3.1).

    The solid is ``(|x/a|^(2/e2) + |y/b|^(2/e2))^(e2/e1) + |z/c|^(2/e1) <= 1``. What is built:

    1. Convex hull. For ``e <= 2`` the solid is convex. For ``e > 2`` it is star-shaped and not
       convex, and its hull is the superellipsoid with that exponent clamped to 2: with
       ``p = 2/e < 1``, ``||v||_1 <= ||v||_p``, so the clamped solid contains the original
       (monotone nesting); and every point of the clamped solid is a convex combination of
       points of the original (the ℓ1 slices are the hulls of the ℓp slices' axis tips, which
       the original contains; the double cone for a clamped ``e1`` is the hull of the poles and
       the equator). So the clamped solid is exactly the hull; both ``e > 2`` gives the
       octahedron ``|x/a| + |y/b| + |z/c| <= 1``.
    2. Tangent planes. The unit solid's support function `superquadric_support` gives a plane
       ``u . x <= h(u)`` touching it for every direction ``u``; the cloud is the vertices of the
       intersection of those halfspaces for the lat-long directions of `ellipsoid` plus the six
       axis directions (so the AABB is exact), scaled by ``radii``. For ``e1 = e2 = 1`` this is
       the ellipsoid's polytope. If Qhull refuses the intersection, the bounding box corners
       (always valid) are returned.

    Parameters
    ----------
    radii : (3,) array_like of float
        ``>= 0`` each.
    e1, e2 : float
        Barr's exponents, ``> 0``: ``e1`` shapes the meridian (z), ``e2`` the cross-section.
    planes : int, default 16
        Longitudinal tangent directions, ``>= 3``.
    bands : int, optional
        Latitude bands, ``>= 2``; default ``max(2, ceil(planes / 2))``.

    Returns
    -------
    PointCloud
    """
    rad = as_array(radii, "radii", (3,))
    if np.any(rad < 0):
        raise ValueError(f"radii: must be >= 0, got {rad}")
    e1 = as_positive(e1, "e1")
    e2 = as_positive(e2, "e2")
    k = as_count(planes, "planes", 3)
    m = _bands(k, bands)
    if e1 >= 2.0 and e2 >= 2.0:
        # The hull is the octahedron of the six tips (step 1): exact, six points.
        return PointCloud(np.concatenate([np.diag(rad), -np.diag(rad)]))
    u = _tangent_directions(k, m)
    h = superquadric_support(u, e1, e2) * TANGENT_INFLATE
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    try:
        verts = HalfspaceIntersection(np.column_stack([u, -h]), np.zeros(3)).intersections
        verts = _hull.hull_vertices(verts)
        if not np.all(np.isfinite(verts)):
            verts = corners
    except (QhullError, ValueError):
        verts = corners
    return PointCloud(verts * rad)


# --------------------------------------------------------------------------------------------
# the plane: not a cloud


@dataclass(frozen=True, eq=False)
class Plane:
    """The solid halfspace ``{x : normal . x <= offset}`` in the geom frame.

    **Unbounded, so not a PointCloud**: no finite cloud, box or sphere contains it, and passing
    it where a cloud is expected raises ``ValueError``. The broad phase handles planes itself
    (a plane against a bounded volume is one support-function test). MuJoCo's plane geom is
    ``normal = (0, 0, 1)``, ``offset = 0``: the solid below its xy plane.

    Attributes
    ----------
    normal : (3,) float64
        Unit outward normal (read-only).
    offset : float
        Signed distance of the boundary plane from the origin along ``normal``.
    """

    normal: np.ndarray
    offset: float

    def __post_init__(self):
        n = as_array(self.normal, "normal", (3,))
        try:
            object.__setattr__(self, "offset", float(self.offset))
        except (TypeError, ValueError):
            raise ValueError(f"offset: expected a number, got {type(self.offset).__name__}") from None
        given = float(self.offset)
        if not math.isfinite(given):
            raise ValueError(f"offset: must be finite, got {given}")
        big = float(np.abs(n).max())
        if big > 0.0 and not 1e-150 < big < 1e150:
            # Divide by the largest component first: |n| overflowed for (1e308, 1e308, 0) and
            # the normal silently became zero.
            n, d0 = n / big, float(self.offset) / big
            object.__setattr__(self, "offset", d0)
        length = float(np.linalg.norm(n))
        if not length > 0.0:
            raise ValueError("normal: must be non-zero")
        d = float(self.offset)
        if not math.isfinite(d):
            # finite as given: the normal's length, far below 1, scaled it past the float range
            raise ValueError(f"normal: too short for its offset (largest component {big:.3g}, offset "
                             f"{given:.3g}: the same halfspace needs offset / |normal|, beyond the float "
                             "range); scale both")
        if abs(length - 1.0) > 1e-12:
            n, d = n / length, d / length
        n = np.array(n, dtype=np.float64)
        n.setflags(write=False)
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "offset", d)

    def __eq__(self, other) -> bool:
        # Written out: the generated __eq__ would compare the normal arrays elementwise.
        if not isinstance(other, Plane):
            return NotImplemented
        return bool(np.array_equal(self.normal, other.normal)) and self.offset == other.offset

    def __hash__(self) -> int:
        return hash((tuple(self.normal.tolist()), self.offset))

    def _unbounded(self, what: str):
        raise ValueError(f"{what}: a Plane is an unbounded halfspace and has no bounding {what}; "
                         "the broad phase handles planes itself (see shapes.plane)")

    def aabb(self):
        """Always raises ``ValueError``: a halfspace has no bounding box."""
        self._unbounded("aabb")

    def obb(self, method: str = "optimal"):
        """Always raises ``ValueError``: a halfspace has no bounding box."""
        self._unbounded("obb")

    def sphere(self, method: str = "exact"):
        """Always raises ``ValueError``: a halfspace has no bounding sphere."""
        self._unbounded("sphere")

    def signed_distance(self, points) -> np.ndarray:
        """``(n,) float64``: ``normal . x - offset`` for ``points`` ``(n, 3)`` (<= 0 inside)."""
        p = as_array(points, "points", (None, 3))
        return p @ self.normal - self.offset


def plane(normal=(0.0, 0.0, 1.0), offset: float = 0.0) -> Plane:
    """The halfspace ``{x : normal . x <= offset}``: a `Plane`, **not** a `PointCloud`.

    A plane is unbounded, so it has no bounding cloud; the broad phase handles planes itself.

    Parameters
    ----------
    normal : (3,) array_like of float, default (0, 0, 1)
        Non-zero; a non-unit normal is normalised together with ``offset`` (same halfspace).
    offset : float, default 0.0

    Returns
    -------
    Plane
    """
    try:
        d = float(offset)
    except (TypeError, ValueError):
        raise ValueError(f"offset: expected a number, got {offset!r}") from None
    return Plane(normal, d)
