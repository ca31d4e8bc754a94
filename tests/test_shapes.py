"""collide.shapes: containment of the true surfaces (property tests), known answers, bad input.

The true surfaces come from collide.testing.surfaces (analytic samplers, never the clouds), so
each containment case checks a constructor against its shape's own definition.
"""

import math

import numpy as np
import pytest
from scipy.spatial import ConvexHull

import collide
from collide import PointCloud, shapes
from collide import testing as T

RTOL = 1e-9
N_SURFACE = 300
PARAM_SETS = 30  # random parameter sets per primitive
MAPS = ("identity", "rigid", "similarity", "affine", "affine")  # per parameter set


def _volumes(cloud: PointCloud):
    return {
        "aabb": cloud.aabb(),
        "sphere exact": cloud.sphere("exact"),
        "sphere ritter": cloud.sphere("ritter"),
        "obb optimal": cloud.obb("optimal"),
        "obb pca": cloud.obb("pca"),
    }


def _assert_contained(cloud: PointCloud, pts: np.ndarray, label: str) -> None:
    for name, vol in _volumes(cloud).items():
        inside = vol.contains(pts, rtol=RTOL)
        if not inside.all():
            worst = pts[~inside][0]
            pytest.fail(f"{label}: {int((~inside).sum())} of {len(pts)} true-surface points outside "
                        f"the {name} {vol}, e.g. {worst}")


def _map(kind: str, rng) -> np.ndarray:
    if kind == "identity":
        return np.eye(4)
    if kind == "rigid":
        return T.random_rigid(rng)
    if kind == "similarity":
        return T.random_similarity(rng)
    return T.random_affine(rng)


# --------------------------------------------------------------------------------------------
# containment: every primitive under rigid, similarity and general affine maps


@pytest.mark.parametrize("kind", T.SHAPE_KINDS)
def test_true_surface_inside_every_volume_under_maps(kind):
    rng = np.random.default_rng(sum(map(ord, kind)))
    cases = 0
    for i in range(PARAM_SETS):
        params = T.random_shape_params(kind, rng)
        cloud = getattr(shapes, kind)(**params)
        pts = T.sample_surface(kind, N_SURFACE, rng, **params)
        for map_kind in MAPS:
            m = _map(map_kind, rng)
            moved = cloud.transform(m)
            if map_kind == "affine" and cloud.radius > 0:
                # a non-similar map must have turned the radius into points
                assert moved.radius == 0.0 and len(moved) > len(cloud)
            _assert_contained(moved, T.apply_affine(m, pts), f"{kind} #{i} {params} under {map_kind}")
            cases += 1
    assert cases == PARAM_SETS * len(MAPS)


DEGENERATE = [
    ("box", {"half_extents": [1.0, 0.0, 2.0]}),
    ("box", {"half_extents": [0.0, 0.0, 0.0]}),
    ("sphere", {"radius": 0.0}),
    ("capsule", {"radius": 0.5, "half_length": 0.0}),
    ("capsule", {"radius": 0.0, "half_length": 1.0}),
    ("cylinder", {"radius": 0.0, "half_length": 1.0}),
    ("cylinder", {"radius": 1.0, "half_length": 0.0, "planes": 3}),
    ("cone", {"radius": 1.0, "height": 0.0}),
    ("cone", {"radius": 0.0, "height": 1.0}),
    ("ellipsoid", {"radii": [1.0, 0.0, 0.5]}),
    ("ellipsoid", {"radii": [0.0, 0.0, 2.0], "planes": 5}),
    ("torus", {"major_radius": 0.0, "minor_radius": 1.0}),
    ("torus", {"major_radius": 1.0, "minor_radius": 0.0}),
    ("torus", {"major_radius": 0.3, "minor_radius": 1.0, "planes": 5, "tube_planes": 3}),
    ("superquadric", {"radii": [1.0, 2.0, 0.0], "e1": 0.5, "e2": 1.5}),
    ("superquadric", {"radii": [1.0, 1.0, 1.0], "e1": 1e-3, "e2": 1e-3}),
    ("superquadric", {"radii": [1.0, 2.0, 3.0], "e1": 10.0, "e2": 0.3}),
    ("superquadric", {"radii": [1.0, 2.0, 3.0], "e1": 0.3, "e2": 10.0}),
    ("superquadric", {"radii": [1.0, 2.0, 3.0], "e1": 2.0, "e2": 2.0}),
    ("bezier_patch", {"control_points": np.zeros((1, 1, 3))}),
    ("bezier_patch", {"control_points": np.stack(np.meshgrid([0.0, 1, 2], [0.0, 1], [0.0],
                                                             indexing="ij"), -1)[:, :, 0, :]}),
    ("extrude", {"contour": [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], "height": 1.0}),
    ("extrude", {"contour": [[0.5, 0.5]], "height": 0.0}),
    ("cone_sweep", {"contour": [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], "height": 0.0}),
    ("revolve", {"contour": [[0.0, -1.0], [0.0, 1.0]]}),
    ("revolve", {"contour": [[1.0, 0.0]], "steps": 3}),
    ("revolve", {"contour": [[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 1.0]], "steps": 4}),
]


@pytest.mark.parametrize("kind, params", DEGENERATE, ids=[f"{k}-{i}" for i, (k, _) in enumerate(DEGENERATE)])
def test_degenerate_shapes_are_valid_and_contained(kind, params):
    # flat, collinear and single-point shapes are valid input and stay conservative
    rng = np.random.default_rng(7)
    cloud = getattr(shapes, kind)(**params)
    assert isinstance(cloud, PointCloud) and not cloud.is_empty
    pts = T.sample_surface(kind, N_SURFACE, rng, **params)
    for map_kind in ("identity", "rigid", "affine"):
        m = _map(map_kind, rng)
        _assert_contained(cloud.transform(m), T.apply_affine(m, pts), f"{kind} {params} {map_kind}")


def _random_chain(rng, depth: int):
    # A random tree of unions and transforms over random primitives; returns the cloud and the
    # true-surface points of everything in it, carried through the same maps.
    if depth == 0 or rng.random() < 0.25:
        kind = T.SHAPE_KINDS[int(rng.integers(len(T.SHAPE_KINDS)))]
        params = T.random_shape_params(kind, rng)
        cloud = getattr(shapes, kind)(**params)
        pts = T.sample_surface(kind, 120, rng, **params)
    else:
        parts = [_random_chain(rng, depth - 1) for _ in range(int(rng.integers(2, 4)))]
        threshold = int(rng.choice([4, 16, 64, 256]))  # small thresholds force hull reductions
        cloud = collide.union([c for c, _ in parts], threshold=threshold)
        pts = np.concatenate([p for _, p in parts])
    m = _map(("rigid", "similarity", "affine")[int(rng.integers(3))], rng)
    return cloud.transform(m), T.apply_affine(m, pts)


@pytest.mark.parametrize("seed", range(4))
def test_true_surfaces_inside_volumes_of_random_union_transform_chains(seed):
    rng = np.random.default_rng(1000 + seed)
    n_chains = 60
    for i in range(n_chains):
        cloud, pts = _random_chain(rng, depth=3)
        # the chain carried real geometry through the maps, not an empty set
        assert not cloud.is_empty and len(pts) >= 120
        _assert_contained(cloud, pts, f"chain {seed}/{i}")


# --------------------------------------------------------------------------------------------
# known answers: exact forms


def test_sphere_is_one_point_plus_radius_and_its_exact_sphere_is_itself():
    c = shapes.sphere(1.5)
    assert len(c) == 1 and c.radius == 1.5
    np.testing.assert_array_equal(c.points, [[0.0, 0.0, 0.0]])
    m = T.random_rigid(np.random.default_rng(3))
    s = c.transform(m).sphere("exact")
    np.testing.assert_allclose(s.center, m[:3, 3], atol=1e-12)
    assert s.radius == pytest.approx(1.5, rel=1e-12)


def test_capsule_is_two_points_on_z_plus_radius():
    c = shapes.capsule(0.25, 1.0)
    assert c.radius == 0.25
    np.testing.assert_array_equal(c.points, [[0, 0, -1.0], [0, 0, 1.0]])
    box = c.aabb()
    np.testing.assert_allclose(box.lo, [-0.25, -0.25, -1.25])
    np.testing.assert_allclose(box.hi, [0.25, 0.25, 1.25])
    assert c.sphere("exact").radius == pytest.approx(1.25, rel=1e-12)


def test_box_is_its_corners_and_its_optimal_obb_is_the_box():
    h = np.array([0.5, 1.0, 2.0])
    c = shapes.box(h)
    assert len(c) == 8 and c.radius == 0.0
    np.testing.assert_array_equal(np.abs(c.points), np.tile(h, (8, 1)))
    rng = np.random.default_rng(4)
    for _ in range(5):
        m = T.random_rigid(rng)
        obb = c.transform(m).obb("optimal")
        assert obb.volume() == pytest.approx(8 * np.prod(h), rel=1e-9)
        np.testing.assert_allclose(np.sort(obb.half_extents), np.sort(h), rtol=1e-9)


def test_mesh_takes_arrays_and_trimesh_and_reduces_to_hull_vertices():
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=2)
    inner = np.random.default_rng(5).normal(scale=0.1, size=(50, 3))
    c = shapes.mesh(np.concatenate([m.vertices, inner]))
    assert len(c) == len(m.vertices)  # interior points dropped
    assert len(shapes.mesh(m)) == len(m.vertices)
    assert len(shapes.mesh(inner, reduce=False)) == 50


def test_patches_and_sweeps_give_their_control_points_and_contour():
    net = np.random.default_rng(6).normal(size=(3, 4, 3))
    for c in (shapes.bezier_patch(net), shapes.bspline_patch(net, degree_u=2, degree_v=1),
              shapes.nurbs_patch(net, np.ones((3, 4)), knots_u=[0, 0, 0, 1, 1, 1])):
        np.testing.assert_array_equal(c.points, net.reshape(-1, 3))
    contour = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.0]])
    e = shapes.extrude(contour, 3.0)
    np.testing.assert_array_equal(e.points[:3], np.column_stack([contour, np.zeros(3)]))
    np.testing.assert_array_equal(e.points[3:], np.column_stack([contour, np.full(3, 3.0)]))
    cs = shapes.cone_sweep(contour, 2.0, apex=(0.5, 0.25))
    np.testing.assert_array_equal(cs.points[-1], [0.5, 0.25, 2.0])
    assert len(cs) == 4


def test_nurbs_rejects_knots_of_the_wrong_length():
    with pytest.raises(ValueError, match="knots_u"):
        shapes.nurbs_patch(np.zeros((3, 3, 3)), np.ones((3, 3)), degree_u=2, knots_u=[0, 0, 1, 1])


# --------------------------------------------------------------------------------------------
# known answers: tangent-plane constructions


def _hull_facets(points):
    # unit outward normals and offsets of the hull's facets
    eq = ConvexHull(points).equations
    return eq[:, :3], -eq[:, 3]


@pytest.mark.parametrize("k", [3, 4, 5, 7, 16, 33])
def test_cylinder_polygon_is_circumscribed_and_tangent(k):
    r, h = 0.7, 1.3
    c = shapes.cylinder(r, h, planes=k)
    assert len(c) == 2 * k
    radial = np.linalg.norm(c.points[:, :2], axis=1)
    np.testing.assert_allclose(radial, r / math.cos(math.pi / k), rtol=1e-11)
    np.testing.assert_allclose(np.abs(c.points[:, 2]), h)
    # every side face touches the cylinder: its distance from the axis is the radius
    normals, offsets = _hull_facets(c.points)
    side = np.abs(normals[:, 2]) < 1e-9
    np.testing.assert_allclose(offsets[side], r, rtol=1e-11)
    if k % 4 == 0:  # tangent planes at x = ±r, y = ±r: the own AABB is exact
        np.testing.assert_allclose(c.aabb().hi, [r, r, h], rtol=1e-11)


def test_cone_base_is_circumscribed():
    c = shapes.cone(2.0, 3.0, planes=6)
    assert len(c) == 7
    np.testing.assert_array_equal(c.points[-1], [0.0, 0.0, 3.0])
    np.testing.assert_allclose(np.linalg.norm(c.points[:-1, :2], axis=1), 2.0 / math.cos(math.pi / 6))
    assert np.all(c.points[:-1, 2] == 0.0)


@pytest.mark.parametrize("k", [3, 4, 5, 6, 8, 12, 16, 31, 64])
def test_ellipsoid_circumradius_matches_its_analytic_value(k):
    c = shapes.ellipsoid([1.0, 1.0, 1.0], planes=k)
    got = float(np.linalg.norm(c.points, axis=1).max())
    assert got == pytest.approx(shapes.sphere_polytope_circumradius(k), rel=1e-11)
    # every facet of the polytope is a tangent plane of the unit sphere (distance 1), none cuts it
    _, offsets = _hull_facets(c.points)
    np.testing.assert_allclose(offsets, 1.0, rtol=1e-9)


def test_circumradius_formula_independent_values():
    # m odd: 1 / (cos(pi/k) cos(pi/2m)); m even: sqrt(sec^2(pi/k) + tan^2(pi/2m))
    assert shapes.sphere_polytope_circumradius(6) == pytest.approx(4.0 / 3.0, rel=1e-14)   # m = 3
    assert shapes.sphere_polytope_circumradius(4) == pytest.approx(math.sqrt(3.0), rel=1e-14)  # m = 2
    assert shapes.sphere_polytope_circumradius(16, bands=9) == pytest.approx(
        1.0 / (math.cos(math.pi / 16) * math.cos(math.pi / 18)), rel=1e-14)
    c = shapes.ellipsoid([1.0, 1.0, 1.0], planes=16, bands=9)
    assert np.linalg.norm(c.points, axis=1).max() == pytest.approx(
        1.0 / (math.cos(math.pi / 16) * math.cos(math.pi / 18)), rel=1e-11)


def test_more_planes_give_a_tighter_cloud():
    radii = shapes.sphere_polytope_circumradius
    values = [radii(k) for k in range(3, 65)]
    assert all(a > b for a, b in zip(values, values[1:]))
    assert values[-1] < 1.003
    ks = (4, 8, 16, 32, 64)
    builders = {
        "cylinder": (lambda k: shapes.cylinder(1.0, 1.0, planes=k), 2 * math.pi),
        "cone": (lambda k: shapes.cone(1.0, 1.0, planes=k), math.pi / 3),
        "ellipsoid": (lambda k: shapes.ellipsoid([1.0, 2.0, 3.0], planes=k), 4 / 3 * math.pi * 6),
        "torus": (lambda k: shapes.torus(2.0, 0.5, planes=k), None),  # hull volume: no closed form here
        "superquadric": (lambda k: shapes.superquadric([1.0, 2.0, 3.0], 0.5, 1.5, planes=k), None),
        "revolve": (lambda k: shapes.revolve([[0, -1], [1, 0], [0, 1]], steps=k), 2 * math.pi / 3),
    }
    for name, (build, true_volume) in builders.items():
        vols = [ConvexHull(build(k).points).volume for k in ks]
        assert all(a > b for a, b in zip(vols, vols[1:])), (name, vols)
        if true_volume is not None:
            assert true_volume < vols[-1] < 1.01 * true_volume, (name, vols[-1], true_volume)


def test_torus_aabb_is_exact_for_multiples_of_four():
    c = shapes.torus(2.0, 0.5, planes=16, tube_planes=8)
    np.testing.assert_allclose(c.aabb().lo, [-2.5, -2.5, -0.5], rtol=1e-11)
    np.testing.assert_allclose(c.aabb().hi, [2.5, 2.5, 0.5], rtol=1e-11)
    assert len(c) == 16 * 8


def test_revolve_scales_radius_outward():
    c = shapes.revolve([[1.0, 0.0], [0.0, 2.0], [2.0, 1.0]], steps=8)
    assert len(c) == 8 + 1 + 8
    radial = np.linalg.norm(c.points[:, :2], axis=1)
    np.testing.assert_allclose(np.sort(np.unique(np.round(radial, 9))),
                               [0.0, 1 / math.cos(math.pi / 8), 2 / math.cos(math.pi / 8)], rtol=1e-9)


def test_superquadric_support_function_against_dense_samples():
    rng = np.random.default_rng(8)
    for e1, e2 in [(0.3, 0.3), (1.0, 1.0), (0.5, 1.8), (2.0, 0.7), (1.5, 2.0)]:
        pts = T.sample_surface("superquadric", 200000, rng, radii=[1, 1, 1], e1=e1, e2=e2)
        u = rng.normal(size=(64, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        h = shapes.superquadric_support(u, e1, e2)
        best = (pts @ u.T).max(axis=0)
        assert np.all(h >= best - 1e-12), (e1, e2)
        np.testing.assert_allclose(h, best, rtol=3e-3, err_msg=f"e1={e1} e2={e2}")


@pytest.mark.parametrize("e1, e2", [(0.2, 0.2), (0.5, 1.5), (1.0, 1.0), (1.9, 0.4), (3.0, 1.0), (0.7, 5.0)])
def test_superquadric_facets_are_tangent_planes(e1, e2):
    # The cloud is an intersection of tangent halfspaces: every facet plane touches the hull of
    # the shape, so its offset equals the support function in its normal direction.
    c = shapes.superquadric([1.0, 1.0, 1.0], e1, e2, planes=12)
    normals, offsets = _hull_facets(c.points)
    np.testing.assert_allclose(offsets, shapes.superquadric_support(normals, e1, e2), rtol=1e-8)
    np.testing.assert_allclose(c.aabb().hi, [1, 1, 1], rtol=1e-11)


def test_superquadric_special_cases():
    sq = shapes.superquadric([1.0, 2.0, 3.0], 1.0, 1.0)
    el = shapes.ellipsoid([1.0, 2.0, 3.0])
    assert len(sq) == len(el)  # the same lat-long tangent polytope
    assert ConvexHull(sq.points).volume == pytest.approx(ConvexHull(el.points).volume, rel=1e-9)
    octa = shapes.superquadric([1.0, 2.0, 3.0], 2.5, 4.0)  # both e >= 2: the hull is the octahedron
    assert len(octa) == 6
    assert ConvexHull(octa.points).volume == pytest.approx(4 / 3 * 6, rel=1e-12)


# --------------------------------------------------------------------------------------------
# the plane


def test_plane_is_a_halfspace_record_not_a_cloud():
    p = shapes.plane()
    assert isinstance(p, shapes.Plane) and not isinstance(p, PointCloud)
    np.testing.assert_array_equal(p.normal, [0.0, 0.0, 1.0])
    assert p.offset == 0.0 and p.normal.dtype == np.float64
    q = shapes.plane([0.0, 3.0, 4.0], 10.0)  # normalised together with the offset: same halfspace
    np.testing.assert_allclose(q.normal, [0.0, 0.6, 0.8])
    assert q.offset == pytest.approx(2.0)
    np.testing.assert_allclose(q.signed_distance([[0, 0, 0], [0, 3, 4]]), [-2.0, 3.0])
    with pytest.raises(Exception):
        q.offset = 1.0  # frozen
    with pytest.raises(ValueError):
        q.normal[0] = 1.0  # read-only
    with pytest.raises(ValueError, match="PointCloud"):
        collide.union([shapes.box([1, 1, 1]), p])
    assert q == shapes.plane([0.0, 0.6, 0.8], 2.0) and q != p and len({p, q, shapes.plane()}) == 2
    for doc in (shapes.plane.__doc__, shapes.Plane.__doc__):
        assert "not** a `PointCloud`" in doc or "not a PointCloud" in doc
        assert "unbounded" in doc.lower()


# --------------------------------------------------------------------------------------------
# bad input


BAD = [
    (lambda: shapes.sphere(-1.0), "radius.*>= 0"),
    (lambda: shapes.sphere(float("nan")), "radius.*finite"),
    (lambda: shapes.capsule(0.5, -1.0), "half_length"),
    (lambda: shapes.box([1.0, -1.0, 1.0]), "half_extents.*>= 0"),
    (lambda: shapes.box([1.0, 1.0]), "half_extents.*shape"),
    (lambda: shapes.box([1.0, np.inf, 1.0]), "half_extents.*non-finite"),
    (lambda: shapes.cylinder(1.0, 1.0, planes=2), "planes.*>= 3"),
    (lambda: shapes.cylinder(1.0, 1.0, planes=4.5), "planes.*integer"),
    (lambda: shapes.cylinder(-1.0, 1.0), "radius"),
    (lambda: shapes.cone(1.0, -2.0), "height"),
    (lambda: shapes.ellipsoid([1.0, 1.0, -1.0]), "radii.*>= 0"),
    (lambda: shapes.ellipsoid([1.0, 1.0, np.nan]), "radii.*non-finite"),
    (lambda: shapes.ellipsoid([1.0, 1.0, 1.0], bands=1), "bands"),
    (lambda: shapes.torus(-1.0, 0.5), "major_radius"),
    (lambda: shapes.torus(1.0, 0.5, tube_planes=2), "tube_planes"),
    (lambda: shapes.superquadric([1.0, 1.0, 1.0], 0.0, 1.0), "e1.*> 0"),
    (lambda: shapes.superquadric([1.0, 1.0, 1.0], 1.0, -1.0), "e2"),
    (lambda: shapes.superquadric([1.0, 1.0], 1.0, 1.0), "radii.*shape"),
    (lambda: shapes.mesh(np.zeros((0, 3))), "empty"),
    (lambda: shapes.mesh([]), "empty"),
    (lambda: shapes.mesh(np.zeros((4, 2))), "vertices.*shape"),
    (lambda: shapes.mesh([[0.0, 0.0, np.nan]]), "vertices.*non-finite"),
    (lambda: shapes.bezier_patch(np.zeros((3, 3))), "control_points.*shape"),
    (lambda: shapes.bezier_patch(np.zeros((0, 3, 3))), "control_points.*empty"),
    (lambda: shapes.bspline_patch(np.zeros((3, 3, 3)), degree_u=3), "degree_u.*4 control points"),
    (lambda: shapes.bspline_patch(np.zeros((3, 3, 3)), degree_v=1, knots_v=[0, 1, 0, 1, 2]),
     "knots_v.*non-decreasing"),
    (lambda: shapes.nurbs_patch(np.zeros((2, 2, 3)), [[1.0, 1.0], [0.0, 1.0]]),
     "weights.*> 0.*convex-hull"),
    (lambda: shapes.nurbs_patch(np.zeros((2, 2, 3)), [[1.0, -2.0], [1.0, 1.0]]), "weights.*> 0"),
    (lambda: shapes.nurbs_patch(np.zeros((2, 2, 3)), np.ones((2, 3))), "weights.*shape"),
    (lambda: shapes.extrude(np.zeros((3, 3)), 1.0), "contour.*shape"),
    (lambda: shapes.extrude(np.zeros((0, 2)), 1.0), "contour"),
    (lambda: shapes.extrude([[0.0, 0.0]], -1.0), "height"),
    (lambda: shapes.cone_sweep([[0.0, 0.0]], 1.0, apex=(0.0, 0.0, 1.0)), "apex.*shape"),
    (lambda: shapes.revolve([[-1.0, 0.0], [1.0, 1.0]]), "contour.*r.*>= 0"),
    (lambda: shapes.revolve([[1.0, 0.0]], steps=2), "steps"),
    (lambda: shapes.plane([0.0, 0.0, 0.0]), "normal.*non-zero"),
    (lambda: shapes.plane([0.0, np.nan, 1.0]), "normal.*non-finite"),
    (lambda: shapes.plane([0.0, 0.0, 1.0], np.inf), "offset.*finite"),
    (lambda: shapes.plane([0.0, 0.0, 1.0], "x"), "offset"),
    (lambda: shapes.Plane([0.0, 0.0, 1.0], None), "offset: expected a number"),
    (lambda: PointCloud([[0.0, 0.0, 0.0]], "1"), "radius: expected a number"),
    (lambda: shapes.box(1.0), r"half_extents: expected shape \(3\), got \(\)"),
    (lambda: shapes.superquadric_support(np.zeros((2, 2)), 1.0, 1.0), r"directions: expected shape \(n, 3\)"),
    (lambda: shapes.superquadric_support(np.ones((2, 3)), -1.0, 1.0), "e1: must be > 0"),
    (lambda: collide.volumes.min_sphere_center([[0.0, np.nan, 0.0]]), "points: non-finite"),
    (lambda: collide.volumes.min_sphere_center(np.zeros((0, 3))), "points: the cloud is empty"),
    # Tessellation counts that would exhaust memory or run for minutes (review, 2026-11-22).
    (lambda: shapes.cylinder(1.0, 1.0, planes=10**10), "would make .* points, more than MAX_POINTS"),
    (lambda: shapes.torus(1.0, 0.5, planes=10**5, tube_planes=10**5), "planes x tube_planes.*more than MAX_POINTS"),
    (lambda: shapes.torus(1.0, 0.5, planes=3, tube_planes=10**9), "planes x tube_planes"),
    (lambda: shapes.ellipsoid([1.0, 1.0, 1.0], planes=10**9), "planes x bands"),
    (lambda: shapes.superquadric([1.0, 1.0, 1.0], 0.5, 0.5, planes=64, bands=10**9), "planes x bands"),
    (lambda: shapes.revolve([[1.0, 0.0], [1.0, 1.0]], steps=10**9), "more than MAX_POINTS"),
    (lambda: PointCloud([[0.0, 0.0, 0.0]], 1.0).with_radius_as_points(level=9), "level: must be <= 7"),
    # The public helpers of hull and volumes check their input too (review, 2026-11-22: lists,
    # NaNs, empty sets and 1e308 reached numpy's own errors or came back as NaN or as "empty").
    (lambda: collide.volumes.min_sphere_center(np.full((2, 3), 1e308)), "points: coordinates.*beyond 1e\\+150"),
    (lambda: collide.hull.affine_basis([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]] * 0), "points: the cloud is empty"),
    (lambda: collide.hull.affine_basis([[0.0, 0.0, np.nan]]), "points: non-finite"),
    (lambda: collide.hull.affine_basis(np.full((3, 3), 1e306)), "points: coordinates.*beyond"),
    (lambda: PointCloud(np.random.default_rng(0).uniform(1e306, 2e306, (400, 3))).reduced(), "beyond 1e\\+150"),
    (lambda: collide.hull.clip_hull(np.eye(3), [[0.0, 0.0, 1.0]], [np.nan]), "offsets: non-finite"),
    (lambda: collide.hull.clip_hull(np.eye(3), np.eye(3), [0.0]), r"offsets: expected shape \(3\), got \(1,\)"),
    (lambda: collide.hull.clip_hull(np.eye(3), [["a", "b", "c"]], [0.0]), "normals: cannot be read"),
    (lambda: collide.volumes.pca_axes(np.zeros((3, 3, 3))), r"points: expected shape \(n, 3\)"),
    (lambda: collide.volumes.pca_axes([]), "points: the cloud is empty"),
    (lambda: collide.volumes.box_from_axes(np.zeros((0, 3)), 0.0, np.eye(3)), "points: the cloud is empty"),
    (lambda: collide.volumes.box_from_axes(np.zeros((2, 3)), "1", np.eye(3)), "radius: expected a number"),
    (lambda: collide.volumes.box_from_axes(np.zeros((2, 3)), 0.0, 2 * np.eye(3)), "rotation: not orthonormal"),
    (lambda: collide.volumes.obb_corners(None, np.eye(3), np.ones(3)), "center"),
    (lambda: collide.volumes.obb_corners(np.zeros(3), np.full((3, 3), np.nan), np.ones(3)), "rotation: non-finite"),
    (lambda: collide.volumes.fit_kdop(np.zeros((2, 3)), k=[26]), "k: expected 6, 14, 18 or 26"),
    (lambda: collide.volumes.kdop_directions([6]), "k: expected 6, 14, 18 or 26"),
    (lambda: collide.volumes.AABB(np.zeros(3), np.ones(3)).contains(np.zeros((1, 3)), np.nan), "rtol: must be finite"),
    (lambda: collide.volumes.Sphere(np.zeros(3), 1.0).contains(np.zeros((1, 3)), -1.0), "rtol: must be >= 0"),
    (lambda: collide.volumes.OBB(np.zeros(3), np.eye(3), np.ones(3)).contains(np.zeros((1, 3)), "0.1"), "rtol"),
]


@pytest.mark.parametrize("call, reason", BAD, ids=[f"bad-{i}" for i in range(len(BAD))])
def test_bad_input_raises_value_error_with_the_reason(call, reason):
    with pytest.raises(ValueError, match=reason):
        call()


# --------------------------------------------------------------------------------------------
# the samplers themselves: points really on the true surface, and spread over it


def _seg_dist(p, a, b):
    t = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    return np.linalg.norm(p - a - t[:, None] * (b - a), axis=1)


def _on_polygon_boundary(q, poly, tol=1e-9):
    d = np.min([_seg_dist(q, poly[i], poly[(i + 1) % len(poly)]) for i in range(len(poly))], axis=0)
    return d < tol


def test_samplers_lie_on_their_implicit_surfaces():
    rng = np.random.default_rng(11)
    n = 2000
    p = T.sample_surface("sphere", n, rng, radius=2.0)
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), 2.0)
    p = T.sample_surface("ellipsoid", n, rng, radii=[1.0, 2.0, 3.0], planes=8)
    np.testing.assert_allclose(np.sum((p / [1.0, 2.0, 3.0]) ** 2, axis=1), 1.0)
    p = T.sample_surface("torus", n, rng, major_radius=2.0, minor_radius=0.5)
    np.testing.assert_allclose((np.hypot(p[:, 0], p[:, 1]) - 2.0) ** 2 + p[:, 2] ** 2, 0.25)
    for e1, e2 in [(0.3, 1.7), (1.0, 1.0), (3.0, 0.5)]:
        p = T.sample_surface("superquadric", n, rng, radii=[1.0, 2.0, 0.5], e1=e1, e2=e2)
        q = np.abs(p / [1.0, 2.0, 0.5])
        f = (q[:, 0] ** (2 / e2) + q[:, 1] ** (2 / e2)) ** (e2 / e1) + q[:, 2] ** (2 / e1)
        np.testing.assert_allclose(f, 1.0, rtol=1e-9)
    h = np.array([1.0, 0.5, 2.0])
    p = T.sample_surface("box", n, rng, half_extents=h)
    np.testing.assert_allclose(np.max(np.abs(p) / h, axis=1), 1.0)
    p = T.sample_surface("capsule", n, rng, radius=0.3, half_length=1.0)
    np.testing.assert_allclose(_seg_dist(p, np.array([0, 0, -1.0]), np.array([0, 0, 1.0])), 0.3)
    p = T.sample_surface("cylinder", n, rng, radius=0.5, half_length=1.0)
    rho = np.hypot(p[:, 0], p[:, 1])
    side = np.isclose(rho, 0.5) & (np.abs(p[:, 2]) <= 1.0)
    cap = np.isclose(np.abs(p[:, 2]), 1.0) & (rho <= 0.5 + 1e-12)
    assert np.all(side | cap) and side.sum() > n / 3 and cap.sum() > n / 10
    p = T.sample_surface("cone", n, rng, radius=1.0, height=2.0)
    rho = np.hypot(p[:, 0], p[:, 1])
    lateral = np.isclose(rho, 1.0 - p[:, 2] / 2.0)
    base = (p[:, 2] == 0.0) & (rho <= 1.0)
    assert np.all(lateral | base) and lateral.sum() > n / 3 and base.sum() > n / 10
    poly = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [1.0, 0.5], [0.0, 2.0]])  # non-convex
    p = T.sample_surface("extrude", n, rng, contour=poly, height=1.5)
    wall = _on_polygon_boundary(p[:, :2], poly) & (p[:, 2] >= 0) & (p[:, 2] <= 1.5)
    caps = np.isin(p[:, 2], [0.0, 1.5])
    assert np.all(wall | caps)
    notch = np.array([[1.0, 1.5]])  # in the polygon's hull, outside the polygon
    assert not np.any(np.linalg.norm(p[caps][:, :2] - notch, axis=1) < 0.3)
    p = T.sample_surface("revolve", n, rng, contour=poly)
    assert np.all(_on_polygon_boundary(np.column_stack([np.hypot(p[:, 0], p[:, 1]), p[:, 2]]), poly))


def test_samplers_spread_over_the_surface():
    rng = np.random.default_rng(12)
    for kind, params, lo, hi in [
        ("ellipsoid", {"radii": [1.0, 2.0, 3.0]}, [-1, -2, -3], [1, 2, 3]),
        ("torus", {"major_radius": 2.0, "minor_radius": 0.5}, [-2.5, -2.5, -0.5], [2.5, 2.5, 0.5]),
        ("cone", {"radius": 1.0, "height": 2.0}, [-1, -1, 0], [1, 1, 2]),
        ("superquadric", {"radii": [1.0, 2.0, 3.0], "e1": 3.0, "e2": 0.2}, [-1, -2, -3], [1, 2, 3]),
    ]:
        p = T.sample_surface(kind, 20000, rng, **params)
        np.testing.assert_allclose(p.min(axis=0), lo, atol=0.03 * np.max(hi), err_msg=kind)
        np.testing.assert_allclose(p.max(axis=0), hi, atol=0.03 * np.max(hi), err_msg=kind)


def test_patch_samplers_agree_with_known_forms():
    # a bilinear Bezier patch is the bilinear interpolation of its corners; a NURBS patch with
    # equal weights is its B-spline patch; degree-1 B-spline with clamped knots is bilinear too
    net = np.random.default_rng(13).normal(size=(2, 2, 3))
    p = T.sample_surface("bezier_patch", 500, np.random.default_rng(1), control_points=net)
    uv = np.random.default_rng(1).random((2, 500))
    u, v = uv[0][:, None], uv[1][:, None]
    expect = ((1 - u) * (1 - v) * net[0, 0] + (1 - u) * v * net[0, 1] + u * (1 - v) * net[1, 0]
              + u * v * net[1, 1])
    np.testing.assert_allclose(p, expect, atol=1e-12)
    bilinear = T.sample_surface("bspline_patch", 500, np.random.default_rng(1), control_points=net)
    np.testing.assert_allclose(bilinear, expect, atol=1e-12)
    big = np.random.default_rng(14).normal(size=(5, 4, 3))
    a = T.sample_surface("bspline_patch", 300, np.random.default_rng(2), control_points=big,
                         degree_u=3, degree_v=2)
    b = T.sample_surface("nurbs_patch", 300, np.random.default_rng(2), control_points=big,
                         weights=np.full((5, 4), 3.7), degree_u=3, degree_v=2)
    np.testing.assert_allclose(a, b, atol=1e-12)


@pytest.mark.parametrize("kind", T.SHAPE_KINDS)
def test_containment_far_from_the_origin(kind):
    # large coordinates (1e5): rounding grows with the translation; the volumes' rtol is relative
    rng = np.random.default_rng(100 + len(kind))
    for _ in range(4):
        params = T.random_shape_params(kind, rng)
        cloud = getattr(shapes, kind)(**params)
        pts = T.sample_surface(kind, N_SURFACE, rng, **params)
        m = T.random_rigid(rng)
        m[:3, 3] = rng.uniform(-1e5, 1e5, 3)
        _assert_contained(cloud.transform(m), T.apply_affine(m, pts), f"{kind} far {params}")


def test_plane_says_it_has_no_bounds_and_survives_huge_normals():
    # Regression: plane.aabb() was an AttributeError; |normal| overflowed for (1e308, 1e308, 0)
    # and the normal silently became zero.
    p = shapes.plane((1e308, 1e308, 0), 1e308)
    np.testing.assert_allclose(p.normal, [2 ** -0.5, 2 ** -0.5, 0], rtol=1e-15)
    assert p.offset == pytest.approx(2 ** -0.5)
    q = shapes.plane((0, 0, 2), 3)
    np.testing.assert_allclose(q.normal, [0, 0, 1])
    assert q.offset == pytest.approx(1.5)
    for method in ("aabb", "obb", "sphere"):
        with pytest.raises(ValueError, match="unbounded"):
            getattr(p, method)()
