"""The swept broad phase's kept end (`collide._kernels.swept_motion._start_source`): a call whose start
poses are bitwise the last call's end poses takes that call's end places instead of placing again,
and a body whose two poses are bitwise equal places once. Neither may change an answer: every call
here equals the same call on a fresh broad phase (nothing kept), array for array."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import collide
from collide import testing
from collide._kernels import swept as _ks
from collide._kernels import swept_motion as _km
from collide.testing.swept import brute_force_swept_pairs
from test_swept_pairs import _scenes  # the same four scenes as the swept broad phase's own tests



def _path(scene, rng, n, size=0.05):
    # n + 1 poses of a motion in small random steps (a simulation loop's), the world fixed
    L = scene.articulation.body_count
    p, r = scene.poses(rng)
    from scipy.spatial.transform import Rotation
    out = [(p.copy(), r.copy())]
    for _ in range(n):
        turn = Rotation.from_rotvec(rng.uniform(-size, size, (L, 3))).as_matrix()
        r = np.einsum("lij,ljk->lik", turn, r)
        p = p + rng.uniform(-size, size, (L, 3))
        r[0], p[0] = out[0][1][0], out[0][0][0]
        out.append((p.copy(), r.copy()))
    return out


def _fresh(art, p0, r0, p1, r1):
    return collide.BroadPhase(art).pairs_swept(p0, r0, p1, r1)


def _sources(bp):
    # Y_BODY's column 4 after the last call: where each body's start places came from
    sp = bp._swept_pairs()
    NB = sp.dims["NB"]
    off = _ks.YWORK.offset(sp.dims, "body")
    return sp._Y[off:off + 5 * NB].reshape(NB, 5)[:, 4].copy()


def _assert_same(a, b, where):
    assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b), where


def test_a_chain_of_calls_equals_fresh_calls():
    rng = np.random.default_rng(1)
    found = kept = 0
    for scene in _scenes():
        a = scene.articulation
        bp = collide.BroadPhase(a)
        path = _path(scene, rng, 8)
        for i in range(1, len(path)):
            (p0, r0), (p1, r1) = path[i - 1], path[i]
            got = bp.pairs_swept(p0.copy(), r0.copy(), p1, r1)  # other arrays, the same bits
            _assert_same(got, _fresh(a, p0, r0, p1, r1), (scene.name, i))
            src = _sources(bp)
            kept += int(np.sum(src == _km.SRC_KEPT))
            if i > 1:
                assert np.all(src[1:] == _km.SRC_KEPT), scene.name  # every moving body took the kept end
            found += len(got)
    assert found > 50 and kept > 50  # real pairs, and the kept end was used


def test_arrays_modified_in_place_between_calls():
    # The caller's arrays are reused and rewritten: the kept end is compared by value, not by
    # identity, so a changed start is placed again.
    rng = np.random.default_rng(2)
    found = placed = 0
    for scene in _scenes():
        a = scene.articulation
        bp = collide.BroadPhase(a)
        path = _path(scene, rng, 6, size=0.2)
        P0, R0 = path[0][0].copy(), path[0][1].copy()
        P1, R1 = path[1][0].copy(), path[1][1].copy()
        for i in range(2, len(path)):
            got = bp.pairs_swept(P0, R0, P1, R1)
            _assert_same(got, _fresh(a, P0, R0, P1, R1), (scene.name, i))
            found += len(got)
            # the start array now holds the last end, nudged by one ulp in one body's position
            P0[:], R0[:] = P1, R1
            P0[2, 0] = np.nextafter(P0[2, 0], np.inf)
            P1[:], R1[:] = path[i]
            got = bp.pairs_swept(P0, R0, P1, R1)
            _assert_same(got, _fresh(a, P0, R0, P1, R1), (scene.name, i, "nudged"))
            assert _sources(bp)[2] == _km.SRC_PLACE
            placed += 1
            P0[:], R0[:] = P1, R1
            P1[:], R1[:] = path[min(i + 1, len(path) - 1)]
    assert found > 20 and placed > 0


def test_alternating_motions_and_a_negative_zero():
    # Two interleaved loops on one broad phase: each call's start is the other loop's end, never
    # the last call's (nothing kept may be taken), then back to a chain.
    rng = np.random.default_rng(3)
    for scene in _scenes():
        a = scene.articulation
        bp = collide.BroadPhase(a)
        pa, pb = _path(scene, rng, 5), _path(scene, rng, 5)
        for i in range(1, 6):
            for path in (pa, pb):
                got = bp.pairs_swept(*path[i - 1], *path[i])
                _assert_same(got, _fresh(a, *path[i - 1], *path[i]), (scene.name, i))
                assert not np.any(_sources(bp) == _km.SRC_KEPT)
    # -0.0 equals 0.0 but is another pose's bits: not taken as the kept end
    scene = _scenes()[0]
    a = scene.articulation
    bp = collide.BroadPhase(a)
    path = _path(scene, rng, 2)
    p1 = path[1][0].copy()
    p1[3, 1] = 0.0
    bp.pairs_swept(*path[0], p1, path[1][1])
    p0 = p1.copy()
    p0[3, 1] = -0.0
    got = bp.pairs_swept(p0, path[1][1], *path[2])
    src = _sources(bp)
    assert src[3] == _km.SRC_PLACE and src[4] == _km.SRC_KEPT
    _assert_same(got, _fresh(a, p0, path[1][1], *path[2]), "negative zero")


def test_a_refused_call_a_grown_buffer_and_a_copy_keep_the_answers():
    rng = np.random.default_rng(4)
    scene = _scenes()[2]
    a = scene.articulation
    bp = collide.BroadPhase(a)
    path = _path(scene, rng, 6, size=0.3)
    bp.pairs_swept(*path[0], *path[1])
    bad = path[2][0].copy()
    bad[3, 0] = np.nan
    with pytest.raises(ValueError, match="end pose"):
        bp.pairs_swept(*path[1], bad, path[2][1])
    with pytest.raises(ValueError, match="start pose"):  # at rest: named as the start
        bp.pairs_swept(bad, path[2][1], bad, path[2][1])
    got = bp.pairs_swept(*path[1], *path[2])  # the kept end is still the first call's
    _assert_same(got, _fresh(a, *path[1], *path[2]), "after a refusal")
    assert np.all(_sources(bp)[1:] == _km.SRC_KEPT)
    sp = bp._swept_pairs()
    sp._set_keys(1)  # the next call overflows its keys, grows them and runs again
    got = bp.pairs_swept(*path[2], *path[3])
    assert len(got) > 1
    _assert_same(got, _fresh(a, *path[2], *path[3]), "grown")
    kept = [(bp.pairs_swept(*path[i - 1], *path[i]), i) for i in range(1, 7)]
    sp._new_arena(5)  # a small arena: full after a call or two, then new ones
    kept += [(bp.pairs_swept(*path[i - 1], *path[i]), i) for i in range(1, 7)]
    for got, i in kept:  # every result handed out is still its call's (rows are never rewritten)
        _assert_same(got, _fresh(a, *path[i - 1], *path[i]), ("kept", i))
    kept[0][0][:] = -1  # the caller's own rows
    _assert_same(bp.pairs_swept(*path[0], *path[1]), _fresh(a, *path[0], *path[1]), "after a write")
    twin = copy.copy(bp)  # rebuilt from the articulation: nothing kept
    for i in range(4, 7):
        got, got2 = bp.pairs_swept(*path[i - 1], *path[i]), twin.pairs_swept(*path[i - 1], *path[i])
        _assert_same(got, got2, ("copy", i))
        _assert_same(got, _fresh(a, *path[i - 1], *path[i]), ("copy", i))


def test_batch_of_a_chain_equals_single_calls():
    # Worlds whose starts are other worlds' ends, as a batch of consecutive steps: a worker's
    # kept end may be taken from world to world only where the bits agree.
    rng = np.random.default_rng(5)
    for scene in _scenes():
        a = scene.articulation
        bp = collide.BroadPhase(a)
        path = _path(scene, rng, 9)
        P = np.array([p for p, _ in path])
        R = np.array([r for _, r in path])
        out = bp.pairs_swept_batch(P[:-1], R[:-1], P[1:], R[1:])
        for w in range(len(path) - 1):
            _assert_same(out[out[:, 0] == w, 1:], _fresh(a, P[w], R[w], P[w + 1], R[w + 1]), (scene.name, w))
        assert len(out) > 0


def test_bodies_at_rest_place_once_and_match_the_twin():
    rng = np.random.default_rng(6)
    found = rest = 0
    for scene in _scenes():
        a = scene.articulation
        bp = collide.BroadPhase(a)
        path = _path(scene, rng, 1, size=0.3)
        (p0, r0), (p1, r1) = path
        still = rng.random(len(p0)) < 0.5
        p1[still], r1[still] = p0[still], r0[still]
        got = bp.pairs_swept(p0, r0, p1, r1)
        assert np.all(_sources(bp)[still] == _km.SRC_REST)
        rest += int(still.sum())
        sure = {tuple(map(int, x)) for x in brute_force_swept_pairs(a, p0, r0, p1, r1, tol=-1e-9)}
        maybe = {tuple(map(int, x)) for x in brute_force_swept_pairs(a, p0, r0, p1, r1, tol=1e-9)}
        fast = {tuple(map(int, x)) for x in got}
        assert sure <= fast <= maybe, scene.name
        found += len(fast)
    assert found > 20 and rest > 10


def test_the_grouped_sweep_equals_one_group(monkeypatch):
    # The sweep by groups (`broadphase.swept.sweep_groups`: each robot of a crowd a group) finds the
    # pairs of a single sweep over every geom, exactly.
    from collide.broadphase import swept as _bs
    rng = np.random.default_rng(7)
    found = cross = 0
    for scene in (testing.many_robots(6, links=5, seed=8, planes=1), testing.many_robots(3, links=8, seed=9)):
        a = scene.articulation
        grouped = collide.BroadPhase(a)
        assert grouped._swept_pairs().dims["R"] > 1
        monkeypatch.setattr(_bs, "_GROUP_MIN", 10 ** 9)
        one = collide.BroadPhase(a)
        assert one._swept_pairs().dims["R"] == 1
        monkeypatch.undo()
        sp = grouped._swept_pairs()
        off = _ks.XTAB.offset(sp.dims, "group")
        group = sp._X[off:off + sp.dims["G"]]
        for size in (0.05, 0.5, 2.0):
            path = _path(scene, rng, 4, size=size)
            for i in range(1, len(path)):
                got = grouped.pairs_swept(*path[i - 1], *path[i])
                _assert_same(got, one.pairs_swept(*path[i - 1], *path[i]), (scene.name, size, i))
                found += len(got)
                solid = ~a.geom_is_plane[got[:, 0]] & ~a.geom_is_plane[got[:, 1]]
                cross += int(np.sum(solid & (group[got[:, 0]] != group[got[:, 1]])))
    assert found > 100 and cross > 10  # pairs within robots and across them


def test_the_mujoco_adapter_in_a_loop_of_two_mjdata():
    # collide.mujoco's pairs_swept keeps the views of the last two MjData it checked: a loop that
    # copies each step's start into one MjData and steps another gets the answers of the arrays.
    mujoco = pytest.importorskip("mujoco")
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / ".." / "shared" / "models" / "shadow_hand" / "scene.xml"
    if not path.is_file():
        pytest.skip(f"{path} absent (see the README's 'Test models')")
    import collide.mujoco as cm
    model = mujoco.MjModel.from_xml_path(str(path))
    col = cm.BroadPhase(model)
    data, before = mujoco.MjData(model), mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rng = np.random.default_rng(10)
    lo, hi = model.actuator_ctrlrange.T
    found = 0
    for step in range(60):
        if step % 10 == 0:
            data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_copyData(before, model, data)
        mujoco.mj_step(model, data)
        got = col.pairs_swept(before, data)
        want = _fresh(col.articulation, before.xpos.copy(), before.xmat.reshape(-1, 3, 3).copy(), data.xpos.copy(),
                      data.xmat.reshape(-1, 3, 3).copy())
        want = want[~(col._no_function[want[:, 0]] & col._no_function[want[:, 1]])] if col._no_function is not None \
            else want
        _assert_same(np.asarray(got), want, step)
        found += len(got)
    assert found > 0
    other = mujoco.MjData(mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>"))
    with pytest.raises(ValueError, match="^data1: made for a model with"):
        col.pairs_swept(before, other)
    with pytest.raises(ValueError, match="data0: expected a mujoco.MjData"):
        col.pairs_swept(before.xpos, data)
    _assert_same(np.asarray(col.pairs_swept(before, data)), np.asarray(col.pairs_swept(before, data)), "again")


def _twin_holds(art, got, p0, r0, p1, r1, where):
    # every pair the twin finds with room to spare is ours, ours are within its rounding's reach,
    # and no pair twice (the grouped sweep meets each overlapping pair once)
    sure = {tuple(x) for x in brute_force_swept_pairs(art, p0, r0, p1, r1, -1e-9).tolist()}
    maybe = {tuple(x) for x in brute_force_swept_pairs(art, p0, r0, p1, r1, 1e-9).tolist()}
    ours = {tuple(x) for x in got.tolist()}
    assert len(ours) == len(got) and sure <= ours <= maybe, where
    return len(sure)


def test_crowd_placements_of_the_grouped_sweep_against_the_twin():
    # Issue 44 attacks on the grouped sweep: the robots (one group each) all at one point (groups
    # inside each other, equal boxes), in a row a robot's size apart, half of them in a cluster
    # inside the spread, and one robot 1e5 away that sweeps across the crowd in one step; a chain
    # of calls (the kept end taken), each answer against the twin.
    rng = np.random.default_rng(44)
    scene = testing.many_robots(16, links=4, seed=16, planes=1)
    art = scene.articulation
    parent = np.asarray(art.body_parent)
    root = np.arange(len(parent))
    for b in range(1, len(parent)):
        root[b] = b if parent[b] == 0 else root[parent[b]]
    robots = np.unique(root[1:])
    of = np.searchsorted(robots, root)
    moving = (root > 0)[:, None]
    bp = collide.BroadPhase(art)
    assert bp._swept_pairs().dims["R"] == len(robots)  # a group a robot
    found = 0
    last = None
    for trial in range(6):
        p, r = scene.poses(rng)
        off = -p[robots]
        if trial % 4 == 0:
            pass  # all at one point
        elif trial % 4 == 1:
            off[:, 0] += np.arange(len(robots)) * 0.5
        elif trial % 4 == 2:
            off[len(robots) // 2:] = 0.0
        else:
            off[:] = 0.0
            off[0] = [1e5, 0.0, 0.0]
        p = p + off[of] * moving
        step = rng.normal(0.0, 0.3, (len(robots), 3))
        if trial % 4 == 3:
            step[0] = [-1e5, 0.0, 0.0]
        p1 = p + step[of] * moving
        start = (p, r) if last is None else last
        for q0, s0, q1, s1 in (start + (p, r), (p, r, p1, r), (p1, r, p1, r)):
            found += _twin_holds(art, bp.pairs_swept(q0, s0, q1, s1), q0, s0, q1, s1, trial)
        last = (p1, r)
    assert found > 1000


def test_argument_forms_in_a_chain():
    # Big-endian, Fortran-ordered, read-only, broadcast and float32 arrays (converted on the
    # checked path) between calls of a chain: each answer is a fresh call's on float64 copies,
    # and the chain's kept end stays right.
    rng = np.random.default_rng(45)
    scene = _scenes()[1]
    a = scene.articulation
    bp = collide.BroadPhase(a)
    path = _path(scene, rng, 6, size=0.2)

    def ro(x):
        x = x.copy()
        x.flags.writeable = False
        return x

    forms = [lambda x: x.astype(">f8"), np.asfortranarray, ro, lambda x: np.broadcast_to(x, x.shape),
             lambda x: x.astype(np.float32)]
    found = 0
    for i in range(1, len(path)):
        (p0, r0), (p1, r1) = path[i - 1], path[i]
        f = forms[i % len(forms)]
        args = (f(p0), f(r0), f(p1), f(r1))
        plain = tuple(np.array(x, np.float64) for x in args)
        got = bp.pairs_swept(*args)
        _assert_same(got, _fresh(a, *plain), i)
        _assert_same(bp.pairs_swept(p0, r0, p1, r1), _fresh(a, p0, r0, p1, r1), (i, "plain"))
        found += len(got)
    assert found > 20
