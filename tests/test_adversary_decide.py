"""helper-47's attacks on c7f7d71: `collide._kernels.check.decide_rows` (closed-form pairs first).

`decide_rows` decides a configuration's closed-form pairs (spheres, capsules, planes, height
fields) before its GJK pairs and claims the answer of the old loop in row order: a hit where some
row is active and every geom of the rows before it (and its own) has a finite pose; else the
error of the first non-finite geom in row order; ``skipped`` (a height field's pair met, no hit)
as that loop. Its twin here is that loop written in Python (`_row_order`): per row, in order, the
subset, then the finiteness of the two geoms (MuJoCo's ``mj_kinematics`` poses), then whether the
pair is active (`Collider.contacts` on MuJoCo's poses of the configuration with the overflowing
body moved back).

The broad phase refuses a non-finite or huge body pose before any row is decided (a clear
ValueError), so a non-finite geom pose cannot reach `decide_rows` through its rows; the rows are
given here instead (``Collider._candidates`` replaced, check_worlds' path): any subset of the
pairs, in any order, with a body whose pose overflows (two coordinates of 1e308 along x) in half
the configurations, so that its geoms' rows come before, between and after the active ones,
closed-form (its sphere) and GJK (its box) alike; and a model without closed-form pairs (every
row in the second pass). The public entry points are attacked too: a
scene with every filter the decision reads, on the lanes path, on check_worlds' and with
distances, and numba's threads and two Python threads on one Collider.
"""

from __future__ import annotations

import mujoco
import numba
import numpy as np
import pytest

import collide.mujoco as cm
from collide import collider as ccol
from collide import testing
from collide._kernels import check as kc
from _threads import in_threads
from contact_check import MODELS

ROWS = """<mujoco><asset><hfield name="h" nrow="3" ncol="3" size=".3 .3 .05 .05"
  elevation="0 0 0 0 0 0 0 0 0"/></asset>
<worldbody>
<geom name="floor" type="plane" size="3 3 .1" pos="0 0 -1"/>
<geom name="hf" type="hfield" hfield="h" pos="2 2 -.5"/>
<body name="s"><freejoint/><geom name="s" type="sphere" size=".1"/></body>
<body name="c"><freejoint/><geom name="c" type="capsule" size=".06 .1" margin=".02" gap=".01"/></body>
<body name="b"><freejoint/><geom name="b" type="box" size=".1 .07 .05"/></body>
<body name="e"><freejoint/><geom name="e" type="ellipsoid" size=".1 .06 .08"/></body>
<body name="y"><freejoint/><geom name="y" type="cylinder" size=".07 .06"/></body>
<body name="far"><freejoint/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>
  <body name="bad" pos=".5 0 0"><joint name="bx" type="slide" axis="1 0 0"/>
  <geom name="bs" type="sphere" size=".1"/><geom name="bb" type="box" size=".1 .1 .1"/></body></body>
</worldbody>
<contact><pair geom1="s" geom2="b" margin=".03" gap=".02"/></contact>
</mujoco>"""
FREE = 6  # the bodies with a free joint; the last ("far") carries "bad"
SUB = ["s", "b", "bs", "c", "hf", "floor"]


# The same without a closed-form pair (no plane, height field, sphere or capsule): `first_pass` 1,
# every row in the second pass
ROWS_GJK = (ROWS.replace('<geom name="floor" type="plane" size="3 3 .1" pos="0 0 -1"/>', "")
            .replace('<geom name="hf" type="hfield" hfield="h" pos="2 2 -.5"/>', "")
            .replace('type="sphere" size=".1"', 'type="ellipsoid" size=".1 .09 .08"')
            .replace('type="capsule" size=".06 .1"', 'type="box" size=".06 .06 .1"'))


def _rows_model(xml=ROWS):
    return mujoco.MjModel.from_xml_string(xml)


def _rows_configs(m, n, seed):
    # n configurations: five free bodies among each other, "far" 3 above them; in about half,
    # far's x and bad's slide 1e308 (far unrotated: bad's x overflows to inf, its geoms' too)
    rng = np.random.default_rng(seed)
    q = np.tile(m.qpos0, (n, 1))
    for b in range(FREE):
        q[:, 7 * b:7 * b + 3] = rng.uniform(-0.17, 0.17, (n, 3))
        quat = rng.normal(size=(n, 4))
        q[:, 7 * b + 3:7 * b + 7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    f = 7 * (FREE - 1)
    q[:, f + 2] += 3.0
    bad = rng.random(n) < 0.5
    q[bad, f] = 1e308
    q[bad, -1] = 1e308
    q[bad, f + 3:f + 7] = [1.0, 0.0, 0.0, 0.0]
    return q, bad


def _rows(m, n, seed):
    # (world, g1, g2) rows: per configuration a random number of the pairs of geoms of two bodies
    # (the static pair left out), in a random order
    rng = np.random.default_rng(seed)
    G = m.ngeom
    allp = [(a, b) for a in range(G) for b in range(a + 1, G)
            if m.geom_bodyid[a] != m.geom_bodyid[b]]
    rows = []
    for w in range(n):
        sel = rng.permutation(len(allp))[:int(rng.integers(0, len(allp) + 1))]
        rows += [(w, *allp[i]) for i in sel]
    return np.array(rows, np.int32).reshape(-1, 3)


def _on_rows(col, q, rows, monkeypatch):
    # check_batch on check_worlds' path deciding these rows: (in_collision, skipped, None) or
    # (None, None, the error's message)
    def cand(qb, first, name=None):
        r = rows[(rows[:, 0] >= first) & (rows[:, 0] < first + len(qb))]
        return r - np.array([first, 0, 0], np.int32)

    with monkeypatch.context() as mp:
        mp.setattr(col, "_in_lanes", lambda *a, **k: False)
        mp.setattr(col, "_trees", lambda: False)
        mp.setattr(col, "_candidates", cand)
        try:
            r = col.check_batch(q)
        except ValueError as exc:
            return None, None, str(exc)
    return r.in_collision.copy(), r.skipped.copy(), None


def _row_order(m, col, q, rows, subset=None):
    """The old loop in row order, in Python: (in_collision, skipped, None) of the batch, or
    (None, None, the message naming the first configuration and geom in error)."""
    d = mujoco.MjData(m)
    n = len(q)
    hit = np.zeros(n, bool)
    skipped = np.zeros(n, bool)
    hf = mujoco.mjtGeom.mjGEOM_HFIELD
    for i in range(n):
        d.qpos[:] = q[i]
        mujoco.mj_kinematics(m, d)
        finite = np.isfinite(d.geom_xpos).all(axis=1) & np.isfinite(d.geom_xmat).all(axis=1)
        x = q[i].copy()
        x[7 * (FREE - 1)] = 0.0  # the same poses, "bad" brought back (no pair of it is read then)
        x[-1] = 0.0
        d.qpos[:] = x
        mujoco.mj_kinematics(m, d)
        c = col.contacts(d)
        active = {tuple(g) for g in c.geom[c.dist < c.margin].tolist()}
        for _, g1, g2 in rows[rows[:, 0] == i].tolist():
            if subset is not None and not (g1 in subset and g2 in subset):
                continue
            bad = [g for g in (g1, g2) if not finite[g]]
            if bad:
                return None, None, f"qpos: configuration {i} gives a non-finite pose (NaN or inf) of geom {bad[0]}"
            if (g1, g2) in active:
                hit[i] = True
                break
            if m.geom_type[g1] == hf or m.geom_type[g2] == hf:
                skipped[i] = True
    return hit, skipped & ~hit, None


def _equal(got, ref):
    assert got[2] == ref[2]
    if ref[2] is None:
        assert np.array_equal(got[0], ref[0]) and np.array_equal(got[1], ref[1])


@pytest.mark.parametrize("xml", [ROWS, ROWS_GJK], ids=["mixed", "gjk_only"])
def test_rows_in_any_order_give_the_row_orders_answer(xml, monkeypatch):
    m = _rows_model(xml)
    names = [x for x in SUB if mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, x) >= 0]
    sub = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, x) for x in names}
    t = cm.Collider(m).table
    assert kc.first_pass(t.cls, t.kind, t.pts_num) == (xml is ROWS_GJK)
    kinds = {}
    for seed in range(24 if xml is ROWS else 12):
        n = 1 + seed % 17
        q, bad = _rows_configs(m, n, seed)
        rows = _rows(m, n, seed + 1000)
        for geoms, subset in ((None, None), (names, sub)):
            col = cm.Collider(m, geoms=geoms)
            for i in range(n):
                r1 = rows[rows[:, 0] == i] * np.array([0, 1, 1], np.int32)
                got = _on_rows(col, q[i:i + 1], r1, monkeypatch)
                _equal(got, _row_order(m, col, q[i:i + 1], r1, subset))
                k = ("bad " if bad[i] else "") + ("error" if got[2] else "hit" if got[0][0] else
                                                   "skipped" if got[1][0] else "none")
                kinds[k] = kinds.get(k, 0) + 1
            # the batch: the first configuration in error named, or every answer
            _equal(_on_rows(col, q, rows, monkeypatch), _row_order(m, col, q, rows, subset))
    # every case many times: a hit before a bad geom's row, its error before a hit, ...
    for k in ("hit", "none", "bad error", "bad hit") + (("skipped",) if xml is ROWS else ()):
        assert kinds.get(k, 0) >= 5, kinds
    assert xml is ROWS_GJK or kinds.get("bad skipped", 0) >= 1, kinds


def test_hand_made_orders(monkeypatch):
    # Rows of one configuration: a GJK pair (s, b: their <pair>) and closed-form ones (s, c; c, bs
    # with bad's sphere; floor's), the bad box's GJK pair (b, bb), in orders where the first pass
    # meets the active closed-form row before, or after, a bad row that the row order meets first.
    m = _rows_model()
    gid = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g): g for g in range(m.ngeom)}
    q = np.tile(m.qpos0, (1, 1))
    f = 7 * (FREE - 1)
    q[0, 0:3] = [0, 0, 0]  # s
    q[0, 7:10] = [0.15, 0, 0]  # c: crosses s (capsule along z, radius .06)
    q[0, 14:17] = [0, 0.15, 0]  # b: 0.15 - .07 < .1 (s-b active)
    q[0, 21:24] = [1, 1, 1]  # e, y apart
    q[0, 28:31] = [-1, -1, 1]
    q[0, f:f + 3] = [1e308, 0, 3]
    q[0, -1] = 1e308
    col = cm.Collider(m)
    s_c, s_b, c_bs, b_bb = ((gid["s"], gid["c"]), (gid["s"], gid["b"]), (gid["c"], gid["bs"]),
                            (gid["b"], gid["bb"]))
    e_y, hf_s = (gid["e"], gid["y"]), (gid["hf"], gid["s"])
    cases = [
        ([s_c, b_bb], (True, False, None)),  # closed-form hit, then a GJK row with a bad geom
        ([b_bb, s_c], (None, None, gid["bb"])),  # the bad GJK row first: the row order's error
        ([s_b, c_bs], (True, False, None)),  # a GJK hit before a bad closed-form row
        ([c_bs, s_b], (None, None, gid["bs"])),
        ([hf_s, e_y, s_b, c_bs, s_c], (True, False, None)),
        ([hf_s, e_y, b_bb, s_b, s_c], (None, None, gid["bb"])),
        ([hf_s, e_y], (False, True, None)),
        ([e_y, hf_s, c_bs], (None, None, gid["bs"])),
    ]
    for order, (hit, skipped, g) in cases:
        rows = np.array([(0, *p) for p in order], np.int32)
        got = _on_rows(col, q, rows, monkeypatch)
        if g is None:
            assert got[2] is None and bool(got[0][0]) == hit and bool(got[1][0]) == skipped, (order, got)
        else:
            assert got[2] == f"qpos: configuration 0 gives a non-finite pose (NaN or inf) of geom {g}", (order, got)
        _equal(got, _row_order(m, col, q, rows))
    good = q.copy()
    good[0, f] = good[0, -1] = 0.0
    assert col.check_batch(good).in_collision.tolist() == [True]  # usable after the errors


SCENE = """<mujoco><asset><hfield name="h" nrow="4" ncol="4" size=".6 .6 .1 .05"
  elevation="0 .2 .4 0 .1 .3 .5 .2 0 .2 .4 .1 .3 0 .2 .1"/></asset>
<worldbody>
<geom name="floor" type="plane" size="3 3 .1" margin=".02" gap=".01"/>
<geom name="hf" type="hfield" hfield="h" pos=".8 0 0"/>
<body name="mc" mocap="true" pos="-.3 0 .25"><geom name="mcs" type="sphere" size=".1"/></body>
<body name="a" pos="0 0 .35"><freejoint/>
  <geom name="a1" type="capsule" size=".05 .15" margin=".01"/><geom name="a2" type="box" size=".08 .05 .05"
    pos=".15 0 0"/></body>
<body name="b" pos=".2 .2 .35"><freejoint/>
  <geom name="b1" type="sphere" size=".07"/><geom name="b2" type="ellipsoid" size=".05 .08 .1" pos="0 .1 0"
    contype="2" conaffinity="2"/></body>
<body name="c" pos="-.2 .2 .35"><freejoint/>
  <geom name="c1" type="cylinder" size=".06 .1"/><geom name="c2" type="capsule" size=".04 .1" pos=".1 0 0"
    margin=".03" gap=".02"/></body>
<body name="d" pos=".5 0 .35"><freejoint/><geom name="d1" type="box" size=".06 .06 .06"/>
  <geom name="d2" type="sphere" size=".05" pos="0 0 .1"/></body>
</worldbody>
<contact><pair geom1="a1" geom2="b1" margin=".04" gap=".03"/><pair geom1="b2" geom2="c1"/>
  <pair geom1="floor" geom2="d1" margin=".05"/><exclude body1="a" body2="c"/></contact>
</mujoco>"""


def _scene_configs(m, n, seed):
    rng = np.random.default_rng(seed)
    q = np.tile(m.qpos0, (n, 1))
    for b in range(4):
        q[:, 7 * b:7 * b + 3] += rng.uniform(-0.2, 0.2, (n, 3))
        quat = rng.normal(size=(n, 4))
        q[:, 7 * b + 3:7 * b + 7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    return q


def _contacts_answer(m, col, q, subset=None):
    # in_collision by Collider.contacts on MuJoCo's poses, and whether some pair is within 1e-7
    # of its margin (either answer right there)
    d = mujoco.MjData(m)
    hit = np.zeros(len(q), bool)
    near = np.zeros(len(q), bool)
    for i, x in enumerate(q):
        d.qpos[:] = x
        mujoco.mj_kinematics(m, d)
        c = col.contacts(d)
        keep = np.ones(len(c), bool) if subset is None else np.isin(c.geom, list(subset)).all(axis=1)
        v = (c.dist - c.margin)[keep]
        hit[i] = bool(np.any(v < 0))
        near[i] = bool(np.any(np.abs(v) < 1e-7))
    return hit, near


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 8, 9, 16, 17, 1000, 2049])
def test_every_filter_on_every_path(n, monkeypatch):
    m = mujoco.MjModel.from_xml_string(SCENE)
    q = _scene_configs(m, n, 100 + n)
    for geoms in (None, ["a1", "a2", "b1", "b2", "c1", "floor", "hf", "mcs"]):
        col = cm.Collider(m, geoms=geoms)
        assert col.broadphase.broadphase.batch_path == "lanes"
        got = col.check_batch(q)
        with monkeypatch.context() as mp:
            mp.setattr(ccol.Collider, "_in_lanes", lambda *a, **k: False)
            worlds = col.check_batch(q)
            dist = col.check_batch(q, distance=True)
        assert np.array_equal(got.in_collision, worlds.in_collision)
        assert np.array_equal(got.skipped, worlds.skipped)
        assert np.array_equal(got.in_collision, dist.in_collision)  # distances asked or not
        assert not np.any(got.skipped & got.in_collision)
        if n in (17, 1000):
            sub = None if geoms is None else {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, x) for x in geoms}
            k = min(n, 200)
            ref, near = _contacts_answer(m, col, q[:k], sub)
            assert np.array_equal(got.in_collision[:k][~near], ref[~near])
            assert 0 < ref.sum() < k and got.skipped.any()


def test_threads_and_huge_coordinates():
    m = mujoco.MjModel.from_xml_string(SCENE)
    q = _scene_configs(m, 600, 5)
    col = cm.Collider(m)
    ref = col.check_batch(q)
    before = numba.get_num_threads()
    try:
        for t in range(2, 5):
            numba.set_num_threads(min(t, numba.config.NUMBA_NUM_THREADS))
            r = col.check_batch(q)
            assert np.array_equal(r.in_collision, ref.in_collision) and np.array_equal(r.skipped, ref.skipped)
    finally:
        numba.set_num_threads(before)
    got = in_threads(lambda i: [col.check_batch(q[i::2]) for _ in range(6)], 2)
    for i in range(2):
        assert len(got[i]) == 6
        for r in got[i]:
            assert np.array_equal(r.in_collision, ref.in_collision[i::2])
            assert np.array_equal(r.skipped, ref.skipped[i::2])
    # a refused pose: named, and the Collider answers as before after it
    for k, v in ((0, 1e200), (9, -1e300), (599, 1e160)):
        bad = q.copy()
        bad[k, 7] = v
        with pytest.raises(ValueError, match=f"configuration {k} "):
            col.check_batch(bad)
        r = col.check_batch(q)
        assert np.array_equal(r.in_collision, ref.in_collision) and np.array_equal(r.skipped, ref.skipped)


@pytest.mark.skipif(not MODELS.is_dir(), reason="the test models are not present (../shared/models)")
@pytest.mark.parametrize("scene", ["shadow_hand", "humanoid100"])
def test_real_models_with_and_without_distances(scene, monkeypatch):
    m = mujoco.MjModel.from_xml_path(str(MODELS / scene / "scene.xml"))
    q = testing.random_configurations(m, 40, np.random.default_rng(3), outside=0.25)
    bodies = list(range(1, m.nbody))
    for kw in ({}, {"bodies": [bodies[: len(bodies) // 3], bodies[len(bodies) // 3:]]}):
        col = cm.Collider(m, **kw)
        got = col.check_batch(q)
        dist = col.check_batch(q, distance=True)
        assert np.array_equal(got.in_collision, dist.in_collision)
        with monkeypatch.context() as mp:
            mp.setattr(ccol.Collider, "_in_lanes", lambda *a, **k: False)
            mp.setattr(ccol.Collider, "_trees", lambda self: False)
            worlds = col.check_batch(q)
        assert np.array_equal(got.in_collision, worlds.in_collision)
        assert 0 < got.in_collision.sum() < len(q)

