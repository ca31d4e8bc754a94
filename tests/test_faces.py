"""Face contacts (issue 46): box-box manifolds, face clipping, hull faces, polytope multi-contact.

Kernels against their brute-force twins (`collide.testing.manifold`) on random cases with fixed
seeds, and against MuJoCo 4's own contacts where it makes them.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from scipy.spatial import ConvexHull

import collide.mujoco as cm
from collide import faces as cf
from collide._kernels import faces as kf
from collide.testing import manifold as tm
from contact_check import MODELS


def _rot(rng) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, q)
    return m.reshape(3, 3)


def _box_case(rng, trial):
    h1, h2 = rng.uniform(0.1, 1.0, 3), rng.uniform(0.1, 1.0, 3)
    r1 = _rot(rng)
    # a third share the orientation (stacked, face on face), a third nearly so
    r2 = r1.copy() if trial % 3 == 0 else (r1 @ _rot_small(rng, 0.02) if trial % 3 == 1 else _rot(rng))
    p1 = rng.normal(size=3)
    p2 = p1 + rng.normal(size=3) * 0.8
    thr = 0.0 if trial % 2 else 0.1
    if trial % 50 == 0:
        # square faces turned 45 degrees on each other: an octagon, 8 contacts
        h1[1] = h1[0]
        h2[:2] = h1[0]
        c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
        r2 = r1 @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        p2 = p1 + r1[:, 2] * (h1[2] + h2[2] - 0.01)
    return p1, r1, h1, p2, r2, h2, thr


def _rot_small(rng, ang):
    a = rng.normal(size=3)
    a *= ang / np.linalg.norm(a)
    q = np.zeros(4)
    mujoco.mju_axisAngle2Quat(q, a / np.linalg.norm(a), np.linalg.norm(a))
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, q)
    return m.reshape(3, 3)


def _same_points(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    return len(a) == len(b) and all(np.min(np.max(np.abs(b - x), axis=1)) < tol for x in a)


def test_box_box_is_its_twin():
    rng = np.random.default_rng(46)
    res, nrm, ws = np.zeros((kf.BOX_MAX, 4)), np.zeros(3), np.zeros(kf.BOX_WS)
    hits = faces = edges = 0
    for trial in range(600):
        p1, r1, h1, p2, r2, h2, thr = _box_case(rng, trial)
        k = kf.box_box(p1, r1, h1, p2, r2, h2, thr, res, nrm, ws)
        twin = tm.box_box_contacts(p1, r1, h1, p2, r2, h2, thr)
        if twin is None:
            assert k == 0, trial
            continue
        dist, pos, normal = twin
        assert k == len(dist), trial
        hits += 1
        faces += k > 1
        edges += k == 1
        assert _same_points(np.c_[res[:k, :1], res[:k, 1:]], np.c_[dist, pos], 1e-8), trial
        np.testing.assert_allclose(nrm, normal, atol=1e-9)
    assert hits > 200 and faces > 100 and edges > 20  # real contacts of both kinds


def test_box_box_is_mujocos():
    # MuJoCo 4's box-box (mjc_BoxBox): the same contacts, one for one, margins included.
    rng = np.random.default_rng(7)
    res, nrm, ws = np.zeros((kf.BOX_MAX, 4)), np.zeros(3), np.zeros(kf.BOX_WS)
    hits = eights = 0
    for trial in range(300):
        p1, r1, h1, p2, r2, h2, thr = _box_case(rng, trial)
        q1, q2 = np.zeros(4), np.zeros(4)
        mujoco.mju_mat2Quat(q1, r1.ravel())
        mujoco.mju_mat2Quat(q2, r2.ravel())

        def f(x):
            return " ".join(map(repr, map(float, x)))
        xml = (f'<mujoco><worldbody><body pos="{f(p1)}" quat="{f(q1)}"><freejoint/><geom type="box" '
               f'size="{f(h1)}" margin="{thr}"/></body><body pos="{f(p2)}" quat="{f(q2)}"><freejoint/>'
               f'<geom type="box" size="{f(h2)}"/></body></worldbody></mujoco>')
        m = mujoco.MjModel.from_xml_string(xml)
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        xm = d.geom_xmat.reshape(-1, 3, 3)
        k = kf.box_box(d.geom_xpos[0], xm[0], h1, d.geom_xpos[1], xm[1], h2, thr, res, nrm, ws)
        assert k == d.ncon, trial
        if k:
            hits += 1
            eights += k == 8
            mj = np.c_[d.contact.dist[:k], d.contact.pos[:k]]
            assert _same_points(res[:k], mj, 1e-9), trial
            np.testing.assert_allclose(nrm, d.contact.frame[0, :3], atol=1e-9)
    assert hits > 100 and eights > 0


def _ccw(poly: np.ndarray, n: np.ndarray) -> np.ndarray:
    c = poly.mean(axis=0)
    u = poly[0] - c
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    return poly[np.argsort(np.arctan2((poly - c) @ w, (poly - c) @ u))]


def test_clip_faces_is_its_twin():
    # A random convex polygon (below a reference face, tilted a little) clipped to the prism over
    # the reference face: the kernel's points are the twin's intersection polygon (reduced to its
    # largest quadrilateral when it has more than 4 vertices), at the twin's heights.
    rng = np.random.default_rng(11)
    poly, tmp, res = np.zeros((40, 3)), np.zeros((40, 3)), np.zeros((4, 4))
    n = np.array([0.0, 0.0, 1.0])
    many = 0
    for trial in range(300):
        ref2 = rng.normal(size=(rng.integers(3, 9), 2))
        ref2 = ref2[ConvexHull(ref2).vertices]  # counter-clockwise
        inc2 = rng.normal(size=(rng.integers(3, 9), 2)) * 0.8 + rng.normal(size=2) * 0.3
        inc2 = inc2[ConvexHull(inc2).vertices]
        tilt = rng.normal(size=2) * 0.02
        ref = np.c_[ref2, np.zeros(len(ref2))]
        inc = np.c_[inc2, -0.05 + inc2 @ tilt]
        k = kf.clip_faces(ref, len(ref), n, inc[::-1].copy(), len(inc), poly, tmp, res, np.zeros(4, np.int64))
        verts = tm.convex_polygon_intersection(inc2, ref2)
        h = -0.05 + verts @ tilt if len(verts) else np.zeros(0)
        keep = h <= 0
        # (dist, x, y, z): the reference plane is z = 0, so a point's height is its z
        want = np.c_[h[keep], verts[keep], h[keep]] if len(verts) else np.zeros((0, 4))
        if len(want) <= 4:
            assert k == len(want), trial
            assert _same_points(res[:k], want, 1e-9), trial
        else:
            many += 1
            assert k == 4
            assert all(np.min(np.max(np.abs(want - x), axis=1)) < 1e-9 for x in res[:4])
            area = tm.max_area_quad(want[:, 1:])
            assert tm.max_area_quad(res[:4, 1:]) >= area * (1 - 1e-9)
    assert many > 20


def test_polytope_faces():
    # A box: 6 quadrilaterals with the axes as normals; a random hull: every face's vertices on its
    # plane, every point on the inner side of every face, Euler's V - E + F = 2.
    pf = cf.polytope_faces(np.array([[x, y, z] for x in (-1, 1) for y in (-2, 2) for z in (-3, 3)], float))
    assert len(pf.normal) == 6 and np.all(pf.vnum == 4)
    assert np.allclose(np.sort(np.abs(pf.normal).max(axis=1)), 1.0)
    rng = np.random.default_rng(5)
    for trial in range(20):
        pts = rng.normal(size=(rng.integers(4, 60), 3))
        if trial % 4 == 0:
            pts = np.round(pts)  # coplanar, duplicate points: merged faces
        pf = cf.polytope_faces(pts)
        if len(pf.normal) == 0:
            continue
        E = 0
        for f in range(len(pf.normal)):
            v = pf.verts[pf.vidx[pf.vadr[f]:pf.vadr[f] + pf.vnum[f]]]
            assert np.allclose(v @ pf.normal[f], pf.offset[f], atol=1e-9)
            # counter-clockwise about the outward normal
            area = sum(np.cross(v[i], v[(i + 1) % len(v)]) for i in range(len(v)))
            assert np.dot(area, pf.normal[f]) > 0
            E += pf.vnum[f]
        assert np.all(pts @ pf.normal.T <= pf.offset + 1e-9)
        assert len(pf.verts) - E // 2 + len(pf.normal) == 2
    # no volume: no faces, never an error
    for flat in (np.zeros((1, 3)), np.c_[rng.normal(size=(9, 2)), np.zeros(9)], np.zeros((0, 3))):
        assert len(cf.polytope_faces(flat).normal) == 0


def _cycles(pf) -> list:
    # Each face's vertex cycle from its lowest id: equal cycles are the same polygon, however a
    # near-tie of angles at the start (+-pi) rotated the list.
    out = []
    for f in range(len(pf.vnum)):
        v = pf.vidx[pf.vadr[f]:pf.vadr[f] + pf.vnum[f]]
        out.append(tuple(np.roll(v, -int(np.argmin(v))).tolist()))
    return out


def test_polytope_faces_is_its_per_face_twin():
    # The all-faces-at-once construction against the loop over faces (collide.testing), on random
    # hulls (rounded: coplanar faces merged; doubled: duplicate points) and every mesh of the
    # real models.
    rng = np.random.default_rng(11)
    clouds = []
    for trial in range(120):
        pts = rng.normal(size=(rng.integers(1, 150), 3))
        if trial % 3 == 0:
            pts = np.round(pts)
        if trial % 5 == 0:
            pts = np.vstack([pts, pts])
        clouds.append(pts)
    for scene in sorted(p.name for p in MODELS.iterdir()) if MODELS.is_dir() else []:
        if (MODELS / scene / "scene.xml").is_file():
            m = mujoco.MjModel.from_xml_path(str(MODELS / scene / "scene.xml"))
            clouds += [m.mesh_vert[a:a + n] for a, n in zip(m.mesh_vertadr, m.mesh_vertnum)]
    merged = 0
    for pts in clouds:
        a, b = cf.polytope_faces(pts), tm.polytope_faces_loop(pts)
        assert np.array_equal(a.verts, b.verts) and np.array_equal(a.normal, b.normal)
        assert np.array_equal(a.vadr, b.vadr) and np.array_equal(a.vnum, b.vnum)
        assert _cycles(a) == _cycles(b)
        assert np.allclose(a.offset, b.offset, rtol=0, atol=1e-12 * max(1.0, float(np.abs(a.verts).max(initial=0))))
        merged += int(np.count_nonzero(a.vnum > 3))
    assert merged > 50  # faces of more than one triangle were merged and ordered


@pytest.mark.parametrize("scene", ["cube_3x3x3", "kinova_gen3", "stonehenge"])
def test_face_contact_counts_near_mujocos(scene):
    # Multi-contact of face contacts over a short simulation: per pair type, the contact count
    # within 15 % of MuJoCo 4's (box-box, box-plane exactly), the deepest contact of each pair
    # within MuJoCo's tolerance (tests/contact_check.py checks that over every model).
    model = mujoco.MjModel.from_xml_path(str(MODELS / scene / "scene.xml"))
    data = mujoco.MjData(model)
    col = cm.Collider(model)
    ctrls = cm._random_controls(model, 200, 0, 100)
    ours = theirs = 0
    for step in range(150):
        if step % 100 == 0 and len(ctrls):
            data.ctrl[:] = ctrls[step // 100]
        mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)
        c = col.contacts(data)
        ours += len(c)
        theirs += int(np.count_nonzero(np.all(data.contact.geom[:data.ncon] >= 0, axis=1)))
    assert theirs > 100
    if scene == "stonehenge":
        assert ours == theirs
    assert abs(ours - theirs) <= 0.15 * theirs, (ours, theirs)
