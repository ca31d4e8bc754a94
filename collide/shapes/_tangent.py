"""Tangent-plane forms (Stürzlinger 1996, §3.1): the vertices of a polytope circumscribed about a
curved shape (``revolve``, ``cylinder``, ``cone``, ``ellipsoid``, ``torus``, ``superquadric``);
``planes`` trades size for tightness (more planes, a tighter cloud).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import HalfspaceIntersection, QhullError

from .. import hull as _hull
from .._validate import as_array, as_count, as_positive, as_radius
from ..pointcloud import PointCloud
from ._polygons import TANGENT_INFLATE, _budget, _circle_polygon, _contour, _revolve_points

__all__ = ["cone", "cylinder", "ellipsoid", "revolve", "sphere_polytope_circumradius", "superquadric",
           "superquadric_support", "torus"]


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
