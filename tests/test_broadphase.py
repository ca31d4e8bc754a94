"""BroadPhase against its brute-force twins on random scenes; filters, planes, batches, bad input."""

import os

import numba
import numpy as np
import pytest

import collide.broadphase
from collide import Articulation, BroadPhase, PointCloud, shapes, testing
from collide._kernels import batch as _batch
from collide._kernels import bounds as _bounds
from collide._kernels import coherence as _coh
from collide._kernels import culling as _cull
from collide._kernels import keys as _keys
from collide._kernels import _ptr
from collide._kernels import _simd
from collide._kernels import lane_tests as _lane_tests
from collide._kernels import layout as _layout
from collide.broadphase import ARENA_ROWS
from collide.testing.scenes import random_rotation
from _threads import in_child, in_threads

BALL = PointCloud([[0, 0, 0]], 0.5)
EYE = np.eye(3)


def _rows(a):
    return set(map(tuple, np.asarray(a).tolist()))


def _field(bp, name):
    # A field of a BroadPhase's flat buffers by its declared name (`_kernels.layout`), read through
    # the field table as the kernels read it.
    for lay, buf in ((_layout.INT, bp._I), (_layout.FLT, bp._F), (_layout.WORK, bp._W)):
        if any(f[0] == name for f in lay.fields):
            return lay.view(bp._I, buf, name)
    raise KeyError(name)


def _check_sorted_unique(p):
    assert p.dtype == np.int32 and p.ndim == 2 and p.shape[1] == 2
    assert np.all(p[:, 0] < p[:, 1])
    keys = p[:, 0].astype(np.int64) * 1_000_000 + p[:, 1]
    assert np.all(np.diff(keys) > 0)


# --------------------------------------------------------------------------- random scenes

SCENES = [
    ("chain", lambda: testing.chain(64, seed=11, planes=1, joint_range=1.6), 16),
    ("tree", lambda: testing.branching_tree(70, seed=12, planes=1), 24),
    ("robots", lambda: testing.many_robots(14, 6, seed=13, spread=0.8, planes=1), 24),
    ("hulls", lambda: testing.free_hulls(64, seed=14, size=1.0, filters=True, planes=1), 12),
]


@pytest.fixture(scope="module")
def totals():
    return {"checked": 0, "touching": 0, "candidates": 0, "scenes": set()}


@pytest.mark.parametrize("name, make, configs", SCENES, ids=[s[0] for s in SCENES])
def test_random_scenes_equal_bounds_twin_and_miss_nothing(name, make, configs, totals):
    sc = make()
    a = sc.articulation
    bp = BroadPhase(a)
    rng = np.random.default_rng(100)
    g1, g2 = testing.filter_passing_pairs(a)
    for _ in range(configs):
        if name == "hulls":
            pos, rot = testing.hull_motion(sc, rng, 1, 0.05)
            pos, rot = pos[0], rot[0]
        else:
            pos, rot = sc.poses(rng)
        got = bp.pairs(pos, rot)
        _check_sorted_unique(got)
        ref = testing.brute_force_bound_pairs(a, pos, rot)
        assert _rows(got) == _rows(ref)
        exact = testing.brute_force_pairs(a, pos, rot)
        missed = _rows(exact) - _rows(got)
        assert not missed, f"{name}: missed {sorted(missed)[:5]}"
        assert bp.stats["pairs"] == len(got)
        totals["checked"] += len(g1) + len(a.pairs)
        totals["touching"] += len(exact)
        totals["candidates"] += len(got)
    totals["scenes"].add(name)
    # every rule and shape kind was present in these scenes
    assert len(a.exclude) and a.geom_is_plane.any()


def test_random_scene_totals(totals):
    # Runs after the scene tests (file order): the scenes had real work in them.
    if totals["scenes"] != {s[0] for s in SCENES}:
        pytest.skip("needs all scene tests of this module")
    assert totals["checked"] >= 100_000, totals
    assert totals["touching"] >= 3_000, totals
    assert totals["candidates"] >= totals["touching"]


def test_every_geom_kind_touches_in_the_scenes():
    sc = testing.branching_tree(70, seed=12, planes=1)
    a = sc.articulation
    rng = np.random.default_rng(100)
    kinds = set()
    planes_touched = 0
    for _ in range(6):
        pos, rot = sc.poses(rng)
        ex = testing.brute_force_pairs(a, pos, rot)
        for g in ex.ravel():
            c = a.geom_cloud[g]
            if a.geom_is_plane[g]:
                planes_touched += 1
            else:
                kinds.add((len(c.points) if len(c.points) <= 8 else "mesh", c.radius > 0))
    assert planes_touched > 0
    assert {(1, True), (2, True), (8, False), ("mesh", False)} <= kinds


# --------------------------------------------------------------------------- batches

def test_batch_equals_single_world_by_world():
    sc = testing.many_robots(10, 5, seed=21, spread=0.9, planes=1)
    bp = BroadPhase(sc.articulation)
    pos, rot = sc.poses(np.random.default_rng(3), worlds=37)
    got = bp.pairs_batch(pos, rot)
    assert got.dtype == np.int32 and got.shape[1] == 3
    total = 0
    for w in range(37):
        single = bp.pairs(pos[w], rot[w])
        mine = got[got[:, 0] == w, 1:]
        assert np.array_equal(mine, single)
        total += len(single)
    assert total > 100 and len(got) == total
    assert np.all(np.diff(got[:, 0]) >= 0)


def _walls_scene(extras, filter_parent):
    art, _, n_free, _ = _walls_and_dumbbells(np.random.default_rng(12), extras, filter_parent)

    def poses(rng, worlds):
        p = [_walls_poses(rng, n_free) for _ in range(worlds)]
        return np.stack([a for a, _ in p]), np.stack([b for _, b in p])
    return art, poses


def _generated(sc):
    return sc.articulation, sc.poses


LANE_SCENES = [
    ("chain", lambda: _generated(testing.chain(40, seed=41, planes=1, joint_range=1.6))),
    ("tree", lambda: _generated(testing.branching_tree(40, seed=42, planes=2))),
    ("robots", lambda: _generated(testing.many_robots(8, 5, seed=43, spread=0.6, planes=1))),
    ("walls", lambda: _walls_scene(True, True)),
    ("walls_no_parent_rule", lambda: _walls_scene(True, False)),
]


@pytest.mark.parametrize("make", [s[1] for s in LANE_SCENES], ids=[s[0] for s in LANE_SCENES])
def test_lanes_equal_single_worlds(make):
    """The batch of a small model runs eight worlds at a time in SIMD lanes (`_kernels.lanes`):
    planes, multi-geom and loose bodies, the world's leaves, explicit pairs (a plane's, two
    planes'), exclusions, masks and bare bodies must give the single-world answers, and a world
    count that leaves a partial group of lanes too."""
    art, poses = make()
    bp = BroadPhase(art)
    assert bp.batch_path == "lanes"  # the lane kernel runs these
    pos, rot = poses(np.random.default_rng(44), 21)
    got = bp.pairs_batch(pos, rot)
    assert bp.stats["pairs"] == len(got)
    total = 0
    for w in range(len(pos)):
        want = bp.pairs(pos[w], rot[w])
        assert np.array_equal(got[got[:, 0] == w, 1:], want)
        total += len(want)
    assert len(got) == total > 40  # the scene had hits
    planes = np.flatnonzero(art.geom_is_plane)
    assert np.isin(got[:, 1:], planes).any()  # and plane pairs


def test_lanes_keep_every_pair_of_each_world_and_name_a_bad_one():
    art, poses = _walls_scene(True, True)
    bp = BroadPhase(art)
    pos, rot = poses(np.random.default_rng(45), 19)
    want = bp.pairs_batch(pos, rot)
    bp._batch.set_buffers(1, 3)  # tiny buffers: grown, rerun
    assert np.array_equal(bp.pairs_batch(pos, rot), want)
    per_world = BroadPhase(art, batch_path="worlds")  # the per-world kernel on the same worlds
    assert np.array_equal(per_world.pairs_batch(pos, rot), want)
    pos[17, 5, 1] = np.nan  # in the last, partial group
    with pytest.raises(ValueError, match="world 17, body 5"):
        bp.pairs_batch(pos, rot)
    keep = pos[2, 4, 0]
    pos[2, 4, 0] = np.inf  # two bad worlds in different chunks: the first is named
    with pytest.raises(ValueError, match="world 2, body 4"):
        bp.pairs_batch(pos, rot)
    pos[2, 4, 0] = keep
    pos[17, 5, 1] = 0.0
    assert np.array_equal(bp.pairs_batch(pos, rot), want)


@pytest.mark.parametrize("lane_kernel", [True, False], ids=["lanes", "world_by_world"])
def test_batch_chunks_are_each_taken_once_whatever_the_workers(lane_kernel):
    # The batch kernels' workers take chunks from a shared counter (`_kernels.batch.next_chunk`)
    # until none is left: with one worker, with as many as threads, and with more workers than
    # threads (several run one after the other on a thread), every chunk is run exactly once, in
    # its own rows, and a bad world in any chunk is still the one named. (The lane kernels run at
    # most one worker a lane workspace, one a thread.)
    from collide._kernels import lanes
    sc = testing.many_robots(6, 4, seed=47, spread=0.6, planes=1)
    bp = BroadPhase(sc.articulation, batch_path="lanes" if lane_kernel else "worlds")
    lane_tables = bp._batch.lane_tables
    pos, rot = sc.poses(np.random.default_rng(48), 45)
    want = [bp.pairs(pos[w], rot[w]) for w in range(len(pos))]
    assert sum(len(p) for p in want) > 40  # the scene had hits

    def run(workers):
        def launch(bt, world_count, world_info, chunk_info, S):
            C = bt["ctx"].shape[0]
            assert C > 2  # more chunks than workers for some of the counts below
            # Poisoned, so that a chunk skipped cannot pass on an earlier run's rows and counts.
            world_count[:] = -99
            chunk_info[:C] = 777
            bt["keys"].fill(-1)
            bt["stats"].fill(-1)
            chunk_info[C, 1] = workers
            if lane_kernel:
                out = lanes.step_lanes(pos, rot, bt["ctx"], lane_tables, bt["LW"], bt["LB"], world_count, world_info,
                                       chunk_info, S, bp._stats)
                nw = min(workers, C, bt["LW"].shape[0])
            else:
                out = _batch.step_batch(pos, rot, bt["ctx"], world_count, world_info, chunk_info, S, bp._stats)
                nw = min(workers, C)
            assert chunk_info[C, 0] == C + nw  # every chunk taken once, then each worker's last try
            return out
        return bp._run_batch(len(pos), launch)

    stats = None
    for workers in (1, 2, 3, 7):
        got = run(workers)
        for w in range(len(pos)):
            assert np.array_equal(got[got[:, 0] == w, 1:], want[w])
        assert len(got) == sum(len(p) for p in want) == bp.stats["pairs"]
        assert stats is None or bp.stats == stats  # the same tests whoever ran them
        stats = bp.stats
    pos[40, 3, 2] = np.nan  # in a later chunk than world 30 (up to 4 threads)
    pos[30, 2, 0] = np.inf
    for workers in (1, 3):
        with pytest.raises(ValueError, match="world 30, body 2"):
            run(workers)
    bad = np.empty((2, _batch.N_CI), np.int64)  # no row for the counter: refused, not overrun
    with pytest.raises(ValueError, match="chunk_info: needs a row"):
        _batch.step_batch(pos[:2], rot[:2], bp._batch.buffers["ctx"][:2], np.empty(2, np.int64),
                          np.empty((2, 4), np.int64), bad, _keys.key_shift(bp.geom_count), bp._stats)


def test_big_models_batch_world_by_world():
    # More static body pairs than the lanes take: the per-world kernel runs the batch.
    sc = testing.free_hulls(125, seed=46)
    bp = BroadPhase(sc.articulation)
    assert bp.batch_path == "worlds"
    pos, rot = testing.hull_motion(sc, np.random.default_rng(0), 3, 0.02)
    got = bp.pairs_batch(pos, rot)
    assert bp.stats["pairs"] == len(got)
    for w in range(len(pos)):
        assert np.array_equal(got[got[:, 0] == w, 1:], bp.pairs(pos[w], rot[w]))
    assert len(got) > 100


def test_batch_grows_its_buffers_and_keeps_every_pair():
    sc = testing.free_hulls(27, seed=5)
    bp = BroadPhase(sc.articulation)
    pos, rot = testing.hull_motion(sc, np.random.default_rng(0), 40, 0.02)
    want = bp.pairs_batch(pos, rot)
    bp._batch.set_buffers(1, 3)  # tiny buffers: grown, rerun
    assert np.array_equal(bp.pairs_batch(pos, rot), want)
    assert len(want) > 40


@pytest.mark.parametrize("n, coherent", [(40, True), (64, False), (64, True)])  # 40: no list either way
def test_single_grows_its_buffer_and_keeps_every_pair(n, coherent):
    # 41 positions: the static masks (`_scan_masks`); 65: the tree
    sc = testing.free_hulls(n, seed=6)
    bp = BroadPhase(sc.articulation, coherent=coherent)
    assert (bp.position_count <= _cull.MASK_MAX) == (n == 40)
    pos, rot = testing.hull_motion(sc, np.random.default_rng(0), 1, 0.02)
    want = testing.brute_force_bound_pairs(sc.articulation, pos[0], rot[0])
    bp._set_buffers(1, 2)  # tiny buffers: grown, rerun
    got = bp.pairs(pos[0], rot[0])
    assert len(got) > 20 and np.array_equal(got, want)


def test_bound_arrays_are_read_in_place():
    # bind(): the kernel reads the arrays where they are, at every pairs() without arguments.
    sc = testing.free_hulls(64, seed=6)
    bp = BroadPhase(sc.articulation)
    L = sc.articulation.body_count
    with pytest.raises(ValueError, match="none bound"):
        bp.pairs()
    pos_b, rot_b = np.zeros((L, 3)), np.zeros((L, 3, 3))
    bp.bind(pos_b, rot_b)
    rng = np.random.default_rng(3)
    total = 0
    for _ in range(4):
        pos, rot = testing.hull_motion(sc, rng, 1, 0.05)
        pos_b[:], rot_b[:] = pos[0], rot[0]  # updated in place, as an engine does
        got = bp.pairs()
        assert np.array_equal(got, testing.brute_force_bound_pairs(sc.articulation, pos[0], rot[0]))
        total += len(got)
    assert total > 50
    want = bp.pairs()
    bp._set_buffers(1, 2)  # tiny buffers: grown, rerun on the bound arrays
    assert np.array_equal(bp.pairs(), want)
    # ... through the bound step: the per-array step (compiled at its first use) was never needed
    assert "_step" not in vars(bp)
    assert np.array_equal(bp.pairs(pos_b.copy(), rot_b.copy()), want)  # explicit arrays still work
    assert "_step" in vars(bp)
    rot_b[3] *= 1.01
    with pytest.raises(ValueError, match="body 3: rotation is not a proper orthonormal"):
        bp.pairs()
    rot_b[3] /= 1.01
    assert np.array_equal(bp.pairs(), want)
    with pytest.raises(ValueError, match="body_pos: bind needs a C-contiguous float64 array, got dtype float32"):
        bp.bind(pos_b.astype(np.float32), rot_b)
    with pytest.raises(ValueError, match="body_pos: .*not C-contiguous"):
        bp.bind(np.asfortranarray(pos_b), rot_b)
    with pytest.raises(ValueError, match="body_rot: expected shape"):
        bp.bind(pos_b, rot_b[:-1])
    assert np.array_equal(bp.pairs(), want)  # a refused bind keeps the arrays bound before



@pytest.mark.skipif(not hasattr(os, "fork"), reason="os.fork: POSIX only")
def test_a_forked_child_answers_right_after_its_parents_thread_left_the_kernel():
    # A thread of the parent that had returned from the kernel (which advanced the arena's rows in
    # the context) but not yet run the bookkeeping after it (`_arena_used`, `_last`) when another
    # thread forked: the child handed out another call's rows (helper-75's adversarial run: 13 of
    # 15 children wrong). Played here by calling the kernel without the bookkeeping
    # (`collide.broadphase._after_fork` makes the child's consistent; the swept step's:
    # test_swept_pairs.py).
    sc = testing.free_hulls(64, seed=6)
    rng = np.random.default_rng(7)
    (p0, r0), (p1, r1) = [(p[0], r[0]) for p, r in (testing.hull_motion(sc, rng, 1, 0.05) for _ in range(2))]
    want0, want1 = (testing.brute_force_bound_pairs(sc.articulation, p, r) for p, r in ((p0, r0), (p1, r1)))
    assert len(want1) > 20 and not np.array_equal(want0, want1)
    for coherent in (True, False):
        bp = BroadPhase(sc.articulation, coherent=coherent)
        assert np.array_equal(bp.pairs(p1, r1), want1)
        bp.pairs(p0, r0)
        assert bp._step(p1, r1, bp._ctx) > 0  # the kernel ran; the Python after it did not
        code = in_child(lambda: np.array_equal(bp.pairs(p1, r1), want1) and np.array_equal(bp.pairs(p0, r0), want0))
        assert code == 0, f"coherent={coherent}: the child's exit code {code}"


@pytest.mark.parametrize("n", [40, 125], ids=["40_children", "125_children"])
def test_wide_nodes_survive_reshuffles(n):
    # Many children at the world: sweep-and-prune, its order persisting between calls (unrelated
    # poses force the full-sort fallback), with a few dozen children or over a hundred.
    sc = testing.free_hulls(n, seed=7)
    a = sc.articulation
    bp = BroadPhase(a)
    rng = np.random.default_rng(1)
    walk_pos, walk_rot = testing.hull_motion(sc, rng, 6, 0.05)
    for s in range(6):
        pos, rot = walk_pos[s], walk_rot[s]
        if s % 2:
            perm = rng.permutation(np.arange(1, a.body_count))
            pos = pos.copy()
            pos[1:] = pos[perm]
        got = bp.pairs(pos, rot)
        assert np.array_equal(got, testing.brute_force_bound_pairs(a, pos, rot))
        assert len(got) > n // 3


def test_wide_node_with_oversized_children():
    # 154 children filling a volume, a few far larger than the rest: each of those long boxes
    # overlaps many others along the sweep axis.
    rng = np.random.default_rng(4)
    n_small, n_big = 150, 4
    clouds = [PointCloud(np.zeros((1, 3)), 0.3) for _ in range(n_small)]
    clouds += [PointCloud(np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * [2.0, 0.1, 0.1])
               for _ in range(n_big)]
    L = n_small + n_big + 1
    a = Articulation(np.zeros(L, int), np.arange(1, L), clouds)
    bp = BroadPhase(a)
    for _ in range(4):
        pos = np.zeros((L, 3))
        pos[1:] = rng.uniform(-2, 2, (L - 1, 3))
        rot = np.concatenate([EYE[None], testing.scenes.random_rotation(rng, L - 1)])
        got = bp.pairs(pos, rot)
        ref = testing.brute_force_bound_pairs(a, pos, rot)
        assert np.array_equal(got, ref)
        big = got[got[:, 1] >= n_small]
        assert len(big) > 5 and len(got) > len(big) + 5


def _world_child_of(a):
    # (L,) the ancestor of each body that is a child of the world (0 for the world)
    root = np.arange(a.body_count)
    for _ in range(a.body_count):
        up = a.body_parent[root]
        root = np.where(up == 0, root, up)
    return root


def _root_subtree_spread(a, pos, rot):
    """Children of the world and the sum of their subtree AABBs' widths along the scene's longest axis,
    over that axis's extent (the sweep's axis in `_traverse`), from the brute bounds."""
    c, R, h, _, _, _ = testing.world_bounds(a, pos, rot)
    half = np.einsum("gij,gj->gi", np.abs(R), h + a.geom_margin[:, None])
    lo, hi = c - half, c + half
    r = _world_child_of(a)[a.geom_body]
    roots = np.unique(r)
    width = np.array([hi[r == q].max(0) - lo[r == q].min(0) for q in roots])
    ext = hi.max(0) - lo.min(0)
    ax = np.argmax(ext)
    return len(roots), width[:, ax].sum() / ext[ax]


def test_wide_node_filling_a_volume_with_subtree_children():
    # Small robots filling a volume: a hundred children of the world on the sweep, their intervals
    # along its axis deep in each other (the widths sum to many times the extent), and the
    # overlapping children are subtrees (a robot against a robot, `_subtree_pair`), not single bodies.
    sc = testing.many_robots(100, 3, seed=5, spread=0.8, planes=0)
    a = sc.articulation
    bp = BroadPhase(a)
    rng = np.random.default_rng(2)
    root_of = _world_child_of(a)
    deep = 0
    for _ in range(3):
        pos, rot = sc.poses(rng)
        kc, spread = _root_subtree_spread(a, pos, rot)
        assert kc > 64 and spread > 16  # many children, most of them overlapping along the axis
        got = bp.pairs(pos, rot)
        assert np.array_equal(got, testing.brute_force_bound_pairs(a, pos, rot))
        b1, b2 = a.geom_body[got[:, 0]], a.geom_body[got[:, 1]]
        deep += np.sum((root_of[b1] != root_of[b2]) & ((a.body_parent[b1] != 0) | (a.body_parent[b2] != 0)))
    assert deep > 100  # pairs below the robots' roots, across robots


# --------------------------------------------------------------------------- filter rules

def _two_balls(**kw):
    # bodies: 0 world, 1 child of world, 2 child of 1, 3 child of world; balls overlap at origin
    parent = kw.pop("parent", [0, 0, 1, 0])
    geom_body = kw.pop("geom_body", [1, 2, 3])
    a = Articulation(parent, geom_body, [BALL] * len(geom_body), **kw)
    L = len(parent)
    return BroadPhase(a), np.zeros((L, 3)), np.tile(EYE, (L, 1, 1))


def test_filter_rules():
    bp, pos, rot = _two_balls()
    assert _rows(bp.pairs(pos, rot)) == {(0, 2), (1, 2)}  # (0, 1): body 2's parent is body 1
    bp, pos, rot = _two_balls(filter_parent=False)
    assert _rows(bp.pairs(pos, rot)) == {(0, 1), (0, 2), (1, 2)}
    # the parent rule does not apply when the parent is the world
    bp, pos, rot = _two_balls(geom_body=[0, 1])
    assert _rows(bp.pairs(pos, rot)) == {(0, 1)}
    # geoms of one body never pair
    bp, pos, rot = _two_balls(geom_body=[1, 1, 3])
    assert _rows(bp.pairs(pos, rot)) == {(0, 2), (1, 2)}
    # weld groups
    bp, pos, rot = _two_balls(body_weld=[0, 1, 2, 1])
    assert _rows(bp.pairs(pos, rot)) == {(1, 2)}
    # excluded body pairs, either order
    bp, pos, rot = _two_balls(exclude=[[3, 2]])
    assert _rows(bp.pairs(pos, rot)) == {(0, 2)}
    # masks: (ct1 & ca2) or (ct2 & ca1)
    bp, pos, rot = _two_balls(geom_contype=[1, 2, 0], geom_conaffinity=[0, 0, 2])
    assert _rows(bp.pairs(pos, rot)) == {(1, 2)}
    bp, pos, rot = _two_balls(geom_contype=[4, 2, 1], geom_conaffinity=[1, 0, 0])
    assert _rows(bp.pairs(pos, rot)) == {(0, 2)}


def test_margins_inflate_bounds():
    bp, pos, rot = _two_balls(geom_body=[1, 3])
    pos[3] = [1.2, 0, 0]  # gap 0.2 between the balls
    assert len(bp.pairs(pos, rot)) == 0
    bp, pos, rot = _two_balls(geom_body=[1, 3], geom_margin=[0.05, 0.05])
    pos[3] = [1.2, 0, 0]
    assert len(bp.pairs(pos, rot)) == 0
    bp, pos, rot = _two_balls(geom_body=[1, 3], geom_margin=[0.15, 0.06])
    pos[3] = [1.2, 0, 0]
    assert _rows(bp.pairs(pos, rot)) == {(0, 1)}


def test_explicit_pairs_bypass_filters_but_not_bounds():
    # geoms 0, 1 on one body, excluded masks: only the explicit pair reports them
    kw = dict(geom_body=[1, 1, 3], geom_contype=[0, 0, 0], geom_conaffinity=[0, 0, 0])
    bp, pos, rot = _two_balls(pairs=[[1, 0]], **kw)
    assert _rows(bp.pairs(pos, rot)) == {(0, 1)}
    # far apart: the bounds test still applies, with the pair's own inflation
    bp, pos, rot = _two_balls(pairs=[[0, 2]], exclude=[[1, 3]], **kw)
    pos[3] = [1.2, 0, 0]
    assert len(bp.pairs(pos, rot)) == 0
    bp, pos, rot = _two_balls(pairs=[[0, 2]], pair_margin=[0.11], exclude=[[1, 3]], **kw)
    pos[3] = [1.2, 0, 0]
    assert _rows(bp.pairs(pos, rot)) == {(0, 2)}
    # an explicit pair overrides the dynamic one: its inflation, reported once
    bp, pos, rot = _two_balls(geom_body=[1, 3], geom_margin=[0.2, 0.2], pairs=[[0, 1]], pair_margin=[0.0])
    pos[3] = [1.2, 0, 0]
    assert len(bp.pairs(pos, rot)) == 0
    pos[3] = [0.9, 0, 0]
    assert bp.pairs(pos, rot).tolist() == [[0, 1]]


def test_planes_are_halfspaces():
    floor = testing.make_plane((0, 0, 1), 0.0)
    a = Articulation([0, 0, 0, 0], [0, 1, 2, 3, 0], [floor, BALL, BALL, BALL, floor],
                     geom_margin=[0.1, 0, 0, 0, 0], geom_pos=[[0, 0, 0]] * 4 + [[0, 0, -5]])
    bp = BroadPhase(a)
    pos = np.array([[0, 0, 0], [0, 0, 0.55], [3, 0, 0.65], [-3, 0, 10.0]])
    rot = np.tile(EYE, (4, 1, 1))
    # ball 1 reaches the floor through its margin, ball 2 does not; nothing reaches z <= -5
    assert _rows(bp.pairs(pos, rot)) == {(0, 1)}
    # a tilted floor, via the world body's pose
    rot[0] = testing.scenes.axis_angle(np.array([0.0, 1.0, 0.0]), -0.3)
    got = _rows(bp.pairs(pos, rot))
    ref = _rows(testing.brute_force_bound_pairs(a, pos, rot))
    assert got == ref and (0, 2) in got
    # planes never pair with planes, even as an explicit pair
    a2 = Articulation([0, 0], [0, 1, 1], [floor, floor, BALL], pairs=[[0, 1]])
    assert len(BroadPhase(a2).pairs(np.zeros((2, 3)), np.tile(EYE, (2, 1, 1)))) == 1


# --------------------------------------------------------------------------- bad input

@pytest.fixture(scope="module")
def robot_bp():
    sc = testing.many_robots(4, 4, seed=2)
    return sc, BroadPhase(sc.articulation)


@pytest.mark.parametrize("what, msg", [
    ("nan_pos", "body 5: pose has a non-finite"),
    ("inf_rot", "body 5: pose has a non-finite"),
    ("scaled_rot", "body 5: rotation is not a proper orthonormal"),
    ("reflection", "body 5: rotation is not a proper orthonormal"),
    ("nan_rot", "body 5: pose has a non-finite"),
    ("inf_pos", "body 5: pose has a non-finite"),
])
def test_bad_poses_name_the_body_and_next_call_works(robot_bp, what, msg):
    sc, bp = robot_bp
    pos, rot = sc.poses(np.random.default_rng(0))
    good = bp.pairs(pos, rot)
    bad_pos, bad_rot = pos.copy(), rot.copy()
    if what == "nan_pos":
        bad_pos[5, 1] = np.nan
        bad_pos[9, 0] = np.nan
    elif what == "inf_rot":
        bad_rot[5, 2, 2] = np.inf
    elif what == "nan_rot":
        bad_rot[5, 0, 1] = np.nan
    elif what == "inf_pos":
        bad_pos[5, 2] = -np.inf
    elif what == "scaled_rot":
        bad_rot[5] *= 1.001
    else:
        bad_rot[5, :, 0] *= -1
    with pytest.raises(ValueError, match=msg):
        bp.pairs(bad_pos, bad_rot)
    assert np.array_equal(bp.pairs(pos, rot), good)
    B = 4
    bpos, brot = np.repeat(pos[None], B, 0), np.repeat(rot[None], B, 0)
    bpos[2], brot[2] = bad_pos, bad_rot
    with pytest.raises(ValueError, match="world 2, " + msg):
        bp.pairs_batch(bpos, brot)
    assert len(bp.pairs_batch(np.repeat(pos[None], B, 0), np.repeat(rot[None], B, 0))) == B * len(good)


def test_positions_up_to_the_coordinate_limit_are_valid_and_beyond_it_refused(robot_bp):
    # Far from the origin: a pose up to 1e150 (the geoms' own coordinate limit), an error beyond,
    # naming the body. Near the float range sums overflowed to inf, and inf times a zero normal
    # component is NaN: a ball touching a plane at 1e308 was lost, silently (review, 2026-11-22).
    sc, bp = robot_bp
    pos, rot = sc.poses(np.random.default_rng(1))
    want = bp.pairs(pos, rot)
    far = pos + 1e150
    got = bp.pairs(far, rot)
    assert got.dtype == np.int32 and got.shape[1] == 2
    assert np.array_equal(bp.pairs_batch(far[None], rot[None])[:, 1:], got)
    beyond = pos.copy()
    beyond[3] = [1.7e308, -1.7e308, 1.7e308]
    for call in (lambda: bp.pairs(beyond, rot), lambda: bp.world_bounds(beyond, rot),
                 lambda: testing.brute_force_bound_pairs(sc.articulation, beyond, rot)):
        with pytest.raises(ValueError, match=r"body 3: position beyond 1e\+150"):
            call()
    with pytest.raises(ValueError, match=r"world 0, body 3: position beyond 1e\+150"):
        bp.pairs_batch(beyond[None], rot[None])
    assert np.array_equal(bp.pairs(pos, rot), want)  # and it keeps working


def test_a_plane_on_a_far_body_keeps_its_touching_balls():
    # The plane's body 1e9 from the origin, its boundary near the origin: the world offset carries
    # ~eps |p| of rounding, which the plane tests' slack (scaled by |offset|) did not cover; a
    # touching ball was lost by every path (review, 2026-11-22). Then a sweep of such layouts.
    R = np.array([[-0.8361936715421523, 0.11393562808107999, 0.536468840033254],
                  [-0.049656705321903104, -0.9898935457849072, 0.1328344068001872],
                  [0.546181613833191, 0.0844360152254579, 0.8334003863950492]])
    p = np.array([-464123151.2672715, 148843237.64170915, -873175464.0769925])
    ball = np.array([0.3944170196932064, -1.8580630714139803, 0.054262339666094395])
    art = Articulation([0, 0, 0], [1, 2], [shapes.plane((0, 0, 1), 956920874.5670179),
                                           PointCloud([[0.0, 0, 0]], 0.01)])
    bp = BroadPhase(art)
    pos, rot = np.array([[0, 0, 0], p, ball]), np.stack([EYE, R, EYE])
    assert testing.brute_force_pairs(art, pos, rot).tolist() == [[0, 1]]
    assert _batch_equals_single(bp, pos, rot) == ([[0, 1]],) * 3
    rng = np.random.default_rng(5)
    touching = 0
    for scale in (1e3, 1e6, 1e12):
        for _ in range(60):
            R = random_rotation(rng)
            p = rng.normal(size=3) * scale
            n = R[:, 2]  # the plane's world normal; its local offset puts it through the origin
            far = Articulation([0, 0, 0], [1, 2], [shapes.plane((0, 0, 1), float(-n @ p)),
                                                   PointCloud([[0.0, 0, 0]], 0.01)])
            q = rng.normal(size=3)
            pos = np.array([[0, 0, 0], p, q - (n @ q) * n + 0.01 * n])  # a ball resting on it near the origin
            rot = np.stack([EYE, R, EYE])
            want = testing.brute_force_pairs(far, pos, rot).tolist()
            touching += want == [[0, 1]]
            got = _batch_equals_single(BroadPhase(far), pos, rot)
            assert got[0] == got[1] == got[2] and set(map(tuple, want)) <= set(map(tuple, got[0])), scale
    assert touching > 100

def test_wrong_shapes_and_dtypes_raise(robot_bp):
    sc, bp = robot_bp
    pos, rot = sc.poses(np.random.default_rng(0))
    L = sc.articulation.body_count
    with pytest.raises(ValueError, match="body_pos: expected shape"):
        bp.pairs(pos[:-1], rot)
    with pytest.raises(ValueError, match="body_rot: expected shape"):
        bp.pairs(pos, rot.reshape(L, 9))
    with pytest.raises(ValueError, match="body_pos: expected a float array"):
        bp.pairs(pos.astype(np.int64), rot)
    with pytest.raises(ValueError, match="body_pos: expected a numpy array"):
        bp.pairs(pos.tolist(), rot)
    with pytest.raises(ValueError, match="body_pos"):
        bp.pairs_batch(pos, rot)
    with pytest.raises(ValueError, match="body_rot: expected shape"):
        bp.pairs_batch(pos[None], rot)
    with pytest.raises(ValueError, match="articulation"):
        BroadPhase("robot")
    # float32 and non-contiguous inputs are converted, not rejected
    ref = bp.pairs(pos, rot)
    assert np.array_equal(bp.pairs(np.asfortranarray(pos), rot), ref)
    assert bp.pairs(pos.astype(np.float32), rot.astype(np.float32)).shape[1] == 2
    # the kernel's own shape check (C-contiguous float64 of the wrong size passes the dispatcher)
    with pytest.raises(ValueError, match="body_pos: expected shape"):
        bp.pairs(np.zeros((L, 4)), rot)
    with pytest.raises(ValueError, match="body_rot: expected shape"):
        bp.pairs(pos, np.zeros((L + 1, 3, 3)))


def test_results_are_not_overwritten_by_the_next_call(robot_bp, monkeypatch):
    # The kernel writes each call's pairs into fresh rows of an output arena and a full arena is
    # replaced: every result must stay as it was through later calls, whatever the arena's size
    # (7 rows: replaced every call or two; 1 row: every result is copied into a new one). Results
    # are read-only; a caller that makes one writable and writes into it gets correct pairs from
    # the next call with the same poses (the kernel compares the rows, not a flag).
    sc, bp = robot_bp
    rng = np.random.default_rng(4)
    calls = [sc.poses(rng) for _ in range(8)]
    want = [testing.brute_force_bound_pairs(sc.articulation, pos, rot) for pos, rot in calls]
    assert sum(len(w) for w in want) > 0
    assert len({len(w) for w in want}) > 1  # the calls really differed
    try:
        for rows in (ARENA_ROWS, 7, 1):
            monkeypatch.setattr(collide.broadphase, "ARENA_ROWS", rows)  # the size of new arenas
            bp._new_arena(rows)
            kept = [bp.pairs(pos, rot) for pos, rot in calls]
            for (pos, rot), w in zip(calls, want):
                got = bp.pairs(pos, rot)
                assert np.array_equal(got, w) and not got.flags.writeable
                if len(got):
                    with pytest.raises(ValueError, match="read-only"):
                        got[0, 0] = -1
                    mine = bp.pairs(pos, rot)
                    assert mine is got  # the same pairs as the last call: its array again
                    if any(mine is a for a in kept):
                        continue  # a kept result handed out again: not ours to write into
                    mine.flags.writeable = True  # its base, the arena, is writable: allowed
                    mine[:] = -1  # a caller writing into its own result
                    again = bp.pairs(pos, rot)
                    assert again is not mine and np.array_equal(again, w) and not again.flags.writeable
            for a, w in zip(kept, want):
                assert np.array_equal(a, w)
            if rows < ARENA_ROWS:
                assert len({id(a.base) for a in kept if len(a)}) > 1  # arenas were replaced
    finally:
        monkeypatch.undo()
        bp._new_arena(ARENA_ROWS)


@pytest.mark.parametrize("rows", [ARENA_ROWS, 5], ids=["arena", "small_arena"])
def test_the_last_results_array_is_handed_out_again(robot_bp, monkeypatch, rows):
    # Pairs equal to the last result come back as that same array (no new view), through both
    # entries (explicit arrays and bound ones), with arenas replaced (5 rows: most results copied
    # into a new arena, `_take`); different pairs, or the same as an older result, come as a new
    # array. (An empty result in between: test_mujoco.py.)
    sc, bp = robot_bp
    rng = np.random.default_rng(14)
    calls = [sc.poses(rng) for _ in range(30)]
    want = [testing.brute_force_bound_pairs(sc.articulation, pos, rot) for pos, rot in calls]
    hit = [i for i, w in enumerate(want) if len(w)]

    def differ(i, j):
        return not np.array_equal(want[i], want[j])

    a, b, c = next((i, j, k) for i in hit for j in hit for k in hit if differ(i, j) and differ(j, k) and differ(i, k))
    L = sc.articulation.body_count
    pos_b, rot_b = np.zeros((L, 3)), np.zeros((L, 3, 3))
    try:
        monkeypatch.setattr(collide.broadphase, "ARENA_ROWS", rows)
        bp._new_arena(rows)
        bp.bind(pos_b, rot_b)
        seq = [a, a, b, b, c, b, a, a, c, c, a]
        same_as_last = [False, True, False, True, False, False, False, True, False, True, False]
        last = None
        for n, (i, same) in enumerate(zip(seq, same_as_last)):
            pos, rot = calls[i]
            if n % 2:
                pos_b[:], rot_b[:] = pos, rot
                got = bp.pairs()
            else:
                got = bp.pairs(pos, rot)
            assert not got.flags.writeable
            assert np.array_equal(got, want[i])
            assert (got is last) == same, (n, i)
            last = got
        bp._set_buffers(1, 2)  # buffers grown and the step rerun: the same pairs, the same array
        assert bp.pairs(*calls[a]) is last
    finally:
        monkeypatch.undo()
        bp._new_arena(ARENA_ROWS)


# --------------------------------------------------------------------------- the GJK twin

def test_gjk_agrees_with_linear_programming():
    rng = np.random.default_rng(8)
    agree = hits = 0
    for k in range(300):
        P = testing.random_hull(rng, 1.0, int(rng.integers(1, 25))).points
        Q = testing.random_hull(rng, 1.0, int(rng.integers(1, 25))).points
        if k % 3 == 0:  # flat and collinear inputs too
            Q = Q * [1, 1, 0] if k % 2 else Q * [1, 0, 0]
        Q = Q + rng.uniform(-0.5, 0.5, 3)
        upper, lower = testing.gjk_distance(P, Q)
        assert lower <= upper + 1e-12 and upper - lower <= 1e-6 * max(upper, 1e-9)
        if upper > 1e-9:
            assert not testing.hulls_intersect_lp(P, Q)
            # moving Q by the distance along the separating direction makes them meet
            d = upper
            c = (P.mean(0), Q.mean(0))
            assert d <= np.linalg.norm(c[0] - c[1])
        else:
            assert testing.hulls_intersect_lp(P, Q)
            hits += 1
        agree += 1
    assert agree == 300 and 50 < hits < 250


def test_gjk_distance_is_exact_on_known_answers():
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    assert np.isclose(testing.gjk_distance(cube, cube + [3, 0, 0])[0], 2.0)
    assert np.isclose(testing.gjk_distance(cube, cube + [2, 2, 0])[0], np.sqrt(2))
    assert np.isclose(testing.gjk_distance(cube, cube + [2, 3, 4])[0], np.sqrt(1 + 4 + 9))
    assert testing.gjk_distance(cube, cube + 0.5)[0] == 0.0
    seg = np.array([[-1.0, 0, 2], [1.0, 0, 2]])
    assert np.isclose(testing.gjk_distance(cube, seg)[0], 1.0)


def test_batch_of_one_and_of_none():
    sc = testing.chain(12, seed=3, planes=1)
    bp = BroadPhase(sc.articulation)
    pos, rot = sc.poses(np.random.default_rng(9), worlds=1)
    got = bp.pairs_batch(pos, rot)
    assert np.array_equal(got[:, 1:], bp.pairs(pos[0], rot[0])) and np.all(got[:, 0] == 0)
    assert len(got) > 0
    empty = bp.pairs_batch(pos[:0], rot[:0])
    assert empty.shape == (0, 3) and empty.dtype == np.int32


def test_far_from_the_origin():
    # Rounding grows with the coordinates: the slack terms keep the bounds conservative.
    sc = testing.many_robots(8, 5, seed=31, spread=0.7, planes=0)
    a = sc.articulation
    bp = BroadPhase(a)
    rng = np.random.default_rng(5)
    touching = 0
    for _ in range(4):
        pos, rot = sc.poses(rng)
        pos = pos + np.array([3e5, -2e5, 1e5])
        got = bp.pairs(pos, rot)
        assert _rows(got) == _rows(testing.brute_force_bound_pairs(a, pos, rot))
        exact = testing.brute_force_pairs(a, pos, rot)
        assert not _rows(exact) - _rows(got)
        touching += len(exact)
    assert touching > 10


def test_tiny_bodies_far_from_the_origin_keep_their_pair():
    # Reproducer (review, 2026-11-21): boxes 1.4e-6 wide at x = 1e6 overlapping by 1.9e-11, less
    # than the rounding of their centres (1.2e-10). The tree's AABB tests had no slack and lost the
    # pair the exact test reports; the body AABBs now carry the OBB test's slack.
    from fractions import Fraction

    h1, h2 = 1.441358639424687e-06, 1.406315392012355e-06
    c1, c2 = 1.7890018458891245e-06, 3.838979540228114e-06
    x1, x2 = 1000000.9028811551, 1000000.9028819528
    assert Fraction(x1) + Fraction(c1) + Fraction(h1) > Fraction(x2) + Fraction(c2) - Fraction(h2)
    art = Articulation([0, 0, 0], [1, 2], [shapes.box([h1] * 3), shapes.box([h2] * 3)],
                       geom_pos=[[c1, 0, 0], [c2, 0, 0]])
    pos = np.array([[0, 0, 0], [x1, 5e5, 5e5], [x2, 5e5, 5e5]])
    rot = np.tile(np.eye(3), (3, 1, 1))
    assert _rows(testing.brute_force_pairs(art, pos, rot)) == {(0, 1)}
    assert _rows(BroadPhase(art).pairs(pos, rot)) == {(0, 1)}
    assert BroadPhase(art).pairs_batch(pos[None], rot[None]).tolist() == [[0, 0, 1]]


def _batch_equals_single(bp, pos, rot):
    # pairs_batch on the lanes (small models) and on the per-world kernel, each against pairs().
    single = bp.pairs(pos, rot).tolist()
    lanes = bp.pairs_batch(pos[None], rot[None])[:, 1:].tolist()
    per_world = BroadPhase(bp.articulation, batch_path="worlds").pairs_batch(pos[None], rot[None])[:, 1:].tolist()
    return single, lanes, per_world


CUBE = PointCloud([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])


def test_batch_lanes_round_as_a_single_world():
    # Reproducers (review, 2026-11-21): pairs_batch's lanes lost pairs that pairs() reports, at
    # the rounding level or at coordinates near the float range.
    # 1. Cubes touching to within an ulp: the lanes added the AABB slack in another order.
    art = Articulation([0, 0, 0], [1, 2], [CUBE, CUBE])
    bp = BroadPhase(art)
    assert bp.batch_path == "lanes"
    pos = np.array([[0.0, 0.0, 0.0], [-0.04156428198829166, 0.3, 0.7], [1.958483718364522, 0.3, 0.7]])
    rot = np.tile(EYE, (3, 1, 1))
    assert testing.brute_force_bound_pairs(art, pos, rot).tolist() == [[0, 1]]
    assert _batch_equals_single(bp, pos, rot) == ([[0, 1]],) * 3
    assert len(bp.pairs_batch(np.repeat(pos[None], 8, 0), np.repeat(rot[None], 8, 0))) == 8
    # 2. A pair handed reversed by the root's sweep (10 children): the OBB test is not bitwise
    # symmetric, and the lanes test the lower position first.
    N = 10
    art = Articulation([0] * (N + 1), np.arange(1, N + 1), [CUBE.transform(np.diag([0.3, 0.2, 0.1]))] * N)
    bp = BroadPhase(art)
    assert bp.batch_path == "lanes"
    pos = np.zeros((N + 1, 3))
    pos[1:, 1] = np.arange(N) * 5.0
    rot = np.tile(EYE, (N + 1, 1, 1))
    pos[2] = [0.0, 5.0, -1.18730931605939]
    pos[9] = [0.45668782766805, 4.902301120177755, -1.1306413376263729]
    rot[2] = [[-0.9155821294021425, 0.15022448836695368, -0.3730173821879163],
              [0.3583099253477091, -0.11632094938321313, -0.9263279301262094],
              [-0.18254687539576825, -0.9817851291547838, 0.05267445731819975]]
    rot[9] = [[0.01831905538467249, 0.09434330661142953, 0.9953711632890695],
              [0.9920210880770458, -0.12591338117235673, -0.006323073001255286],
              [0.12473400907630461, 0.9875450171710487, -0.09589716388082481]]
    # apart by less than rounding: the twins' wider slack keeps the pair, the exact test does not
    assert testing.brute_force_bound_pairs(art, pos, rot).tolist() == [[1, 8]]
    assert testing.brute_force_pairs(art, pos, rot).tolist() == []
    single, lanes, per_world = _batch_equals_single(bp, pos, rot)
    assert single == lanes == per_world
    # 3. A body near the float range: an OBB axis projection overflowed to NaN, which separated
    # nothing in the scalar test and everything in the vectorised one. Such poses are refused
    # now (beyond MAX_POSITION, 2026-11-22), by every path alike; at the limit all three agree.
    box = CUBE.transform(0.1 * EYE)
    art = Articulation([0, 0, 0], [1, 1, 2], [box, box.transform(EYE, [0.3, 0, 0]), box])
    bp = BroadPhase(art)
    hits = 0
    for seed in range(50):
        rng = np.random.default_rng(seed)
        pos = np.zeros((3, 3))
        pos[1] = 1.7e308
        rot = np.tile(EYE, (3, 1, 1))
        rot[1:] = random_rotation(rng, 2)
        with pytest.raises(ValueError, match="body 1: position beyond"):
            bp.pairs(pos, rot)
        with pytest.raises(ValueError, match="world 0, body 1: position beyond"):
            bp.pairs_batch(pos[None], rot[None])
        pos[1] = _bounds.MAX_POSITION
        pos[2] = _bounds.MAX_POSITION * (1 - 1e-16 * rng.integers(0, 3))
        single, lanes, per_world = _batch_equals_single(bp, pos, rot)
        assert single == lanes == per_world, seed
        hits += len(single)
    assert hits > 0


def test_lane_workspace_rows_are_cache_line_aligned():
    """Every worker's lane workspace starts on a 64-byte boundary (its blocks are whole (LANES,)
    float64 rows, 64 bytes each): numpy aligns to 16 only, and a row across two cache lines cost
    the chain's batch 7 %. The answer does not depend on it; this keeps the layout from drifting."""
    scene = testing.chain(12, seed=3, planes=1)
    bp = BroadPhase(scene.articulation)
    assert bp.batch_path == "lanes"
    B = 3 * _simd.LANES + 1
    pos, rot = scene.poses(np.random.default_rng(0), worlds=B)
    out = bp.pairs_batch(pos, rot)
    LW = bp._batch.buffers["LW"]
    assert LW.ctypes.data % 64 == 0 and LW.strides[0] % 64 == 0
    assert LW.shape[0] == min(numba.config.NUMBA_NUM_THREADS, bp._batch.buffers["ctx"].shape[0])  # a row a worker
    from collide._kernels import broadphase as _k, layout

    # every block of the lane workspace starts on a cache line as its row does
    assert all(off % _simd.LANES == 0 for off, _ in layout.LANE_WORK.spans(_k.model_dims(bp._I)))
    assert len(out) > 0
    for w in range(B):
        assert np.array_equal(out[out[:, 0] == w, 1:], bp.pairs(pos[w], rot[w]))


def test_lane_intrinsics_equal_the_scalar_code():
    """`_simd.aabb_mask8` and `_simd.aabb_merge8` (LLVM vector IR) give numba's scalar answers bit for
    bit: ties, signed zeros, the empty box's BIG sentinels, NaN; and a block merged with itself."""
    import numba

    @numba.njit
    def vector(q, x):
        m = _simd.aabb_mask8(q.ctypes.data, x.ctypes.data)
        _simd.aabb_merge8(q.ctypes.data, x.ctypes.data)
        return m

    @numba.njit
    def scalar(q, x):
        m = 0
        for l in range(8):
            ok = True
            for i in range(3):
                ok &= (q[i, l] <= x[3 + i, l]) & (x[i, l] <= q[3 + i, l])
            m |= int(ok) << l
        for i in range(3):
            for l in range(8):
                q[i, l] = min(q[i, l], x[i, l])
                q[3 + i, l] = max(q[3 + i, l], x[3 + i, l])
        return m

    rng = np.random.default_rng(5)
    values = np.array([-0.0, 0.0, 1.0, -1.0, 0.5, _bounds.BIG, -_bounds.BIG, np.nan, 1e-300, -2.5])
    hits = 0
    for trial in range(400):
        if trial % 2:  # the special values
            q, x = (rng.choice(values, size=(6, 8)) for _ in range(2))
        else:  # proper boxes on a coarse grid (ties; half of the lanes overlap)
            q, x = (np.round(rng.uniform(-2, 2, (6, 8)) * 2) / 2 for _ in range(2))
            q[3:], x[3:] = q[:3] + np.abs(q[3:]), x[:3] + np.abs(x[3:])
        q1, q2 = q.copy(), q.copy()
        m1, m2 = vector(q1, x), scalar(q2, x)
        assert m1 == m2
        assert np.array_equal(q1.view(np.int64), q2.view(np.int64))
        hits += bin(m1).count("1")
        q3 = q.copy()
        vector(q3, q3)  # merged with itself: unchanged bits
        assert np.array_equal(q3.view(np.int64), q.view(np.int64))
    assert hits > 100, hits  # the masks had real hits (236 with this seed)


def test_slightly_scaled_rotations_never_lose_a_touching_pair():
    # Rotations are accepted up to |R^T R - I| <= 1e-6 (float32 poses); the bounds carry the slack.
    # Reproducer (2026-11-21): a rotation scaled by 1 + 4.5e-7 missed boxes 4e-7 apart.
    art = Articulation([0, 0, 0], [1, 2], [shapes.box([1, 1, 1]), shapes.box([1, 1, 1])])
    bp = BroadPhase(art)
    hits = 0
    for gap in np.linspace(1e-7, 8e-7, 8):
        for scale in (1 + 4.5e-7, 1 - 4.5e-7):
            pos = np.array([[0, 0, 0], [0, 0, 0], [2 + gap, 0, 0]])
            rot = np.stack([np.eye(3), np.eye(3) * scale, np.eye(3)])
            truth = testing.brute_force_pairs(art, pos, rot)
            ours = bp.pairs(pos, rot)
            assert set(map(tuple, truth)) <= set(map(tuple, ours))
            assert np.array_equal(ours, testing.brute_force_bound_pairs(art, pos, rot))
            hits += len(truth)
    assert hits > 0  # some of these poses really touch


def _walls_and_dumbbells(rng, extras=False, filter_parent=True):
    # The world's static geoms (a ring of walls, scattered blocks) become leaves of their own,
    # and dumbbells (two small geoms far apart) have body bounds that are mostly empty space.
    # A floor in the world too (never paired with the world's leaves: one weld group), wall 1
    # on its own mask (pairs with nothing but its explicit pair with the first geom of body 2),
    # and the world excluded with body 1: the leaves inherit the world's rules. With extras, a
    # second plane and explicit pairs of a plane with a geom and of the two planes (never a pair).
    walls = [((0, 3, 0), (3, 0.2, 0.5)), ((0, -3, 0), (3, 0.2, 0.5)), ((3, 0, 0), (0.2, 3, 0.5)),
             ((-3, 0, 0), (0.2, 3, 0.5)), ((1, 1, 0), (0.3, 0.3, 0.3)), ((-1.5, 0.5, 0), (0.2, 0.2, 0.2))]
    n_free = 30
    parent = [0] + [0] * n_free
    geom_body, clouds, gpos = [], [], []
    for c, h in walls:
        geom_body.append(0)
        clouds.append(shapes.box(h))
        gpos.append(c)
    for b in range(1, n_free + 1):
        if b % 3 == 0:  # a dumbbell: two spheres 2.4 apart
            for off in (-1.2, 1.2):
                geom_body.append(b)
                clouds.append(shapes.sphere(0.15))
                gpos.append((off, 0, 0))
        else:
            geom_body.append(b)
            clouds.append(testing.scenes.random_shape(rng, 0.4))
            gpos.append((0, 0, 0))
    geom_body.append(0)
    clouds.append(shapes.plane((0, 0, 1), -0.3))
    gpos.append((0, 0, 0))
    g_b2 = geom_body.index(2)
    pairs = [(1, g_b2)]
    if extras:
        floor = len(geom_body) - 1
        geom_body.append(0)
        clouds.append(shapes.plane((1, 0, 0), -2.5))
        gpos.append((0, 0, 0))
        pairs += [(floor, floor + 1), (floor, geom_body.index(4)), (geom_body.index(5), floor + 1)]
    G = len(geom_body)
    contype = np.ones(G, np.int64)
    contype[1] = 2
    art = Articulation(parent, geom_body, clouds, geom_pos=np.array(gpos, float),
                       geom_contype=contype, geom_conaffinity=contype, geom_margin=rng.uniform(0, 0.02, G),
                       exclude=[(0, 1)], pairs=pairs, filter_parent=filter_parent)
    return art, len(walls), n_free, g_b2


def _walls_poses(rng, n_free):
    pos = np.concatenate([np.zeros((1, 3)), rng.uniform([-3.2, -3.2, -0.5], [3.2, 3.2, 0.5], (n_free, 3))])
    rot = np.concatenate([np.eye(3)[None], testing.scenes.random_rotation(rng, n_free)])
    return pos, rot


def test_loose_multi_geom_bodies_skip_body_tests_and_lose_nothing():
    # Both the world's leaves and the loose dumbbells (the kernel skips their body-level tests:
    # BroadPhase's `single` < 0) must still equal the bounds twin.
    rng = np.random.default_rng(12)
    art, n_walls, n_free, g_b2 = _walls_and_dumbbells(rng)
    bp = BroadPhase(art)
    # The world's 6 geoms became leaves of their own (positions 1..6); the dumbbells are loose.
    I = bp._I
    Lp, V = I[_layout.H_L], I[_layout.H_V]
    assert V == n_walls and Lp == art.body_count + V == bp.position_count
    single, has_bounds = _field(bp, "single"), _field(bp, "has_bounds")
    assert has_bounds[0] == 0 and np.all(single[1:V + 1] == 1)
    assert np.sum(single < 0) == n_free // 3
    hits = touching = explicit = 0
    for _ in range(40):
        pos, rot = _walls_poses(rng, n_free)
        got = bp.pairs(pos, rot)
        assert _rows(got) == _rows(testing.brute_force_bound_pairs(art, pos, rot))
        exact = testing.brute_force_pairs(art, pos, rot)
        assert not _rows(exact) - _rows(got)
        hits += int(np.sum(np.asarray(art.geom_body)[got[:, 0]] == 0))
        touching += len(exact)
        gb = np.asarray(art.geom_body)[got]
        assert not np.any((gb[:, 0] == 0) & (gb[:, 1] == 0))  # never the world with itself
        assert not np.any(((gb[:, 0] == 0) & (gb[:, 1] == 1)) | ((gb[:, 0] == 1) & (gb[:, 1] == 0)))
        wall1 = got[(got[:, 0] == 1) | (got[:, 1] == 1)]
        assert all(tuple(r) == (1, g_b2) for r in wall1)
        explicit += len(wall1)
    assert hits > 40 and touching > 40  # the walls and dumbbells really met the others
    assert explicit > 0  # the explicit pair of wall 1 did fire


@pytest.mark.parametrize("order", ["shuffled", "runs", "sorted", "nearly", "reversed", "one_first_id"])
@pytest.mark.parametrize("distinct", [False, True])
@pytest.mark.parametrize("G, k", [(30, 85), (419, 226), (5000, 150), (70000, 3000), (7, 1), (7, 2), (78, 110)])
def test_key_sort_equals_numpy(G, k, order, distinct):
    # The kernel's output sort (a bit set of the key space when small, duplicates sent on; insertion
    # sort on a few runs, else two counting passes; two parts merged) against np.sort, on the orders
    # the kernel produces and worse; the keys buffer's tail and everything outside the scratch stay
    # untouched, and garbage in the scratch does no harm.
    rng = np.random.default_rng(G + k)
    S = _keys.key_shift(G)
    g = np.sort(rng.integers(0, G, (k, 2)), axis=1)
    if order == "one_first_id":
        g[:, 0] = 0
    if distinct:  # as the kernel's keys (each pair found once): the bit-set sort's case
        g = np.unique(g, axis=0)
        g = g[rng.permutation(len(g))]
        k = len(g)
    keys = (g[:, 0].astype(np.int64) << S) | g[:, 1]
    ref = np.sort(keys)
    if order == "runs":  # a few ascending runs, as positions following ids give
        keys = np.concatenate([np.sort(part) for part in np.array_split(rng.permutation(keys), 5)])
    elif order == "sorted":
        keys = ref.copy()
    elif order == "nearly":  # a few neighbours swapped: insertion sort finishes within its budget
        keys = ref.copy()
        for i in range(0, k - 1, 7):
            keys[i], keys[i + 1] = keys[i + 1], keys[i]
    elif order == "reversed":
        keys = ref[::-1].copy()
    cap = k + 3
    for k4 in sorted({0, k // 3, k}):  # body-level keys first, then plane keys: each part sorted apart
        buf = np.concatenate([keys, [-7, -7, -7]])
        scr = np.full(_keys.scratch_size(G, cap) + 2, -9, np.int64)
        _keys._sort_keys(buf, k, k4, S, G, scr[:-2])
        assert np.array_equal(buf[:k], ref) and np.all(buf[k:] == -7) and np.all(scr[-2:] == -9)


def test_traversal_paths_equal_bounds_twin():
    """Each way the traversal finds body pairs agrees with the twin, on scenes that reach it.

    Two 70-link chains coiled in one box: most bodies of each meet the other's subtree AABB, so
    the pair of subtrees (`_subtree_pair`) walks deep into both. Small
    branching robots (more than `MASK_MAX` positions, so that the tree is walked): their pairs come
    from the static masks made at set-up (`flat_root`).
    """
    rng = np.random.default_rng(31)
    n = 70
    parent = np.r_[0, 0, np.arange(1, n), 0, np.arange(n + 1, 2 * n)]
    a = Articulation(parent, np.arange(1, 2 * n + 1), [PointCloud([[0, 0, 0], [0.1, 0, 0]], 0.04)] * (2 * n))
    bp = BroadPhase(a, coherent=False)  # the walk itself (its subtree AABBs are read below)
    assert not _field(bp, "flat_root").any()
    total = 0
    for _ in range(5):
        pos = rng.uniform(-1, 1, (2 * n + 1, 3))
        rot = np.stack([testing.random_rotation(rng) for _ in range(2 * n + 1)])
        got = bp.pairs(pos, rot)
        assert np.array_equal(got, testing.brute_force_bound_pairs(a, pos, rot))
        total += len(got)
        # most bodies of each chain meet the other chain's subtree AABB
        baabb, saabb = _field(bp, "baabb"), _field(bp, "saabb")
        meets = [((baabb[ch, :3] <= saabb[other, 3:]) & (saabb[other, :3] <= baabb[ch, 3:])).all(axis=1).sum()
                 for ch, other in ((np.arange(1, n + 1), n + 1), (np.arange(n + 1, 2 * n + 1), 1))]
        assert min(meets) > n // 2
    assert total > 50  # the scenes had hits

    sc = testing.many_robots(11, 6, seed=32, spread=0.5)
    bp = BroadPhase(sc.articulation)
    flat_root = _field(bp, "flat_root")
    assert flat_root.sum() >= 5 and bp.position_count > _cull.MASK_MAX  # walked: up to 64, no tree
    pos, rot = sc.poses(np.random.default_rng(33), worlds=6)
    total = 0
    for w in range(len(pos)):
        got = bp.pairs(pos[w], rot[w])
        assert np.array_equal(got, testing.brute_force_bound_pairs(sc.articulation, pos[w], rot[w]))
        total += len(got)
    assert total > 100


def test_flat_root_of_64_positions():
    """A flat root spanning 64 positions: its last body is bit 63 of the static masks.

    Body 1 forks into two 31- and 32-link chains (positions follow ids); only the first and last
    eight bodies collide, so the root's list stays short enough to be flat, and the pairs reaching
    position 64 (the sign bit of an int64 mask) must be found like any other.
    """
    n = 64
    parent = np.r_[0, 0, np.arange(1, 32), 1, np.arange(33, n)]
    coll = np.r_[np.ones(8), np.zeros(n - 16), np.ones(8)].astype(int)
    cloud = PointCloud([[0, 0, 0], [0.3, 0, 0]], 0.1)
    a = Articulation(parent, np.arange(1, n + 1), [cloud] * n, geom_contype=coll, geom_conaffinity=coll)
    bp = BroadPhase(a)
    flat_root, flat_mask = _field(bp, "flat_root"), _field(bp, "flat_mask")
    assert flat_root[1] == 1 and flat_mask.min() < 0  # one flat root, a mask with bit 63 set
    rng = np.random.default_rng(64)
    total = last = 0
    for _ in range(40):
        pos = rng.uniform(-0.6, 0.6, (n + 1, 3))
        rot = np.stack([testing.random_rotation(rng) for _ in range(n + 1)])
        got = bp.pairs(pos, rot)
        assert np.array_equal(got, testing.brute_force_bound_pairs(a, pos, rot))
        total += len(got)
        last += int((got[:, 1] == n - 1).sum())  # geom n - 1 is on body 64
    assert total > 200 and last > 10


def test_copies_and_pickles_are_rebuilt():
    """copy, deepcopy and pickle give working broad phases, independent of the original.

    The kernel's context holds raw addresses of the object's own buffers; a copy reusing them read
    another object's memory (garbage pairs, then a crash once the original was freed).
    """
    import copy
    import gc
    import pickle

    sc = testing.many_robots(4, 5, seed=41, spread=0.4)
    pos, rot = sc.poses(np.random.default_rng(42), worlds=3)
    bp = BroadPhase(sc.articulation)
    want = [bp.pairs(pos[w], rot[w]) for w in range(3)]
    assert sum(len(p) for p in want) > 10  # the scene had hits
    copies = [copy.copy(bp), copy.deepcopy(bp), pickle.loads(pickle.dumps(bp))]
    del bp
    gc.collect()
    for c in copies:
        for w in range(3):
            assert np.array_equal(c.pairs(pos[w], rot[w]), want[w])
        assert np.array_equal(c.pairs_batch(pos, rot)[:, 1:], np.concatenate(want))


def test_one_copy_per_thread():
    # The documented way to use threads: each its own copy, all at once, each answer its own, in
    # its own memory (the kernels hold the GIL, so a shared instance would rarely race; the
    # arenas tell whether the copies share state).
    import copy

    sc = testing.many_robots(4, 5, seed=45, spread=0.4)
    pos, rot = sc.poses(np.random.default_rng(46), worlds=40)
    bp = BroadPhase(sc.articulation)
    want = [bp.pairs(pos[w], rot[w]).copy() for w in range(40)]
    assert sum(len(p) for p in want) > 100  # the scene had hits

    def run(t):
        mine = copy.copy(bp)
        return [[mine.pairs(pos[w], rot[w]) for w in range(40)] for _ in range(25)]

    got = in_threads(run, 4)
    for rounds in got:
        for answers in rounds:
            for w in range(40):
                assert np.array_equal(answers[w], want[w])
    arenas = [{id(a.base) for answers in got[t] for a in answers if len(a)} for t in range(4)]
    assert all(arenas) and all(arenas[t].isdisjoint(arenas[u]) for t in range(4) for u in range(t))


def test_read_only_pose_arrays():
    # A memory map or another framework's buffer arrives read-only: read, never written.
    sc = testing.many_robots(3, 5, seed=43, spread=0.3)
    pos, rot = sc.poses(np.random.default_rng(44), worlds=1)
    bp = BroadPhase(sc.articulation)
    want = bp.pairs(pos[0], rot[0])
    assert len(want) > 0
    p, r = pos[0].copy(), rot[0].copy()
    p.flags.writeable = False
    r.flags.writeable = False
    assert np.array_equal(bp.pairs(p, r), want)
    assert np.array_equal(bp.pairs(p, rot[0]), want)
    assert np.array_equal(bp.pairs(pos[0], r), want)


# --------------------------------------------------------------------------- world bounds

def _primitive_articulation(rng, n_bodies=8):
    # A tree of bodies, each with one or two random primitives (every kind of collide.shapes) at a
    # random place in its body, random margins, a floor plane on the world; returns the
    # articulation and, per geom, its kind and parameters (for true-surface sampling).
    parent = np.array([0] + [int(rng.integers(0, b)) for b in range(1, n_bodies)])
    geom_body, clouds, specs, gpos, grot = [0], [shapes.plane((0, 0.6, 0.8), -0.3)], [None], [np.zeros(3)], [EYE]
    for b in range(1, n_bodies):
        for _ in range(int(rng.integers(1, 3))):
            kind = testing.SHAPE_KINDS[int(rng.integers(len(testing.SHAPE_KINDS)))]
            params = testing.random_shape_params(kind, rng)
            geom_body.append(b)
            clouds.append(getattr(shapes, kind)(**params))
            specs.append((kind, params))
            gpos.append(rng.normal(size=3))
            grot.append(random_rotation(rng))
    G = len(geom_body)
    margin = rng.choice([0.0, 0.01, 0.3], size=G)
    art = Articulation(parent, geom_body, clouds, geom_pos=np.array(gpos), geom_rot=np.array(grot),
                       geom_margin=margin)
    return art, specs


def _inside(points, wb, i, tol):
    # points (n, 3) world: inside row i's OBB, sphere and AABB, each given up to tol.
    local = (points - wb.obb_center[i]) @ wb.obb_rot[i]
    obb = np.abs(local) <= wb.obb_half[i] + tol
    sphere = np.linalg.norm(points - wb.sphere_center[i], axis=1) <= wb.sphere_radius[i] + tol
    box = (points >= wb.aabb_min[i] - tol) & (points <= wb.aabb_max[i] + tol)
    return obb.all(), sphere.all(), box.all()


@pytest.mark.parametrize("seed", range(3))
def test_world_bounds_contain_the_true_surfaces_under_random_poses(seed):
    rng = np.random.default_rng(40 + seed)
    art, specs = _primitive_articulation(rng)
    bp = BroadPhase(art)
    checked = 0
    for scale in (1e-2, 1.0, 1e3):
        pos = rng.normal(scale=scale, size=(art.body_count, 3))
        rot = random_rotation(rng, art.body_count)
        geoms = bp.world_bounds(pos, rot)
        tight = bp.world_bounds(pos, rot, inflate=False)
        bodies = bp.world_bounds(pos, rot, of="bodies")
        for g in range(1, art.geom_count):
            kind, params = specs[g]
            local = testing.sample_surface(kind, 200, rng, **params) @ art.geom_rot[g].T + art.geom_pos[g]
            b = art.geom_body[g]
            pts = local @ rot[b].T + pos[b]
            d = rng.normal(size=pts.shape)
            grown = pts + art.geom_margin[g] * d / np.linalg.norm(d, axis=1, keepdims=True)
            tol = 1e-12 * (1.0 + scale)
            assert _inside(pts, tight, g, tol) == (True, True, True), (kind, params, scale)
            assert _inside(grown, geoms, g, tol) == (True, True, True), (kind, scale)
            assert _inside(grown, bodies, b, tol) == (True, True, True), (kind, scale)
            checked += len(pts)
        # the inflated bounds of a geom are its tight ones grown by its margin (an AABB side by at
        # most sqrt(3) margins each way: the box's grown diagonal), and no looser
        m = art.geom_bound_margin[1:, None]
        assert np.allclose(geoms.obb_half[1:], tight.obb_half[1:] + m)
        assert np.allclose(geoms.sphere_radius[1:], tight.sphere_radius[1:] + m[:, 0])
        grow = (geoms.aabb_max[1:] - geoms.aabb_min[1:]) - (tight.aabb_max[1:] - tight.aabb_min[1:])
        assert np.all(grow <= 2 * np.sqrt(3) * m + 1e-9) and np.all(grow >= -1e-9)
    assert checked > 5000


def test_world_bounds_agree_with_the_twin_and_the_bound_arrays():
    sc = testing.branching_tree(30, seed=3, planes=2)
    a = sc.articulation
    bp = BroadPhase(a)
    pos, rot = sc.poses(np.random.default_rng(1))
    pos, rot = np.ascontiguousarray(pos), np.ascontiguousarray(rot)
    wb = bp.world_bounds(pos, rot, inflate=False)
    c, R, h, sc_, sr, plane = testing.world_bounds(a, pos, rot)
    solid = ~a.geom_is_plane
    assert np.allclose(wb.obb_center[solid], c[solid], atol=1e-12) and np.allclose(wb.obb_rot[solid], R[solid])
    assert np.array_equal(wb.obb_half[solid], h[solid]) and np.array_equal(wb.sphere_radius[solid], sr[solid])
    assert np.allclose(wb.sphere_center[solid], sc_[solid], atol=1e-12)
    assert np.allclose(wb.plane[~solid], plane[~solid]) and not wb.plane[solid].any()
    # planes: unbounded, centred on their boundary, offset grown by the margin when inflated
    q = np.flatnonzero(~solid)
    assert len(q) == 2 and np.all(np.isinf(wb.obb_half[q])) and np.all(np.isinf(wb.sphere_radius[q]))
    assert np.all(wb.aabb_min[q] == -np.inf) and np.all(wb.aabb_max[q] == np.inf)
    assert np.allclose(np.einsum("ni,ni->n", wb.plane[q, :3], wb.obb_center[q]), wb.plane[q, 3])
    inflated = bp.world_bounds(pos, rot)
    assert np.allclose(inflated.plane[q, 3], wb.plane[q, 3] + a.geom_bound_margin[q])
    # bodies without a solid geom are empty boxes; the others' AABBs hold their geoms' AABBs
    bodies = bp.world_bounds(pos, rot, of="bodies")
    bare = ~a.body_has_bounds
    assert bare.any() and np.all(bodies.aabb_min[bare] == np.inf) and np.all(bodies.sphere_radius[bare] == -np.inf)
    for g in np.flatnonzero(solid):
        b = a.geom_body[g]
        assert np.all(bodies.aabb_min[b] <= inflated.aabb_min[g] + 1e-9)
        assert np.all(bodies.aabb_max[b] >= inflated.aabb_max[g] - 1e-9)
    # the arrays given to bind are read when no pose is given
    bp.bind(pos, rot)
    again = bp.world_bounds()
    assert all(np.array_equal(x, y) for x, y in zip(again, inflated))


def test_world_bounds_refuse_bad_input():
    bp = BroadPhase(Articulation([0, 0, 1], [1, 2], [BALL, BALL]))
    pos, rot = np.zeros((3, 3)), np.tile(EYE, (3, 1, 1))
    with pytest.raises(ValueError, match="no pose arrays given and none bound"):
        bp.world_bounds()
    bad = pos.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="body 2: pose has a non-finite value"):
        bp.world_bounds(bad, rot)
    skew = rot.copy()
    skew[1] *= 1.01
    with pytest.raises(ValueError, match="body 1: rotation is not a proper orthonormal matrix"):
        bp.world_bounds(pos, skew)
    mirror = rot.copy()
    mirror[1, 0, 0] = -1.0
    with pytest.raises(ValueError, match="body 1: rotation is not a proper orthonormal matrix"):
        bp.world_bounds(pos, mirror)
    with pytest.raises(ValueError, match=r"body_pos: expected shape \(3, 3\)"):
        bp.world_bounds(pos[:2], rot)
    with pytest.raises(ValueError, match="body_rot: expected a float array"):
        bp.world_bounds(pos, rot.astype(int))
    with pytest.raises(ValueError, match="of: expected 'geoms' or 'bodies'"):
        bp.world_bounds(pos, rot, of="links")
    with pytest.raises(ValueError, match="inflate: expected True or False"):
        bp.world_bounds(pos, rot, inflate="yes")
    assert bp.world_bounds(pos, rot).obb_center.shape == (2, 3)  # and it still works


def test_world_bounds_of_a_box_and_a_ball_are_known():
    # A box's bounds are the box, turned with its body; a ball's AABB is its sphere's box (the
    # OBB's AABB would be wider once turned): both within the set-up's conservative slack.
    half = np.array([1.0, 2.0, 3.0])
    art = Articulation([0, 0, 0], [1, 2], [shapes.box(half), PointCloud([[0, 0, 0]], 0.5)], geom_margin=[0.0, 0.1])
    bp = BroadPhase(art)
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    pos = np.array([[0, 0, 0], [5.0, 0, 0], [0, 0, 7.0]])
    rot = np.stack([EYE, turn, turn])
    wb = bp.world_bounds(pos, rot)
    w = np.array([(1 + 2) * c, (1 + 2) * c, 3.0])  # the turned box's AABB half widths
    assert np.all(wb.aabb_max[0] - pos[1] >= w) and np.all(wb.aabb_max[0] - pos[1] <= w + 1e-4)
    assert np.all(pos[1] - wb.aabb_min[0] >= w) and np.all(pos[1] - wb.aabb_min[0] <= w + 1e-4)
    assert np.allclose(np.sort(wb.obb_half[0]), half, atol=1e-4) and np.all(np.sort(wb.obb_half[0]) >= half)
    assert np.allclose(wb.aabb_max[1] - pos[2], 0.6, atol=1e-5) and np.allclose(wb.sphere_radius[1], 0.6, atol=1e-5)
    assert np.all(wb.aabb_max[1] - pos[2] >= 0.6) and np.all(pos[2] - wb.aabb_min[1] >= 0.6)


@pytest.mark.parametrize("explicit", [False, True], ids=["geom_margin", "pair_margin"])
@pytest.mark.parametrize("scale", [1 - 4.9e-7, 1 + 4.9e-7])
def test_margins_are_covered_under_accepted_nearly_orthonormal_rotations(scale, explicit):
    # Two points with margin 1, 2 - 1e-7 apart: touching. Body rotations scaled by 1 -/+ 4.9e-7
    # are accepted (|R^T R - I| = 9.8e-7 <= 1e-6); the bounds moved the margin with them and the
    # pair was lost, and a point of the inflated shape fell outside the world bounds (review,
    # 2026-11-22). The same for an explicit pair's own margin.
    dot = PointCloud([[0, 0, 0]])
    art = (Articulation([0, 0, 0], [1, 2], [dot, dot], pairs=[(0, 1)], pair_margin=[1.0]) if explicit
           else Articulation([0, 0, 0], [1, 2], [dot, dot], geom_margin=[1.0, 1.0]))
    bp = BroadPhase(art)
    rot = np.stack([EYE, scale * EYE, scale * EYE])
    pos = np.array([[0, 0, 0], [0, 0, 0], [2 - 1e-7, 0, 0.0]])
    assert testing.brute_force_pairs(art, pos, rot).tolist() == [[0, 1]]
    assert bp.pairs(pos, rot).tolist() == [[0, 1]]
    assert bp.pairs_batch(pos[None], rot[None]).tolist() == [[0, 0, 1]]
    assert testing.brute_force_bound_pairs(art, pos, rot).tolist() == [[0, 1]]
    if explicit:
        return  # world_bounds inflates by the geoms' margins (0 here), not by a pair's
    wb = bp.world_bounds(pos, rot)
    reach = np.vstack([EYE, -EYE])  # the inflated point's extremes, margin 1 in the world
    assert np.all(np.abs((reach - wb.obb_center[0]) @ wb.obb_rot[0]) <= wb.obb_half[0])
    assert np.all(reach <= wb.aabb_max[0]) and np.all(reach >= wb.aabb_min[0])


def test_the_exact_twin_keeps_exact_margins_and_the_bounds_their_slack():
    # Points with margin 1, 2 (1 + 1e-5) apart: not touching (the exact twin), but within the
    # bounds' margin slack (MARGIN_SLACK = 3.2e-5 relative): the broad phase and its bound twin
    # report them, the exact twin does not.
    dot = PointCloud([[0, 0, 0]])
    art = Articulation([0, 0, 0], [1, 2], [dot, dot], geom_margin=[1.0, 1.0])
    pos = np.array([[0, 0, 0], [0, 0, 0], [2 * (1 + 1e-5), 0, 0.0]])
    rot = np.tile(EYE, (3, 1, 1))
    assert testing.brute_force_pairs(art, pos, rot).tolist() == []
    assert testing.brute_force_bound_pairs(art, pos, rot).tolist() == [[0, 1]]
    assert BroadPhase(art).pairs(pos, rot).tolist() == [[0, 1]]


def test_position_limit_is_the_geoms_coordinate_limit():
    assert _bounds.MAX_POSITION == collide.hull.MAX_COORDINATE


def test_world_aabbs_carry_the_rounding_slack_of_their_centres():
    # A point geom far from the origin: its world AABB is as wide as the kernels' slack of its
    # centre's magnitude (SLACK_POS |c|_1 each way, 6e-5 here), which covers the rounding of c;
    # without it, one ulp (6e-8). Compared at half, the widths themselves being rounded at 3e8.
    bp = BroadPhase(Articulation([0, 0], [1], [PointCloud([[0.3, 0.2, 0.1]])]))
    pos = np.array([[0, 0, 0], [1e8, -2e8, 3e8]])
    wb = bp.world_bounds(pos, np.stack([EYE, random_rotation(np.random.default_rng(0))]))
    assert np.all(wb.aabb_max[0] - wb.aabb_min[0] >= _bounds.SLACK_POS * np.abs(wb.obb_center[0]).sum())


def test_planes_on_nearly_orthonormal_bodies_are_moved_exactly():
    # A plane on a body whose accepted rotation is skewed by 4.9e-7: the world normal was R n, not
    # R^-T n, and the halfspace missed the moved plane by the skew times the distance along it (a
    # ball touching the plane 1 km out was lost; review, 2026-11-22).
    R = np.eye(3) + np.array([[0, 0, 1], [0, 0, 0], [1, 0, 0.0]]) * 4.9e-7
    art = Articulation([0, 0, 0], [1, 2], [shapes.plane((0, 0, 1), 0.0), PointCloud([[0, 0, 0]], 0.01)])
    bp = BroadPhase(art)
    rot = np.stack([EYE, R, EYE])
    true_n = np.linalg.inv(R).T @ [0, 0, 1.0]
    true_n /= np.linalg.norm(true_n)
    for far in (1.0, 1e3, 1e5):
        pos = np.zeros((3, 3))
        pos[2] = R @ [far, 0, 0] + true_n * (0.01 - 1e-6 * max(1.0, far / 1e3))  # the ball dips into the plane
        assert testing.brute_force_pairs(art, pos, rot).tolist() == [[0, 1]], far
        assert bp.pairs(pos, rot).tolist() == [[0, 1]], far
        assert bp.pairs_batch(pos[None], rot[None]).tolist() == [[0, 0, 1]], far
        wb = bp.world_bounds(pos, rot, inflate=False)
        n, d = wb.plane[0, :3], wb.plane[0, 3]
        for y in ([far, 0, 0], [0, far, 0], [-far, 0, 0], [0, -far, 0]):
            assert n @ (R @ np.array(y)) - d <= 1e-15 * far  # the moved boundary lies in the halfspace


def test_planes_placed_by_nearly_orthonormal_geom_rotations_keep_their_pairs():
    # The same for a plane's geom_rot (accepted within ORTHO_TOL): the articulation mapped the
    # normal by R n, and a ball 100 out dipping 1e-7 into the true plane was lost in 21 of 200
    # float32-rounded rotations (review, 2026-11-22).
    rng = np.random.default_rng(3)
    for _ in range(40):
        R = random_rotation(rng).astype(np.float32).astype(np.float64)
        art = Articulation([0, 0], [0, 1], [shapes.plane(), shapes.sphere(0.1)], geom_rot=[R, EYE])
        true_n = np.linalg.solve(R.T, [0, 0, 1.0])
        true_n /= np.linalg.norm(true_n)
        np.testing.assert_allclose(art.geom_plane[0, :3], true_n, rtol=0, atol=1e-15)
        u = np.cross(true_n, rng.standard_normal(3))
        centre = 100.0 * u / np.linalg.norm(u) + true_n * (0.1 - 1e-7)  # on the plane 100 out, dipping in
        pos, rot = np.array([[0, 0, 0], centre]), np.stack([EYE, EYE])
        assert BroadPhase(art).pairs(pos, rot).tolist() == [[0, 1]]
        assert testing.brute_force_pairs(art, pos, rot).tolist() == [[0, 1]]


# --------------------------------------------------------------------------- frame coherence

COHERENT_SCENES = [
    ("chain", lambda: testing.chain(64, seed=21, planes=1, joint_range=1.6), 0.001),  # the tip moves 64 joints' worth
    ("tree", lambda: testing.branching_tree(70, seed=22, planes=1), 0.002),
    ("robots", lambda: testing.many_robots(11, 6, seed=23, spread=0.6, planes=1), 0.01),  # flat roots
    ("hulls_sweep", lambda: testing.free_hulls(64, seed=24, filters=True, planes=1), 0.01),
    ("hulls_many", lambda: testing.free_hulls(125, seed=25, filters=True), 0.01),
]


def _coherence_state(bp):
    return _field(bp, "coh")


def _motion(sc, rng, steps, step=0.01):
    if sc.meta.get("home_pos") is not None:
        return testing.hull_motion(sc, rng, steps, step)
    return testing.scene_motion(sc, rng, steps, step)


@pytest.mark.parametrize("name, make, step", COHERENT_SCENES, ids=[s[0] for s in COHERENT_SCENES])
def test_coherent_calls_equal_the_walk_along_motions_and_jumps(name, make, step):
    # Along a smooth motion the kept list is reused (and rebuilt when a body leaves its fat box);
    # every 40 calls the poses jump to an unrelated configuration. Each call must equal the walk's
    # (coherent=False) and, every tenth, the bounds twin. (More than MASK_MAX positions: below, no
    # list is kept, `test_static_masks_equal_the_twin_and_keep_no_list`.)
    sc = make()
    a = sc.articulation
    coh, walk = BroadPhase(a), BroadPhase(a, coherent=False)
    assert coh.coherent and not walk.coherent and coh.position_count > _cull.MASK_MAX
    rng = np.random.default_rng(7)
    pos, rot = _motion(sc, rng, 120, step)
    reused = pairs = 0
    for s in range(len(pos)):
        p, r = (pos[s], rot[s]) if s % 40 != 39 else sc.poses(rng)
        got = coh.pairs(p, r)
        reused += coh.stats["reused"]
        assert np.array_equal(got, walk.pairs(p, r)), s
        assert walk.stats["reused"] == 0
        # the same body pairs on to the same tests (a loose pair's body test skipped in both)
        for key in ("geom_aabb_tests", "geom_sphere_tests", "geom_obb_tests", "plane_tests", "body_sphere_tests",
                    "body_obb_tests"):
            assert coh.stats[key] == walk.stats[key], (s, key)
        if s % 10 == 0:
            assert np.array_equal(got, testing.brute_force_bound_pairs(a, p, r)), s
        pairs += len(got)
    assert pairs > 100  # the scenes had hits
    assert 0.3 * len(pos) < reused < len(pos) - 3  # the list was reused, and rebuilt


MASK_SCENES = [
    # 64 positions, the most held as masks (the last body is bit 63: an int64's sign), loose bodies
    ("tree_64_positions", lambda: testing.branching_tree(63, seed=22, planes=1)),
    ("robots", lambda: testing.many_robots(10, 6, seed=23, spread=0.6, planes=1)),
    ("hulls", lambda: testing.free_hulls(40, seed=24, filters=True, planes=1)),
    ("chain", lambda: testing.chain(40, seed=25, planes=1, joint_range=1.6)),
]


def _check_static_masks(bp, a):
    # The bits of `pack`'s smask: the pairs the static filter (`_filter`, run on all pairs with
    # bounds) passes, less those without a geom pair whose masks match that is not an explicit pair
    # (their geom loop would emit nothing); returns how many were dropped so.
    L = bp.position_count
    smask = _field(bp, "smask")
    single, has_bounds, weld, parent_pos, contype, conaffinity, ex_start, ex_other = (
        _field(bp, n) for n in ("single", "has_bounds", "weld", "parent_pos", "contype", "conaffinity", "ex_start",
                                "ex_other"))
    allp = np.array([(x, y) for x in range(L) for y in range(x + 1, L) if has_bounds[x] and has_bounds[y]], np.int64)
    n = _cull._filter(allp, len(allp), contype, conaffinity, weld, parent_pos, a.filter_parent, ex_start, ex_other,
                      single)
    gstart, pgeoms, gct, gca = (_field(bp, n) for n in ("gstart", "pgeoms", "geom_contype", "geom_conaffinity"))
    explicit = set(_field(bp, "pair_keys").tolist())
    S = int(bp._I[_layout.H_KS])
    want = np.zeros(L, np.uint64)
    dropped = 0
    for x, y in allp[:n]:
        y = y ^ (y >> 63)
        if any(((gct[g1] & gca[g2]) or (gct[g2] & gca[g1])) and (min(g1, g2) << S | max(g1, g2)) not in explicit
               for g1 in pgeoms[gstart[x]:gstart[x + 1]] for g2 in pgeoms[gstart[y]:gstart[y + 1]]):
            want[x] |= np.uint64(1) << np.uint64(y)
        else:
            dropped += 1
    assert np.array_equal(smask[:L].view(np.uint64), want) and smask[L] == n - dropped
    if L == 64:
        assert smask[:L].min() < 0 and np.any(single < 0)  # bit 63 in use; loose bodies
    return dropped


@pytest.mark.parametrize("make", [s[1] for s in MASK_SCENES], ids=[s[0] for s in MASK_SCENES])
def test_kernel_filter_is_the_static_filter(make):
    """`_kernels.culling._filter` (the per-step filter of the pairs the walk finds) and
    `broadphase.tables.StaticFilter.bodies` (from which masks, flat roots, planes and lanes derive)
    agree on every position pair with bounds: the one rule, in its two forms."""
    from collide.broadphase import tables

    a = make().articulation
    bp = BroadPhase(a)
    _, fields, filt = tables.model_tables(a)
    has_bounds = fields["has_bounds"]
    L = bp.position_count
    allp = np.array([(x, y) for x in range(L) for y in range(L) if x != y and has_bounds[x] and has_bounds[y]],
                    np.int64)
    want = filt.bodies(allp[:, 0], allp[:, 1])
    got = np.zeros(len(allp), bool)
    for i, (x, y) in enumerate(allp):  # one pair a call: the kernel compacts its buffer
        one = np.array([[x, y]], np.int64)
        got[i] = _cull._filter(one, 1, *(_field(bp, n) for n in ("contype", "conaffinity", "weld", "parent_pos")),
                               a.filter_parent, _field(bp, "ex_start"), _field(bp, "ex_other"),
                               _field(bp, "single")) == 1
    assert np.array_equal(got, want)
    assert want.any() and not want.all()  # the scenes have pairs the filter keeps and drops


@pytest.mark.parametrize("make", [s[1] for s in MASK_SCENES], ids=[s[0] for s in MASK_SCENES])
def test_static_masks_equal_the_twin_and_keep_no_list(make):
    # Up to MASK_MAX positions the body pairs come from static masks (`_scan_masks`), with or
    # without coherence (the same code then: no list is kept): the bounds twin's pairs at every
    # call, and the batch's lane kernel's (`_kernels.lanes`: its own static pair list, no masks).
    sc = make()
    a = sc.articulation
    coh, walk = BroadPhase(a), BroadPhase(a, coherent=False)
    L = coh.position_count
    assert L <= _cull.MASK_MAX and coh.batch_path == "lanes"
    _check_static_masks(coh, a)
    smask = _field(coh, "smask")
    rng = np.random.default_rng(7)
    pos, rot = _motion(sc, rng, 60, 0.01)
    pairs = 0
    for s in range(len(pos)):
        p, r = (pos[s], rot[s]) if s % 20 != 19 else sc.poses(rng)
        got = coh.pairs(p, r)
        assert coh.stats["reused"] == 0 and coh.stats["subtree_tests"] == 0
        assert coh.stats["body_aabb_tests"] == smask[L]
        assert np.array_equal(got, testing.brute_force_bound_pairs(a, p, r)), s
        if s % 6 == 0:
            assert np.array_equal(got, coh.pairs_batch(p[None], r[None])[:, 1:]), s
        assert np.array_equal(got, walk.pairs(p, r)), s
        pairs += len(got)
    assert pairs > 50  # the scenes had hits


def test_static_masks_drop_the_pairs_left_to_explicit_pairs_and_keep_the_worlds_rules():
    # Body pairs whose only matching geom pairs are explicit ones are not in the masks (the
    # explicit pairs are tested on their own), in some of the scenes above; the walls scene (the
    # world's geoms as leaves, an exclusion of the world, wall 1's explicit pair) has its masks
    # built by the same rules as `_filter`'s (its pairs: `test_loose_multi_geom_bodies_...`).
    dropped = 0
    for _, make in MASK_SCENES:
        sc = make()
        dropped += _check_static_masks(BroadPhase(sc.articulation), sc.articulation)
    assert dropped > 0
    art = _walls_and_dumbbells(np.random.default_rng(12))[0]
    bp = BroadPhase(art)
    assert bp._I[_layout.H_V] > 0 and bp.position_count <= _cull.MASK_MAX
    _check_static_masks(bp, art)


def test_coherence_gives_way_to_the_walk_when_bodies_keep_leaving_their_boxes():
    # Unrelated poses at every call: after a few rebuilds the walk runs for a spell (COH_SKIP),
    # longer each time; a smooth motion afterwards brings the list back. The same pairs throughout.
    sc = testing.many_robots(11, 6, seed=26, spread=0.6, planes=1)
    a = sc.articulation
    coh, walk = BroadPhase(a), BroadPhase(a, coherent=False)
    rng = np.random.default_rng(8)
    pos, rot = sc.poses(rng, worlds=60)
    spells = []  # the length of each spell on the walk, as it starts
    total = 0
    for s in range(len(pos)):
        got = coh.pairs(pos[s], rot[s])
        assert coh.stats["reused"] == 0
        assert np.array_equal(got, walk.pairs(pos[s], rot[s]))
        total += len(got)
        st = _coherence_state(coh)
        if st[_coh.COH_SKIP] > 0 and st[_coh.COH_SKIP] == st[_coh.COH_BACKOFF] - 1:
            spells.append(st[_coh.COH_BACKOFF])
    assert total > 500
    assert len(spells) >= 2 and spells[0] == _coh.COH_BACKOFF_MIN and spells[1] == 2 * spells[0]
    pos, rot = _motion(sc, rng, 80)
    reused = 0
    for s in range(len(pos)):
        got = coh.pairs(pos[s], rot[s])
        reused += coh.stats["reused"]
        assert np.array_equal(got, walk.pairs(pos[s], rot[s]))
    assert reused > 10


def test_coherence_survives_new_buffers_and_bad_poses():
    n = 64
    sc = testing.free_hulls(n, seed=27, filters=True, planes=1)
    a = sc.articulation
    coh, walk = BroadPhase(a), BroadPhase(a, coherent=False)
    pos, rot = testing.hull_motion(sc, np.random.default_rng(9), 40, 0.01)
    total = 0
    for s in range(len(pos)):
        if s == 10:
            coh._set_buffers(1, 1)  # a new, tiny list: cleared, rebuilt, grown and rerun
        if s == 20:
            bad = pos[s].copy()
            bad[5, 1] = np.nan
            with pytest.raises(ValueError, match="body 5"):
                coh.pairs(bad, rot[s])
        got = coh.pairs(pos[s], rot[s])
        assert np.array_equal(got, walk.pairs(pos[s], rot[s])), s
        total += len(got)
        if s in (10, 11, 21):
            assert coh.stats["reused"] == (s != 10)  # rebuilt after new buffers, then kept
    assert total > 40 * 20


def test_coherent_must_be_a_bool():
    with pytest.raises(ValueError, match="coherent"):
        BroadPhase(testing.chain(4, seed=1).articulation, coherent="no")


@numba.njit  # not cached: numba's cache would not see a change to the kernels it inlines
def _lane_bounds_both(A, B, ma, mb, out):
    # every block pair's lane mask, through the lanes' vector form and the loop over the lanes
    rb = _lane_tests.ROW_BYTES
    at = np.int64(A.ctypes.data)
    bt = np.int64(B.ctypes.data)
    for k in range(A.shape[0]):
        out[k, 0] = _lane_tests.bounds8(at + rb * k, ma[k], bt + rb * k, mb[k])
        out[k, 1] = _bounds.bounds_mask(A, k, ma[k], B, k, mb[k], _simd.LANES)


def test_lane_bounds_as_vectors_are_the_scalar_test_bit_for_bit():
    # `lane_tests.bounds8` replays `_bounds_ok`'s source on LLVM vectors: lane by lane the scalar test's
    # outcome, on boxes near each other (hits and misses by every axis), margins, and non-finite
    # coordinates (NaN separates nothing).
    rng = np.random.default_rng(3)
    n, R, L = 4000, _layout.ROW, _simd.LANES

    def rows():
        X = np.empty((n, R, L))
        X[:, 3:12] = random_rotation(rng, n * L).reshape(n, L, 9).transpose(0, 2, 1)
        X[:, 0:3] = rng.normal(size=(n, 3, L))
        X[:, 12:15] = rng.uniform(0.0, 1.0, (n, 3, L))
        X[:, 15:18] = X[:, 0:3] + rng.normal(size=(n, 3, L)) * 0.1
        X[:, 18] = rng.uniform(0.0, 1.5, (n, L))
        return X

    A, B = rows(), rows()
    A[::97, 0, 3] = np.nan
    B[::89, 5, 6] = np.inf
    A[::53, 16, 1] = 1e300
    ma = rng.uniform(0.0, 0.1, n)
    mb = rng.uniform(0.0, 0.1, n)
    ma[::4] = 0.0
    out = np.zeros((n, 2), np.uint64)
    _lane_bounds_both(A, B, ma, mb, out)
    hits = sum(bin(int(v)).count("1") for v in out[:, 1])
    assert 0.05 * n * L < hits < 0.95 * n * L  # both outcomes, many times
    assert np.array_equal(out[:, 0], out[:, 1])


@numba.njit  # not cached, as above
def _lane_places_both(ps, src, cap, gp, m, rows, boxes, planes, want_rows, want_boxes, want_planes):
    # Case k: the lanes' vector forms (`lane_tests.place8`, `lane_tests.plane8`) on the poses ps[k] (12, LANES),
    # and the per-world kernel's scalar functions lane by lane.
    L = _simd.LANES
    for k in range(ps.shape[0]):
        pa = np.int64(ps.ctypes.data) + _lane_tests.POSE_BYTES * k
        _lane_tests.place8(pa, np.int64(src.ctypes.data) + 8 * _layout.ROW * k, np.int64(cap.ctypes.data) + 32 * k,
                           m[k], np.int64(rows.ctypes.data) + 8 * _layout.ROW * L * k,
                           np.int64(boxes.ctypes.data) + 48 * L * k, np.int64(boxes.ctypes.data) + 48 * L * k)
        _lane_tests.plane8(pa, np.int64(gp.ctypes.data) + 32 * k, np.int64(planes.ctypes.data) + 32 * L * k)
        rot = np.empty((1, 3, 3))
        pos = np.empty((1, 3))
        for lane in range(L):
            for i in range(3):
                pos[0, i] = ps[k, i, lane]
                for j in range(3):
                    rot[0, i, j] = ps[k, 3 + 3 * i + j, lane]
            w = _bounds._world_row(rot, pos, 0, src, k, want_rows[k], lane)
            _bounds._world_aabb(w, m[k], want_boxes[k], lane)
            _bounds._cap_aabb(rot, 0, cap, k, w, m[k], want_boxes[k], lane)
            _bounds._plane_world(0, pos, rot, np.zeros(1, np.int64), gp[k:k + 1], want_planes[k], lane)


def test_lane_rows_boxes_and_planes_are_the_single_world_values_bit_for_bit():
    # The values themselves, not only outcomes: a one-ulp difference between the lanes and one world
    # (an fmuladd split, a sum reordered) can flip a touching pair in either.
    rng = np.random.default_rng(11)
    n, R, L = 300, _layout.ROW, _simd.LANES
    ps = np.empty((n, 12, L))
    ps[:, 0:3] = rng.normal(size=(n, 3, L)) * 10.0 ** rng.integers(-6, 6, (n, 1, 1))
    ps[:, 3:12] = random_rotation(rng, n * L).reshape(n, L, 9).transpose(0, 2, 1)
    src = rng.normal(size=(n, R))
    src[:, 12:15] = np.abs(src[:, 12:15])
    src[:, 18] = np.abs(src[:, 18])
    cap = rng.normal(size=(n, 4))
    cap[:, 3] = np.abs(cap[:, 3])
    gp = rng.normal(size=(n, 4))
    m = rng.uniform(0.0, 0.1, n)
    m[::3] = 0.0
    rows, want_rows = np.full((n, R, L), np.nan), np.full((n, L, R), np.nan)
    boxes, want_boxes = np.full((n, 6, L), np.nan), np.full((n, L, 6), np.nan)
    planes, want_planes = np.full((n, 4, L), np.nan), np.full((n, L, 4), np.nan)
    _lane_places_both(ps, src, cap, gp, m, rows, boxes, planes, want_rows, want_boxes, want_planes)
    for got, want in ((rows, want_rows), (boxes, want_boxes), (planes, want_planes)):
        assert np.array_equal(got.transpose(0, 2, 1).view(np.int64), want.view(np.int64))


@numba.njit(_nrt=False)  # as the per-step kernels (`_ptr.NO_NRT`): where numba.carray is refused
def _views_of(fa, ia, ja, n):
    a = _ptr.view_of(_ptr.f64_ptr(fa), (n, 3))
    b = _ptr.view_of(_ptr.i64_ptr(ia), n)
    c = _ptr.view_of(_ptr.i32_ptr(ja), (2, n, 2))
    d = _ptr.view_of(_ptr.i64_ptr(ia), (n,))  # a 1-tuple shape: as an integer
    a[n - 1, 2] = -1.0  # written through to the buffer
    return (a[1, 2] + a[n - 1, 0] + b[n - 1] + c[1, n - 1, 1] + a.shape[0] + c.strides[0] + a[1:, 1].sum()
            + d[n - 2] * 1000)


def test_pointer_views_are_the_buffers_c_order():
    # `_ptr.view_of`: the array numba.carray would give (shape, C strides, the buffer's memory, no copy).
    n = 5
    f = np.arange(3.0 * n).reshape(n, 3)
    i = np.arange(n, dtype=np.int64) * 7
    j = np.arange(4 * n, dtype=np.int32).reshape(2, n, 2)
    got = _views_of(f.ctypes.data, i.ctypes.data, j.ctypes.data, n)
    assert f[n - 1, 2] == -1.0
    assert got == (f[1, 2] + f[n - 1, 0] + i[n - 1] + j[1, n - 1, 1] + n + j.strides[0] + f[1:, 1].sum()
                   + i[n - 2] * 1000)


# ------------------------------------------------- issue 42: scenes of the removed mechanisms' paths
# The hash grid, FLAT_DESC, FLAT_MAX's lists, box_row8 and pair_bits are gone (issue 42): the scenes
# that took them now take the sweep, the walk and the scalar row loops; each against the twin.

def _star(n, under, rng, size=0.1):
    # n balls of radius ``size``, children of the world (under=0) or of body 1, a child of the world
    parent = np.r_[0, 0, np.ones(n, int)] if under else np.r_[0, np.zeros(n, int)]
    L = len(parent)
    return Articulation(parent, np.arange(1, L), [PointCloud([[0, 0, 0], [size, 0, 0]], size) for _ in range(L - 1)])


def _both_equal_twin(a, poses):
    # pairs() with and without coherence against the twin, in order (coherence keeps its list between
    # the poses); returns the pairs seen.
    bps = (BroadPhase(a), BroadPhase(a, coherent=False))
    total = 0
    for pos, rot in poses:
        ref = testing.brute_force_bound_pairs(a, pos, rot)
        for bp in bps:
            assert np.array_equal(bp.pairs(pos, rot), ref)
        total += len(ref)
    return total


@pytest.mark.parametrize("under", [0, 1], ids=["under_world", "under_a_body"])
def test_300_children_spread_clustered_and_at_one_point_equal_twin(under):
    # One node of 300 children (a filled volume was the grid's, now the sweep's at any count): spread,
    # in five clusters, moved a little, and all at one point (every interval overlaps on every axis,
    # the sweep tests all pairs). Under a body, its walk culls by the children it may not pair.
    rng = np.random.default_rng(420)
    n = 300
    a = _star(n, under, rng)
    L = a.body_count
    nchild = _field(BroadPhase(a), "nchild")
    assert nchild.max() == n > _cull.MASK_MAX
    poses = []
    base = rng.uniform(-1, 1, (L, 3))
    for mode in ("spread", "moved", "clusters", "point"):
        rot = random_rotation(rng, L)
        if mode == "moved":
            pos = base + rng.normal(0, 0.05, (L, 3))
        elif mode == "clusters":
            pos = rng.uniform(-1, 1, (5, 3))[rng.integers(0, 5, L)] + rng.normal(0, 0.1, (L, 3))
        elif mode == "point":
            pos = np.tile([0.3, -0.2, 0.1], (L, 1))
        else:
            pos = base
        pos[0], rot[0] = 0.0, EYE
        poses.append((pos, rot))
    assert _both_equal_twin(a, poses) > n * (n - 1) // 2  # the point alone gives every pair


def test_deep_subtrees_and_a_coiled_chain_equal_twin():
    # Two random trees of 200 bodies under one body, thrown into one box: most pairs across them
    # are found deep in both (once the flat lists' past FLAT_MAX), and a 300-link chain coiled in a
    # box: each link against its descendants (the walk; FLAT_DESC's flat loop is gone).
    rng = np.random.default_rng(421)
    n = 200
    parent = [0, 0]
    for blk in range(2):
        base = 2 + blk * n
        parent += [1] + [base + int(rng.integers(0, i)) for i in range(1, n)]
    parent = np.array(parent)
    L = len(parent)
    a = Articulation(parent, np.arange(2, L), [PointCloud([[0, 0, 0], [0.1, 0, 0]], 0.04)] * (L - 2))
    poses = []
    for ext in (0.6, 1.5):
        pos = rng.uniform(-ext, ext, (L, 3))
        rot = random_rotation(rng, L)
        pos[:2], rot[:2] = 0.0, EYE
        poses.append((pos, rot))
    assert _both_equal_twin(a, poses) > 300

    n = 300
    a = Articulation(np.r_[0, 0, np.arange(1, n)], np.arange(1, n + 1), [PointCloud([[0, 0, 0], [0.1, 0, 0]], 0.04)] * n)
    poses = [(np.r_[np.zeros((1, 3)), rng.uniform(-0.5, 0.5, (n, 3))], np.r_[EYE[None], random_rotation(rng, n)])
             for _ in range(2)]
    assert _both_equal_twin(a, poses) > 300


def test_huge_and_tiny_geoms_under_one_parent_equal_twin():
    # 200 bodies of sizes 1e-4 to 50 (capsules and hulls) under one body with a chain inside, at three
    # scales of spread: the sweep's intervals from a point to the whole scene.
    rng = np.random.default_rng(422)
    n = 200
    clouds = []
    for i in range(n):
        s = (1e-4, 1e-2, 1.0, 50.0)[i % 4]
        clouds.append(PointCloud([[0, 0, 0], [s, 0, 0]], 0.3 * s) if i % 3 else testing.random_hull(rng, s))
    parent = np.r_[0, 0, np.ones(n - 1, int)]
    parent[50:80] = np.arange(49, 79)
    a = Articulation(parent, np.arange(1, n + 1), clouds)
    poses = [(np.r_[np.zeros((1, 3)), rng.uniform(-e, e, (n, 3))], np.r_[EYE[None], random_rotation(rng, n)])
             for e in (1e-2, 1.0, 30.0)]
    assert _both_equal_twin(a, poses) > 3 * n


@pytest.mark.parametrize("n", [40, 64])
def test_mask_rows_reach_the_last_position(n):
    # Up to 64 positions the pairs come from the static masks' rows (`culling._row_hits`), which
    # read a row's partners' columns up to its last one: all bodies at one point (every bit of
    # every row a hit, the last position's column included), single worlds and both batch paths.
    rng = np.random.default_rng(423)
    a = _star(n - 1, 0, rng)
    assert BroadPhase(a).position_count == n <= _cull.MASK_MAX
    pos = np.tile([0.3, -0.2, 0.1], (n, 1))
    pos[0] = 0.0
    rot = random_rotation(rng, n)
    rot[0] = EYE
    assert _both_equal_twin(a, [(pos, rot)]) == (n - 1) * (n - 2) // 2
    ref = testing.brute_force_bound_pairs(a, pos, rot)
    assert ref[:, 1].max() == n - 2  # the last body's geom
    for path in ("lanes", "worlds"):
        got = BroadPhase(a, batch_path=path).pairs_batch(pos[None], rot[None])
        assert np.array_equal(got[:, 1:], ref)
