"""Regression tests for the reference implementations in `collide.testing` (adversarial review)."""

import numpy as np
import pytest

from collide import testing


@pytest.mark.parametrize("scale, offset", [(1e-6, 0.0), (1e-6, 1e-3), (1e4, 0.0), (1.0, 1e5)])
def test_gjk_distance_is_scale_free(scale, offset):
    # Regression: on micrometre-sized shapes the simplex solver's singularity test (absolute)
    # accepted a degenerate tetrahedron and reported distance 0 for hulls 0.08 of their size
    # apart, so brute_force_pairs listed a non-touching pair as touching.
    rng = np.random.default_rng(11)
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    d = testing.gjk_distance(cube * scale + offset, (cube + [3, 0, 0]) * scale + offset)[0]
    assert np.isclose(d, 2.0 * scale, rtol=1e-9)
    hits = misses = 0
    for k in range(150):
        P = testing.random_hull(rng, 1.0, int(rng.integers(1, 25))).points
        Q = testing.random_hull(rng, 1.0, int(rng.integers(1, 25))).points
        if k % 3 == 0:
            Q = Q * [1, 1, 0]
        Q = Q + rng.uniform(-0.8, 0.8, 3)
        upper, lower = testing.gjk_distance(P * scale + offset, Q * scale + offset)
        ref_upper, _ = testing.gjk_distance(P, Q)
        assert upper == pytest.approx(ref_upper * scale, rel=1e-6, abs=1e-9 * scale)
        touching = testing.hulls_intersect_lp(P, Q)
        if upper > 1e-9 * scale:
            assert not touching
            misses += 1
        else:
            assert touching
            hits += 1
    assert hits > 10 and misses > 20


def test_gjk_distance_box_against_flat_polygon_at_small_scale():
    # The reproducer family: a box against a flat random polygon, sizes 1e-7 to 1e-4. Before the
    # fix 3 of these 3000 cases came out as distance 0 (e.g. 2.7e-8 apart at size 4.6e-7).
    from collide.testing.scenes import random_rotation

    rng = np.random.default_rng(3)
    for k in range(3000):
        s = 10 ** rng.uniform(-7, -4)
        P = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        P = (P * rng.uniform(0.2, 1, 3)) @ random_rotation(rng).T
        Q = rng.normal(size=(10, 3))
        Q[:, 2] = 0
        Q = Q @ random_rotation(rng).T + rng.normal(size=3) * 1.5
        small = testing.gjk_distance(P * s, Q * s)[0]
        unit = testing.gjk_distance(P, Q)[0]
        assert small == pytest.approx(unit * s, rel=1e-6, abs=1e-9 * s), k


def test_gjk_finds_a_point_inside_a_thin_box():
    # Review reproducer (2026-11-21): a point 5e-8 inside a 2 x 1.5 x 2e-7 box. The simplex
    # solver's singularity test was quadratic in the tetrahedron's volume and rejected it, so GJK
    # reported the distance to a face (5e-8, 97 rotations in 100) and the twin missed the pair.
    from collide import Articulation, PointCloud
    from collide.testing.scenes import random_rotation

    rng = np.random.default_rng(1)
    h = np.array([1.0, 0.75, 1e-7])
    box = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * h
    art = Articulation([0, 0, 0], [1, 2], [PointCloud(box), PointCloud([[0.0, 0.0, 0.0]])])
    for _ in range(100):
        rot = random_rotation(rng)
        inside = rot @ np.array([*(rng.uniform(-0.9, 0.9, 2) * h[:2]), 0.5 * h[2]])
        assert testing.gjk_distance(box @ rot.T, inside[None]) == (0.0, 0.0)
        pos = np.array([[0, 0, 0], [0, 0, 0], inside])
        assert testing.brute_force_pairs(art, pos, np.stack([np.eye(3), rot, np.eye(3)])).tolist() == [[0, 1]]
        # and just outside the face: apart by 1e-8, never touching
        outside = rot @ np.array([0.1, 0.2, h[2] + 1e-8])
        upper, lower = testing.gjk_distance(box @ rot.T, outside[None])
        assert lower > 0.9e-8 and upper < 1.1e-8


def test_explicit_pair_margin_replaces_the_geom_margins_with_or_without_candidates():
    # Review (2026-11-21): with candidates=, an explicit pair was tested with the geoms' margins as
    # well as its own, so a pair margin smaller than theirs reported pairs the broad phase (and
    # the twin without candidates) rightly drops.
    from collide import Articulation, BroadPhase, PointCloud

    ball = PointCloud([[0.0, 0.0, 0.0]], 0.5)
    rot = np.tile(np.eye(3), (3, 1, 1))
    for pair_margin, gap, touching in ((0.05, 0.2, False), (0.05, 0.08, True), (0.3, 0.4, True), (0.3, 0.7, False)):
        art = Articulation([0, 0, 0], [1, 2], [ball, ball], geom_margin=[0.2, 0.2], pairs=[(0, 1)],
                           pair_margin=[pair_margin])
        pos = np.array([[0, 0, 0], [0, 0, 0], [1.0 + gap, 0, 0]])
        want = [[0, 1]] if touching else []
        assert testing.brute_force_pairs(art, pos, rot).tolist() == want
        assert testing.brute_force_pairs(art, pos, rot, candidates=([0], [1])).tolist() == want
        assert testing.brute_force_pairs(art, pos, rot, candidates=([1], [0])).tolist() == want
        assert BroadPhase(art).pairs(pos, rot).tolist() == want


def test_twins_refuse_the_poses_the_broad_phase_refuses():
    sc = testing.many_robots(2, 3, seed=5)
    pos, rot = sc.poses(np.random.default_rng(6))
    for twin in (testing.brute_force_bound_pairs, testing.brute_force_pairs):
        p = pos.copy()
        p[2, 1] = np.nan
        with pytest.raises(ValueError, match="body 2: pose has a non-finite"):
            twin(sc.articulation, p, rot)
        r = rot.copy()
        r[3] = -r[3]  # a reflection
        with pytest.raises(ValueError, match="body 3: rotation is not a proper orthonormal"):
            twin(sc.articulation, pos, r)


@pytest.mark.parametrize("k", [-340, -120, 120, 340])
def test_the_polytope_oracle_is_scale_free(k):
    # The signed distance of two boxes scaled by 2**k is 2**k times theirs (exact scaling): at
    # 1e100 the oracle's triangle distances overflowed (+1.25e100 for -0.85e100: helper-78,
    # 2026-12-02), and it reported brackets of collide.distance as wrong.
    rng = np.random.default_rng(8)
    box = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    for _ in range(40):
        a = box * rng.uniform(0.2, 1.0, 3) @ testing.random_rotation(rng).T
        b = box * rng.uniform(0.2, 1.0, 3) @ testing.random_rotation(rng).T + rng.normal(size=3)
        unit = testing.polytope_signed_distance(a, b)
        assert testing.polytope_signed_distance(np.ldexp(a, k), np.ldexp(b, k)) == pytest.approx(
            np.ldexp(unit, k), rel=1e-12, abs=0.0)
