"""Adversarial checks of the narrow phase's warm start across calls (4143c45: `collide._kernels.warm`,
`collide._kernels.epa.epa_warm`): a warm answer equals a cold one (same pairs, contact counts, deepest
dist within the contact tolerance, normals within 1e-3 rad) whatever the cache holds, and a kept
polytope's certified answer is as good as EPA's: its distance within the tolerance of the exact one
(`collide.testing.polytope_signed_distance`) and its normal a direction along which the Minkowski
difference reaches no farther than the depth plus the tolerance.

Found: a kept polytope is not convex in general (its vertices moved with the two shapes, or the
row is another pair's), so the nearest triangle `epa_warm` took for the witness could lie on a face
that is within the tolerance of the nearest plane but is no face of ``C``: the normal it reported
was up to 2x the tolerance off the depth (EPA's own polytope, convex, holds the origin's foot point
in its nearest face). `epa_warm` now checks that face as it checks the nearest one, or declines.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

import collide.mujoco as cm
from collide import contacts as cc
from collide._kernels import epa as ke
from collide._kernels.distance import OUT_ITERATIONS, OUT_LOWER, OUT_UPPER, WS_F, WS_I, pair_distance_within
from collide._kernels.manifold import CONTACT_TOL
from collide._kernels.warm import SEP_LEN, WARM_HITS, WARM_KEYS, WARM_LEN, WARM_ROWS, WARM_TRIES
from collide.pointcloud import PointCloud
from collide.support import support_data
from collide.testing.narrow import polytope_signed_distance
from _threads import in_threads

EYE = np.eye(3)


def _shape(sd, rot, pos):
    return (sd.kind, sd.prm, sd.points, sd.nbr_start, sd.nbr, np.ascontiguousarray(rot),
            np.ascontiguousarray(pos, dtype=float))


def _compare(w, c, size) -> int:
    # Same pairs and contact counts; per pair the deepest dist within both answers' tolerance and
    # its normal within 1e-3 rad. Returns the number of penetrating contacts (the scene's hits).
    def by_pair(x):
        out = {}
        for i, g in enumerate(map(tuple, x.geom.tolist())):
            out.setdefault(g, []).append(i)
        return out

    dw, dc = by_pair(w), by_pair(c)
    assert dw.keys() == dc.keys()
    for g, iw in dw.items():
        ic = dc[g]
        assert len(iw) == len(ic), g
        a = min(iw, key=lambda i: w.dist[i])
        b = min(ic, key=lambda i: c.dist[i])
        assert abs(w.dist[a] - c.dist[b]) <= 2.0 * CONTACT_TOL * (size[g[0]] + size[g[1]]) + 1e-12, g
        assert w.normal[a] @ c.normal[b] >= np.cos(1e-3), g
    return int(np.sum(c.dist < 0.0))


def _mesh_scene(n, seed, spread=0.1, margin=0.0):
    # n free meshes (boxes, random blobs, tetrahedra) heaped within ``spread``: most pairs overlap.
    rng = np.random.default_rng(seed)
    assets, bodies = [], []
    for i in range(n):
        if i % 3 == 0:
            p = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * rng.uniform(0.05, 0.2, 3)
        elif i % 3 == 1:
            p = rng.normal(size=(int(rng.integers(8, 40)), 3))
            p = p / np.linalg.norm(p, axis=1)[:, None] * rng.uniform(0.05, 0.2, 3)
        else:
            p = rng.normal(size=(4, 3)) * 0.1
        assets.append(f'<mesh name="m{i}" vertex="{" ".join(map(str, p.ravel()))}"/>')
        x = rng.uniform(-spread, spread, 3)
        bodies.append(f'<body pos="{x[0]} {x[1]} {x[2]}"><freejoint/>'
                      f'<geom type="mesh" mesh="m{i}" margin="{margin}"/></body>')
    xml = f'<mujoco><asset>{"".join(assets)}</asset><worldbody>{"".join(bodies)}</worldbody></mujoco>'
    return mujoco.MjModel.from_xml_string(xml)


def test_more_penetrating_pairs_than_slots():
    """60 heaped meshes (1,770 pairs, most penetrating: more than the cache's 1024 slots, so that
    pairs share slots and take them over), small moves, a teleport every fourth call and a NaN
    pose between two calls: every call as a cold table's."""
    model = _mesh_scene(60, seed=60)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    col = cm.Collider(model)
    cold = cc.GeomTable(model)
    rng = np.random.default_rng(0)
    nb = model.nbody - 1
    pen = crowd = 0
    for step in range(12):
        q = data.qpos.reshape(nb, 7)
        if step % 4 == 3:
            q[:, :3] = rng.uniform(-0.1, 0.1, (nb, 3))
        q[:, :3] += rng.normal(scale=1e-3, size=(nb, 3))
        q[:, 3:] += rng.normal(scale=1e-2, size=(nb, 4))
        q[:, 3:] /= np.linalg.norm(q[:, 3:], axis=1)[:, None]
        mujoco.mj_kinematics(model, data)
        pairs = col.pairs(data)
        if step == 6:  # an error mid-call leaves the cache usable
            bad = data.geom_xpos.copy()
            bad[int(pairs[len(pairs) // 2, 0])] = np.nan
            with pytest.raises(ValueError, match="non-finite"):
                cc.narrow_phase(col.table, pairs, bad, data.geom_xmat)
        w = cc.narrow_phase(col.table, pairs, data.geom_xpos, data.geom_xmat)
        cold._wsi[-WARM_LEN - SEP_LEN:] = 0  # both caches (`collide._kernels.warm`)
        c = cc.narrow_phase(cold, pairs, data.geom_xpos, data.geom_xmat)
        pen += _compare(w, c, col.table.size)
        crowd = max(crowd, len({tuple(g) for g in c.geom[c.dist < 0.0].tolist()}))
    cache = col.table._wsi[-WARM_LEN:]
    assert pen > 10000 and cache[WARM_HITS] > 1000  # real hits, and the warm path answered many
    assert crowd > 1024 and np.count_nonzero(cache[WARM_KEYS:WARM_ROWS]) > 700  # more pairs than slots


def _two_cubes(margin):
    cube = " ".join(map(str, (np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * 0.1).ravel()))
    xml = f'''<mujoco><asset><mesh name="c" vertex="{cube}"/></asset><worldbody>
      <body><freejoint/><geom type="mesh" mesh="c" margin="{margin}"/></body>
      <body><freejoint/><geom type="mesh" mesh="c" margin="{margin}"/></body></worldbody></mujoco>'''
    return mujoco.MjModel.from_xml_string(xml)


@pytest.mark.parametrize("margin", [0.0, 0.01])
def test_two_cubes_slide_tilt_part_and_jump(margin):
    """Two mesh cubes face on face: sliding across each other, tilting and spinning (the kept
    polytope's vertices move apart from C's faces), apart and back, jumping between two poses,
    depths that cross (the normal switches axis): as a cold table's, face contacts counted."""
    model = _two_cubes(margin)
    data = mujoco.MjData(model)
    one = np.array([1.0, 0, 0, 0])
    poses = [(np.array([x, 0.0, 0.18]), one) for x in np.linspace(-0.15, 0.15, 31)]
    for axis in (1, 3):  # tilting about x, spinning about z
        for a in np.linspace(0, 1, 31):
            quat = np.array([np.cos(a / 2), 0.0, 0.0, 0.0])
            quat[axis] = np.sin(a / 2)
            poses.append((np.array([0.0, 0.0, 0.17]), quat))
    poses += [(np.array([0.0, 0.0, z]), one) for z in np.r_[np.linspace(0.15, 0.25, 11), np.linspace(0.25, 0.15, 11)]]
    poses += [(np.array([0.1, 0.05, 0.0]) if s % 2 else np.array([0.0, -0.03, -0.17]), one) for s in range(10)]
    # depths that cross: x's from 0.0705 to 0.0295 against z's 0.05, never tied (at a tie either
    # normal is right: the warm one keeps the side it had, the cold one may take the other)
    poses += [(np.array([0.1295 + t, 0.0, 0.15]), one) for t in np.linspace(0.0, 0.041, 42)]
    col = cm.Collider(model)
    cold = cc.GeomTable(model)
    pairs = np.array([[0, 1]], np.int32)
    pen = 0
    for pos, quat in poses:
        data.qpos[:] = 0.0
        data.qpos[3] = 1.0
        data.qpos[7:10], data.qpos[10:14] = pos, quat
        mujoco.mj_kinematics(model, data)
        w = cc.narrow_phase(col.table, pairs, data.geom_xpos, data.geom_xmat)
        cold._wsi[-WARM_LEN - SEP_LEN:] = 0  # both caches (`collide._kernels.warm`)
        pen += _compare(w, cc.narrow_phase(cold, pairs, data.geom_xpos, data.geom_xmat), col.table.size)
    assert pen > 100 and col.table._wsi[-WARM_LEN:][WARM_HITS] > 100


def _cloud(rng, kind):
    if kind == "flat":
        p = rng.normal(size=(20, 3))
        p[:, 2] = 0.0
        return p
    if kind == "thin":
        return rng.normal(size=(30, 3)) * [1.0, 1.0, 1e-7]
    if kind == "dup":
        return np.repeat(rng.normal(size=(6, 3)), 3, axis=0)
    if kind == "four":
        return rng.normal(size=(4, 3))
    if kind == "box":
        return np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * rng.uniform(0.3, 1, 3)
    p = rng.normal(size=(100, 3))  # a sphere-like hull: supports hill-climb
    return p / np.linalg.norm(p, axis=1)[:, None]


def test_kept_rows_against_the_exact_distance():
    """Pairs of clouds (flat, 1e-7 thin, duplicated, four points, boxes, 100-point hulls), some
    1e3 from the origin, through small moves, large rotations and jumps, with one cache row each:
    every answer from the row has the exact distance (the Minkowski-difference oracle) within
    its bracket and within 2 tol, and agrees with the cold query's."""
    kinds = ["flat", "thin", "dup", "four", "box", "big"]
    rng = np.random.default_rng(3)
    hits = 0
    for trial in range(48):
        A, B = _cloud(rng, kinds[trial % 6]), _cloud(rng, kinds[(trial // 6) % 6])
        sa, sb = support_data(PointCloud(A)), support_data(PointCloud(B))
        size = sa.size + sb.size
        tol = CONTACT_TOL * size
        off = (1e3 if trial % 2 else 0.0) * rng.normal(size=3)
        ra, rb = Rotation.random(random_state=trial), Rotation.random(random_state=1000 + trial)
        pa, pb = off + rng.normal(scale=0.3, size=3), off + rng.normal(scale=0.3, size=3)
        entry = np.zeros(ke.ENTRY, np.int64)
        for _ in range(8):
            mode = rng.integers(4)
            if mode == 0:
                ra = Rotation.from_rotvec(rng.normal(scale=0.02, size=3)) * ra
                pa = pa + rng.normal(scale=0.01, size=3)
            elif mode == 1:
                rb = Rotation.from_rotvec(rng.normal(scale=0.3, size=3)) * rb
                pb = pb + rng.normal(scale=0.2, size=3)
            elif mode == 2:
                pa = off + rng.normal(scale=0.5, size=3)
            sA, sB = _shape(sa, ra.as_matrix(), pa), _shape(sb, rb.as_matrix(), pb)
            had = entry[ke.E_NV] > 0
            ow, oc = np.zeros(16), np.zeros(16)
            fws, iws = np.empty(WS_F), np.empty(WS_I, np.int64)  # the scratch
            pair_distance_within(sA, sB, tol, 10.0, np.zeros(3), -1, -1, 128, ow, fws, iws, entry)
            pair_distance_within(sA, sB, tol, 10.0, np.zeros(3), -1, -1, 128, oc, fws, iws)
            if not (had and ow[OUT_ITERATIONS] == 0):
                continue
            hits += 1
            truth = polytope_signed_distance(sa.points @ ra.as_matrix().T + pa, sb.points @ rb.as_matrix().T + pb)
            assert ow[OUT_LOWER] - 1e-12 * size <= truth <= ow[OUT_UPPER] + 1e-12 * size
            assert abs(ow[0] - truth) <= 2.0 * tol and abs(ow[0] - oc[0]) <= 2.0 * tol
    assert hits > 40  # rows answered


def test_star_shaped_rows_give_a_normal_of_the_depth():
    """Rows holding a closed surface around the origin through vertices of a random cloud (a
    sphere of their directions: star-shaped, every face in front of the origin, not convex),
    always with the cloud's nearest facet, against a point (``C`` is the cloud): wherever
    `epa_warm` answers, its normal ``n`` has ``h_C(n) <= depth + tol`` (as EPA's, whose nearest
    face is a face of C within tol) and the depth is within its bracket. A loose tolerance (a
    tenth of the depth and more) makes the faces near the nearest plane that are no face of C
    common; before the fix, 3 of these rows answered with a normal 1.3 to 2.0 tol too long."""
    rng = np.random.default_rng(1)
    sb = support_data(PointCloud(np.zeros((1, 3))))
    sB = _shape(sb, EYE, np.zeros(3))
    res = np.empty(13)
    answered = 0
    for _ in range(6000):
        sa = support_data(PointCloud(rng.normal(size=(30, 3)) * [1, 1, 0.6]))
        pos = rng.normal(scale=0.3, size=3)
        P = sa.points + pos
        hull = ConvexHull(P)
        depth = float(np.min(-hull.equations[:, 3]))
        if depth <= 0.0:
            continue
        tol = depth * rng.uniform(0.01, 0.6)
        k = int(rng.integers(5, 17))
        near = hull.simplices[np.argmin(-hull.equations[:, 3])]
        rest = rng.permutation([i for i in range(len(P)) if i not in near])
        vs = np.array(list(near) + list(rest[:k - 3]))
        V = P[vs]
        try:
            sphere = ConvexHull(V / np.linalg.norm(V, axis=1)[:, None])
        except Exception:  # noqa: BLE001 (Qhull: a flat set of directions)
            continue
        if len(sphere.vertices) != len(vs) or len(sphere.simplices) > ke.WARM_NF:
            continue
        row = np.zeros(ke.ENTRY, np.int64)
        row[ke.E_NV], row[ke.E_NF] = len(vs), len(sphere.simplices)
        row[ke.E_VERT:ke.E_VERT + len(vs)] = vs  # index in the cloud, 0 in the point
        for m, (a, b, c) in enumerate(sphere.simplices):
            if np.cross(V[b] - V[a], V[c] - V[a]) @ V[a] < 0:
                b, c = c, b
            row[ke.E_FACE + m] = a | (b << 8) | (c << 16)
        st, _ = ke.epa_warm(_shape(sa, EYE, pos), sB, row, tol, res, np.empty(ke.WARM_F),
                              np.empty(ke.WARM_I, np.int64))
        if st != ke.CONVERGED:
            continue
        answered += 1
        assert float(np.max(P @ res[9:12])) - depth <= tol * (1 + 1e-9)
        assert res[0] - 1e-12 <= -depth <= res[1] + 1e-12
    assert answered > 300


def _poses_walk(model, data, rng, sd):
    q = data.qpos.reshape(model.nbody - 1, 7)
    q[:, :3] += rng.normal(scale=sd, size=(model.nbody - 1, 3))
    q[:, 3:] += rng.normal(scale=sd, size=(model.nbody - 1, 4))
    q[:, 3:] /= np.linalg.norm(q[:, 3:], axis=1)[:, None]
    mujoco.mj_kinematics(model, data)


def _walk_against_cold(model, col, data, rng, steps, sd):
    # `steps` random steps of the poses (`_poses_walk`): each call of col as a cold table's, its
    # cache rows cleared first; returns the penetrating contacts compared
    cold = cc.GeomTable(model)
    pen = 0
    for _ in range(steps):
        _poses_walk(model, data, rng, sd)
        w = col.contacts(data)
        cold._wsi[-WARM_LEN - SEP_LEN:] = 0  # both caches (`collide._kernels.warm`)
        pen += _compare(w, cc.narrow_phase(cold, col.pairs(data), data.geom_xpos, data.geom_xmat), col.table.size)
    return pen


def test_pair_overrides_and_duplicate_pairs():
    """Explicit <pair>s over heaped meshes: margins, gaps beyond the margin (a negative contact
    threshold) and a geom pair listed twice (collided twice a call, one slot): as a cold table's."""
    n = 12
    rng = np.random.default_rng(7)
    names = [f"g{i}" for i in range(n)]
    assets, bodies = [], []
    for i in range(n):
        p = rng.normal(size=(int(rng.integers(6, 30)), 3)) * 0.1
        assets.append(f'<mesh name="m{i}" vertex="{" ".join(map(str, p.ravel()))}"/>')
        x = rng.uniform(-0.1, 0.1, 3)
        bodies.append(f'<body pos="{x[0]} {x[1]} {x[2]}"><freejoint/><geom name="{names[i]}" type="mesh" mesh="m{i}" '
                      'margin="0.004" gap="0.002"/></body>')
    pairs = "".join(f'<pair geom1="g{i}" geom2="g{i + 1}" margin="{0.02 if i % 2 else 0.0}" '
                    f'gap="{0.03 if i % 3 == 0 else 0.0}"/>' for i in range(n - 1))
    pairs += "".join(f'<pair geom1="g{i}" geom2="g{i + 2}" margin="0.005"/>'
                     f'<pair geom1="g{i}" geom2="g{i + 2}" gap="0.01" margin="0.001"/>' for i in range(0, n - 2, 3))
    model = mujoco.MjModel.from_xml_string(f'<mujoco><asset>{"".join(assets)}</asset><worldbody>{"".join(bodies)}'
                                           f'</worldbody><contact>{pairs}</contact></mujoco>')
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    col = cm.Collider(model)
    pen = _walk_against_cold(model, col, data, rng, 30, 2e-3)
    assert pen > 300 and col.table._wsi[-WARM_LEN:][WARM_HITS] > 100


def test_threads_share_one_cache():
    """Two threads on one Collider, each walking its own poses (each thread's calls find the
    other's rows, at other poses): every call as a cold table's."""
    model = _mesh_scene(24, seed=21)
    col = cm.Collider(model)

    def walk(seed):
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        return _walk_against_cold(model, col, data, np.random.default_rng(seed), 20, 3e-3)

    pens = in_threads(walk, 2)
    assert min(pens) > 1000 and col.table._wsi[-WARM_LEN:][WARM_TRIES] > 500
