"""Barr's global deformations about the z axis, each with a proven bound on its second derivative.

Barr (1984), "Global and local deformations of solid primitives", SIGGRAPH '84, 21-30: twisting,
bending and tapering. Each map here is a callable ``f(points (n, 3)) -> (n, 3)`` that `collide.deform`
accepts without a user's bound, because it also answers:

- ``second_derivative_bound(points) -> M``: an upper bound, over the axis-aligned box of
  ``points`` (which contains their hull), of ``|D²f(x)[u, u]|`` (the Euclidean norm of the second
  directional derivative) for every unit vector ``u``;
- ``is_regular(points) -> bool``: True when the Jacobian of ``f`` is nonsingular at every interior
  point of that box, so that ``f`` is an open map there and the image of the hull's surface bounds
  the image of the solid (see `collide.deform`).

The maps act about the z axis through the origin; move a cloud first (``PointCloud.transform``)
to deform it about another axis.
"""

from __future__ import annotations

import numpy as np

from ._validate import _as_finite, as_points

__all__ = ["Bend", "Deformation", "Taper", "Twist", "bend", "taper", "twist"]


def _box(points) -> tuple[np.ndarray, np.ndarray]:
    pts = as_points(points, "points")
    if len(pts) == 0:
        raise ValueError("points: the box of an empty set is undefined")
    return pts.min(axis=0), pts.max(axis=0)


def _map_input(points) -> np.ndarray:
    return as_points(points, "points")


class Deformation:
    """Base of the deformations that know a bound on their own second derivative.

    Subclasses implement ``__call__``, ``second_derivative_bound`` and ``is_regular``.
    """

    def __call__(self, points) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def second_derivative_bound(self, points) -> float:  # pragma: no cover - abstract
        """Upper bound ``M`` of ``|D²f(x)[u, u]|`` over the box of ``points`` ``(n, 3)``, unit ``u``."""
        raise NotImplementedError

    def is_regular(self, points) -> bool:  # pragma: no cover - abstract
        """True when ``det Df != 0`` on the interior of the box of ``points`` ``(n, 3)``."""
        raise NotImplementedError


class Twist(Deformation):
    """Twist about the z axis: ``θ = rate z``; ``X = x cos θ - y sin θ``, ``Y = x sin θ + y cos θ``,
    ``Z = z`` (Barr 1984, twisting with ``θ = f(z)`` linear).

    Second derivative (derivation): with ``P = (x, y)`` and the rotation ``Rot(θ)`` of the xy
    plane, ``D²f[u, u] = Rot(θ) (2 a u_z J u_P - a² u_z² P)`` (``a`` the rate, ``J`` the quarter
    turn), so ``|D²f[u, u]| <= |a| (2 t sqrt(1 - t²) + m t²)`` with ``t = |u_z|``,
    ``m = |a| ρ_max`` and ``ρ_max`` the largest distance from the z axis over the box (at a
    corner). Writing ``t = sin φ``: ``|a| (sin 2φ + m (1 - cos 2φ) / 2) <= |a| (m / 2 +
    sqrt(1 + m² / 4))``, the bound returned. ``det Df = 1`` everywhere: always regular.

    Parameters
    ----------
    rate : float
        Turn per unit of z, radians.
    """

    def __init__(self, rate: float):
        self.rate = _as_finite(rate, "rate")

    def __repr__(self) -> str:
        return f"twist({self.rate!r})"

    def __call__(self, points) -> np.ndarray:
        p = _map_input(points)
        th = self.rate * p[:, 2]
        c, s = np.cos(th), np.sin(th)
        return np.stack([p[:, 0] * c - p[:, 1] * s, p[:, 0] * s + p[:, 1] * c, p[:, 2]], axis=1)

    def second_derivative_bound(self, points) -> float:
        lo, hi = _box(points)
        rho = max(np.hypot(x, y) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]))
        a = abs(self.rate)
        m = a * rho
        return float(a * (0.5 * m + np.sqrt(1.0 + 0.25 * m * m)))

    def is_regular(self, points) -> bool:
        return True


class Taper(Deformation):
    """Linear taper along the z axis: ``r = 1 + slope z``; ``X = r x``, ``Y = r y``, ``Z = z``
    (Barr 1984, tapering with ``r = f(z)`` linear).

    Second derivative (derivation): ``r'' = 0``, so the only second partials are
    ``∂²X/∂x∂z = ∂²Y/∂y∂z = slope`` and ``D²f[u, u] = 2 slope u_z (u_x, u_y, 0)``, of norm
    ``2 |slope| |u_z| sqrt(u_x² + u_y²) <= |slope| (u_x² + u_y² + u_z²) = |slope|``: the bound
    returned, on any box. ``det Df = r²``: regular on a box whose z range keeps ``r`` of one
    strict sign at both ends (``r`` is linear in z).

    Parameters
    ----------
    slope : float
        Change of the xy scale per unit of z (the scale is 1 at ``z = 0``).
    """

    def __init__(self, slope: float):
        self.slope = _as_finite(slope, "slope")

    def __repr__(self) -> str:
        return f"taper({self.slope!r})"

    def __call__(self, points) -> np.ndarray:
        p = _map_input(points)
        r = 1.0 + self.slope * p[:, 2]
        return np.stack([r * p[:, 0], r * p[:, 1], p[:, 2]], axis=1)

    def second_derivative_bound(self, points) -> float:
        _box(points)
        return abs(self.slope)

    def is_regular(self, points) -> bool:
        lo, hi = _box(points)
        r = 1.0 + self.slope * np.array([lo[2], hi[2]])
        return bool(np.all(r > 0.0) or np.all(r < 0.0))


class Bend(Deformation):
    """Bend of the z axis into a circle of radius ``1 / curvature`` in the xz plane, towards +x.

    With ``θ = k z`` (``k`` the curvature): ``X = x cos θ + (1 - cos θ) / k``, ``Y = y``,
    ``Z = sin θ / k - x sin θ`` (the identity at ``k = 0``). This is Barr's (1984) bend with his
    y axis as our z, his z as our x, the bend centre at ``z = 0`` and the bending region the whole
    z range (no straight continuation); the centre of curvature is the line ``x = 1 / k``,
    ``z = 0``. Bends of more than a full turn overlap themselves: still bounded (see
    `collide.deform`).

    Second derivative (derivation): ``f = C + w u(θ) + y e_y`` with ``w = 1 / k - x``,
    ``u(θ) = (-cos θ, 0, sin θ)`` and ``u' ⟂ u``, both unit. Then ``∂f/∂x = -u``,
    ``∂f/∂z = w k u'``, ``∂²f/∂x∂z = -k u'``, ``∂²f/∂z² = -w k² u``, the rest zero, so
    ``|D²f[u, u]|² = 4 k² u_x² u_z² + (k w)² k² u_z⁴ <= k² (4 q (1 - q) + m² q²)`` with
    ``q = u_z²`` and ``m = max |1 - k x|`` over the box's x range. The quadratic's maximum on
    ``q in [0, 1]`` is ``4 / (4 - m²)`` (at ``q = 2 / (4 - m²)``) when ``m² <= 2``, else ``m²``
    (at ``q = 1``): the bound is ``2 |k| / sqrt(4 - m²)`` or ``|k| m``. ``det Df = ±(1 - k x)``:
    regular on a box whose x range keeps ``1 - k x`` of one strict sign (away from the centre).

    Parameters
    ----------
    curvature : float
        ``k``: the inverse of the bend radius; negative bends towards -x.
    """

    def __init__(self, curvature: float):
        self.curvature = _as_finite(curvature, "curvature")

    def __repr__(self) -> str:
        return f"bend({self.curvature!r})"

    def __call__(self, points) -> np.ndarray:
        p = _map_input(points)
        k = self.curvature
        x, z = p[:, 0], p[:, 2]
        th = k * z
        half = 0.5 * th
        # sin θ / k = z sinc(θ), (1 - cos θ) / k = z sin(θ/2) sinc(θ/2): exact at k = 0.
        sin_k = z * np.sinc(th / np.pi)
        vers_k = z * np.sin(half) * np.sinc(half / np.pi)
        return np.stack([x * np.cos(th) + vers_k, p[:, 1], sin_k - x * np.sin(th)], axis=1)

    def second_derivative_bound(self, points) -> float:
        lo, hi = _box(points)
        k = abs(self.curvature)
        m = max(abs(1.0 - self.curvature * lo[0]), abs(1.0 - self.curvature * hi[0]))
        if m * m <= 2.0:
            return float(2.0 * k / np.sqrt(4.0 - m * m))
        return float(k * m)

    def is_regular(self, points) -> bool:
        lo, hi = _box(points)
        w = 1.0 - self.curvature * np.array([lo[0], hi[0]])
        return bool(np.all(w > 0.0) or np.all(w < 0.0))


def twist(rate: float) -> Twist:
    """Twist about the z axis by ``rate`` radians per unit of z (see `Twist` for the formulas)."""
    return Twist(rate)


def bend(curvature: float) -> Bend:
    """Bend of the z axis into a circle of radius ``1 / curvature`` (see `Bend` for the formulas)."""
    return Bend(curvature)


def taper(slope: float) -> Taper:
    """Linear taper along the z axis, xy scale ``1 + slope z`` (see `Taper` for the formulas)."""
    return Taper(slope)
