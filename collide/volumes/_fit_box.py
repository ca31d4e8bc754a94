"""Boxes fitted to a cloud ``hull(points) ⊕ ball(radius)``: the exact AABB, the box with given
axes, and the OBB (``"exact"``, ``"optimal"``, ``"pca"``).

Fitters only choose an orientation; extents are then measured from the points themselves, so
every fitted box contains its cloud by construction (up to rounding, covered by a pad).
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.spatial import ConvexHull

from .. import hull as _hull
from .._validate import as_points, as_radius
from . import _obb_exact as _exact
from ._axes import (_frame_from_normal, _hull_points, _orthonormal, _principal, _right_handed, _same_axes,
                    _surface_pca, pca_axes)
from ._records import _EXACT_ROTATION, _PAD_FLOOR, _ROUNDING_PAD, AABB, OBB, _rotation

__all__ = ["MAX_COORDINATE", "box_from_axes", "fit_aabb", "fit_obb"]

# Largest coordinate (plus radius) the fitters accept (`hull.MAX_COORDINATE`): their squared
# distances and SVDs overflow float64 beyond about 1e154 (1e300 gave "radius: must be finite, got
# inf" and "rotation: not orthonormal", naming nothing the user passed).
MAX_COORDINATE = _hull.MAX_COORDINATE
_require_points = _hull.require_bounded


def fit_aabb(points: np.ndarray, radius: float = 0.0) -> AABB:
    """Exact AABB of ``hull(points) ⊕ ball(radius)``; an empty cloud gives the empty box.

    Parameters
    ----------
    points : (n, 3) float64
    radius : float
    """
    points = as_points(points, "points")
    radius = as_radius(radius, "radius")
    if len(points) == 0:
        return AABB.empty()
    with np.errstate(over="ignore"):
        lo, hi = points.min(axis=0) - radius, points.max(axis=0) + radius
        if radius > 0.0:
            # The sums are rounded to nearest, which can fall an ulp inside the ball's extreme
            # point (0.1 + 0.7 -> 0.7999999999999999): one ulp outward makes the box contain it.
            lo, hi = np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ValueError(f"aabb: coordinates plus radius overflow float64 (largest |coordinate| "
                         f"{float(np.abs(points).max()):.3g}, radius {radius:.3g})")
    return AABB(lo, hi)


def box_from_axes(points: np.ndarray, radius: float, rotation: np.ndarray) -> OBB:
    """The smallest box with the given axes that contains the cloud.

    Parameters
    ----------
    points : (n, 3) float64
    radius : float
    rotation : (3, 3) float64
        Orthonormal (within `ROTATION_TOL`: the nearest rotation is used); columns are the axes.
    """
    points = as_points(points, "points")
    radius = as_radius(radius, "radius")
    _require_points(points, "points", radius)
    rotation = _rotation(rotation, "rotation")
    if float(np.abs(rotation.T @ rotation - np.eye(3)).max()) > _EXACT_ROTATION:
        rotation = _orthonormal(rotation)  # the axes are a choice: take the nearest orthonormal ones
    local = points @ rotation
    lo, hi = local.min(axis=0), local.max(axis=0)
    center = rotation @ ((lo + hi) / 2.0)
    return OBB(center, rotation, (hi - lo) / 2.0 + radius)


def _box_volumes(points: np.ndarray, rots: np.ndarray, radius: float) -> np.ndarray:
    # Volumes (k,) of the boxes with axes rots (k, 3, 3) around points (n, 3): one BLAS
    # product against all 3k axes, then contiguous column reductions.
    proj = points @ rots.transpose(0, 2, 1).reshape(-1, 3).T
    ext = (proj.max(axis=0) - proj.min(axis=0)).reshape(-1, 3)
    return np.prod(ext + 2.0 * radius, axis=1)


# The 26 directions of the compass (pattern) search on rotation vectors.
_COMPASS = np.array([[x, y, z] for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1)
                     if (x, y, z) != (0, 0, 0)], dtype=np.float64)
_COMPASS /= np.linalg.norm(_COMPASS, axis=1)[:, None]


@numba.njit(cache=True)
def _nb_volume(points, rot, radius, index, count):
    # Volume of the box with axes ``rot`` around points[index[:count]].
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for t in range(count):
        i = index[t]
        for a in range(3):
            p = points[i, 0] * rot[0, a] + points[i, 1] * rot[1, a] + points[i, 2] * rot[2, a]
            lo[a] = min(lo[a], p)
            hi[a] = max(hi[a], p)
    w = 2.0 * radius
    return (hi[0] - lo[0] + w) * (hi[1] - lo[1] + w) * (hi[2] - lo[2] + w)


@numba.njit(cache=True)
def _nb_polish(points, rot, radius, step, min_step, max_iter, compass):
    # Compass search on SO(3) (Kolda, Lewis & Torczon 2003, "Optimization by direct search",
    # SIAM Review 45): try the 26 body-frame rotations by angle ``step``, move to the best one
    # if it shrinks the box, else halve the step. Only points that can become extreme are
    # evaluated: turning a unit axis by angle t moves p's projection by at most t |p|, so a
    # point more than 2 t max|p| inside both extremes of every axis cannot reach one.
    n = points.shape[0]
    every = np.arange(n)
    best = _nb_volume(points, rot, radius, every, n)
    rmax = 0.0
    for i in range(n):
        rmax = max(rmax, np.sqrt(points[i, 0] ** 2 + points[i, 1] ** 2 + points[i, 2] ** 2))
    proj = np.empty((n, 3))
    near = np.empty(n, dtype=np.int64)
    cand = np.empty((3, 3))
    best_cand = np.empty((3, 3))
    k = compass.shape[0]
    for _ in range(max_iter):
        if step < min_step:
            break
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for i in range(n):
            for a in range(3):
                p = points[i, 0] * rot[0, a] + points[i, 1] * rot[1, a] + points[i, 2] * rot[2, a]
                proj[i, a] = p
                lo[a] = min(lo[a], p)
                hi[a] = max(hi[a], p)
        reach = 2.0 * step * rmax * (1.0 + 1e-9)
        count = 0
        for i in range(n):
            for a in range(3):
                if proj[i, a] >= hi[a] - reach or proj[i, a] <= lo[a] + reach:
                    near[count] = i
                    count += 1
                    break
        s, c = np.sin(step), np.cos(step)
        found = -1.0
        for j in range(k):
            # Rodrigues: R = I + s K + (1 - c) K^2 for the unit axis compass[j].
            x, y, z = compass[j, 0], compass[j, 1], compass[j, 2]
            r = np.array([[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
                          [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
                          [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]])
            for a in range(3):
                for b in range(3):
                    cand[a, b] = rot[a, 0] * r[0, b] + rot[a, 1] * r[1, b] + rot[a, 2] * r[2, b]
            v = _nb_volume(points, cand, radius, near, count)
            if v < best * (1.0 - 1e-12) and (found < 0.0 or v < found):
                found = v
                best_cand[:, :] = cand
        if found >= 0.0:
            rot = best_cand.copy()
            best = found
        else:
            step *= 0.5
    return rot, best


_FACE_CANDIDATES = 12
_POLISH_STARTS = 3
_POLISH_STEP = 0.1
_POLISH_MIN_STEP = 1e-5
# The "optimal" OBB is the exact one for hulls of up to _EXACT_HULL vertices. Larger hulls get
# _SUBSET_ROUNDS rounds of the exact search (to a relative _SUBSET_TOL) on their vertices
# extreme along 13 directions and the _SEED_SUPPORTS most extreme along each axis of the best
# _POLISH_STARTS starting boxes (_obb_exact.exact_axes): its box where it is certified minimal
# for the whole hull, else one more start, polished first. Chosen with tests/bench/fitting.py
# (the ablation in fitting.txt).
_EXACT_HULL = 64
_SUBSET_ROUNDS = 1
_SUBSET_TOL = 1e-6
_SEED_SUPPORTS = 1


# Box evaluations the "optimal" fitter gives the exact search of a small hull (see
# _optimal_rotation); round hulls need far fewer, near-flat ones more.
_EXACT_BUDGET = 300_000


def _optimal_rotation(verts: np.ndarray, hull: "ConvexHull | None", radius: float,
                      rounding: float = 0.0) -> np.ndarray:
    # verts: hull vertices, centred; hull: Qhull's hull of a superset of verts in the same frame
    # (None for degenerate clouds); rounding: as `_axes._principal`'s.
    # Returns the rotation of a box within 1 % of the minimum
    # volume on every cloud tested (the rule is in fit_obb's docstring): a minimal box often has
    # a face flush with a hull face (the face candidates), otherwise two adjacent faces flush
    # with hull edges (O'Rourke 1985), which the exact search on a subset and the polish reach.
    # The exact search within a budget of box evaluations: its branch and bound splits in
    # proportion to 1 / thickness on near-flat hulls. Out of
    # budget, its best box joins the starts below (which include the box flush with the slab's
    # face) and the polish.
    exact_rot = None
    if len(verts) <= _EXACT_HULL:
        exact_rot, certified = _exact_rotation(verts, radius, budget=_EXACT_BUDGET, rounding=rounding)
        if certified:
            return exact_rot
    axes, rank = _principal(verts, rounding)
    if rank <= 1:
        return _right_handed(axes.T)
    if rank == 2:
        # Exact minimal-area rectangle; with a radius the box has thickness 2 r and a slight
        # tilt can trade it against area, so polish then.
        rot = _right_handed(_frame_from_normal(axes[2], verts))
        if radius > 0.0:
            rot = _orthonormal(_nb_polish(np.ascontiguousarray(verts), rot, float(radius), _POLISH_STEP,
                                          _POLISH_MIN_STEP, 1000, _COMPASS)[0])
        return rot
    starts = [_right_handed(axes.T)]
    if hull is not None:
        starts.append(_surface_pca(hull.points, hull.simplices))
        normals = hull.equations[:, :3]
        tri = hull.points[hull.simplices]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        # Qhull splits a planar face into triangles with (nearly) equal normals: merge them.
        _, group = np.unique(np.round(normals, 6), axis=0, return_inverse=True)
        group = group.ravel()
        group_area = np.bincount(group, weights=area)
        group_normal = np.zeros((len(group_area), 3))
        np.add.at(group_normal, group, area[:, None] * normals)
        for g in np.argsort(-group_area)[:_FACE_CANDIDATES]:
            norm = float(np.linalg.norm(group_normal[g]))
            if norm > 0.0:
                starts.append(_right_handed(_frame_from_normal(group_normal[g] / norm, verts)))
    if exact_rot is not None:
        starts.append(exact_rot)
    vols = _box_volumes(verts, np.stack(starts), radius)
    order = np.argsort(vols, kind="stable")
    if _SUBSET_ROUNDS > 0 and exact_rot is None:
        # The exact search on the vertices extreme along 13 directions and near the faces of
        # the best starting boxes: its box is the exact one where it is certified minimal for
        # the whole hull, and otherwise one more start.
        sub_rot, certified = _exact_rotation(verts, radius, _SUBSET_ROUNDS, 0, _SUBSET_TOL,
                                             [starts[k] for k in order[:_POLISH_STARTS]], rounding=rounding)
        if certified:
            return sub_rot
        starts.append(sub_rot)
        order = np.r_[len(starts) - 1, order]
    chosen: list[np.ndarray] = []
    for k in order:
        if len(chosen) == _POLISH_STARTS:
            break
        if not any(_same_axes(starts[k], c) for c in chosen):
            chosen.append(starts[k])
    best_rot, best_vol = chosen[0], np.inf
    pts = np.ascontiguousarray(verts)
    for rot in chosen:
        rot, vol = _nb_polish(pts, np.ascontiguousarray(rot), float(radius), _POLISH_STEP,
                              _POLISH_MIN_STEP, 1000, _COMPASS)
        if vol < best_vol:
            best_rot, best_vol = rot, vol
    return _orthonormal(best_rot)


def _exact_rotation(verts: np.ndarray, radius: float, rounds: int | None = None,
                    direct: int = _exact.DIRECT, tol: float = _exact.TOL, seeds=(),
                    budget: int = -1, rounding: float = 0.0) -> tuple[np.ndarray, bool]:
    # verts: hull vertices (centred by the caller); rounding: as `_axes._principal`'s.
    # Rotation of the minimum-volume box of
    # hull(verts) ⊕ ball(radius) and whether it is certified (always, unless ``rounds`` limits
    # the subset rounds of _obb_exact.exact_axes). By cases of the affine rank:
    # 0: any box is a cube of side 2r. 1: the segment's axis; of every box of a segment of
    # length L, prod(L |d . u_i| + 2r) is least along it (the sum of the logs is concave and
    # increasing in each |d . u_i|, whose sum is >= 1, so its least value on the simplex, at a
    # vertex, bounds it). 2 with r = 0: volume 0 with the plane's normal as an axis, and among
    # those the least area (the minimal rectangle, as the "optimal" fitter). Otherwise the
    # exact search of _obb_exact over the hull's (or the polygon's) Gauss map.
    axes, rank = _principal(verts, rounding)
    if rank <= 1:
        return _right_handed(axes.T), True
    if rank == 2 and radius == 0.0:
        return _right_handed(_frame_from_normal(axes[2], verts)), True
    c = verts.mean(axis=0)
    scale = float(np.abs(verts - c).max())
    local = (verts - c) / scale
    # In units of the hull's size; beyond 1e15 every orientation's volume is (2r)^3 within
    # rounding (the widths change it by 3e-15 at most), and the cap keeps the cubes finite.
    r = min(radius / scale, 1e15)
    if rank == 2:
        start = _right_handed(_frame_from_normal(axes[2], verts))
        rot, _, certified = _exact.exact_axes(local, r, start, lambda sub: _exact.flat_graph(sub, axes),
                                              rounds, direct, tol, seeds, _SEED_SUPPORTS, budget)
    else:
        rot, _, certified = _exact.exact_axes(local, r, _right_handed(axes.T), _exact.solid_graph,
                                              rounds, direct, tol, seeds, _SEED_SUPPORTS, budget)
    return _orthonormal(rot), certified


def fit_obb(points: np.ndarray, radius: float = 0.0, method: str = "optimal") -> OBB:
    """Oriented box of ``hull(points) ⊕ ball(radius)``.

    Parameters
    ----------
    points : (n, 3) float64
        Non-empty.
    radius : float
        The cloud's radius, ``>= 0``.
    method : {"optimal", "exact", "pca"}
        ``"exact"``: the minimum volume, exact up to rounding (relative 1e-12), by O'Rourke's
        theorem (1985: a minimal box has two adjacent faces flush with hull edges; it holds for
        ``prod(e_i + 2 radius)`` too, see collide/volumes/_obb_exact.py) and a certified branch and
        bound over its edge-pair families, on the hull's vertices; hulls of more than 64
        vertices through subsets of them with a certificate of optimality. ``O(E^2)`` pair
        screening plus about ``E^1.5`` evaluations (``E`` hull edges) for hulls with evenly
        spread faces, ``O(n^3)`` at worst (``n`` hull vertices). Slow cases: near-flat hulls
        take time in proportion to 1 / thickness (smallest over largest principal spread), and
        highly symmetric hulls (prisms over regular polygons) approach the worst case.
        ``"optimal"`` (the
        default): the exact box where the hull has at most 64 vertices and its search ends
        within 300,000 box evaluations (near-flat hulls may not: their best box so far then
        joins the local search's starts below, with the box flush with the slab's face).
        Otherwise one round of the exact
        search on a subset of the hull's vertices (those extreme along 13 directions and near
        the faces of the best starting boxes below): its box if it is certified minimal for the
        whole hull; else it joins the starts (the PCA axes, the hull surface's principal axes
        and boxes flush with the largest hull faces, each with its minimal-area rectangle by
        rotating calipers), and the best three are polished by a compass search on rotations.
        Within 1 % of the exact box on every cloud tested (tests/test_obb_exact.py,
        tests/bench/fitting.txt). ``"pca"``: principal axes of the hull vertices. Flat clouds
        (``radius = 0``) get a zero extent and their exact minimal-area rectangle.

    Returns
    -------
    OBB
        The method only picks the axes (a right-handed rotation); the centre and half extents
        are then measured from the points, plus ``radius``, so the box always contains the
        cloud. Degenerate clouds give boxes with zero extents (plus ``radius``).
    """
    points = as_points(points, "points")
    radius = as_radius(radius, "radius")
    _require_points(points, "obb", radius)
    if method not in ("optimal", "exact", "pca"):
        raise ValueError(f"method: expected 'optimal', 'exact' or 'pca', got {method!r}")
    # Centre first: Qhull and the SVD lose precision on coordinates far from the origin.
    offset = 0.5 * (points.min(axis=0) + points.max(axis=0))
    local = points - offset
    # The axes are chosen on the cloud scaled to unit size by a power of two (exact): a 1e-160
    # cloud's squares and products underflow, and its rotations came out not orthonormal. The
    # radius scales with it (capped where it dwarfs the cloud: any axes then do).
    e = int(np.frexp(float(np.abs(local).max()))[1])
    unit = np.ldexp(local, -e)
    unit_radius = min(float(np.ldexp(radius, -e)), 1e15)
    # The coordinates' own rounding, in these units: a spread at its level is no shape (`_principal`).
    rounding = float(np.ldexp(float(np.abs(points).max()), -e))
    verts, hull = _hull_points(unit, rounding)
    if method == "pca":
        rot = pca_axes(verts)
    elif method == "exact":
        rot = _exact_rotation(verts, unit_radius, rounding=rounding)[0]
    else:
        rot = _optimal_rotation(verts, hull, unit_radius, rounding)
    # Extents from every point, not only the hull vertices: _hull_points (axes only) treats
    # thickness below ~1e-12 of the spread as flat and drops it, the box must not.
    box = box_from_axes(local, radius, rot)
    # A few ulps of the coordinates' size: moving the centre back by ``offset`` and a later
    # containment test in world coordinates each round by about eps * |x| (DESIGN.md: a tiny
    # conservative inflation rather than an exact comparison that rounding can break).
    # The radius too: half extent + radius rounds by up to an ulp of the radius.
    pad = _ROUNDING_PAD * (float(np.abs(offset).max()) + float(np.abs(local).max()) + radius) + _PAD_FLOOR
    return OBB(box.center + offset, box.rotation, box.half_extents + pad)


# ----------------------------------------------------------------------------------------------
# Fitting: spheres
