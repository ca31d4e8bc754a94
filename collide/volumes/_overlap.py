"""Overlap tests between bounding volumes: one pair of any two kinds (`overlap`), and many
pairs at once as parallel arrays (`overlap_spheres`, `overlap_obbs`: numpy; the broad phase's
per-step kernels are separate, these serve setup code and as their reference).

Conservative under rounding: every comparison gets a slack of `OVERLAP_RTOL` times the size of
the numbers compared, so rounding can only report an overlap, never hide one.
"""

from __future__ import annotations

import numpy as np

from .._validate import as_array
from ._kdop import KDOP, _kdop_kdop
from ._records import OVERLAP_RTOL, AABB, OBB, Sphere, _slack

__all__ = ["overlap", "overlap_obbs", "overlap_spheres"]

def _sphere_sphere(a: Sphere, b: Sphere) -> bool:
    d = a.center - b.center
    reach = a.radius + b.radius + _slack(a.center, b.center, a.radius, b.radius)
    return bool(d @ d <= reach * reach)


def _aabb_aabb(a: AABB, b: AABB) -> bool:
    if a.is_empty or b.is_empty:
        return False
    pad = _slack(a.lo, a.hi, b.lo, b.hi)
    return bool(np.all(a.lo <= b.hi + pad) and np.all(b.lo <= a.hi + pad))


def _sphere_aabb(s: Sphere, b: AABB) -> bool:
    if b.is_empty:
        return False
    # Closest point of the box to the centre (RTCD §5.2.5); compare its distance to the radius.
    d = s.center - np.clip(s.center, b.lo, b.hi)
    reach = s.radius + _slack(s.center, s.radius, b.lo, b.hi)
    return bool(d @ d <= reach * reach)


def _sphere_obb(s: Sphere, b: OBB) -> bool:
    # The same in the box's frame (RTCD §5.2.6).
    local = (s.center - b.center) @ b.rotation
    d = local - np.clip(local, -b.half_extents, b.half_extents)
    reach = s.radius + _slack(s.center, s.radius, b.center, b.half_extents)
    return bool(d @ d <= reach * reach)


def _obb_obb(a: OBB, b: OBB) -> bool:
    # Separating-axis test on all 15 axes (Gottschalk 1996; Ericson, Real-Time Collision
    # Detection, 2005, §4.4.1): the 3 + 3 face normals and the 9 edge-edge cross products,
    # written in a's frame. An epsilon added to |R| keeps near-parallel edges, whose cross
    # product is a near-zero (meaningless) axis, from reporting a false separation.
    r = a.rotation.T @ b.rotation            # r[i, j] = a_i . b_j
    t = (b.center - a.center) @ a.rotation   # b's centre in a's frame
    eps = 1e-12
    ar = np.abs(r) + eps
    ha, hb = a.half_extents, b.half_extents
    pad = _slack(a.center, b.center, ha, hb)
    # a's axes
    if np.any(np.abs(t) > ha + ar @ hb + pad):
        return False
    # b's axes
    if np.any(np.abs(t @ r) > ar.T @ ha + hb + pad):
        return False
    # a_i x b_j, i, j in 0..2 (Ericson's nine cases, vectorised): with (i1, i2) the other two
    # indices of i and (j1, j2) those of j,
    #   |t[i2] r[i1, j] - t[i1] r[i2, j]| > ha[i1] ar[i2, j] + ha[i2] ar[i1, j]
    #                                      + hb[j1] ar[i, j2] + hb[j2] ar[i, j1]
    i1, i2 = np.array([1, 2, 0]), np.array([2, 0, 1])
    lhs = np.abs(t[i2][:, None] * r[i1, :] - t[i1][:, None] * r[i2, :])
    rhs = (ha[i1][:, None] * ar[i2, :] + ha[i2][:, None] * ar[i1, :]
           + ar[:, i2] * hb[i1][None, :] + ar[:, i1] * hb[i2][None, :])
    return not bool(np.any(lhs > rhs + pad))


def _as_obb(box: AABB) -> OBB:
    return OBB(box.center, np.eye(3), box.half_extents)


def overlap(a, b) -> bool:
    """Whether two bounding volumes may intersect (closed sets: touching counts).

    Parameters
    ----------
    a, b : AABB, Sphere, OBB or KDOP
        In any combination; the test is symmetric.

    Returns
    -------
    bool
        Exact up to rounding for spheres, AABBs and OBBs, and conservative: comparisons get a
        slack of `OVERLAP_RTOL` times the coordinates' size, so rounding can only report an
        overlap. A k-DOP is tested against another by its shared slabs, and against any other
        kind by its axis slabs (its AABB): conservative, not exact. Empty boxes overlap
        nothing.
    """
    kinds = (AABB, Sphere, OBB, KDOP)
    for name, v in (("a", a), ("b", b)):
        if not isinstance(v, kinds):
            raise ValueError(f"{name}: expected an AABB, Sphere, OBB or KDOP, got {type(v).__name__}")
    if isinstance(a, KDOP) and isinstance(b, KDOP):
        return _kdop_kdop(a, b)
    if isinstance(a, KDOP):
        a = a.aabb()
    if isinstance(b, KDOP):
        b = b.aabb()
    if isinstance(b, Sphere) and not isinstance(a, Sphere):
        a, b = b, a
    if isinstance(a, Sphere):
        if isinstance(b, Sphere):
            return _sphere_sphere(a, b)
        return _sphere_aabb(a, b) if isinstance(b, AABB) else _sphere_obb(a, b)
    if isinstance(a, AABB) and isinstance(b, AABB):
        return _aabb_aabb(a, b)
    if (isinstance(a, AABB) and a.is_empty) or (isinstance(b, AABB) and b.is_empty):
        return False
    return _obb_obb(_as_obb(a) if isinstance(a, AABB) else a, _as_obb(b) if isinstance(b, AABB) else b)


# ----------------------------------------------------------------------------------------------


# Batched forms: many pairs at once, as parallel arrays (numpy; the per-step kernels of the
# broad phase are separate, these serve setup code and as their reference).

def overlap_spheres(center_a, radius_a, center_b, radius_b) -> np.ndarray:
    """Pairwise sphere overlap, ``a[i]`` against ``b[i]`` (same rule as `overlap`).

    Parameters
    ----------
    center_a, center_b : (n, 3) float64
    radius_a, radius_b : (n,) float64
        ``>= 0``.

    Returns
    -------
    overlaps : (n,) bool
    """
    ca = as_array(center_a, "center_a", (None, 3))
    n = len(ca)
    cb = as_array(center_b, "center_b", (n, 3))
    ra = as_array(radius_a, "radius_a", (n,))
    rb = as_array(radius_b, "radius_b", (n,))
    if np.any(ra < 0) or np.any(rb < 0):
        raise ValueError("radius_a, radius_b: must be >= 0")
    size = np.maximum.reduce([np.abs(ca).max(axis=1, initial=0.0), np.abs(cb).max(axis=1, initial=0.0),
                              ra, rb, np.ones(n)])
    reach = ra + rb + OVERLAP_RTOL * size
    return np.sum((ca - cb) ** 2, axis=1) <= reach * reach


def overlap_obbs(center_a, rotation_a, half_a, center_b, rotation_b, half_b) -> np.ndarray:
    """Pairwise OBB overlap, ``a[i]`` against ``b[i]``: the 15-axis test of `overlap`, batched.

    Parameters
    ----------
    center_a, center_b : (n, 3) float64
    rotation_a, rotation_b : (n, 3, 3) float64
        Rotations; columns are the box axes (not checked for orthonormality here).
    half_a, half_b : (n, 3) float64
        Half extents, ``>= 0``.

    Returns
    -------
    overlaps : (n,) bool
        Conservative under rounding, like `overlap`.
    """
    ca = as_array(center_a, "center_a", (None, 3))
    n = len(ca)
    cb = as_array(center_b, "center_b", (n, 3))
    ra_ = as_array(rotation_a, "rotation_a", (n, 3, 3))
    rb_ = as_array(rotation_b, "rotation_b", (n, 3, 3))
    ha, hb = as_array(half_a, "half_a", (n, 3)), as_array(half_b, "half_b", (n, 3))
    if np.any(ha < 0) or np.any(hb < 0):
        raise ValueError("half_a, half_b: must be >= 0")
    r = np.einsum("nki,nkj->nij", ra_, rb_)                  # r[n, i, j] = a_i . b_j
    t = np.einsum("nk,nki->ni", cb - ca, ra_)                 # b's centre in a's frame
    ar = np.abs(r) + 1e-12                                    # Ericson's epsilon, see _obb_obb
    size = np.maximum.reduce([np.abs(ca).max(axis=1, initial=0.0), np.abs(cb).max(axis=1, initial=0.0),
                              ha.max(axis=1, initial=0.0), hb.max(axis=1, initial=0.0), np.ones(n)])
    pad = OVERLAP_RTOL * size
    sep = np.any(np.abs(t) > ha + np.einsum("nij,nj->ni", ar, hb) + pad[:, None], axis=1)
    tb = np.einsum("ni,nij->nj", t, r)                       # b's centre on b's axes
    sep |= np.any(np.abs(tb) > np.einsum("nij,ni->nj", ar, ha) + hb + pad[:, None], axis=1)
    i1, i2 = np.array([1, 2, 0]), np.array([2, 0, 1])
    lhs = np.abs(t[:, i2, None] * r[:, i1, :] - t[:, i1, None] * r[:, i2, :])
    rhs = (ha[:, i1, None] * ar[:, i2, :] + ha[:, i2, None] * ar[:, i1, :]
           + ar[:, :, i2] * hb[:, None, i1] + ar[:, :, i1] * hb[:, None, i2])
    sep |= np.any(lhs > rhs + pad[:, None, None], axis=(1, 2))
    return ~sep
