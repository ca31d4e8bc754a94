"""World bounds at given poses, and the pose rules every broad-phase call enforces.

`BroadPhase.world_bounds` (`world_bounds` here) computes in numpy, off the per-step path, the
spheres, OBBs, AABBs and planes the kernels test, with the kernels' rounding slack; `check_pose_values`
and `raise_pose_error` state, for Python callers (the brute-force twins among them), the rules by
which the kernels refuse a pose (`collide._kernels.broadphase._pose_ok`) and the message that names it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._kernels import broadphase as _k
from .._kernels import bounds as _kbounds
from ..articulation import Articulation

__all__ = ["WorldBounds", "check_pose_values", "raise_pose_error", "world_bounds", "world_planes"]


class WorldBounds(NamedTuple):
    """World bounding volumes of n geoms or bodies (`BroadPhase.world_bounds`).

    Attributes
    ----------
    obb_center : (n, 3) float64
    obb_rot : (n, 3, 3) float64
        Columns are the box axes in the world.
    obb_half : (n, 3) float64
    sphere_center : (n, 3) float64
    sphere_radius : (n,) float64
    aabb_min, aabb_max : (n, 3) float64
        The intersection of the OBB's, the sphere's and the capsule's world AABBs (each contains
        the shape, so their intersection does), padded by the broad phase's rounding slack. The
        broad phase tests the OBB's cut to the capsule's (`collide.articulation`, bounds
        semantics), not the sphere's: a reported pair may have disjoint AABBs here (never a
        touching one).
    plane : (n, 4) float64
        For plane geoms, the world halfspace ``{x : plane[:3] . x <= plane[3]}``; zeros otherwise.
    """

    obb_center: np.ndarray
    obb_rot: np.ndarray
    obb_half: np.ndarray
    sphere_center: np.ndarray
    sphere_radius: np.ndarray
    aabb_min: np.ndarray
    aabb_max: np.ndarray
    plane: np.ndarray


def raise_pose_error(status: int, body: int, where: str = "") -> None:
    """Raise the ``ValueError`` of a pose the kernels refused with ``status`` (``_k.BAD_*``) at ``body``.

    ``where`` prefixes the message (``"world 3, "``).
    """
    if status == _k.BAD_NONFINITE:
        raise ValueError(f"{where}body {body}: pose has a non-finite value (NaN or inf)")
    if status == _k.BAD_RANGE:
        raise ValueError(f"{where}body {body}: position beyond {_kbounds.MAX_POSITION:g} (the coordinate limit)")
    raise ValueError(f"{where}body {body}: rotation is not a proper orthonormal matrix "
                     f"(|R^T R - I| > {_kbounds.ORTHO_TOL:g} or det <= 0)")


def check_pose_values(body_pos: np.ndarray, body_rot: np.ndarray, where: str = "") -> None:
    """Raise ``ValueError`` naming the first body whose pose the kernel refuses (`_kbounds._pose_ok`).

    Parameters
    ----------
    body_pos : (L, 3) float64
    body_rot : (L, 3, 3) float64
    where : str
        Prefix of the message (``"world 3, "``).
    """
    finite = np.isfinite(body_pos).all(axis=1) & np.isfinite(body_rot).all(axis=(1, 2))
    with np.errstate(invalid="ignore", over="ignore"):
        near = (np.abs(body_pos) <= _kbounds.MAX_POSITION).all(axis=1)
        err = np.abs(np.einsum("lji,ljk->lik", body_rot, body_rot) - np.eye(3)).max(axis=(1, 2), initial=0.0)
        ok = finite & near & (err <= _kbounds.ORTHO_TOL) & (np.linalg.det(body_rot) > 0)
    if not ok.all():
        b = int(np.flatnonzero(~ok)[0])
        status = _k.BAD_NONFINITE if not finite[b] else _k.BAD_RANGE if not near[b] else _k.BAD_ROTATION
        raise_pose_error(status, b, where)


def world_planes(rot: np.ndarray, pos: np.ndarray, local: np.ndarray,
                 slack: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """World halfspaces ``{x : n . x <= d}`` (unit ``n``) of local ones under ``x = R y + p``.

    Parameters
    ----------
    rot : (n, 3, 3) float64
        Proper, not necessarily orthonormal (poses are accepted within ``_kbounds.ORTHO_TOL``).
    pos : (n, 3) float64
    local : (n, 4) float64
        Local unit normal and offset.
    slack : bool, default True
        Grow the offset by the kernels' rounding slack of the body position (``SLACK_POS |p|_1``),
        as `_kbounds.plane_world` does; False: the plane itself, up to rounding.

    Returns
    -------
    normal : (n, 3) float64
    offset : (n,) float64
        ``n`` along ``R^-T n_local``: the image of the plane under the map as given (the kernels'
        `_kbounds.plane_world`, with a linear solve instead of the cofactors).
    """
    w = np.linalg.solve(np.swapaxes(rot, 1, 2), local[:, :3, None])[:, :, 0]
    norm = np.linalg.norm(w, axis=1)
    normal = w / norm[:, None]
    offset = local[:, 3] / norm + np.einsum("ni,ni->n", normal, pos)
    return normal, offset + (_kbounds.SLACK_POS * np.abs(pos).sum(axis=1) if slack else 0.0)


def world_bounds(a: Articulation, body_pos: np.ndarray, body_rot: np.ndarray, of: str,
                 inflate: bool) -> WorldBounds:
    """`BroadPhase.world_bounds` on checked poses (C-contiguous float64, every pose valid): see there."""
    if of == "geoms":
        ids = a.geom_body
        center, rot, half = a.geom_obb_center, a.geom_obb_rot, a.geom_obb_half
        sc, sr = a.geom_sphere_center, a.geom_sphere_radius
        m = a.geom_bound_margin if inflate else np.zeros(a.geom_count)
        half, sr = half + m[:, None], sr + m
        cap_half, cap_r = a.geom_capsule_half, a.geom_capsule_radius + m
        unbounded, empty = a.geom_is_plane, np.zeros(a.geom_count, bool)
    else:
        ids = np.arange(a.body_count)
        center, rot, half = a.body_obb_center, a.body_obb_rot, a.body_obb_half.copy()
        sc, sr = a.body_sphere_center, a.body_sphere_radius.copy()
        cap_half, cap_r = a.body_capsule_half, a.body_capsule_radius.copy()
        unbounded, empty = np.zeros(a.body_count, bool), ~a.body_has_bounds
    R, p = body_rot[ids], body_pos[ids]
    c = np.einsum("nij,nj->ni", R, center) + p
    obb_rot = R @ rot
    s = np.einsum("nij,nj->ni", R, sc) + p
    # The kernel's slack (`_kbounds.aabb_slack`, `_kbounds.capsule_half`, and the sphere test's): rounding
    # never lets a shape's point out.
    w = np.abs(obb_rot) @ half[:, :, None]
    w = w[:, :, 0] + (_kbounds.SLACK_REL * half.sum(1) + _kbounds.SLACK_POS * np.abs(c).sum(1))[:, None]
    rs = (sr + _kbounds.SLACK_REL * sr + _kbounds.SLACK_POS * np.abs(s).sum(1))[:, None]
    e = np.abs(np.einsum("nij,nj->ni", R, cap_half))
    wc = e + (cap_r + _kbounds.SLACK_REL * (e.sum(1) + cap_r) + _kbounds.SLACK_POS * np.abs(c).sum(1))[:, None]
    lo = np.maximum(np.maximum(c - w, s - rs), c - wc)
    hi = np.minimum(np.minimum(c + w, s + rs), c + wc)
    plane = np.zeros((len(ids), 4))
    if unbounded.any():
        q = np.flatnonzero(unbounded)
        n, d = world_planes(R[q], p[q], a.geom_plane[q])
        d = d + (a.geom_bound_margin[q] if inflate else 0.0)
        plane[q, :3], plane[q, 3] = n, d
        c[q] = s[q] = n * d[:, None]
        obb_rot[q] = np.eye(3)
        half[q], sr[q], lo[q], hi[q] = np.inf, np.inf, -np.inf, np.inf
    if empty.any():
        half[empty], sr[empty], lo[empty], hi[empty] = -np.inf, -np.inf, np.inf, -np.inf
    return WorldBounds(c, obb_rot, half, s, sr, lo, hi, plane)
