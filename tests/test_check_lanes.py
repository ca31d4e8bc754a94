"""check_batch decided in the batch broad phase's pass (`collide._kernels.check_lanes`).

Its twin is the path it replaces: `collide._kernels.check.check_worlds` on the rows of
`collide.mujoco.BroadPhase.pairs_batch` (`Collider._in_lanes` patched to decline). The two must give
the same ``in_collision`` and ``skipped`` on every configuration: on real models (with hits and
misses), on checked subsets, where the broad phase's buffers are too short (the call runs again),
on a model with a height field (whose pairs the broad phase drops), and where the broad phase's
own kinematics is overridden (the old path then); the broad phase's counters are those of
``pairs_batch`` on the same configurations.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import collide.mujoco as cm
from collide import collider as ccol
from collide import testing
from collide._kernels import check_lanes as kl
from contact_check import MODELS

NO_MODELS = f"the test models are not present at {MODELS} (../shared/models)"


def _twin(col, q, monkeypatch):
    # check_batch through check_worlds on pairs_batch's rows (the path before check_lanes)
    with monkeypatch.context() as m:
        m.setattr(ccol.Collider, "_in_lanes", lambda *a, **k: False)
        return col.check_batch(q)


def _same(a, b):
    assert np.array_equal(a.in_collision, b.in_collision)
    assert np.array_equal(a.skipped, b.skipped)


@pytest.mark.skipif(not MODELS.is_dir(), reason=NO_MODELS)
@pytest.mark.parametrize("scene", ["franka_emika_panda", "shadow_hand", "unitree_h1", "humanoid"])
def test_the_lanes_path_is_check_worlds_on_real_models(scene, monkeypatch):
    model = mujoco.MjModel.from_xml_path(str(MODELS / scene / "scene.xml"))
    q = testing.random_configurations(model, 600, np.random.default_rng(7), outside=0.2)
    col = cm.Collider(model)
    assert col.broadphase.broadphase.batch_path == "lanes"
    calls = []
    real = kl.check_lanes_kin

    def spy(*a):
        calls.append(len(a[0]))
        return real(*a)

    with monkeypatch.context() as m:
        m.setattr(kl, "check_lanes_kin", spy)
        got = col.check_batch(q)
    assert calls == [len(q)]  # the lanes decided them, in one call
    ref = _twin(col, q, monkeypatch)
    _same(got, ref)
    assert 0 < got.in_collision.sum() < len(q)  # hits and misses both
    # the broad phase's counters: those of pairs_batch on the same configurations
    stats = col.broadphase.stats.copy()
    col.broadphase.pairs_batch(model, q)
    assert np.array_equal(stats, col.broadphase.stats)


def test_subsets_short_buffers_and_blocks_are_check_worlds(monkeypatch):
    model = cm.default_scene(seed=3, objects=12)
    q = testing.random_configurations(model, 300, np.random.default_rng(4), outside=0.1)
    nb = model.nbody
    moving = list(range(1, nb))
    half = (list(range(1, nb // 2)), [0] + list(range(nb // 2, nb)))
    for kw in ({}, {"bodies": moving}, {"bodies": half}):
        col = cm.Collider(model, **kw)
        ref = _twin(col, q, monkeypatch)
        assert 0 < ref.in_collision.sum() < len(q), (kw, ref.in_collision.sum())
        _same(col.check_batch(q), ref)
        # key and body-pair buffers far too short: the call finds it out, grows them, runs again
        batch = col.broadphase.broadphase._batch
        batch.set_buffers(1, 1)
        _same(col.check_batch(q), ref)
        assert batch.buffers["keys"].shape[1] > 1
        with monkeypatch.context() as m:
            m.setattr(ccol, "BLOCK", 37)  # several blocks
            _same(col.check_batch(q), ref)


def test_height_field_pairs_the_broad_phase_drops_are_dropped(monkeypatch):
    # a height field on a free body over a plane, and a sphere: the plane-hfield pair has no
    # collision function (the broad phase drops it); the sphere-hfield pair is reported skipped
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><asset><hfield name="h" nrow="3" ncol="3" size=".3 .3 .05 .05" elevation="0 0 0 0 0 0 0 0 0"/>'
        '</asset><worldbody><geom type="plane" size="2 2 .1"/>'
        '<body pos="0 0 .2"><freejoint/><geom type="hfield" hfield="h"/></body>'
        '<body pos="1 0 .5"><freejoint/><geom type="sphere" size=".1"/></body></worldbody></mujoco>')
    rng = np.random.default_rng(5)
    q = np.tile(model.qpos0, (64, 1))
    q[:, 2] = rng.uniform(-0.02, 0.3, len(q))  # the height field near the plane, or not
    q[:, 7:10] = rng.uniform((-0.5, -0.5, -0.05), (0.5, 0.5, 0.4), (len(q), 3))  # the sphere anywhere about it
    col = cm.Collider(model)
    got = col.check_batch(q)
    ref = _twin(col, q, monkeypatch)
    _same(got, ref)
    near = np.abs(q[:, 2]) < 0.1
    assert got.skipped.any() and not got.skipped.all() and (near & ~got.skipped).any()


def test_a_broad_phase_with_its_own_kinematics_keeps_check_worlds(monkeypatch):
    model = cm.default_scene(seed=3, objects=12)
    q = testing.random_configurations(model, 200, np.random.default_rng(6))
    seen = []

    class Own(cm.BroadPhase):
        def kinematics_batch(self, m, qpos):
            seen.append(len(qpos))
            return super().kinematics_batch(m, qpos)

    col = cm.Collider(model)
    ref = col.check_batch(q)
    col.broadphase = Own(model)
    called = []
    real = kl.check_lanes_kin
    with monkeypatch.context() as m:
        m.setattr(kl, "check_lanes_kin", lambda *a: called.append(1) or real(*a))
        got = col.check_batch(q)
    _same(got, ref)
    assert seen and not called
