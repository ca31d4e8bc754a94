"""The swept broad phase's brute-force twin and the oracle it answers to.

`brute_force_swept_pairs` evaluates `collide._kernels.swept`'s tests pair by pair in numpy, from
the `Articulation`'s own arrays and this package's brute static filter (no sweep-and-prune, no bit
matrix, no kept order). `motion_poses` gives the poses of the step's motion at any times, for the
sampling oracle (`BroadPhase.pairs` at many intermediate times, whose union the swept pairs must
contain).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .._kernels.bounds import ORTHO_TOL, SLACK_POS, SLACK_REL
from .._kernels.swept_motion import COS_SLACK
from ..articulation import Articulation
from .brute import _bounds_test, _check_poses, filter_passing_pairs, world_bounds

__all__ = ["brute_force_swept_pairs", "motion_poses"]


def motion_poses(pos0, rot0, pos1, rot1, s) -> tuple[np.ndarray, np.ndarray]:
    """Body poses at times ``s`` of the motion `collide._kernels.swept` bounds: ``R(s) = exp(s
    log(R1 R0ᵀ)) R0``, ``t(s) = (1 - s) t0 + s t1``.

    Parameters
    ----------
    pos0, pos1 : (L, 3) float64
    rot0, rot1 : (L, 3, 3) float64
    s : (T,) float
        Times in ``[0, 1]``.

    Returns
    -------
    pos : (T, L, 3) float64
    rot : (T, L, 3, 3) float64
    """
    s = np.asarray(s, np.float64)
    rv = Rotation.from_matrix(np.einsum("lij,lkj->lik", rot1, rot0)).as_rotvec()  # (L, 3)
    turn = Rotation.from_rotvec((s[:, None, None] * rv[None]).reshape(-1, 3)).as_matrix()
    turn = turn.reshape(len(s), -1, 3, 3)
    rot = np.einsum("tlij,ljk->tlik", turn, rot0)
    pos = (1.0 - s)[:, None, None] * pos0[None] + s[:, None, None] * pos1[None]
    return pos, rot


def _swept_geoms(art: Articulation, pos0, rot0, pos1, rot1, tol):
    # per geom: swept box (G, 6), sphere ends (G, 2, 3), radius (G,), centre deviation (G,)
    tr = np.einsum("lij,lij->l", rot0, rot1)
    theta = np.arccos(np.clip(0.5 * (tr - 1.0) - COS_SLACK, -1.0, 1.0))
    same = (pos0 == pos1).all(axis=1) & (rot0 == rot1).all(axis=(1, 2))
    k = np.where(same, 0.0, theta ** 2 * (0.125 * (1.0 + 1e-12)))
    turn = np.where(same, 0.0, np.minimum(theta, 2.0) * (1.0 + 2.0 * ORTHO_TOL))  # |R0 x| <= (1 + 1.5 tol) |x|
    shift = np.where(same, 0.0, np.linalg.norm(pos1 - pos0, axis=1))
    G = art.geom_count
    m = art.geom_bound_margin
    b = art.geom_body
    boxes = []  # per end: the OBB's world AABB, then the capsule's (swept apart, then cut)
    ends = []
    for R, p in ((rot0, pos0), (rot1, pos1)):
        Rb, pb = R[b], p[b]
        c = np.einsum("gij,gj->gi", Rb, art.geom_obb_center) + pb
        axes = np.einsum("gij,gjk->gik", Rb, art.geom_obb_rot)
        e = art.geom_obb_half + m[:, None]
        t = SLACK_REL * e.sum(1) + SLACK_POS * np.abs(c).sum(1)
        h = np.einsum("gij,gj->gi", np.abs(axes), e) + t[:, None]
        d = np.abs(np.einsum("gij,gj->gi", Rb, art.geom_capsule_half))
        r = art.geom_capsule_radius + m
        tc = SLACK_REL * (d.sum(1) + r) + SLACK_POS * np.abs(c).sum(1)
        hc = d + (r + tc)[:, None]
        boxes.append((np.concatenate([c - h, c + h], axis=1), np.concatenate([c - hc, c + hc], axis=1)))
        ends.append(np.einsum("gij,gj->gi", Rb, art.geom_sphere_center) + pb)
    cn = np.linalg.norm(art.geom_obb_center, axis=1)
    rho = np.maximum(cn + np.linalg.norm(art.geom_obb_half + m[:, None], axis=1),
                     cn + np.linalg.norm(art.geom_capsule_half, axis=1) + art.geom_capsule_radius + m)
    dev = rho * k[b] * (1.0 + SLACK_REL) + tol
    reach = (rho * turn[b] + shift[b]) * (1.0 + SLACK_REL)
    (o0, c0), (o1, c1) = boxes
    lo = np.maximum(np.minimum(o0[:, :3], o1[:, :3]), np.minimum(c0[:, :3], c1[:, :3])) - dev[:, None]
    hi = np.minimum(np.maximum(o0[:, 3:], o1[:, 3:]), np.maximum(c0[:, 3:], c1[:, 3:])) + dev[:, None]
    box = np.concatenate([np.maximum(lo, np.maximum(o1[:, :3], c1[:, :3]) - (reach + tol)[:, None]),
                          np.minimum(hi, np.minimum(o1[:, 3:], c1[:, 3:]) + (reach + tol)[:, None])], axis=1)
    cdev = np.linalg.norm(art.geom_sphere_center, axis=1) * k[b]
    assert box.shape == (G, 6)
    return box, np.stack(ends, axis=1), art.geom_sphere_radius, cdev, same, reach, turn[b]


def _spheres(ends, rad, cdev, g1, g2, m1, m2, tol):
    d = ends[g1, 0] - ends[g2, 0]
    v = (ends[g1, 1] - ends[g2, 1]) - d
    vv = (v * v).sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(vv > 0.0, np.clip(-(d * v).sum(1) / vv, 0.0, 1.0), 0.0)
    e = d + s[:, None] * v
    r = rad[g1] + m1 + cdev[g1] + rad[g2] + m2 + cdev[g2]
    pos = np.abs(ends[g1]).sum((1, 2)) + np.abs(ends[g2]).sum((1, 2))
    r = r + SLACK_REL * r + SLACK_POS * pos + tol
    return (e * e).sum(1) <= r * r


def _world_plane(art: Articulation, q, pos, rot):
    # {x : n . x <= e} in the world for plane geom q (normal along R^-T n_local)
    R, p = rot[art.geom_body[q]], pos[art.geom_body[q]]
    n = np.linalg.solve(R.T, art.geom_plane[q, :3])
    det = np.linalg.det(R)
    norm = np.linalg.norm(n)
    return n / norm, art.geom_plane[q, 3] * det / norm + (n / norm) @ p + SLACK_POS * np.abs(p).sum()


def _plane(art, q, g, mq, mg, box, ends, rad, cdev, pos1, rot1, tol, corner_too=True):
    n, e = _world_plane(art, q, pos1, rot1)
    lim = e + mq
    c = min(n @ ends[g, 0], n @ ends[g, 1])
    r = rad[g] + mg + cdev[g]
    corner = n @ np.where(n < 0.0, box[g, 3:], box[g, :3])
    scale = abs(e) + np.abs(ends[g]).sum() + np.abs(box[g]).sum()
    t = SLACK_REL * r + SLACK_POS * scale + tol
    return (c - r <= lim + t) and (corner <= lim + t or not corner_too)


def brute_force_swept_pairs(art: Articulation, pos0, rot0, pos1, rot1, tol: float = 0.0) -> np.ndarray:
    """`BroadPhase.pairs_swept` pair by pair (see `collide._kernels.swept` for the tests).

    Parameters
    ----------
    art : Articulation
    pos0, pos1 : (L, 3) float64
    rot0, rot1 : (L, 3, 3) float64
    tol : float
        Added to every test's threshold (a distance): ``-1e-9`` gives the pairs that pass with
        room to spare, ``+1e-9`` every pair the kernel's rounding could let through.

    Returns
    -------
    pairs : (K, 2) int32
        Lower id first, sorted.
    """
    pos0, rot0 = _check_poses(art, pos0, rot0)
    pos1, rot1 = _check_poses(art, pos1, rot1)
    box, ends, rad, cdev, same, reach, turn = _swept_geoms(art, pos0, rot0, pos1, rot1, tol)
    wb = world_bounds(art, pos1, rot1)

    def at_end(x, y, mx, my):
        # the single step's test at s = 1 with every volume grown by its reach (and tol); an
        # explicit pair's margin above the geom's own grows the reach by sqrt(3) (margin
        # difference) times the turn
        x, y = np.atleast_1d(x), np.atleast_1d(y)
        rx = reach[x] + np.sqrt(3.0) * np.maximum(0.0, mx - m[x]) * turn[x] * (1.0 + SLACK_REL)
        ry = reach[y] + np.sqrt(3.0) * np.maximum(0.0, my - m[y]) * turn[y] * (1.0 + SLACK_REL)
        return _bounds_test(wb, x, y, mx + rx + tol, my + ry + tol, art.geom_is_plane)

    m = art.geom_bound_margin
    plane = art.geom_is_plane
    g1, g2 = filter_passing_pairs(art)
    keep = []
    solid = ~plane[g1] & ~plane[g2]
    a, b = g1[solid], g2[solid]
    ok = ((box[a, :3] <= box[b, 3:]) & (box[b, :3] <= box[a, 3:])).all(1)
    ok &= _spheres(ends, rad, cdev, a, b, m[a], m[b], tol)
    ok &= at_end(a, b, m[a], m[b])
    keep.append(np.stack([a[ok], b[ok]], 1))
    for x, y in zip(g1[~solid], g2[~solid]):
        q, g = (x, y) if plane[x] else (y, x)
        if not same[art.geom_body[q]] or (_plane(art, q, g, m[q], m[g], box, ends, rad, cdev, pos1, rot1, tol)
                                          and at_end(q, g, m[q], m[g])[0]):
            keep.append(np.array([[x, y]]))
    pm = art.pair_bound_margin
    for i, (x, y) in enumerate(art.pairs):
        mx = m[x] if np.isnan(pm[i]) else pm[i]
        my = m[y] if np.isnan(pm[i]) else pm[i]
        if plane[x] and plane[y]:
            continue
        if plane[x] or plane[y]:
            q, g, mq, mg = (x, y, mx, my) if plane[x] else (y, x, my, mx)
            hit = not same[art.geom_body[q]] or (_plane(art, q, g, mq, mg, box, ends, rad, cdev, pos1, rot1, tol,
                                                        corner_too=False) and at_end(q, g, mq, mg)[0])
        else:
            hit = bool(_spheres(ends, rad, cdev, np.array([x]), np.array([y]), mx, my, tol)[0]) and at_end(x, y, mx, my)[0]
        if hit:
            keep.append(np.array([[x, y]]))
    out = np.concatenate(keep).astype(np.int32) if keep else np.zeros((0, 2), np.int32)
    out = np.sort(out, axis=1)
    return np.unique(out, axis=0) if len(out) else out.reshape(0, 2)
