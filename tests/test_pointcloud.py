"""PointCloud and its operators (paper §3.2-§3.3): transforms, unions, intersections, bad input."""

import numpy as np
import pytest

import collide
from collide import PointCloud

CUBE = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])


def _rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _box_of_rotated_box(lo, hi, rotation):
    # What a box-of-box hierarchy does: the AABB of the rotated AABB.
    center, half = (lo + hi) / 2, (hi - lo) / 2
    c = rotation @ center
    h = np.abs(rotation) @ half
    return c - h, c + h


def test_points_are_a_read_only_copy():
    src = np.zeros((3, 3))
    cloud = PointCloud(src)
    src[0, 0] = 5.0
    assert cloud.points[0, 0] == 0.0
    with pytest.raises(ValueError):
        cloud.points[0, 0] = 1.0
    assert len(cloud) == 3 and cloud.radius == 0.0


def test_empty_cloud():
    e = PointCloud.empty()
    assert len(e) == 0 and e.is_empty
    assert e.transform(np.eye(4)).is_empty
    assert e.aabb().volume() == 0.0
    assert len(collide.union([e, e])) == 0
    assert len(PointCloud([])) == 0


def test_cube_rotated_45_degrees_100_times_keeps_its_exact_box():
    # The paper's motivating example (§1): the cloud stays exact, the box of boxes explodes.
    cloud = PointCloud(CUBE)
    lo, hi = CUBE.min(axis=0), CUBE.max(axis=0)
    axes = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0)]
    total = np.eye(3)
    for i in range(100):
        r = _rot(axes[i % len(axes)], np.pi / 4)
        cloud = cloud.transform(r, np.zeros(3))
        lo, hi = _box_of_rotated_box(lo, hi, r)
        total = r @ total
    exact = CUBE @ total.T
    box = cloud.aabb()
    np.testing.assert_allclose(box.lo, exact.min(axis=0), atol=1e-12)
    np.testing.assert_allclose(box.hi, exact.max(axis=0), atol=1e-12)
    growth = np.prod(hi - lo) / box.volume()
    assert growth > 1e6, growth  # orders of magnitude (measured ~1e11 on 2026-11-21)


def test_transform_forms_agree():
    rng = np.random.default_rng(0)
    cloud = PointCloud(rng.normal(size=(20, 3)), 0.2)
    r, t = _random_rotation(rng), rng.normal(size=3)
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = r, t
    a, b, c = cloud.transform(m), cloud.transform(r, t), cloud.transform((r, t))
    for other in (b, c):
        np.testing.assert_array_equal(a.points, other.points)
        assert a.radius == other.radius == pytest.approx(0.2)
    assert cloud.transform(2.5 * r, t).radius == pytest.approx(0.5)


def test_general_affine_turns_radius_into_points_conservatively():
    rng = np.random.default_rng(1)
    sphere = PointCloud([[0.0, 0.0, 0.0]], 1.0)
    a = np.diag([1.0, 2.0, 3.0]) @ _random_rotation(rng)
    out = sphere.transform(a, np.zeros(3))
    assert out.radius == 0.0 and len(out) > 10
    # Points on the true ellipsoid surface lie in the cloud's AABB and in its hull (support test).
    d = rng.normal(size=(5000, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    surface = d @ a.T
    assert np.all(out.aabb().contains(surface, rtol=1e-12))
    dirs = rng.normal(size=(2000, 3))
    assert np.all(np.max(dirs @ out.points.T, axis=1) >= np.max(dirs @ surface.T, axis=1) - 1e-12)


def test_near_similarity_maps_keep_a_ball_that_contains_the_mapped_ball():
    # A float32-rounded rotation, or one stretched by 1e-4, is not a similarity to 1e-9: the
    # radius became a polytope up to 7.1 % wider (review, 2026-11-21). Within 0.1 % it stays a
    # ball, of radius x the largest singular value, and still contains the true mapped capsule.
    rng = np.random.default_rng(4)
    capsule = PointCloud([[0.0, 0.0, -0.5], [0.0, 0.0, 0.5]], 0.3)
    for k in range(20):
        rot = _random_rotation(rng)
        m = rot.astype(np.float32).astype(np.float64) if k % 2 else rot @ np.diag(1 + rng.uniform(-5e-4, 5e-4, 3))
        out = capsule.transform(m, rng.normal(size=3))
        assert len(out) == 2 and out.radius <= 0.3 * (1 + 1e-3)
        # the true surface: the segment's points plus the radius in every direction, mapped
        u = rng.normal(size=(4000, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        surface = (np.column_stack([np.zeros((4000, 2)), rng.uniform(-0.5, 0.5, 4000)]) + 0.3 * u) @ m.T
        surface += out.points[0] - m @ capsule.points[0]
        a, b = out.points
        t = np.clip((surface - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        dist = np.linalg.norm(surface - (a + t[:, None] * (b - a)), axis=1)
        assert np.all(dist <= out.radius * (1 + 1e-12))


def test_union_threshold_and_mixed_radii():
    rng = np.random.default_rng(2)
    clouds = [PointCloud(rng.normal(size=(100, 3)) + i) for i in range(3)]
    assert len(collide.union(clouds, threshold=1000)) == 300
    reduced = collide.union(clouds, threshold=256)
    assert len(reduced) < 300
    # A sphere (radius 1) and a box (radius 0): the result keeps radius 0 and bounds the sphere.
    mixed = collide.union([PointCloud([[3.0, 0, 0]], 1.0), PointCloud(CUBE)])
    assert mixed.radius == 0.0
    d = rng.normal(size=(3000, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    sphere_surface = d + [3.0, 0, 0]
    assert np.all(np.max(d @ mixed.points.T, axis=1) >= np.max(d @ sphere_surface.T, axis=1) - 1e-12)
    # Equal radii are kept as they are (a capsule from two spheres is exact).
    caps = collide.union([PointCloud([[0, 0, -1.0]], 0.5), PointCloud([[0, 0, 1.0]], 0.5)])
    assert caps.radius == 0.5 and len(caps) == 2


def test_union_does_not_mutate_inputs():
    a = PointCloud(CUBE)
    b = a.transform(np.eye(3), [5.0, 0, 0])
    collide.union([a, b])
    np.testing.assert_array_equal(a.points, CUBE)


def test_exact_intersection_of_overlapping_boxes_is_their_box():
    a = PointCloud(CUBE)
    b = PointCloud(CUBE * [2.0, 1.0, 0.5] + [0.7, 0.2, -0.1])
    out = collide.intersection(a, b)
    box = out.aabb()
    lo = np.maximum(a.points.min(0), b.points.min(0))
    hi = np.minimum(a.points.max(0), b.points.max(0))
    np.testing.assert_allclose(box.lo, lo, atol=1e-9)
    np.testing.assert_allclose(box.hi, hi, atol=1e-9)
    assert len(out.reduced()) == 8


def test_exact_intersection_of_rotated_boxes_bounds_sampled_intersection():
    rng = np.random.default_rng(4)
    a = PointCloud(CUBE)
    b = PointCloud(CUBE).transform(_random_rotation(rng), [0.4, 0.1, 0.0])
    out = collide.intersection(a, b)
    # Points inside both boxes (rejection sampling) lie in the AABB of the result.
    samples = rng.uniform(-0.9, 0.9, size=(200000, 3))
    in_a = np.all(np.abs(samples) <= 0.5, axis=1)
    rot = _random_rotation(np.random.default_rng(4))
    in_b = np.all(np.abs((samples - [0.4, 0.1, 0.0]) @ rot) <= 0.5, axis=1)
    both = samples[in_a & in_b]
    assert len(both) > 1000
    assert np.all(out.aabb().contains(both, rtol=1e-12))
    assert out.aabb().volume() < a.aabb().volume()


def test_intersection_disjoint_touching_and_box_variant():
    a = PointCloud(CUBE)
    assert collide.intersection(a, a.transform(np.eye(3), [1.5, 0, 0])).is_empty
    touching = collide.intersection(a, a.transform(np.eye(3), [1.0, 0, 0]))
    assert not touching.is_empty
    box = touching.aabb()
    np.testing.assert_allclose(box.lo, [0.5, -0.5, -0.5], atol=1e-9)
    np.testing.assert_allclose(box.hi, [0.5, 0.5, 0.5], atol=1e-9)
    fast = collide.intersection(a, a.transform(np.eye(3), [0.5, 0, 0]), exact=False)
    assert len(fast) == 8
    np.testing.assert_allclose(fast.aabb().lo, [0.0, -0.5, -0.5])
    assert collide.intersection(a, a.transform(np.eye(3), [2.0, 0, 0]), exact=False).is_empty
    assert collide.intersection(a, PointCloud.empty()).is_empty


def test_intersection_with_radii_and_flat_clouds():
    s1 = PointCloud([[0.0, 0, 0]], 1.0)
    s2 = PointCloud([[1.5, 0, 0]], 1.0)
    lens = collide.intersection(s1, s2)
    box = lens.aabb()
    # The true lens spans x in [0.5, 1.0] and |y|, |z| <= sqrt(1 - 0.75^2) = 0.661.
    assert box.lo[0] <= 0.5 + 1e-9 and box.hi[0] >= 1.0 - 1e-9
    assert box.hi[1] >= np.sqrt(1 - 0.75**2) - 1e-9
    square = PointCloud([[0, 0, 0], [2, 0, 0], [0, 2, 0], [2, 2, 0.0]])
    flat = collide.intersection(square, PointCloud(CUBE + [1.0, 1.0, 0.0]))
    assert not flat.is_empty
    np.testing.assert_allclose(flat.aabb().hi, [1.5, 1.5, 0.0], atol=1e-9)


def test_difference_keeps_first_operand():
    a, b = PointCloud(CUBE), PointCloud(CUBE + 0.2)
    assert collide.difference(a, b) is a


@pytest.mark.parametrize(
    "points",
    [
        [[0.0, 0.0, 0.0]],
        [[1.0, 1.0, 1.0]] * 5,
        [[0, 0, 0], [1, 1, 1], [2, 2, 2.0]],
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]],
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]) + 1e5).tolist(),
    ],
    ids=["point", "duplicates", "collinear", "flat", "far"],
)
def test_degenerate_clouds_work_everywhere(points):
    rng = np.random.default_rng(5)
    cloud = PointCloud(points, 0.1)
    pts = np.asarray(points)
    for c in (cloud, cloud.reduced(), cloud.transform(np.diag([1.0, 2.0, 0.5]), np.ones(3))):
        assert not c.is_empty
        c.aabb()
    r = _random_rotation(rng)
    moved = cloud.transform(r, np.zeros(3)).reduced()
    assert np.all(moved.aabb().contains(pts @ r.T, rtol=1e-12))
    assert not collide.union([cloud, cloud]).is_empty
    assert not collide.intersection(cloud, cloud).is_empty


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: PointCloud([[np.nan, 0, 0]]), "non-finite"),
        (lambda: PointCloud([[np.inf, 0, 0]]), "non-finite"),
        (lambda: PointCloud([[0, 0]]), "shape"),
        (lambda: PointCloud(np.zeros((2, 3, 1))), "shape"),
        (lambda: PointCloud([[0, 0, 0]], -1.0), ">= 0"),
        (lambda: PointCloud([[0, 0, 0]], np.nan), "finite"),
        (lambda: PointCloud([["a", 0, 0]]), "points"),
        (lambda: PointCloud(CUBE).transform(np.ones((3, 4))), "shape"),
        (lambda: PointCloud(CUBE).transform(np.full((4, 4), 1.0)), "last row"),
        (lambda: PointCloud(CUBE).transform(np.eye(3), [0, np.nan, 0]), "non-finite"),
        (lambda: collide.union([PointCloud(CUBE), CUBE]), "PointCloud"),
        (lambda: collide.union([PointCloud(CUBE)], threshold=0), "threshold"),
        (lambda: collide.intersection(PointCloud(CUBE), None), "PointCloud"),
    ],
)
def test_bad_input_raises_a_clear_value_error(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_complex_points_and_single_cloud_union_raise_value_error():
    # Regression: complex points were cast to float with only a warning (imaginary part
    # dropped silently); union(cloud) crashed with a TypeError.
    with pytest.raises(ValueError, match="complex"):
        PointCloud(np.array([[1j, 0, 0]]))
    cloud = PointCloud([[0, 0, 0]])
    with pytest.raises(ValueError, match="complex"):
        cloud.transform(np.eye(4, dtype=complex))
    with pytest.raises(ValueError, match="single PointCloud"):
        collide.union(cloud)
    with pytest.raises(ValueError, match="iterable"):
        collide.union(3)


def test_intersection_exact_flag_must_be_a_bool():
    # Regression: exact="no" was truthy and silently ran the exact path.
    cloud = PointCloud([[0, 0, 0], [1, 1, 1]])
    with pytest.raises(ValueError, match="exact"):
        collide.intersection(cloud, cloud, exact="no")
    assert len(collide.intersection(cloud, cloud, exact=np.bool_(False))) == 8


def test_review_inputs_get_clear_errors_and_copies_stay_read_only():
    # Review, 2026-11-22: empty arrays of the wrong shape became the empty cloud, radius=True was
    # radius 1, a bad `reduce` was accepted, a superquadric exponent's rule was misstated, a
    # plane with a subnormal normal blamed its finite offset; copies and pickles of clouds and
    # volumes came back writable.
    import copy
    import pickle

    from collide import shapes
    from collide import volumes as V

    for bad in (np.zeros((3, 0)), np.zeros((0, 4)), [[]]):
        with pytest.raises(ValueError, match=r"points: expected shape \(n, 3\)"):
            PointCloud(bad)
    assert PointCloud([]).is_empty and PointCloud(np.zeros((0, 3))).is_empty
    with pytest.raises(ValueError, match="radius: expected a number, got True"):
        PointCloud([[0, 0, 0]], radius=True)
    with pytest.raises(ValueError, match="reduce: expected True or False"):
        shapes.mesh([[0, 0, 0]], reduce="x")
    with pytest.raises(ValueError, match="e1: must be > 0"):
        shapes.superquadric([1, 1, 1], -1, 1)
    with pytest.raises(ValueError, match="normal: too short for its offset"):
        shapes.plane([5e-324, 0, 0], 1.0)
    assert shapes.plane([5e-324, 0, 0], 0.0).normal.tolist() == [1.0, 0.0, 0.0]
    # Overflow inside a computation names the computation, not an argument the user never gave.
    with pytest.raises(ValueError, match="aabb: coordinates plus radius overflow"):
        PointCloud([[1e308, 0, 0]], 1e308).aabb()
    with pytest.raises(ValueError, match="transform: the moved cloud overflows"):
        PointCloud([[1e200, 0, 0]]).transform(np.eye(3) * 1e200)
    rng = np.random.default_rng(0)
    cases = [(PointCloud(rng.random((5, 3)), 0.5), ("points",)), (V.OBB(np.zeros(3), np.eye(3), [1, 2, 3]),
             ("center", "rotation", "half_extents")), (V.AABB(np.zeros(3), np.ones(3)), ("lo", "hi")),
             (V.AABB.empty(), ("lo", "hi")), (V.Sphere([1, 2, 3], 2.0), ("center",)),
             (V.fit_kdop(rng.random((10, 3)), 0.0, 14), ("lo", "hi"))]
    for vol, names in cases:
        for twin in (copy.copy(vol), copy.deepcopy(vol), pickle.loads(pickle.dumps(vol))):
            for a in names:
                assert not getattr(twin, a).flags.writeable and np.array_equal(getattr(twin, a), getattr(vol, a))
