"""Exact cloud forms: ``box`` (8 corners), ``sphere`` (1 point + radius), ``capsule`` (2 points +
radius), ``mesh`` (its vertices), the free-form patches (their control points: the convex-hull
property of Bezier, B-spline and positive-weight NURBS surfaces) and the sweeps of polygonal
contours (``extrude``, ``cone_sweep``).
"""

from __future__ import annotations

import numpy as np

from .. import hull as _hull
from .._validate import as_array, as_count, as_points, as_radius
from ..pointcloud import PointCloud
from ._polygons import _contour

__all__ = ["bezier_patch", "box", "bspline_patch", "capsule", "cone_sweep", "extrude", "mesh", "nurbs_patch", "sphere"]


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
