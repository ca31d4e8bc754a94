"""Swept bounds of rigid motion: a cloud containing every position of a cloud during a step.

The motion (one simulator step at constant velocity): ``p(s) = R(s) x + t(s)`` for ``s`` in
``[0, 1]``, with ``R(s) = exp(s log(R1 R0ᵀ)) R0`` (a constant-rate turn by the angle ``θ`` of
``R1 R0ᵀ`` about its fixed axis ``a``) and ``t(s) = (1 - s) t0 + s t1``.

The bound (derivation). Let ``y = R0 x`` and ``ℓ(s) = (1 - s) p(0) + s p(1)``, a point of the
segment between the point's two end positions, so of the hull of the two end clouds. Then
``p(s) - ℓ(s) = Rot(a, sθ) y - ((1 - s) y + s Rot(a, θ) y)``: the translations cancel (both are
linear in ``s``), and so does the component of ``y`` along ``a``. What is left is the deviation of
the curve ``c(s) = Rot(a, sθ) y_⊥`` (a circular arc of radius ``ρ = |y_⊥|``, the distance of ``y``
from the axis through the origin) from its linear interpolant at the same parameter. ``c`` has
``|c''(s)| = ρ θ²``, and the interpolation bound (Taylor with integral remainder at both ends, the
1-D case of `collide.deforming`) gives ``|p(s) - ℓ(s)| <= (ρ θ² / 2) s (1 - s) <= ρ θ² / 8``. So
the swept set lies in the hull of the end clouds grown by ``ρ_max θ² / 8``, with ``ρ_max`` the
largest distance from the axis over the cloud (its hull vertices' plus its radius: the distance
from a line is convex). (The chord's sagitta, ``ρ (1 - cos(θ/2))``, is the same to second order.)

Sub-steps: the motion restricted to ``[s_j, s_{j+1}]`` has the same form with angle ``θ / m``, so
with ``m = ceil(θ / max_angle)`` sub-steps the hull of the ``m + 1`` intermediate clouds grown by
``ρ_max (θ / m)² / 8`` bounds the sweep. At ``θ = π`` the logarithm is not unique (either way
round): within ``1e-7`` of it, both turns are bounded.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from . import hull as _hull
from ._validate import _as_finite, as_affine
from .pointcloud import PointCloud

__all__ = ["sweep_deviation", "swept"]

# Largest |R^T R - I| accepted for a pose's rotation (float32-rounded rotations pass).
ORTHO_TOL = 1e-5

# Rounding slack of the radius, relative to the largest coordinate.
SLACK = 256 * np.finfo(np.float64).eps


def sweep_deviation(rho: float, angle: float, steps: int = 1) -> float:
    """Proven bound on how far a point at distance ``rho`` from the axis, turning by ``angle``
    (radians) in ``steps`` equal sub-steps, leaves the segments between its sub-step positions
    (``rho (angle / steps)² / 8``; module docstring)."""
    return float(rho) * (float(angle) / steps) ** 2 / 8.0


def _pose(pose, name: str) -> tuple[np.ndarray, np.ndarray]:
    try:
        R, t = as_affine(pose, None, name)
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(msg if msg.startswith(name) else f"{name}: {msg}") from None
    err = float(np.abs(R.T @ R - np.eye(3)).max())
    if not err <= ORTHO_TOL or np.linalg.det(R) <= 0.0:
        raise ValueError(f"{name}: the rotation must be orthonormal with determinant +1 "
                         f"(|RᵀR - I| = {err:.3g}, det = {np.linalg.det(R):.3g})")
    return R, t


def swept(cloud: PointCloud, pose0, pose1, max_angle: float = math.pi / 4) -> PointCloud:
    """A cloud containing every position of ``cloud`` while it moves from ``pose0`` to ``pose1``.

    Parameters
    ----------
    cloud : PointCloud
        In its own (body) frame.
    pose0, pose1 : tuple or (4, 4) array_like
        ``(R (3, 3), t (3,))`` pairs (or homogeneous matrices): positions ``R x + t`` at the
        step's start and end. The motion between them turns at a constant rate about the fixed
        axis of ``R1 R0ᵀ`` while the origin moves on a line (module docstring).
    max_angle : float, default pi / 4
        The step is split into ``m = ceil(θ / max_angle)`` sub-steps, ``θ`` the angle of
        ``R1 R0ᵀ``.

    Returns
    -------
    PointCloud
        Hull vertices of the ``m + 1`` sub-step clouds (in the world frame), radius the cloud's
        plus ``sweep_deviation(ρ_max, θ, m)`` plus rounding slack. A pure translation gives the
        hull of the two end clouds (radius: the cloud's plus rounding slack).

    Raises
    ------
    ValueError
        Naming the argument: not a PointCloud, a cloud of non-zero extent below
        `collide.hull.MIN_EXTENT` or reaching, with its radius, beyond
        `collide.hull.MAX_COORDINATE`, a pose that is not a rotation and a translation, non-finite
        entries, ``max_angle`` not in ``(0, pi]``.
    """
    if not isinstance(cloud, PointCloud):
        raise ValueError(f"cloud: expected a PointCloud, got {type(cloud).__name__}")
    R0, t0 = _pose(pose0, "pose0")
    R1, t1 = _pose(pose1, "pose1")
    max_angle = _as_finite(max_angle, "max_angle")
    if not 0.0 < max_angle <= math.pi:
        raise ValueError(f"max_angle: must be in (0, pi], got {max_angle}")
    if cloud.is_empty:
        return PointCloud.empty()
    _hull.require_bounded(cloud.points, "cloud", cloud.radius)  # as every bound refuses it (helper-78)
    _hull.require_not_tiny(cloud.points, "cloud", cloud.radius)
    P = _hull.hull_vertices(cloud.points)
    Y = P @ R0.T
    rotvec = Rotation.from_matrix(R1 @ R0.T).as_rotvec()
    theta = float(np.linalg.norm(rotvec))
    turns = [rotvec]
    if theta > math.pi - 1e-7:  # log(R1 R0ᵀ) is ambiguous at pi: bound both ways round
        turns.append(-rotvec / theta * (2.0 * math.pi - theta))
    parts = [P @ R1.T + t1]
    deviation = 0.0
    for turn in turns:
        angle = float(np.linalg.norm(turn))
        m = max(1, math.ceil(angle / max_angle))
        if angle > 0.0:
            axis = turn / angle
            # hypot, not a norm's squares: a point 1e-200 off the axis had rho 0, and its arc was lost
            off = Y - np.outer(Y @ axis, axis)
            rho = float(np.hypot(np.hypot(off[:, 0], off[:, 1]), off[:, 2]).max()) + cloud.radius
            deviation = max(deviation, sweep_deviation(rho, angle, m))
        for j in range(m + 1):
            s = j / m
            Rs = Rotation.from_rotvec(s * turn).as_matrix()
            parts.append(Y @ Rs.T + ((1.0 - s) * t0 + s * t1))
    pts = np.concatenate(parts)
    radius = cloud.radius + deviation + SLACK * (float(np.abs(pts).max()) + cloud.radius)
    return PointCloud(_hull.hull_vertices(pts), radius)
