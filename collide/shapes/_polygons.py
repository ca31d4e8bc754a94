"""Helpers of the shape constructors: circumscribed polygons, revolutions, contours, the size
budget, and the inflation every tangent-plane construction carries (`TANGENT_INFLATE`).
"""

from __future__ import annotations

import math

import numpy as np

from .._validate import as_array

__all__ = ["MAX_POINTS", "TANGENT_INFLATE"]


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


def _contour(contour, name: str = "contour") -> np.ndarray:
    c = as_array(contour, name, (None, 2))
    if len(c) == 0:
        raise ValueError(f"{name}: needs at least one point")
    return c
