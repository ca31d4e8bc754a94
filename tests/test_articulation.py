"""Articulation: tree validation, depth-first layout, local bounds that contain their geoms, filters."""

import numpy as np
import pytest

from collide import Articulation, PointCloud, shapes, testing

BOX = PointCloud(np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * [0.3, 0.2, 0.1])
BALL = PointCloud([[0, 0, 0]], 0.25)


def _art(parent, geom_body, **kw):
    return Articulation(parent, geom_body, [BOX] * len(geom_body), **kw)


def test_depth_first_layout_ranges_are_subtrees():
    sc = testing.branching_tree(50, seed=3, filters=False, planes=0, geoms_per_body=(0, 1))
    a = sc.articulation
    order, pos, end = a.body_dfs_order, a.body_dfs_pos, a.body_subtree_end
    assert sorted(order.tolist()) == list(range(a.body_count))
    assert np.array_equal(pos[order], np.arange(a.body_count))

    def is_ancestor(x, y):  # x is y or an ancestor of y
        while True:
            if y == x:
                return True
            if y == 0:
                return False
            y = a.body_parent[y]
    for b in range(a.body_count):
        inside = {int(order[p]) for p in range(pos[b], end[b])}
        assert inside == {y for y in range(a.body_count) if is_ancestor(b, y)}


@pytest.mark.parametrize("parent, msg", [
    ([0, 2, 1], "cycle"),
    ([0, 0, 2], "cycle"),           # a self-parented body other than the world
    ([0, 0, 5], "out of range"),
    ([0, -1, 0], "out of range"),
    ([1, 0, 0], "world"),
])
def test_invalid_trees_raise(parent, msg):
    with pytest.raises(ValueError, match=msg):
        _art(parent, [1])


def test_bad_geoms_and_arrays_raise():
    with pytest.raises(ValueError, match="geom 1 is on body 7"):
        _art([0, 0], [1, 7])
    with pytest.raises(ValueError, match="geom_cloud"):
        Articulation([0, 0], [1], [np.zeros((3, 3))])
    with pytest.raises(ValueError, match="geom_cloud"):
        Articulation([0, 0], [1], [BOX, BOX])
    with pytest.raises(ValueError, match="body_parent: expected integers"):
        _art([0.0, 0.0], [1])
    with pytest.raises(ValueError, match="geom_pos"):
        _art([0, 0], [1], geom_pos=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="geom_rot: rotation of geom 0"):
        _art([0, 0], [1], geom_rot=np.diag([1.0, 1.0, 1.1])[None])
    with pytest.raises(ValueError, match="geom_rot: rotation of geom 0"):
        _art([0, 0], [1], geom_rot=np.diag([1.0, 1.0, -1.0])[None])
    with pytest.raises(ValueError, match="geom_margin"):
        _art([0, 0], [1], geom_margin=[-0.1])
    with pytest.raises(ValueError, match="geom_pos: non-finite"):
        _art([0, 0], [1], geom_pos=[[0, np.nan, 0]])
    with pytest.raises(ValueError, match="exclude: row 0 names a body"):
        _art([0, 0], [1], exclude=[[0, 3]])
    with pytest.raises(ValueError, match="pairs: row 0 names a geom"):
        _art([0, 0], [1], pairs=[[0, 3]])
    with pytest.raises(ValueError, match="itself"):
        _art([0, 0], [1, 1], pairs=[[1, 1]])
    with pytest.raises(ValueError, match="pair_margin"):
        _art([0, 0], [1, 1], pairs=[[0, 1]], pair_margin=[0.1, 0.2])
    with pytest.raises(ValueError, match="body_weld"):
        _art([0, 0], [1], body_weld=[0])
    with pytest.raises(ValueError, match="geom_cloud: expected a list"):
        Articulation([0, 0], [1], 5)
    with pytest.raises(ValueError, match="filter_parent: expected True or False"):
        _art([0, 0], [1], filter_parent="no")
    with pytest.raises(ValueError, match=r"body_parent: expected shape \(n\), got \(\)"):
        Articulation(0, [], [])  # a scalar is not a one-element array
    with pytest.raises(ValueError, match="body_parent: value 9223372036854775808 is out of range"):
        _art(np.array([0, 2**63], np.uint64), [1])
    with pytest.raises(ValueError, match=r"geom_cloud\[1\]: obb: coordinates"):
        Articulation([0, 0], [1, 1], [BOX, PointCloud([[1e200, 0, 0]])])
    with pytest.raises(ValueError, match="exclude: cannot be read as an integer array"):
        _art([0, 0, 0], [1, 2], exclude=[[1, 2], [1]])
    with pytest.raises(ValueError, match="pairs: cannot be read as an integer array"):
        _art([0, 0, 0], [1, 2], pairs=[[0, 1], [1]])
    # Only shapes.Plane is a plane: another object with a normal and an offset (here a zero
    # normal, which shapes.Plane refuses) is not taken for one.
    fake = type("FakePlane", (), {"normal": np.zeros(3), "offset": 0.0})()
    with pytest.raises(ValueError, match=r"geom_cloud\[0\]: expected a PointCloud or shapes.Plane"):
        Articulation([0, 0], [1, 1], [fake, BOX])


def test_caller_arrays_are_copied():
    # Changing the caller's arrays afterwards changes neither the articulation nor a broad phase
    # built from it: both keep the values given.
    from collide import BroadPhase
    parent, gbody, margin = np.array([0, 0, 0]), np.array([1, 2]), np.zeros(2)
    art = Articulation(parent, gbody, [BOX, BOX], geom_margin=margin)
    margin[:] = 1.0
    parent[2] = 1
    gbody[:] = 0
    assert np.all(art.geom_margin == 0) and list(art.body_parent) == [0, 0, 0] and list(art.geom_body) == [1, 2]
    pos = np.array([[0, 0, 0], [0, 0, 0], [1.5, 0, 0.0]])
    rot = np.tile(np.eye(3), (3, 1, 1))
    assert len(BroadPhase(art).pairs(pos, rot)) == 0
    assert len(testing.brute_force_bound_pairs(art, pos, rot)) == 0
    pos[2, 0] = 0.2  # and the pair is found when the boxes do overlap
    assert len(BroadPhase(art).pairs(pos, rot)) == 1


def test_pairs_and_excludes_are_normalised():
    a = _art([0, 0, 1], [1, 2, 2], exclude=[[2, 1], [1, 2]], pairs=[[2, 0], [0, 2], [1, 0]],
             pair_margin=[0.1, 0.3, 0.0])
    assert a.exclude.tolist() == [[1, 2]]
    assert a.pairs.tolist() == [[0, 1], [0, 2]]
    assert a.pair_margin.tolist() == [0.0, 0.3]  # duplicates keep the larger inflation


def _inside_obb(points, c, R, h, tol=1e-9):
    local = (points - c) @ R
    return np.all(np.abs(local) <= h + tol)


def _capsule_distance(points, c, d):
    # Distance of each point to the segment c - d .. c + d.
    v = points - c
    dd = float(d @ d)
    t = np.clip(v @ d / dd, -1.0, 1.0) if dd > 0 else np.zeros(len(v))
    return np.linalg.norm(v - t[:, None] * d, axis=1)


def test_local_bounds_contain_geoms_and_bodies_contain_geom_bounds():
    sc = testing.branching_tree(30, seed=5, planes=1)
    a = sc.articulation
    rng = np.random.default_rng(0)
    for g in np.flatnonzero(~a.geom_is_plane):
        cloud = a.geom_local_cloud[g]
        # points of the exact set: hull points pushed out by the radius in random directions
        d = rng.normal(size=(200, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        pts = cloud.points[rng.integers(len(cloud.points), size=200)] + cloud.radius * d
        assert _inside_obb(pts, a.geom_obb_center[g], a.geom_obb_rot[g], a.geom_obb_half[g])
        assert np.all(np.linalg.norm(pts - a.geom_sphere_center[g], axis=1) <= a.geom_sphere_radius[g] + 1e-9)
        b, m = a.geom_body[g], a.geom_margin[g]
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        corners = a.geom_obb_center[g] + (signs * (a.geom_obb_half[g] + m)) @ a.geom_obb_rot[g].T
        assert _inside_obb(corners, a.body_obb_center[b], a.body_obb_rot[b], a.body_obb_half[b])
        reach = np.linalg.norm(a.geom_sphere_center[g] - a.body_sphere_center[b]) + a.geom_sphere_radius[g] + m
        assert reach <= a.body_sphere_radius[b] + 1e-9
        # the capsule holds the shape; the body's holds the geom's, inflated (its two end balls)
        c = a.geom_obb_center[g]
        assert np.all(_capsule_distance(pts, c, a.geom_capsule_half[g]) <= a.geom_capsule_radius[g] + 1e-9)
        ends = np.stack([c + a.geom_capsule_half[g], c - a.geom_capsule_half[g]])
        reach = _capsule_distance(ends, a.body_obb_center[b], a.body_capsule_half[b]) + a.geom_capsule_radius[g] + m
        assert np.all(reach <= a.body_capsule_radius[b] + 1e-9)
    bare = [b for b in range(a.body_count) if not np.any((a.geom_body == b) & ~a.geom_is_plane)]
    assert bare and not np.any(a.body_has_bounds[bare])


def test_a_capsule_geom_keeps_its_own_capsule_and_a_tighter_world_aabb():
    # A limb at 45 degrees: the AABB of its OBB is larger than the capsule's by about (sqrt(2) - 1) r
    # on each side across it; the world bounds give the capsule's.
    R = testing.random_rotation(np.random.default_rng(3))
    a = Articulation([0, 0], [1], [shapes.capsule(0.05, 0.2)], geom_rot=R[None])
    assert np.isclose(a.geom_capsule_radius[0], 0.05, rtol=1e-5)
    assert np.isclose(np.linalg.norm(a.geom_capsule_half[0]), 0.2, rtol=1e-5)
    assert np.allclose(np.abs(a.geom_capsule_half[0] / 0.2), np.abs(R[:, 2]), atol=1e-5)  # MuJoCo's z axis
    from collide import BroadPhase
    tilt = testing.random_rotation(np.random.default_rng(4))
    wb = BroadPhase(a).world_bounds(np.zeros((2, 3)), np.stack([np.eye(3), tilt]))
    u = tilt @ R[:, 2]
    exact = 0.2 * np.abs(u) + 0.05
    assert np.allclose(wb.aabb_max[0], exact, rtol=1e-4) and np.allclose(wb.aabb_min[0], -exact, rtol=1e-4)


def test_optimal_obb_is_tighter_than_aabb_for_rotated_boxes():
    R = testing.random_rotation(np.random.default_rng(1))
    a = Articulation([0, 0], [1], [BOX], geom_rot=R[None])
    # rtol: every bound carries the pose-rotation slack of 8e-6 * sum(half) (articulation.ROTATION_SLACK)
    assert np.isclose(np.prod(a.geom_obb_half[0]), 0.3 * 0.2 * 0.1, rtol=2e-4)


def test_planes_are_halfspaces_in_the_body_frame():
    plane = testing.make_plane((0, 0, 1), 0.5)
    R = testing.random_rotation(np.random.default_rng(2))
    a = Articulation([0, 0], [0, 1], [plane, BALL], geom_pos=[[1, 2, 3], [0, 0, 0]],
                     geom_rot=np.stack([R, np.eye(3)]))
    n = R @ [0, 0, 1]
    assert np.allclose(a.geom_plane[0, :3], n)
    assert np.isclose(a.geom_plane[0, 3], 0.5 + n @ [1, 2, 3])
    assert a.geom_is_plane.tolist() == [True, False]
    assert not a.body_has_bounds[0] and a.body_has_bounds[1]


def test_degenerate_geoms_work():
    # a single point, duplicates, a segment, a flat polygon: valid shapes, tight bounds
    from collide import BroadPhase
    clouds = [PointCloud([[0.1, 0.2, 0.3]]), PointCloud([[0, 0, 0]] * 5, 0.1),
              PointCloud([[0, 0, 0], [1, 1, 1], [0.5, 0.5, 0.5]]),
              PointCloud([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])]
    a = Articulation([0, 0, 0, 0, 0], [1, 2, 3, 4], clouds)
    assert np.all(np.isfinite(a.geom_obb_half)) and np.all(a.geom_obb_half >= 0)
    assert a.geom_sphere_radius[0] < 1e-6 and np.isclose(a.geom_sphere_radius[1], 0.1, rtol=1e-5)  # 2e-6: rotation slack
    assert np.isclose(a.geom_sphere_radius[2], np.sqrt(3) / 2, rtol=1e-5)
    pos = np.zeros((5, 3))
    rot = np.tile(np.eye(3), (5, 1, 1))
    got = BroadPhase(a).pairs(pos, rot)
    assert {tuple(r) for r in got.tolist()} == {(1, 2), (1, 3), (2, 3)}  # the point at (0.1, 0.2, 0.3) touches none


def test_a_huge_margin_on_a_multi_geom_body_names_the_body():
    # Review, 2026-11-22: the error named only the OBB fit ("obb: coordinates plus radius reach ...").
    with pytest.raises(ValueError, match=r"body 1: the bounds of its geoms \[0, 1\], inflated by geom_margin"):
        Articulation([0, 0], [1, 1], [shapes.sphere(1.0), shapes.sphere(1.0)], geom_margin=[1e200, 0.0])
