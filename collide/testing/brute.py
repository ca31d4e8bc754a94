"""Brute-force twins of the broad phase: every filter-passing geom pair, tested without a tree.

- `brute_force_bound_pairs`: the same world bounds as `collide.BroadPhase` (each geom's sphere, OBB
  and world AABB -- its OBB's cut to its capsule's --, inflated by its margin; planes as
  halfspaces) compared pairwise in plain numpy: no tree, no sweep-and-prune, no body-level bounds.
  The broad phase's candidate set must *equal* it.
- `brute_force_pairs`: the pairs whose exact sets ``hull(points) ⊕ ball(radius + margin)``
  intersect, decided by GJK distance between the two hulls (`collide.testing.hull_distance`, numba;
  no bounding volume involved).
  The broad phase must report every one of them.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from .._kernels import bounds as _k
from ..articulation import Articulation
from ..broadphase import check_pose_values, world_planes
from .hull_distance import gjk_distance, hulls_intersect_lp

__all__ = [
    "brute_force_bound_pairs", "brute_force_pairs", "filter_passing_pairs", "gjk_distance",
    "hulls_intersect_lp", "world_bounds", "world_capsules",
]


# ------------------------------------------------------------------------------- static filter

def _filter_mask(art: Articulation, g1: np.ndarray, g2: np.ndarray) -> np.ndarray:
    """``(n,) bool``: which geom pairs ``(g1, g2)`` pass the static filter of the dynamic path
    (explicit pairs excluded: they are tested separately)."""
    b1, b2 = art.geom_body[g1], art.geom_body[g2]
    ok = art.body_weld[b1] != art.body_weld[b2]
    if art.filter_parent:
        par = art.body_parent
        ok &= ~((par[b1] == b2) & (b2 != 0)) & ~((par[b2] == b1) & (b1 != 0))
    ct, ca = art.geom_contype, art.geom_conaffinity
    ok &= ((ct[g1] & ca[g2]) != 0) | ((ct[g2] & ca[g1]) != 0)
    L, G = art.body_count, art.geom_count
    if len(art.exclude):
        lo, hi = np.minimum(b1, b2), np.maximum(b1, b2)
        ok &= ~np.isin(lo * L + hi, art.exclude[:, 0] * L + art.exclude[:, 1])
    if len(art.pairs):
        lo, hi = np.minimum(g1, g2), np.maximum(g1, g2)
        ok &= ~np.isin(lo * G + hi, art.pairs[:, 0] * G + art.pairs[:, 1])
    ok &= ~art.geom_is_plane[g1] | ~art.geom_is_plane[g2]
    return ok


def filter_passing_pairs(art: Articulation) -> tuple[np.ndarray, np.ndarray]:
    """All geom pairs tested by the dynamic path, ``g1 < g2`` (two ``(n,) int64`` arrays)."""
    g1, g2 = np.triu_indices(art.geom_count, 1)
    keep = _filter_mask(art, g1, g2)
    return g1[keep], g2[keep]


def _check_poses(art: Articulation, body_pos, body_rot):
    L = art.body_count
    body_pos = np.asarray(body_pos, np.float64)
    body_rot = np.asarray(body_rot, np.float64)
    if body_pos.shape != (L, 3) or body_rot.shape != (L, 3, 3):
        raise ValueError(f"poses: expected ({L}, 3) and ({L}, 3, 3), got {body_pos.shape}, {body_rot.shape}")
    check_pose_values(body_pos, body_rot)  # BroadPhase's rules: a twin must not answer where it refuses
    return body_pos, body_rot


# ------------------------------------------------------------------------------- world bounds

def world_bounds(art: Articulation, body_pos, body_rot):
    """World bounds of every geom, not inflated.

    Returns
    -------
    center : (G, 3), rot : (G, 3, 3), half : (G, 3), sphere_center : (G, 3), sphere_radius : (G,)
    plane : (G, 4) float64
        World normal and offset of planes (zeros for other geoms).
    """
    body_pos, body_rot = _check_poses(art, body_pos, body_rot)
    Rb, pb = body_rot[art.geom_body], body_pos[art.geom_body]
    center = np.einsum("gij,gj->gi", Rb, art.geom_obb_center) + pb
    rot = Rb @ art.geom_obb_rot
    sc = np.einsum("gij,gj->gi", Rb, art.geom_sphere_center) + pb
    plane = np.zeros((art.geom_count, 4))
    q = np.flatnonzero(art.geom_is_plane)
    if len(q):
        n, d = world_planes(Rb[q], pb[q], art.geom_plane[q])
        plane[q, :3], plane[q, 3] = n, d
    return center, rot, art.geom_obb_half.copy(), sc, art.geom_sphere_radius.copy(), plane


def world_capsules(art: Articulation, body_pos, body_rot):
    """World capsules of every geom, not inflated: ``(G, 3)`` half segments (``R d``) and ``(G,)``
    radii, centred on the OBB centres of `world_bounds`."""
    body_pos, body_rot = _check_poses(art, body_pos, body_rot)
    Rb = body_rot[art.geom_body]
    return np.einsum("gij,gj->gi", Rb, art.geom_capsule_half), art.geom_capsule_radius.copy()


def _world_aabb(c, R, h, d, r):
    # The world AABB (lo, hi) of an OBB (centre c, axes R, half extents h) cut to that of the
    # capsule (centre c, world half segment d, radius r), each with the kernels' rounding slack
    # (`_k.aabb_slack`, `_k.capsule_half`).
    w = np.sum(np.abs(R) * h[:, None, :], axis=2) + (_k.SLACK_REL * h.sum(1) + _k.SLACK_POS * np.abs(c).sum(1))[:, None]
    e = np.abs(d)
    wc = e + (r + _k.SLACK_REL * (e.sum(1) + r) + _k.SLACK_POS * np.abs(c).sum(1))[:, None]
    return np.maximum(c - w, c - wc), np.minimum(c + w, c + wc)


def _sat_overlap(ca, Ra, ea, cb, Rb, eb) -> np.ndarray:
    # Generic 15-axis SAT, vectorised over n box pairs: project both boxes on each axis.
    A = np.swapaxes(Ra, 1, 2)  # rows = axes
    B = np.swapaxes(Rb, 1, 2)
    cross = np.cross(A[:, :, None, :], B[:, None, :, :]).reshape(-1, 9, 3)
    axes = np.concatenate([A, B, cross], axis=1)  # (n, 15, 3)
    d = cb - ca
    ra = np.sum(np.abs(np.einsum("nkx,nix->nki", axes, A)) * ea[:, None, :], axis=2)
    rb = np.sum(np.abs(np.einsum("nkx,nix->nki", axes, B)) * eb[:, None, :], axis=2)
    dist = np.abs(np.einsum("nkx,nx->nk", axes, d))
    size = ea.sum(1) + eb.sum(1)
    pos = np.abs(ca).sum(1) + np.abs(cb).sum(1)
    tol = (_k.SLACK_REL + 2 * _k.EPS_PAR) * size + _k.SLACK_POS * pos
    return np.all(dist <= ra + rb + tol[:, None], axis=1)


def _sphere_overlap(c1, r1, c2, r2) -> np.ndarray:
    r = r1 + r2
    pos = np.abs(c1).sum(1) + np.abs(c2).sum(1)
    r = r + _k.SLACK_REL * r + _k.SLACK_POS * pos
    return np.sum((c1 - c2) ** 2, axis=1) <= r * r


def _plane_overlap(plane, c, R, h, sc, sr) -> np.ndarray:
    n, d = plane[:, :3], plane[:, 3]
    pos = np.abs(c).sum(1) + np.abs(d)
    s_ok = np.sum(n * sc, 1) - sr <= d + _k.SLACK_REL * sr + _k.SLACK_POS * pos
    ext = np.sum(np.abs(np.einsum("nx,nxi->ni", n, R)) * h, axis=1)
    b_ok = np.sum(n * c, 1) - ext <= d + _k.SLACK_REL * ext + _k.SLACK_POS * pos
    return s_ok & b_ok


def _bounds_test(wb, g1, g2, m1, m2, is_plane, caps=None) -> np.ndarray:
    # caps: `world_capsules`, for the AABB tests of the dynamic path (explicit pairs: None, their
    # spheres and OBBs only).
    c, R, h, sc, sr, pl = wb
    p1, p2 = is_plane[g1], is_plane[g2]
    out = np.zeros(len(g1), bool)
    both = ~p1 & ~p2
    i, j = g1[both], g2[both]
    ok = _sphere_overlap(sc[i], sr[i] + m1[both], sc[j], sr[j] + m2[both])
    if caps is not None:
        d, r = caps
        lo1, hi1 = _world_aabb(c[i], R[i], h[i] + m1[both, None], d[i], r[i] + m1[both])
        lo2, hi2 = _world_aabb(c[j], R[j], h[j] + m2[both, None], d[j], r[j] + m2[both])
        ok &= np.all((lo1 <= hi2) & (lo2 <= hi1), axis=1)
    sel = np.flatnonzero(both)[ok]
    i, j = g1[sel], g2[sel]
    out[sel] = _sat_overlap(c[i], R[i], h[i] + m1[sel, None], c[j], R[j], h[j] + m2[sel, None])
    one = p1 ^ p2
    gp = np.where(p1, g1, g2)[one]
    gs = np.where(p1, g2, g1)[one]
    mp = np.where(p1, m1, m2)[one]
    ms = np.where(p1, m2, m1)[one]
    pl_inf = pl[gp].copy()
    pl_inf[:, 3] += mp
    hit = _plane_overlap(pl_inf, c[gs], R[gs], h[gs] + ms[:, None], sc[gs], sr[gs] + ms)
    if caps is not None:
        # the AABB's corner deepest along the normal, with the kernels' slack
        d, r = caps
        lo, hi = _world_aabb(c[gs], R[gs], h[gs] + ms[:, None], d[gs], r[gs] + ms)
        n, pd = pl[gp, :3], pl[gp, 3]
        v = np.sum(n * np.where(n > 0, lo, hi), axis=1)
        hit &= v <= (pd + mp) + _k.SLACK_POS * (np.abs(v) + np.abs(pd))
    out[one] = hit
    return out


def _explicit_margins(art: Articulation, bound: bool):
    # bound: the margins the bounds carry (the broad phase's, `Articulation.geom_bound_margin`);
    # else the exact ones.
    g1, g2 = art.pairs[:, 0], art.pairs[:, 1]
    pm, gm = (art.pair_bound_margin, art.geom_bound_margin) if bound else (art.pair_margin, art.geom_margin)
    m1 = np.where(np.isnan(pm), gm[g1], pm)
    m2 = np.where(np.isnan(pm), gm[g2], pm)
    keep = ~(art.geom_is_plane[g1] & art.geom_is_plane[g2])
    return g1[keep], g2[keep], m1[keep], m2[keep]


def _as_pairs(g1, g2) -> np.ndarray:
    out = np.stack([np.minimum(g1, g2), np.maximum(g1, g2)], axis=1).astype(np.int32)
    if len(out) == 0:
        return np.zeros((0, 2), np.int32)
    return np.unique(out, axis=0)


def brute_force_bound_pairs(art: Articulation, body_pos, body_rot, chunk: int = 200_000) -> np.ndarray:
    """All filter-passing geom pairs whose world bounds (inflated by margins) overlap.

    Overlap is the sphere test, the world AABBs' test (each the OBB's world AABB cut to the
    capsule's; against a plane, the corner deepest along its normal) and the 15-axis
    separating-axis test, each with the kernels' rounding slack (``SLACK_REL`` of the sizes plus
    ``SLACK_POS`` of the coordinates). The fast path equals this set up to pairs inside that
    slack: it also culls with body-level bounds (which contain their geoms', up to rounding), and
    the 15 axes can under-state a separation along a world axis (vertex-vertex closest features).
    At ordinary scales the slack is ~1e-12 of a body's size; it becomes visible only for bodies
    below ~1e-6 of their distance to the origin.

    Parameters
    ----------
    art : Articulation
    body_pos : (L, 3) float64
    body_rot : (L, 3, 3) float64
    chunk : int
        Pairs tested per numpy batch (memory bound only).

    Returns
    -------
    pairs : (K, 2) int32
        Lower id first, rows sorted and unique; explicit pairs with their own inflation.
    """
    wb = world_bounds(art, body_pos, body_rot)
    caps = world_capsules(art, body_pos, body_rot)
    g1, g2 = filter_passing_pairs(art)
    m = art.geom_bound_margin
    keep = []
    for s in range(0, len(g1), chunk):
        a, b = g1[s:s + chunk], g2[s:s + chunk]
        keep.append(_bounds_test(wb, a, b, m[a], m[b], art.geom_is_plane, caps))
    keep = np.concatenate(keep) if keep else np.zeros(0, bool)
    e1, e2, em1, em2 = _explicit_margins(art, bound=True)
    ek = _bounds_test(wb, e1, e2, em1, em2, art.geom_is_plane)
    return _as_pairs(np.r_[g1[keep], e1[ek]], np.r_[g2[keep], e2[ek]])


# ------------------------------------------------------------------------------- exact: GJK (hull_distance)

@nb.njit(cache=True)
def _moved(pts, s, e, R, p):
    out = np.empty((e - s, 3))
    for i in range(e - s):
        for r in range(3):
            out[i, r] = p[r] + R[r, 0] * pts[s + i, 0] + R[r, 1] * pts[s + i, 1] + R[r, 2] * pts[s + i, 2]
    return out


@nb.njit(cache=True)
def _pairs_touch(g1, g2, rad, pts, pstart, wrot, wpos, gbody, out):
    for k in range(g1.shape[0]):
        a, b = g1[k], g2[k]
        Pa = _moved(pts, pstart[a], pstart[a + 1], wrot[gbody[a]], wpos[gbody[a]])
        Pb = _moved(pts, pstart[b], pstart[b + 1], wrot[gbody[b]], wpos[gbody[b]])
        upper, lower = gjk_distance(Pa, Pb)
        scale = 0.0
        for i in range(3):
            scale = max(scale, abs(wpos[gbody[a], i]), abs(wpos[gbody[b], i]))
        for i in range(Pa.shape[0]):
            for c in range(3):
                scale = max(scale, abs(Pa[i, c]))
        for i in range(Pb.shape[0]):
            for c in range(3):
                scale = max(scale, abs(Pb[i, c]))
        # Touching within rounding (far below the bounds' 1e-10 guard): decided on the upper bound.
        out[k] = upper <= rad[k] * (1 + 1e-13) + 1e-14 * scale


def brute_force_pairs(art: Articulation, body_pos, body_rot, candidates=None) -> np.ndarray:
    """All filter-passing geom pairs whose exact sets intersect: ``hull(points) ⊕ ball(radius +
    margin)`` of each, by GJK distance (planes: the hull's lowest point against the halfspace).

    Parameters
    ----------
    art : Articulation
    body_pos : (L, 3) float64
    body_rot : (L, 3, 3) float64
    candidates : tuple of two (n,) int arrays, optional
        Test only these pairs (default: every filter-passing pair, plus the explicit pairs). An
        explicit pair among them is inflated by its own ``pair_margin`` where one is given.

    Returns
    -------
    pairs : (K, 2) int32
        Lower id first, rows sorted and unique.
    """
    body_pos, body_rot = _check_poses(art, body_pos, body_rot)
    if candidates is None:
        g1, g2 = filter_passing_pairs(art)
        m1, m2 = art.geom_margin[g1], art.geom_margin[g2]
        e1, e2, em1, em2 = _explicit_margins(art, bound=False)
        g1, g2, m1, m2 = np.r_[g1, e1], np.r_[g2, e2], np.r_[m1, em1], np.r_[m2, em2]
    else:
        g1, g2 = (np.asarray(c, np.int64) for c in candidates)
        m1, m2 = art.geom_margin[g1], art.geom_margin[g2]
        # A candidate that is an explicit pair with its own margin is tested with that margin only,
        # as without candidates and as the broad phase does (the explicit pair replaces the
        # dynamic one). art.pairs are unique rows, lower id first, so their keys are sorted.
        G = len(art.geom_body)
        ekey = art.pairs[:, 0] * G + art.pairs[:, 1]
        key = np.minimum(g1, g2) * G + np.maximum(g1, g2)
        at = np.searchsorted(ekey, key)
        hit = at < len(ekey)
        hit[hit] &= ekey[at[hit]] == key[hit]
        pm = np.full(len(key), np.nan)
        pm[hit] = art.pair_margin[at[hit]]
        given = ~np.isnan(pm)
        m1, m2 = np.where(given, pm, m1), np.where(given, pm, m2)
    is_plane = art.geom_is_plane
    sizes = np.array([0 if c is None else len(c) for c in art.geom_local_cloud])
    pstart = np.r_[0, np.cumsum(sizes)].astype(np.int64)
    pts = np.concatenate([c.points for c in art.geom_local_cloud if c is not None] or [np.zeros((0, 3))])
    crad = np.array([0.0 if c is None else c.radius for c in art.geom_local_cloud])
    touch = np.zeros(len(g1), bool)
    both = ~is_plane[g1] & ~is_plane[g2]
    idx = np.flatnonzero(both)
    res = np.zeros(len(idx), bool)
    rad = crad[g1[idx]] + crad[g2[idx]] + m1[idx] + m2[idx]
    _pairs_touch(g1[idx].astype(np.int64), g2[idx].astype(np.int64), rad, pts, pstart, body_rot, body_pos,
                 art.geom_body.astype(np.int64), res)
    touch[idx] = res
    for k in np.flatnonzero(is_plane[g1] ^ is_plane[g2]):
        gp, gs = (g1[k], g2[k]) if is_plane[g1[k]] else (g2[k], g1[k])
        mp, ms = (m1[k], m2[k]) if is_plane[g1[k]] else (m2[k], m1[k])
        bp_, b = art.geom_body[gp], art.geom_body[gs]
        n, d = world_planes(body_rot[bp_][None], body_pos[bp_][None], art.geom_plane[gp][None], slack=False)
        P = art.geom_local_cloud[gs].points @ body_rot[b].T + body_pos[b]
        low = float(np.min(P @ n[0])) - crad[gs] - ms
        # the plane's offset carries ~eps of its body's position, the points ~eps of theirs (as
        # the GJK branch's relative 1e-14)
        scale = float(np.abs(body_pos[bp_]).sum() + np.abs(P).max() + abs(d[0]))
        touch[k] = low <= d[0] + mp + 1e-14 * scale
    return _as_pairs(g1[touch], g2[touch])
