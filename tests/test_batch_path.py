"""`BroadPhase.batch_path`, `BroadPhase.pairs_batch_joints` and `KinematicTree`: the public batch
entry on joint configurations, on both paths, and its checks."""

import copy
import pickle

import mujoco
import numpy as np
import pytest

import collide.mujoco as cm
from collide import BroadPhase
from collide.broadphase import KinematicTree

# A floor, a free body and a chain of every joint type under a hinge: enough pairs to compare.
XML = """<mujoco><worldbody><geom type="plane" size="5 5 .1"/>
  <body pos="0 0 .3"><freejoint/><geom type="box" size=".1 .08 .06"/></body>
  <body pos=".2 0 .2"><joint type="hinge" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 .3 0 0" size=".05"/>
    <body pos=".3 0 0"><joint type="ball"/><geom type="sphere" size=".08"/>
      <body pos=".1 0 0"><joint type="slide" axis="1 0 0"/><geom type="box" size=".05 .05 .05"/></body>
    </body></body></worldbody></mujoco>"""


def _qpos(model, worlds, rng):
    q = np.tile(model.qpos0, (worlds, 1))
    q[:, :3] = rng.uniform(-0.4, 0.4, (worlds, 3)) + [0.2, 0, 0.2]  # the free body, near the chain
    q[:, 3:7] = rng.normal(size=(worlds, 4))
    q[:, 7] = rng.uniform(-1.5, 1.5, worlds)  # hinge
    q[:, 8:12] = rng.normal(size=(worlds, 4))  # ball
    q[:, 12] = rng.uniform(-0.1, 0.1, worlds)  # slide
    return q


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_string(XML)


def test_batch_path_is_chosen_forced_and_kept(model):
    art = cm.articulation(model)
    assert BroadPhase(art).batch_path == "lanes"  # a small model
    assert BroadPhase(art, batch_path="lanes").batch_path == "lanes"
    worlds = BroadPhase(art, batch_path="worlds")
    assert worlds.batch_path == "worlds"
    assert copy.copy(worlds).batch_path == "worlds" and pickle.loads(pickle.dumps(worlds)).batch_path == "worlds"
    with pytest.raises(ValueError, match="batch_path: expected 'auto', 'lanes' or 'worlds', got 'simd'"):
        BroadPhase(art, batch_path="simd")
    xml = "<mujoco><worldbody>" + "".join(
        f'<body pos="{i % 10} {i // 10} 0"><freejoint/><geom size=".3"/></body>' for i in range(100)) + \
        "</worldbody></mujoco>"
    art_big = cm.articulation(mujoco.MjModel.from_xml_string(xml))
    assert BroadPhase(art_big).batch_path == "worlds"  # more static body pairs than the lanes take
    with pytest.raises(ValueError, match="batch_path: 'lanes' takes a model of at most"):
        BroadPhase(art_big, batch_path="lanes")


@pytest.mark.parametrize("path", ["lanes", "worlds"])
def test_pairs_batch_joints_equal_poses_then_batch(model, path):
    # The fused call (lanes: poses computed in each thread's workspace) and the worlds' path
    # (poses, then the per-world kernel) give pairs_batch's rows on KinematicTree.poses, and its
    # stats, which give the single worlds' rows; the poses are MuJoCo's.
    bp = BroadPhase(cm.articulation(model), batch_path=path)
    tree = cm.kinematic_tree(model)
    q = _qpos(model, 21, np.random.default_rng(3))
    got = bp.pairs_batch_joints(tree, q)
    stats = bp.stats
    pos, rot = tree.poses(q)
    want = bp.pairs_batch(pos, rot)
    assert np.array_equal(got, want) and bp.stats == stats and stats["pairs"] == len(got)
    for w in range(len(q)):
        assert np.array_equal(got[got[:, 0] == w, 1:], bp.pairs(pos[w], rot[w]))
    assert len(np.unique(got[:, 0])) > 15 and len(got) > 40  # the scene had hits in most worlds
    data = mujoco.MjData(model)
    data.qpos[:] = q[5]
    mujoco.mj_kinematics(model, data)
    np.testing.assert_allclose(pos[5], data.xpos, atol=1e-12)
    np.testing.assert_allclose(rot[5].reshape(-1, 9), data.xmat, atol=1e-12)


@pytest.mark.parametrize("path", ["lanes", "worlds"])
def test_pairs_batch_joints_name_bad_input_and_keep_working(model, path):
    bp = BroadPhase(cm.articulation(model), batch_path=path)
    tree = cm.kinematic_tree(model)
    q = _qpos(model, 11, np.random.default_rng(4))
    want = bp.pairs_batch_joints(tree, q)
    bad = q.copy()
    bad[9, 7] = np.nan  # the hinge's angle
    for arg in (bad, bad.tolist(), np.asfortranarray(bad)):  # unchecked on the lanes, then named; checked
        with pytest.raises(ValueError, match=r"qpos: non-finite value \(NaN or inf\) at index \(9, 7\)"):
            bp.pairs_batch_joints(tree, arg)
    far = q.copy()
    far[4, 0] = 1e200  # a finite qpos, a pose the broad phase refuses: the world and body named
    with pytest.raises(ValueError, match="world 4, body 1: position beyond"):
        bp.pairs_batch_joints(tree, far)
    with pytest.raises(ValueError, match="qpos: expected shape"):
        bp.pairs_batch_joints(tree, q[:, :5])
    with pytest.raises(ValueError, match="tree: expected a collide.broadphase.KinematicTree, got tuple"):
        bp.pairs_batch_joints(tree.arrays, q)
    other = KinematicTree(*(a[:3] if i in (1, 2, 3, 4, 5) else a for i, a in enumerate(tree.arrays)))
    with pytest.raises(ValueError, match="tree: has 3 bodies, this broad phase's articulation 5"):
        bp.pairs_batch_joints(other, q)
    assert np.array_equal(bp.pairs_batch_joints(tree, q), want)  # still works


def _arrays(model):
    return dict(qpos0=model.qpos0, body_parent=model.body_parentid, body_pos=model.body_pos,
                body_quat=model.body_quat, body_jntadr=model.body_jntadr, body_jntnum=model.body_jntnum,
                jnt_type=model.jnt_type, jnt_qposadr=model.jnt_qposadr, jnt_pos=model.jnt_pos,
                jnt_axis=model.jnt_axis)


def _with(model, **changes):
    a = {k: np.array(v) for k, v in _arrays(model).items()}
    for k, (index, value) in changes.items():
        a[k][index] = value
    return a


@pytest.mark.parametrize("changes, message", [
    (dict(body_parent=(2, 3)), "body_parent: body 2's parent 3 is not a body before it"),
    (dict(body_parent=(1, -1)), "body_parent: body 1's parent -1 is not a body before it"),
    (dict(body_jntnum=(0, 1)), r"body_jntnum: body 0 \(the world\) has no joints"),
    (dict(body_jntnum=(4, -1)), "body_jntnum: negative at body 4"),
    (dict(body_jntadr=(4, 4)), "body_jntadr: body 4's joints 4..4 are not among the 4 joints"),
    (dict(jnt_type=(2, 7)), r"jnt_type: joint 2 has type 7, not one of 0 \(free\)"),
    (dict(jnt_qposadr=(3, 13)), "jnt_qposadr: joint 3's 1 qpos entries from 13 are not among the 13"),
    (dict(jnt_qposadr=(2, 10)), "jnt_qposadr: joint 2's 4 qpos entries from 10 are not among the 13"),
    (dict(body_jntnum=(1, 2)), "jnt_type: body 1 has a free joint among 2 joints"),
])
def test_kinematic_tree_refuses_what_the_kernels_would_misread(model, changes, message):
    with pytest.raises(ValueError, match=message):
        KinematicTree(**_with(model, **changes))


def test_kinematic_tree_shapes_and_views(model):
    a = _arrays(model)
    with pytest.raises(ValueError, match=r"body_pos: expected shape \(5, 3\), got \(4, 3\)"):
        KinematicTree(**dict(a, body_pos=model.body_pos[:4]))
    with pytest.raises(ValueError, match=r"jnt_axis: expected shape \(4, 3\)"):
        KinematicTree(**dict(a, jnt_axis=model.jnt_axis[:, :2]))
    with pytest.raises(ValueError, match="jnt_type: expected integers, got dtype float64"):
        KinematicTree(**dict(a, jnt_type=np.asarray(model.jnt_type, float)))
    with pytest.raises(ValueError, match=r"body_parent: expected shape \(L,\) with L >= 1"):
        KinematicTree(**dict(a, body_parent=np.zeros(0, int)))
    tree = KinematicTree(**a)
    assert repr(tree) == "KinematicTree(5 bodies, 4 joints, nq=13)"
    # the float arrays are the model's own: a change in place reaches the tree's poses
    q = _qpos(model, 2, np.random.default_rng(5))
    before = tree.poses(q)[0]
    model.body_pos[2, 2] += 1.0
    try:
        after = tree.poses(q)[0]
    finally:
        model.body_pos[2, 2] -= 1.0
    assert np.allclose(after[:, 2:] - before[:, 2:], [0, 0, 1.0]) and np.array_equal(after[:, :2], before[:, :2])
