"""The narrow phase's warm start across calls (`collide._kernels.warm`, `collide._kernels.epa.epa_warm`).

A pair of point clouds found penetrating takes a slot; from its next call on it keeps its last
EPA polytope as vertex indices, and the call after rebuilds it at the new poses and takes its
certified answer, or runs GJK and EPA as before; it leaves the slot once apart. The answers then
differ from a cold call's within the contact tolerance (not bit for bit), and the cache is a hint
only: whatever it holds, the answers stay certified. Pairs that never penetrate never use a row.
"""

from __future__ import annotations

import copy
import math
import pickle

import mujoco
import numpy as np
import pytest

import collide.mujoco as cm
from collide._kernels import epa as ke
from collide._kernels.manifold import CONTACT_TOL
from collide._kernels.support import POINTS
from collide._kernels.warm import (SEP_LEN, SEP_ROW, SEP_SLOTS, WARM_HITS, WARM_KEYS, WARM_LEN, WARM_ROWS,
                                   WARM_SLOTS, WARM_TRIES, warm_slot)
from contact_check import MODELS

SCENES = sorted(p.name for p in MODELS.iterdir() if (p / "scene.xml").is_file()) if MODELS.is_dir() else []
needs_models = pytest.mark.skipif(not SCENES, reason=f"the test models are not present at {MODELS}")


def _cache(col: cm.Collider) -> np.ndarray:
    return col.table._wsi[-WARM_LEN:]  # the scratch's tail (`collide._kernels.manifold.scratch_sizes`)


def _sep(col: cm.Collider) -> np.ndarray:
    # the separation cache, before the warm-start cache: (SEP_SLOTS, SEP_ROW) int64
    return col.table._wsi[-WARM_LEN - SEP_LEN:-WARM_LEN].reshape(SEP_SLOTS, SEP_ROW)


def _empty(col: cm.Collider) -> None:
    # both caches emptied: the call after is cold
    col.table._wsi[-WARM_LEN - SEP_LEN:] = 0


def _deepest(c) -> dict:
    # Per geom pair: (deepest dist, its normal, contacts).
    out = {}
    for i, g in enumerate(map(tuple, c.geom.tolist())):
        if g not in out or c.dist[i] < out[g][0]:
            out[g] = (float(c.dist[i]), c.normal[i].copy(), out.get(g, (0, 0, 0))[2] + 1)
        else:
            out[g] = (out[g][0], out[g][1], out[g][2] + 1)
    return out


def _compare(warm, cold, size) -> tuple[float, float]:
    # Same pairs; each pair's deepest dist within both answers' tolerance (each is within
    # CONTACT_TOL * (size1 + size2) of the truth); normals within 1e-3 rad. Returns the worst.
    dw, dc = _deepest(warm), _deepest(cold)
    assert dw.keys() == dc.keys()
    worst_d = worst_a = 0.0
    for g, (d, n, _) in dw.items():
        e = abs(d - dc[g][0])
        assert e <= 2.0 * CONTACT_TOL * (size[g[0]] + size[g[1]]) + 1e-12, (g, d, dc[g][0])
        a = float(np.arccos(np.clip(n @ dc[g][1], -1.0, 1.0)))
        assert a <= 1e-3, (g, n, dc[g][1])
        worst_d, worst_a = max(worst_d, e), max(worst_a, a)
    return worst_d, worst_a


def _steps(name: str, steps: int, seed: int = 0, hold: int = 10):
    model = mujoco.MjModel.from_xml_path(str(MODELS / name / "scene.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ctrls = cm._random_controls(model, steps, seed, hold)
    for step in range(steps):
        if step % hold == 0 and len(ctrls):
            data.ctrl[:] = ctrls[step // hold]
        mujoco.mj_step(model, data)
        yield model, data


@needs_models
@pytest.mark.parametrize("scene", SCENES)
def test_warm_agrees_with_cold(scene):
    """Every model, 200 steps: a Collider that keeps its cache against one emptied before each
    call (cold, as before the warm start)."""
    warm = cold = None
    n = 0
    for model, data in _steps(scene, 200):
        if warm is None:
            warm, cold = cm.Collider(model), cm.Collider(model)
        cw = warm.contacts(data)
        _empty(cold)
        cc = cold.contacts(data)
        _compare(cw, cc, warm.table.size)
        n += len(cc)
    hits, tries = _cache(warm)[WARM_HITS], _cache(warm)[WARM_TRIES]
    assert hits <= tries and _cache(cold)[WARM_HITS] == 0
    if scene == "cube_3x3x3":
        # the scene had real contacts, and the warm path answered most of its penetrating pairs
        assert n > 10000 and hits > 5000 and hits > 0.5 * tries


@needs_models
def test_garbage_cache_still_certified():
    """Rows of random indices, rows of valid-looking polytopes at random, and another model's
    cache: answers as a cold call's (the rows are checked and declined, or certified). Every
    candidate pair's key is set first, so that every pair of two point clouds reads its row."""
    rng = np.random.default_rng(7)
    other = None
    for model, data in _steps("kinova_gen3", 60):
        if other is None:
            other = cm.Collider(model)
        other.contacts(data)
    assert _cache(other)[WARM_TRIES] > 0  # the foreign cache holds polytopes
    warm = cold = None
    steps = read = 0
    for model, data in _steps("cube_3x3x3", 120, seed=3):
        if warm is None:
            warm, cold = cm.Collider(model), cm.Collider(model)
        cache = _cache(warm)
        rows = cache[WARM_ROWS:].reshape(WARM_SLOTS, ke.ENTRY)
        for g1, g2 in warm.pairs(data).tolist():
            key = g1 * model.ngeom + g2 + 1
            cache[WARM_KEYS + warm_slot(key)] = key
        kind = steps % 3
        if kind == 0:  # random everything
            rows[:] = rng.integers(-2**40, 2**40, size=(WARM_SLOTS, ke.ENTRY))
            rows[:, ke.E_NV] = rng.integers(0, 20, size=WARM_SLOTS)
            rows[:, ke.E_NF] = rng.integers(0, 30, size=WARM_SLOTS)
        elif kind == 1:  # in-range vertex indices (cube meshes: 8 vertices), random faces
            nv = rng.integers(4, ke.WARM_NV + 1, size=WARM_SLOTS)
            rows[:, ke.E_NV] = nv
            rows[:, ke.E_NF] = rng.integers(4, ke.WARM_NF + 1, size=WARM_SLOTS)
            ia = rng.integers(0, 8, size=(WARM_SLOTS, ke.WARM_NV))
            ib = rng.integers(0, 8, size=(WARM_SLOTS, ke.WARM_NV))
            rows[:, ke.E_VERT:ke.E_FACE] = ia | (ib << 32)
            f = rng.integers(0, 4, size=(WARM_SLOTS, ke.WARM_NF, 3))  # small: closed tetrahedra happen
            rows[:, ke.E_FACE:] = f[..., 0] | (f[..., 1] << 8) | (f[..., 2] << 16)
        else:  # another model's cache
            cache[:] = _cache(other)
        t0 = cache[WARM_TRIES]
        cw = warm.contacts(data)
        if kind != 2:
            read += cache[WARM_TRIES] - t0
        _empty(cold)
        _compare(cw, cold.contacts(data), warm.table.size)
        steps += 1
    assert steps == 120 and read > 1000  # garbage rows were read


@needs_models
def test_only_penetrating_pairs_hold_a_slot():
    """pal_talos (meshes, mostly apart): after each call, every pair of the call that holds a
    slot penetrates (a contact with dist < 0), and no row was written but those of slots that
    some pair held: the pairs that stay apart take the cold query and leave the rows alone."""
    col = None
    held_ever = set()
    held_now = apart = 0
    for model, data in _steps("pal_talos", 150):
        if col is None:
            col = cm.Collider(model)
            G = model.ngeom
            eligible = col.table.kind == POINTS
        c = col.contacts(data)
        cache = _cache(col)
        deep = {g1 * G + g2 + 1 for (g1, g2), d in zip(c.geom.tolist(), c.dist) if d < 0.0}
        for g1, g2 in col.pairs(data).tolist():
            key = g1 * G + g2 + 1
            held = cache[WARM_KEYS + warm_slot(key)] == key
            assert not held or key in deep, (g1, g2)
            held_now += held
            apart += bool(eligible[g1] and eligible[g2] and max(col.table.pts_num[[g1, g2]]) > 2 and key not in deep)
        held_ever |= set(np.flatnonzero(cache[WARM_KEYS:WARM_ROWS]).tolist())
    rows = cache[WARM_ROWS:].reshape(WARM_SLOTS, ke.ENTRY)
    assert set(np.flatnonzero(rows.any(axis=1)).tolist()) <= held_ever
    assert held_now > 10 and apart > 500  # the scene had penetrating pairs and many apart


def test_tetrahedron_rows_inside_out_are_declined():
    """A closed surface seen from outside (the origin not within it) and an open one are declined;
    the same closed tetrahedron around the origin is certified."""
    pts_a = np.array([[1.0, 0, 0], [-1, 1, 0], [-1, -1, 0.1], [0, 0, 1.5], [0, 0, -1.5]])
    pts_b = np.zeros((1, 3))
    eye = np.eye(3)
    none = np.zeros(1, np.int32)

    def shape(p, pos):
        return (0, np.zeros(4), p, none, none, eye, np.asarray(pos, float))

    row = np.zeros(ke.ENTRY, np.int64)
    faces = [(0, 1, 3), (1, 2, 3), (2, 0, 3), (1, 0, 4), (2, 1, 4), (0, 2, 4)]  # a bipyramid, outward

    def fill(fs, verts=range(5)):
        row[ke.E_NV] = len(list(verts))
        row[ke.E_NF] = len(fs)
        for i, v in enumerate(verts):
            row[ke.E_VERT + i] = v  # index in A, 0 in B
        for k, (a, b, c) in enumerate(fs):
            row[ke.E_FACE + k] = a | (b << 8) | (c << 16)

    res = np.empty(13)
    ws = (np.empty(ke.WARM_F), np.empty(ke.WARM_I, np.int64))  # epa_warm's scratch
    # orient the faces outward as the kernel defines it (counter-clockwise from outside)
    fs = []
    for a, b, c in faces:
        n = np.cross(pts_a[b] - pts_a[a], pts_a[c] - pts_a[a])
        fs.append((a, b, c) if n @ pts_a[a] > 0 else (a, c, b))
    fill(fs)
    st, _ = ke.epa_warm(shape(pts_a, [0, 0, 0]), shape(pts_b, [0, 0, 0]), row, 1e-9, res, *ws)
    assert st == ke.CONVERGED or st == ke.WARM_MISS  # converged only where a face is the hull's
    st_out, _ = ke.epa_warm(shape(pts_a, [0, 0, 0]), shape(pts_b, [5, 0, 0]), row, 1e9, res, *ws)
    assert st_out == ke.WARM_MISS  # origin outside: faces behind it
    fill(fs[:-1])
    assert ke.epa_warm(shape(pts_a, [0, 0, 0]), shape(pts_b, [0, 0, 0]), row, 1e9, res, *ws)[0] == ke.WARM_MISS
    fill(fs)
    row[ke.E_VERT] = 5  # out of A's range
    assert ke.epa_warm(shape(pts_a, [0, 0, 0]), shape(pts_b, [0, 0, 0]), row, 1e9, res, *ws)[0] == ke.WARM_MISS
    fill(fs)
    st, _ = ke.epa_warm(shape(pts_a, [0, 0, 0]), shape(pts_b, [0, 0, 0]), row, 1e9, res, *ws)
    assert st == ke.CONVERGED and res[1] < 0 and res[0] <= res[1] + 1e-12  # a loose tolerance: certified
    # the bracket holds: the true depth of the origin in hull(pts_a) (its nearest face plane)
    from scipy.spatial import ConvexHull
    h = ConvexHull(pts_a)
    depth = float(np.min(-h.equations[:, 3]))
    assert res[0] - 1e-12 <= -depth <= res[1] + 1e-12


@needs_models
def test_copies_get_their_own_cache():
    gen = _steps("cube_3x3x3", 30)
    model, data = next(gen)
    col = cm.Collider(model)
    for _, data in gen:
        col.contacts(data)
    assert _cache(col)[WARM_TRIES] > 0
    for t in (copy.copy(col.table), copy.deepcopy(col.table), pickle.loads(pickle.dumps(col.table))):
        assert not np.shares_memory(t._wsi, col.table._wsi)
        assert not np.any(t._wsi[-WARM_LEN:])


# ---- the separation cache (`collide._kernels.warm.sep_test`): pairs kept apart along a direction

def _sep_shape(rng, k):
    # a convex set of each kind the narrow phase runs GJK on: a point cloud with a radius (a mesh,
    # a box), a flat and a collinear cloud, and the exact curved primitives
    from collide import Cone, Cylinder, Ellipsoid, PointCloud
    j = k % 6
    if j == 0:
        return PointCloud(rng.normal(size=(30, 3)), rng.uniform(0.0, 0.2))
    if j == 1:
        return PointCloud(rng.normal(size=(12, 3)) * [1.0, 1.0, 0.0], 0.0)  # flat
    if j == 2:
        return PointCloud(np.outer(rng.normal(size=5), rng.normal(size=3)), rng.uniform(0.0, 0.3))  # collinear
    if j == 3:
        return Cylinder(rng.uniform(0.2, 1.0), rng.uniform(0.2, 1.0))
    if j == 4:
        return Cone(rng.uniform(0.2, 1.0), rng.uniform(0.2, 2.0))
    return Ellipsoid(rng.uniform(0.2, 1.0, 3))


def test_separation_rows_are_certificates():
    """A row's direction settles a pair only when the pair is apart beyond ``thr``: random pairs
    of every kind at their exact distance ``D``, ``thr`` just below, at and above it (down to 1e-12
    of the size), directions the exact normal tilted by 0 to 1e-2 rad, reversed, and garbage
    (zero, NaN, huge): whenever `sep_test` answers apart, ``thr`` is below the exact distance's
    certified upper bound, and the kept row (`sep_keep`) of the exact answer settles the pair
    while ``thr`` stays a little below ``D``."""
    from collide._kernels import distance as kd
    from collide._kernels import warm as kw
    from collide.support import support_data
    from collide.testing.surfaces import random_rotation

    rng = np.random.default_rng(52)
    sep = np.zeros(SEP_LEN, np.int64)
    sepf = sep.view(np.float64)
    pa, pb = np.zeros(3), np.zeros(3)
    out = np.empty(kd.OUT_SIZE)
    key = 12345
    o = warm_slot(key) * SEP_ROW
    answers = {True: 0, False: 0}
    kept = 0
    for k in range(600):
        da, db = support_data(_sep_shape(rng, k)), support_data(_sep_shape(rng, k // 6))
        ra, rb = random_rotation(rng), random_rotation(rng)
        ta = rng.normal(size=3)
        tb = ta + rng.normal(size=3) * rng.uniform(0.5, 4.0)
        sa, sb = da.posed(ra, ta), db.posed(rb, tb)
        size = da.size + db.size
        kd.pair_distance(sa, sb, 1e-12 * size, np.zeros(3), -1, -1, 128, out)
        D, upper, n = out[kd.OUT_DISTANCE], out[kd.OUT_UPPER], out[kd.OUT_NORMAL:kd.OUT_NORMAL + 3].copy()
        exact = out.copy()
        for delta in (1e-2, 1e-9, 1e-12, 0.0, -1e-12, -1e-3):
            thr = D - delta * size
            for tilt in (0.0, 1e-8, 1e-4, 1e-2, math.pi, -1.0, -2.0, -3.0):
                if tilt == -1.0:
                    u = np.zeros(3)
                elif tilt == -2.0:
                    u = np.full(3, np.nan)
                elif tilt == -3.0:
                    u = n * 1e300
                else:
                    w = np.cross(n, rng.normal(size=3))
                    u = math.cos(tilt) * n + math.sin(tilt) * w / np.linalg.norm(w)
                sep[o] = key
                sepf[o + 1:o + 4] = u
                sep[o + 4] = int(rng.integers(-2**62, 2**62))  # any hints
                apart = kw.sep_test(sep, key, sa, sb, thr, pa, pb)
                answers[apart] += 1
                if apart:
                    assert thr < upper and tilt >= 0.0, (k, delta, tilt, D, thr)
        if D > 0.0:  # the row kept from the exact answer settles the pair below D
            kw.sep_keep(sep, key, exact)
            kept += kw.sep_test(sep, key, sa, sb, D - 1e-6 * size, pa, pb)
        sep[o] = key + 1  # another pair's row: not read
        assert not kw.sep_test(sep, key, sa, sb, -1e300, pa, pb)
    assert answers[True] > 1000 and answers[False] > 1000 and kept > 400, (answers, kept)


def _apart_rows(col: cm.Collider, pairs, G: int) -> set:
    # the pairs of the call that hold a row of the separation cache
    rows = _sep(col)
    keys = {g1 * G + g2 + 1 for g1, g2 in pairs.tolist()}
    return {int(rows[s, 0]) for s in range(SEP_SLOTS) if rows[s, 0] in keys}


def _as_cold(col: cm.Collider, cold: cm.Collider, data):
    # col's contacts with its kept polytopes dropped (their answers differ from a cold call's by
    # the tolerance) and its separation rows kept, against cold's with both caches emptied: bit
    # for bit the same. Returns col's.
    _cache(col)[:] = 0
    c = col.contacts(data)
    _empty(cold)
    cc = cold.contacts(data)
    for f in ("geom", "dist", "pos", "normal", "margin"):
        assert np.array_equal(getattr(c, f), getattr(cc, f)), f
    return c


@needs_models
def test_separation_rows_settle_the_pairs_that_stay_apart():
    """shadow_hand (curved geoms and meshes, mostly apart): the pairs that GJK found apart hold
    rows, none in contact does, and the contacts are a cold call's bit for bit; the same state
    again is settled by the rows (read, not rewritten: a mark in their directions survives)."""
    col = cold = None
    for model, data in _steps("shadow_hand", 120):
        if col is None:
            col, cold = cm.Collider(model), cm.Collider(model)
            G = model.ngeom
        c = _as_cold(col, cold, data)
        pairs = col.pairs(data)
        touching = {g1 * G + g2 + 1 for g1, g2 in c.geom.tolist()}
        held = _apart_rows(col, pairs, G)
        assert not held & touching
    assert len(c) > 0 and len(held) > 5  # real contacts, and pairs held apart
    rows = _sep(col)
    rowsf = rows.view(np.float64)
    scale = 1.0 + 2.0 ** -30  # a mark: GJK's normals are unit within rounding
    for s in range(SEP_SLOTS):
        if rows[s, 0] in held:
            rowsf[s, 1:4] *= scale
    marked = rowsf[:, 1:4].copy()
    again = col.contacts(data)
    _compare(again, c, col.table.size)
    settled = sum(1 for s in range(SEP_SLOTS) if rows[s, 0] in held and np.array_equal(rowsf[s, 1:4], marked[s]))
    assert settled >= 0.9 * len(held), (settled, len(held))


@needs_models
def test_garbage_separation_rows_still_certified():
    """Every candidate pair's key set, with random directions (some settle pairs: they are
    separating planes of pairs far enough apart), garbage ones and random hints: the contacts are
    a cold call's, bit for bit."""
    rng = np.random.default_rng(5)
    col = cold = None
    steps = n = 0
    for model, data in _steps("shadow_hand", 90, seed=2):
        if col is None:
            col, cold = cm.Collider(model), cm.Collider(model)
            G = model.ngeom
        rows = _sep(col)
        rowsf = rows.view(np.float64)
        for g1, g2 in col.pairs(data).tolist():
            key = g1 * G + g2 + 1
            s = warm_slot(key)
            rows[s, 0] = key
            u = rng.normal(size=3)
            rowsf[s, 1:4] = (u / np.linalg.norm(u)) if steps % 3 else rng.choice([0.0, np.nan, 1e300, 0.6], 3)
            rows[s, 4] = int(rng.integers(-2**62, 2**62))
        n += len(_as_cold(col, cold, data))
        steps += 1
    assert steps == 90 and n > 50
