"""Adversarial review of check_batch decided in the broad phase's pass (2e29ab3, `collide._kernels.check_lanes`).

The strongest attacks of helper-45's review, kept quick (no kernel compiled for them): a hand-made
scene with every filter the decision reads (explicit ``<pair>`` s inside one body and with the world
body, margins and gaps, an ``<exclude>``, a plane, a mocap body, ball, hinge, slide and free joints,
``mjENBL_OVERRIDE``) at batch sizes about the lanes' groups of 8, against the old path
(`collide._kernels.check.check_worlds` on `pairs_batch`'s rows) and MuJoCo; every layout of
``qpos`` a user passes; a pose the broad phase refuses in one configuration (named, the Collider
right after it); one thread, and two Python threads on one Collider; a model without joints.
"""

from __future__ import annotations

import mujoco
import numba
import numpy as np
import pytest

import collide.mujoco as cm
from collide import collider as ccol
from collide import testing
from _threads import in_threads
from test_check import mujoco_active

MIX = """<mujoco><option {opt}/><worldbody>
<geom name="floor" type="plane" size="3 3 .1" margin="0.02" gap="0.01"/>
<geom name="wbox" type="box" size=".1 .1 .1" pos="0.5 0 0.3"/>
<body name="mc" mocap="true" pos="-0.4 0 0.3"><geom type="sphere" size=".12"/></body>
<body name="a" pos="0 0 1"><joint type="ball"/>
  <geom name="a1" type="capsule" size=".05 .3" pos="0 0 -.35" margin=".01"/>
  <geom name="a2" type="sphere" size=".04" pos=".2 0 -.1"/>
  <body name="b" pos="0 0 -.7"><joint type="hinge" axis="0 1 0" range="-2 2"/>
    <joint type="slide" axis="1 0 0" range="-.3 .3"/><geom name="b1" type="box" size=".05 .05 .2" pos="0 0 -.2"/>
    <geom name="b2" type="ellipsoid" size=".05 .08 .1" pos="0 .1 -.1" contype="2" conaffinity="2"/>
    <geom name="bp" type="box" size=".2 .2 .01" pos="0 0 -.4"/></body></body>
<body name="f" pos=".3 .3 .4"><freejoint/><geom name="f1" type="cylinder" size=".06 .1"/>
  <geom name="f2" type="box" size=".04 .04 .04" pos=".13 0 0"/></body>
</worldbody><contact><pair geom1="a1" geom2="a2" margin=".05"/><pair geom1="floor" geom2="wbox"/>
<pair geom1="b2" geom2="f1" gap=".02" margin=".03"/><pair geom1="f1" geom2="f2"/><pair geom1="floor" geom2="bp"/>
<exclude body1="a" body2="f"/></contact></mujoco>"""
OVERRIDE = 'o_margin="0.01"><flag override="enable"/></option><option'


def _old(col, q):
    # the path before 2e29ab3: check_worlds on pairs_batch's rows
    real = ccol.Collider._in_lanes
    ccol.Collider._in_lanes = lambda *a, **k: False
    try:
        return col.check_batch(q)
    finally:
        ccol.Collider._in_lanes = real


def _same(a, b):
    assert np.array_equal(a.in_collision, b.in_collision)
    assert np.array_equal(a.skipped, b.skipped)


def _mix(opt=""):
    model = mujoco.MjModel.from_xml_string(MIX.format(opt=opt))
    q = testing.random_configurations(model, 300, np.random.default_rng(3), outside=0.25)
    q[:, 7:10] = np.random.default_rng(4).uniform(-0.6, 0.6, (len(q), 3)) + (0.0, 0.0, 0.5)  # the free body about
    return model, q


@pytest.mark.parametrize("opt", ["", OVERRIDE])
def test_every_filter_at_the_group_edges(opt):
    model, q = _mix(opt)
    col = cm.Collider(model)
    assert col.broadphase.broadphase.batch_path == "lanes"
    got = col.check_batch(q)
    _same(got, _old(col, q))
    mj, _ = mujoco_active(model, mujoco.MjData(model), q)
    assert np.array_equal(got.in_collision, mj)
    assert 0 < got.in_collision.sum() < len(q)
    for n in (1, 7, 8, 9, 17):  # a group of 8 part full, full, one over
        _same(col.check_batch(q[-n:]), _old(col, q[-n:]))
    assert col.check_batch(q[:0]).in_collision.shape == (0,)


def test_every_layout_of_qpos_is_the_same_answer():
    model, q = _mix()
    col = cm.Collider(model)
    ref = _old(col, q)
    ro = q.copy()
    ro.setflags(write=False)
    wide = np.repeat(q, 2, axis=1)[:, ::2]  # columns strided
    for x in (np.asfortranarray(q), np.repeat(q, 2, axis=0)[::2], wide, ro, q.tolist()):
        _same(col.check_batch(x), ref)


@pytest.mark.parametrize("bad", [0, 7, 8, 13])
def test_a_refused_pose_is_named_and_the_collider_still_answers(bad):
    # a finite qpos whose body lands beyond the broad phase's coordinate limit
    model, q = _mix()
    col = cm.Collider(model)
    ref = _old(col, q[:16])
    x = q[:16].copy()
    x[bad, 7] = 1e200
    with pytest.raises(ValueError, match=f"configuration {bad} gives a pose the broad phase refuses"):
        col.check_batch(x)
    _same(col.check_batch(q[:16]), ref)


def test_one_thread_and_two_callers_on_one_collider():
    model, q = _mix()
    col = cm.Collider(model)
    parts = [q[:150], q[150:]]
    refs = [_old(col, p) for p in parts]
    old = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        _same(col.check_batch(q), _old(col, q))
    finally:
        numba.set_num_threads(old)
    got = in_threads(lambda i: [col.check_batch(parts[i]) for _ in range(10)], 2)
    for i in range(2):
        assert len(got[i]) == 10
        for r in got[i]:
            _same(r, refs[i])


def test_a_model_without_joints():
    # nq = 0 (qpos (B, 0)): a mocap body's sphere and a static body's in the world's box, all
    # welded to the world as MuJoCo filters them (no contact)
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><geom type="box" size=".1 .1 .1"/><body pos=".15 0 0"><geom type="sphere" size=".1"/>'
        '</body><body mocap="true" pos="0 0 .15"><geom type="sphere" size=".1"/></body></worldbody></mujoco>')
    col = cm.Collider(model)
    q = np.zeros((9, 0))
    got = col.check_batch(q)
    mj, _ = mujoco_active(model, mujoco.MjData(model), q)
    assert np.array_equal(got.in_collision, mj)
    _same(got, _old(col, q))
