"""The swept broad phase (`BroadPhase.pairs_swept`, issue 44): every pair that may touch at some time
of a step, against its brute-force twin and a sampling oracle."""

from __future__ import annotations

import os

import numpy as np
import pytest

import collide
from collide import shapes, testing
from collide.testing.swept import brute_force_swept_pairs, motion_poses
from _threads import in_child, in_threads


def _set(p):
    return {tuple(map(int, r)) for r in np.asarray(p).reshape(-1, 2)}


def _scenes():
    return [
        testing.chain(12, seed=1, planes=1),
        testing.branching_tree(30, seed=2, planes=1),
        testing.many_robots(4, links=5, seed=3, planes=1),
        testing.free_hulls(16, seed=4, filters=True, planes=1),
    ]


def _pose_pair(scene, rng, size):
    L = scene.articulation.body_count
    p0, r0 = scene.poses(rng)
    if size is None:
        p1, r1 = scene.poses(rng)
    else:
        turn = testing.scenes.random_rotation(rng, L)
        ang = rng.uniform(0, size, L)
        from scipy.spatial.transform import Rotation
        rv = Rotation.from_matrix(turn).as_rotvec()
        rv *= (ang / np.maximum(np.linalg.norm(rv, axis=1), 1e-300))[:, None]
        r1 = np.einsum("lij,ljk->lik", Rotation.from_rotvec(rv).as_matrix(), r0)
        p1 = p0 + rng.uniform(-size, size, (L, 3))
        r1[0], p1[0] = r0[0], p0[0]  # the world stays put
    return p0, r0, p1, r1


@pytest.mark.parametrize("size", [0.05, 0.5, None])
def test_swept_equals_its_brute_force_twin(size):
    rng = np.random.default_rng(10)
    found = 0
    for scene in _scenes():
        a = scene.articulation
        bp = collide.BroadPhase(a)
        for _ in range(4):
            p0, r0, p1, r1 = _pose_pair(scene, rng, size)
            fast = _set(bp.pairs_swept(p0, r0, p1, r1))
            sure = _set(brute_force_swept_pairs(a, p0, r0, p1, r1, tol=-1e-9))
            maybe = _set(brute_force_swept_pairs(a, p0, r0, p1, r1, tol=1e-9))
            assert sure <= fast <= maybe, (scene.name, sorted(sure - fast), sorted(fast - maybe))
            found += len(fast)
    assert found > 50  # the scenes had real candidates


@pytest.mark.parametrize("size", [0.2, 1.0, None])
def test_swept_contains_every_pair_of_the_steps_in_between(size):
    # The oracle: the single-step broad phase at 300 times of the motion; its union must be inside.
    rng = np.random.default_rng(20)
    s = np.linspace(0.0, 1.0, 301)
    between = 0
    for scene in _scenes():
        a = scene.articulation
        bp = collide.BroadPhase(a)
        for _ in range(3):
            p0, r0, p1, r1 = _pose_pair(scene, rng, size)
            swept = _set(bp.pairs_swept(p0, r0, p1, r1))
            pos, rot = motion_poses(p0, r0, p1, r1, s)
            seen = set()
            for t in range(len(s)):
                seen |= _set(bp.pairs(np.ascontiguousarray(pos[t]), np.ascontiguousarray(rot[t])))
            assert seen <= swept, (scene.name, sorted(seen - swept))
            between += len(seen - _set(bp.pairs(p0, r0)) - _set(bp.pairs(p1, r1)))
    assert between > 0  # some pairs met only between the step's ends


def _rod_and_plate():
    # A rod spinning about its centre by up to pi a step beside a small plate; a fast ball and a
    # thin wall; a floor.
    art = collide.Articulation(
        body_parent=[0, 0, 0, 0],
        geom_body=[0, 1, 2, 3, 0],
        geom_cloud=[shapes.plane(), shapes.capsule(0.02, 1.0), shapes.box([0.1, 0.1, 0.1]),
                    shapes.sphere(0.05), shapes.box([0.01, 1.0, 1.0])],
        geom_pos=[[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0], [5.0, 0, 3.0]],
    )
    return art


def test_spinning_rod_and_bullet_found_between_the_ends():
    from scipy.spatial.transform import Rotation
    art = _rod_and_plate()
    bp = collide.BroadPhase(art)
    rz = Rotation.from_euler("z", 179.0, degrees=True).as_matrix()
    cap = Rotation.from_euler("y", 90.0, degrees=True).as_matrix()  # the capsule along x
    p0 = np.array([[0, 0, 0], [0, 0, 3.0], [0, 0.95, 3.0], [3.0, 0, 3.0]])
    r0 = np.tile(np.eye(3), (4, 1, 1))
    r0[1] = cap
    p1 = p0.copy()
    p1[3] = [7.0, 0, 3.0]  # the ball jumps through the wall
    r1 = r0.copy()
    r1[1] = rz @ cap
    ends = _set(bp.pairs(p0, r0)) | _set(bp.pairs(p1, r1))
    assert (1, 2) not in ends and (3, 4) not in ends  # the discrete broad phase misses both
    swept = _set(bp.pairs_swept(p0, r0, p1, r1))
    assert {(1, 2), (3, 4)} <= swept
    # and they do touch in between: the rod along y at s = 1/2, the ball inside the wall at 1/2
    pos, rot = motion_poses(p0, r0, p1, r1, np.array([0.5]))
    touching = _set(testing.brute_force_pairs(art, pos[0], rot[0]))
    assert {(1, 2), (3, 4)} <= touching
    assert (0, 1) not in swept and (0, 3) not in swept  # well above the floor all along


def test_planes_fixed_and_moving():
    # A ball above a fixed floor (a half-space: nothing tunnels through it), then the floor's body moved
    art = collide.Articulation(body_parent=[0, 0, 0], geom_body=[1, 2],
                               geom_cloud=[shapes.plane(), shapes.sphere(0.1)], geom_margin=[0.0, 0.01])
    bp = collide.BroadPhase(art)
    p0 = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 1.0]])
    r = np.tile(np.eye(3), (3, 1, 1))
    p1 = p0.copy()
    p1[2] = [0, 0, -1.0]
    assert _set(bp.pairs(p0, r)) == set() and _set(bp.pairs(p1, r)) == {(0, 1)}
    assert _set(bp.pairs_swept(p0, r, p1, r)) == {(0, 1)}
    p1[2] = [0.5, 0, 0.9]
    assert _set(bp.pairs_swept(p0, r, p1, r)) == set()  # stays above: a fixed plane is exact here
    p1b = p1.copy()
    p1b[1] = [0, 0, 1e-9]  # the plane's body moved: every pair its filter lets through
    assert _set(bp.pairs_swept(p0, r, p1b, r)) == {(0, 1)}
    assert _set(brute_force_swept_pairs(art, p0, r, p1b, r)) == {(0, 1)}


def test_no_motion_gives_at_least_the_single_step_pairs():
    rng = np.random.default_rng(30)
    for scene in _scenes():
        bp = collide.BroadPhase(scene.articulation)
        p, r = scene.poses(rng)
        assert _set(bp.pairs(p, r)) <= _set(bp.pairs_swept(p, r, p, r))


def test_touching_in_between_is_found():
    # Exact geometry (GJK) at 60 times of large motions: every touching pair is a swept candidate.
    rng = np.random.default_rng(40)
    scene = testing.free_hulls(10, seed=5, filters=True, planes=1)
    a = scene.articulation
    bp = collide.BroadPhase(a)
    s = np.linspace(0, 1, 61)
    touched = 0
    for _ in range(3):
        p0, r0, p1, r1 = _pose_pair(scene, rng, 1.0)
        swept = _set(bp.pairs_swept(p0, r0, p1, r1))
        pos, rot = motion_poses(p0, r0, p1, r1, s)
        for t in range(len(s)):
            tp = _set(testing.brute_force_pairs(a, pos[t], rot[t]))
            assert tp <= swept
            touched += len(tp)
    assert touched > 0


def test_batch_equals_single_worlds():
    rng = np.random.default_rng(50)
    scene = testing.many_robots(3, links=4, seed=6, planes=1)
    bp = collide.BroadPhase(scene.articulation)
    B = 7
    p0, r0 = scene.poses(rng, worlds=B)
    p1, r1 = scene.poses(rng, worlds=B)
    out = bp.pairs_swept_batch(p0, r0, p1, r1)
    assert out.shape[1] == 3 and out.dtype == np.int32 and len(out) > 0
    for w in range(B):
        np.testing.assert_array_equal(out[out[:, 0] == w, 1:], bp.pairs_swept(p0[w], r0[w], p1[w], r1[w]))
    assert bp.pairs_swept_batch(p0[:0], r0[:0], p1[:0], r1[:0]).shape == (0, 3)


def test_bad_input_is_named_and_the_object_still_works():
    scene = testing.chain(6, seed=7, planes=1)
    bp = collide.BroadPhase(scene.articulation)
    rng = np.random.default_rng(60)
    p0, r0 = scene.poses(rng)
    p1, r1 = scene.poses(rng)
    good = bp.pairs_swept(p0, r0, p1, r1)
    bad = p1.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="end pose, body 3"):
        bp.pairs_swept(p0, r0, bad, r1)
    skew = r0.copy()
    skew[2] *= 1.1
    with pytest.raises(ValueError, match="start pose, body 2.*rotation"):
        bp.pairs_swept(p0, skew, p1, r1)
    with pytest.raises(ValueError, match="body_pos0: expected shape"):
        bp.pairs_swept(p0[:-1], r0, p1, r1)
    with pytest.raises(ValueError, match="body_rot1: expected shape"):
        bp.pairs_swept(p0, r0, p1, r1[:, :2])
    with pytest.raises(ValueError, match="body_pos1: expected a float array"):
        bp.pairs_swept(p0, r0, p1.astype(int), r1)
    P0, R0 = scene.poses(rng, worlds=3)
    P1, R1 = scene.poses(rng, worlds=3)
    P1[2, 4, 0] = np.inf
    with pytest.raises(ValueError, match="world 2, end pose, body 4"):
        bp.pairs_swept_batch(P0, R0, P1, R1)
    with pytest.raises(ValueError, match="worlds"):
        bp.pairs_swept_batch(P0, R0, P1[:2], R1[:2])
    with pytest.raises(ValueError, match="body_rot1: expected shape"):
        bp.pairs_swept_batch(P0, R0, P1, R1[:2])
    np.testing.assert_array_equal(bp.pairs_swept(p0, r0, p1, r1), good)


def test_two_threads():
    scene = testing.branching_tree(30, seed=8, planes=1)
    bp = collide.BroadPhase(scene.articulation)
    rng = np.random.default_rng(70)
    steps = [_pose_pair(scene, rng, 0.3) for _ in range(20)]
    want = [bp.pairs_swept(*s) for s in steps]

    def run(_):
        for _ in range(5):
            for s, w in zip(steps, want):
                np.testing.assert_array_equal(bp.pairs_swept(*s), w)

    in_threads(run, 2)


MODELS = __import__("pathlib").Path(__file__).resolve().parents[1] / ".." / "shared" / "models"


@pytest.mark.parametrize("name", ["humanoid", "shadow_hand", "anybotics_anymal_c"])
def test_mujoco_steps(name):
    # A MuJoCo simulation with a 3x time step and bang-bang controls: every step's swept pairs hold
    # both ends' pairs and MuJoCo's contacts at the end.
    mujoco = pytest.importorskip("mujoco")
    path = MODELS / name / "scene.xml"
    if not path.is_file():
        pytest.skip(f"{path} absent (see the README's 'Test models')")
    import collide.mujoco as cm
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.timestep *= 3.0
    col = cm.Collider(model)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rng = np.random.default_rng(0)
    lo, hi = model.actuator_ctrlrange.T if model.nu else (np.zeros(0), np.zeros(0))
    contacts = steps = 0
    for step in range(200):
        if step % 10 == 0:
            data.ctrl[:] = np.where(rng.random(model.nu) < 0.5, lo, hi)
        before = mujoco.MjData(model)
        before.qpos[:], before.qvel[:] = data.qpos, data.qvel
        mujoco.mj_forward(model, before)
        mujoco.mj_step(model, data)
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
            break
        swept = _set(col.pairs_swept(before, data))
        ends = _set(col.pairs(before)) | _set(col.pairs(data))
        assert ends <= swept, sorted(ends - swept)
        made = {tuple(sorted(map(int, c.geom))) for c in data.contact[:data.ncon]}
        assert made <= swept
        contacts += len(made)
        steps += 1
    assert steps > 20 and contacts > 0
    with pytest.raises(ValueError, match="data1"):
        col.pairs_swept(before, mujoco.MjData(model))
    other = mujoco.MjData(mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>"))
    with pytest.raises(ValueError, match="^data0: made for a model with"):
        col.pairs_swept(other, data)


def test_the_demo_runs(tmp_path):
    # demos/deformations.py: the deformed bar's bounds hold their samples, and the swept phase finds
    # the rod-block and ball-wall pairs that both ends miss (the demo exits non-zero otherwise).
    import subprocess
    import sys
    demo = __import__("pathlib").Path(__file__).resolve().parents[1] / "demos" / "deformations.py"
    if not demo.is_file():
        pytest.skip(f"{demo} is absent")
    run = subprocess.run([sys.executable, str(demo), "--out", str(tmp_path)], capture_output=True, text=True,
                         timeout=900)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "single step at both ends: no pairs" in run.stdout
    assert "'wall-ball', 'rod-block'" in run.stdout
    assert (tmp_path / "deformations.png").stat().st_size > 10_000 and (tmp_path / "swept.png").stat().st_size > 10_000


def test_an_aabb_cut_to_the_capsule_in_between_is_inside():
    # A single step cuts a geom's OBB box to its capsule box. Here, along y, the capsule's is the
    # tighter at s = 0 and the OBB's at s = 1, and in between the cut is wider than at both ends:
    # the plate's pair was reported by `pairs` at s ~ 0.4 to 0.57 and missed by a swept box made
    # of the union of the ends' cut boxes (adversarial review of issue 44).
    from scipy.spatial.transform import Rotation
    rv = Rotation.from_rotvec
    pts = [[-0.124, 0.694, -0.229], [0.147, 0.161, -0.792], [-0.066, 0.305, -0.219], [-0.461, 0.29, 0.247],
           [0.161, -0.283, -0.081], [-0.149, 0.991, -0.311], [-0.274, -0.134, 0.26], [-0.072, -0.167, 0.78],
           [0.468, -0.543, -0.131], [0.623, 0.214, -0.12], [0.406, -0.562, 0.305]]
    art = collide.Articulation([0, 0, 0], [1, 2], [collide.PointCloud(pts, 0.008), shapes.box([5.0, 0.1, 5.0])],
                               geom_pos=[[-0.3473, 0.1492, -0.0582], [0, 0, 0]],
                               geom_rot=[rv([-0.8668, -2.3257, 0.4645]).as_matrix(), np.eye(3)])
    bp = collide.BroadPhase(art)
    r0 = np.array([np.eye(3), rv([-1.5034, -1.5864, -1.5914]).as_matrix(), np.eye(3)])
    r1 = np.array([np.eye(3), rv([-1.5532, -1.5205, -1.7114]).as_matrix(), np.eye(3)])
    p0 = np.array([[0, 0, 0], [-0.0423, -1.0891, -0.1445], [0, -2.2975, -0.85]])
    p1 = np.array([[0, 0, 0], [-0.1300, -1.1092, -0.0685], [0, -2.2975, -0.85]])
    pos, rot = motion_poses(p0, r0, p1, r1, np.linspace(0, 1, 201))
    seen = [t for t in range(len(pos)) if len(bp.pairs(np.ascontiguousarray(pos[t]), np.ascontiguousarray(rot[t])))]
    assert len(bp.pairs(p0, r0)) == 0 and len(bp.pairs(p1, r1)) == 0 and 0 < len(seen) < 100  # in between only
    assert _set(bp.pairs_swept(p0, r0, p1, r1)) == {(0, 1)}
    assert _set(brute_force_swept_pairs(art, p0, r0, p1, r1, tol=-1e-9)) == {(0, 1)}


def test_a_half_turn_from_a_stretched_rotation_keeps_the_start_pair():
    # Rotations are accepted within ORTHO_TOL of orthonormal: a start rotation stretched by 4.9e-7
    # along x carries the point 1 + 4.9e-7 from its body's origin, and a half turn (θ = π, where
    # the cos slack adds nothing) moves it 2 + 4.9e-7: the reach 2 |x| alone lost the start pose's
    # own pair (adversarial review of issue 44).
    art = collide.Articulation([0, 0, 0], [1, 2], [collide.PointCloud([[0, 0, 0]], 0.0),
                                                   collide.PointCloud([[0, 0, 0]], 1e-7)],
                               geom_pos=[[1.0, 0, 0], [0, 0, 0]])
    bp = collide.BroadPhase(art)
    eye = np.eye(3)
    r0 = np.array([eye, np.diag([1 + 4.9e-7, 1.0, 1.0]), eye])
    r1 = np.array([eye, np.diag([-1.0, -1.0, 1.0]), eye])
    p = np.array([[0, 0, 0], [0, 0, 0], [1 + 5.4e-7, 0, 0]])
    assert _set(bp.pairs(p, r0)) == {(0, 1)} and _set(bp.pairs(p, r1)) == set()
    assert _set(bp.pairs_swept(p, r0, p, r1)) == {(0, 1)}
    assert _set(brute_force_swept_pairs(art, p, r0, p, r1, tol=-1e-9)) == {(0, 1)}


def test_an_explicit_plane_pair_with_its_own_margin():
    # An explicit (plane, ball) pair whose margin (0.1) exceeds the ball's own (0): a single step
    # inflates both by the pair's margin and reports the ball 0.15 above the floor; the swept
    # phase's fixed-plane test also cut with the ball's swept box, made with its own margin, and
    # lost the pair even without motion (adversarial review of issue 44).
    art = collide.Articulation([0, 0], [0, 1], [shapes.plane(), shapes.sphere(0.1)], pairs=[[0, 1]],
                               pair_margin=[0.1], geom_contype=[0, 0], geom_conaffinity=[0, 0])
    bp = collide.BroadPhase(art)
    r = np.tile(np.eye(3), (2, 1, 1))
    p0 = np.array([[0, 0, 0], [0, 0, 0.25]])
    p1 = np.array([[0, 0, 0], [0.3, 0, 0.25]])
    assert _set(bp.pairs(p0, r)) == _set(bp.pairs(p1, r)) == {(0, 1)}
    for end in (p0, p1):
        assert _set(bp.pairs_swept(p0, r, end, r)) == {(0, 1)}
        assert _set(brute_force_swept_pairs(art, p0, r, end, r, tol=-1e-9)) == {(0, 1)}
    p2 = np.array([[0, 0, 0], [0, 0, 0.35]])  # 0.25 above: beyond both margins, all along
    assert _set(bp.pairs_swept(p2, r, p2 + [[0, 0, 0], [0.3, 0, 0]], r)) == set()


@pytest.mark.skipif(not hasattr(os, "fork"), reason="os.fork: POSIX only")
def test_a_forked_child_answers_right_after_its_parents_thread_left_the_swept_kernel():
    # As test_broadphase.py's fork test, for the swept step: a thread of the parent had returned
    # from the swept kernel (which advanced its arena's offset in the context) but not run the
    # bookkeeping after it, when another thread forked; the child handed out that call's rows
    # (`collide.broadphase._after_fork` gives the swept broad phase its buffers and a fresh arena).
    sc = testing.free_hulls(64, seed=6)
    rng = np.random.default_rng(7)
    (p0, r0), (p1, r1) = [(p[0], r[0]) for p, r in (testing.hull_motion(sc, rng, 1, 0.05) for _ in range(2))]
    fresh = collide.BroadPhase(sc.articulation)
    want0, want1 = fresh.pairs_swept(p0, r0, p0, r0), fresh.pairs_swept(p1, r1, p1, r1)
    assert len(want0) > 20 and not np.array_equal(want0, want1)
    assert _set(want0) >= _set(brute_force_swept_pairs(sc.articulation, p0, r0, p0, r0))
    bp = collide.BroadPhase(sc.articulation)
    assert np.array_equal(bp.pairs_swept(p1, r1, p1, r1), want1)
    sp = bp._swept_pairs()
    assert sp._call(p1, r1, p1, r1, sp._ctx) > 0  # the kernel ran; the Python after it did not
    code = in_child(lambda: np.array_equal(bp.pairs_swept(p0, r0, p0, r0), want0))
    assert code == 0, f"the child's exit code {code}"
