"""check_batch's early exit by kinematic trees (`collide._kernels.check_trees`, issue 43).

The trees' path may only ever say "in collision" where the full path (batch broad phase, then
`check.check_worlds`) says so too, and leave every other configuration to it: so `check_batch`
with the early exit must equal `check_batch` without it (``TREE_SHARE = -1``), configuration by
configuration, on scenes where both paths really decide something: a scene built here (four arms,
a floating body, a static obstacle, a floor, an explicit ``<pair>`` between two arms, an
``<exclude>`` inside an arm, a geom whose contype matches nothing), with ``geoms=`` / ``bodies=``
subsets, and 22_humanoids. Each test also shows that the trees decided some configurations, that
some collided only through pairs between trees (the full path's), and that some were free.
"""

from __future__ import annotations

import mujoco
import numba
import numpy as np
import pytest

import collide.mujoco as cm
from collide import collider as ccol
from collide import testing
from collide._kernels import check_trees as kt
from contact_check import MODELS


def _arm(i: int, x: float, y: float) -> str:
    # three capsule links on hinges about alternating axes: they fold onto themselves and reach
    # the next arm and the floor
    return (f'<body name="a{i}" pos="{x} {y} .35"><joint type="hinge" axis="0 1 0" range="-2.6 2.6"/>'
            f'<geom name="a{i}g0" type="capsule" size=".05" fromto="0 0 0 0 0 .3"/>'
            f'<body name="b{i}" pos="0 0 .3"><joint type="hinge" axis="1 0 0" range="-2.6 2.6"/>'
            f'<geom name="b{i}g" type="capsule" size=".05" fromto="0 0 0 0 0 .3"/>'
            f'<body name="c{i}" pos="0 0 .3"><joint type="hinge" axis="0 1 0" range="-2.6 2.6"/>'
            f'<geom name="c{i}g" type="capsule" size=".05" fromto="0 0 0 0 0 .3"/>'
            f'<geom name="c{i}s" type="sphere" size=".07" pos="0 0 .3"/></body></body></body>')


def _arms_model() -> mujoco.MjModel:
    arms = "".join(_arm(i, x, y) for i, (x, y) in enumerate([(0, 0), (.5, 0), (0, .5), (.5, .5)]))
    return mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><geom name="floor" type="plane" size="5 5 .1"/>'
        '<body name="post" pos=".25 .25 .2"><geom name="post" type="box" size=".04 .04 .2"/></body>'
        + arms +
        '<body name="float" pos="1.2 0 .5"><freejoint/><geom name="fl" type="box" size=".1 .1 .1"/>'
        '<geom name="ghost" type="sphere" size=".1" pos=".2 0 0" contype="4" conaffinity="4"/></body>'
        '</worldbody><contact><pair geom1="c0s" geom2="c1s" margin=".2"/><exclude body1="a2" body2="c2"/>'
        '</contact></mujoco>')


def _configs(model, n: int, seed: int) -> np.ndarray:
    q = testing.random_configurations(model, n, np.random.default_rng(seed), outside=0.1)
    fa = model.jnt_qposadr[model.jnt_type == mujoco.mjtJoint.mjJNT_FREE]
    for a in fa:  # the floating box somewhere near the arms
        q[:, a:a + 3] = np.random.default_rng(seed + 1).uniform([-.2, -.2, .05], [1.4, .9, 1.0], (n, 3))
    return q


def _both(model, q, monkeypatch, **kw):
    """check_batch with the early exit, and without it; the trees' own answer (kernel call)."""
    col = cm.Collider(model, **kw)
    trees = col._trees()
    decided = np.zeros(len(q), np.bool_)
    if trees:
        col.check_batch(q[:2])  # kernels ready
        _, kargs = col._setup_check(), col.table._kargs
        kt.check_trees(q, ccol.TREE_QMAX, *col._setup_check(), *trees, 4, 1, np.zeros(1, np.int64), *kargs, decided)
    early = col.check_batch(q)
    with monkeypatch.context() as m:
        m.setattr(ccol, "TREE_SHARE", -1.0)
        full = cm.Collider(model, **kw).check_batch(q)
    return trees, decided, early, full


def test_the_trees_path_is_the_full_path_on_arms_pairs_excludes_and_subsets(monkeypatch):
    model = _arms_model()
    q = _configs(model, 600, 5)
    arms = ["a0", "b0", "c0", "a1", "b1", "c1"]
    # (subset, whether the trees decide some configurations there): the whole scene; a geom subset
    # with two arms' own pairs; two arms against the rest (the trees hold only their pairs with the
    # floor and the post, which never touch: all left to the full path)
    cases = [(dict(), True), (dict(geoms=["a0g0", "b0g", "c0g", "c0s", "a1g0", "b1g", "c1g", "c1s", "floor", "post",
                                          "fl"]), True),
             (dict(bodies=(arms, ["world", "post", "a2", "b2", "c2", "a3", "b3", "c3", "float"])), False)]
    active = 0
    for kw, decides in cases:
        trees, decided, early, full = _both(model, q, monkeypatch, **kw)
        assert np.array_equal(early.in_collision, full.in_collision), kw
        assert np.array_equal(early.skipped, full.skipped), kw
        assert not (decided & ~full.in_collision).any(), kw  # the trees only ever find real contacts
        assert (full.in_collision & ~decided).sum() > 5, kw  # in collision through pairs between trees
        assert (~full.in_collision).sum() > 5, kw  # and free ones
        if decides:
            assert trees and decided.sum() > 20, kw
            active += 1
    assert active >= 2  # the whole scene and at least one subset took the trees' path


def test_the_sample_gate_and_huge_coordinates_leave_configurations_to_the_full_path(monkeypatch):
    model = _arms_model()
    q = _configs(model, 400, 9)
    free = model.jnt_qposadr[model.jnt_type == mujoco.mjtJoint.mjJNT_FREE][0]
    col = cm.Collider(model)
    trees = col._trees()
    assert trees
    # configurations with a coordinate beyond TREE_QMAX: never decided by the trees
    big = q.copy()
    big[::3, free] = 2 * ccol.TREE_QMAX
    hit = np.zeros(len(q), np.bool_)
    col.check_batch(q[:2])
    kt.check_trees(big, ccol.TREE_QMAX, *col._setup_check(), *trees, 8, 1, np.zeros(1, np.int64), *col.table._kargs,
                   hit)
    assert not hit[::3].any() and hit.any()
    # a sample the trees decide little of (free configurations first): the rest goes the full way
    _, decided, early, full = _both(model, q, monkeypatch)
    order = np.argsort(decided, kind="stable")  # undecided first: the sample of TREE_SAMPLE fails the gate
    assert 2 * decided[order][:ccol.TREE_SAMPLE].sum() < ccol.TREE_SAMPLE and decided.any()
    again = cm.Collider(model).check_batch(q[order])
    assert np.array_equal(again.in_collision, full.in_collision[order])
    for x in (big, q):
        with monkeypatch.context() as m:
            m.setattr(ccol, "TREE_SHARE", -1.0)
            ref = cm.Collider(model).check_batch(x)
        assert np.array_equal(cm.Collider(model).check_batch(x).in_collision, ref.in_collision)
    # one thread and several blocks: the same answers
    old = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        monkeypatch.setattr(ccol, "BLOCK", 37)
        one = cm.Collider(model).check_batch(q)
    finally:
        numba.set_num_threads(old)
    assert np.array_equal(one.in_collision, full.in_collision)


def test_a_bad_configuration_is_named_by_its_own_index():
    model = _arms_model()
    q = _configs(model, 300, 2)
    col = cm.Collider(model)
    assert col._trees()
    free = model.jnt_qposadr[model.jnt_type == mujoco.mjtJoint.mjJNT_FREE][0]
    bad = q.copy()
    bad[277, free] = 1e300  # finite, beyond the broad phase's range: refused, and named
    with pytest.raises(ValueError, match="configuration 277"):
        col.check_batch(bad)
    bad = q.copy()
    bad[123, 4] = np.nan
    with pytest.raises(ValueError, match="configuration 123"):
        col.check_batch(bad)
    assert np.array_equal(col.check_batch(q).in_collision, cm.Collider(model).check_batch(q).in_collision)


@pytest.mark.skipif(not (MODELS / "22_humanoids").is_dir(), reason="the test models are not present")
def test_22_humanoids_trees_path_is_the_full_path(monkeypatch):
    model = mujoco.MjModel.from_xml_path(str(MODELS / "22_humanoids" / "scene.xml"))
    q = testing.random_configurations(model, 300, np.random.default_rng(4), outside=0.2)
    trees, decided, early, full = _both(model, q, monkeypatch)
    assert trees and decided.sum() > 100
    assert np.array_equal(early.in_collision, full.in_collision)
    assert not (decided & ~full.in_collision).any()
