"""Robust hulls: every degenerate input works, reductions keep the hull, ball polytopes contain the ball."""

import numpy as np
import pytest
from scipy.optimize import linprog

from collide import PointCloud, hull, intersection


def _in_hull(points: np.ndarray, query: np.ndarray, tol: float = 1e-9) -> bool:
    # Brute force: query is a convex combination of points (feasibility LP), up to tol.
    n = len(points)
    a_eq = np.vstack([points.T, np.ones((1, n))])
    for q in query:
        res = linprog(np.zeros(n), A_eq=a_eq, b_eq=np.append(q, 1.0), bounds=(0, None),
                      method="highs", options={"primal_feasibility_tolerance": tol})
        if res.status != 0:
            return False
    return True


def _inside(b: np.ndarray, query: np.ndarray) -> np.ndarray:
    # (len(query),) bool: query points on the inner side of every facet plane of hull(b) (b full-
    # dimensional). Qhull's facet equations: the same answer as Delaunay(b).find_simplex >= 0 on
    # these tests' samples, without its point location (seconds a call on thin sample clouds).
    from scipy.spatial import ConvexHull

    eq = ConvexHull(b).equations
    return (query @ eq[:, :3].T + eq[:, 3] <= 0).all(axis=1)


@pytest.mark.parametrize("seed", range(5))
def test_hull_vertices_keep_the_hull(seed):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(200, 3))
    verts = hull.hull_vertices(pts)
    assert len(verts) < len(pts)
    assert _in_hull(verts, pts[::7])


@pytest.mark.parametrize(
    "pts, expected",
    [
        (np.array([[1.0, 2.0, 3.0]]), 1),
        (np.array([[1.0, 2.0, 3.0]] * 6), 1),
        (np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2], [0.5, 0.5, 0.5]], float), 2),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.5, 0]], float), 4),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), 3),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float), 4),
    ],
    ids=["point", "duplicates", "collinear", "flat-square", "triangle", "tetrahedron"],
)
def test_degenerate_inputs(pts, expected):
    for shift in (0.0, 1e5):
        verts = hull.hull_vertices(pts + shift)
        assert len(verts) == expected
        assert _in_hull(verts, pts + shift, tol=1e-7)


def test_flat_rotated_polygon_far_from_origin():
    rng = np.random.default_rng(3)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    xy = rng.uniform(-1, 1, size=(100, 2))
    pts = np.column_stack([xy, np.zeros(100)]) @ q.T + 1e5
    verts = hull.hull_vertices(pts)
    assert 3 <= len(verts) < 30
    assert hull.affine_basis(pts)[2] == 2


@pytest.mark.parametrize("half", [[1.0, 1.0, 1e-13], [1e6, 1e6, 1e-7], [1.0, 1e-13, 1e-13]],
                         ids=["plate", "wide-plate", "needle"])
def test_thin_sets_keep_their_thickness(half):
    # Review reproducer (2026-11-21): thickness below FLAT_TOL of the spread (flat for
    # affine_basis) but far above the rounding of the coordinates was dropped by the reduction,
    # which kept one face's corners. Now every box corner, under random rotations, stays inside
    # the hull of the reduced points, measured along the box's own thin axes.
    from collide import shapes, union

    rng = np.random.default_rng(11)
    half = np.array(half)
    box = shapes.box(half)
    for _ in range(4):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        q *= np.sign(np.linalg.det(q))
        moved = box.transform(q, rng.normal(size=3))
        for cloud in (moved.reduced(), union([moved, moved], threshold=1)):
            local = (cloud.points - moved.points.mean(axis=0)) @ q  # back in the box's frame
            # rounding of the rotated coordinates: a few ulps of their size
            tol = 1e-14 * float(np.abs(moved.points).max())
            np.testing.assert_allclose(local.max(axis=0), half, rtol=0, atol=tol)
            np.testing.assert_allclose(local.min(axis=0), -half, rtol=0, atol=tol)


@pytest.mark.parametrize("level", [0, 1, 2])
def test_ball_polytope_contains_the_unit_ball(level):
    # The support function of the polytope is >= 1 in every direction (it circumscribes the ball).
    poly = hull.ball_polytope(level)
    dirs = np.random.default_rng(level).normal(size=(20000, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    assert np.min(np.max(dirs @ poly.T, axis=1)) >= 1.0
    # ...and it is tight: the circumradius falls with the level.
    assert np.max(np.linalg.norm(poly, axis=1)) < [1.26, 1.071, 1.019][level]


def test_minkowski_ball_bounds_the_rounded_hull():
    rng = np.random.default_rng(7)
    pts = rng.normal(size=(30, 3))
    r = 0.3
    out = hull.minkowski_ball(pts, r)
    dirs = rng.normal(size=(5000, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    exact_support = np.max(dirs @ pts.T, axis=1) + r
    assert np.all(np.max(dirs @ out.T, axis=1) >= exact_support - 1e-12)


def test_intersect_hulls_of_flat_sets_is_conservative():
    square = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [2, 2, 0]], float)
    cube = np.array([[x, y, z] for x in (1, 3) for y in (1, 3) for z in (-1, 1)], float)
    out = hull.intersect_hulls(square, cube)
    assert len(out) > 0
    lo, hi = out.min(axis=0), out.max(axis=0)
    np.testing.assert_allclose(lo, [1, 1, 0], atol=1e-9)
    np.testing.assert_allclose(hi, [2, 2, 0], atol=1e-9)


def test_intersect_hulls_far_from_origin_and_flat_is_conservative():
    # Regression: manifold3d's hulls lost volume far from the origin (two 0.01-wide clouds at
    # 6e4 intersected to nothing) and a flat cloud thickened at rounding level gave a cloud
    # that missed up to 17 % of the true intersection. Sampled points of hull(a) inside hull(b)
    # must lie in the hull of the result.
    rng = np.random.default_rng(7)
    checked = 0
    for i in range(30):
        s = 10 ** rng.uniform(-6, 6)
        off = rng.normal(size=3) * 10 ** rng.uniform(0, 7)
        a = rng.normal(size=(20, 3)) * s + off
        b = rng.normal(size=(20, 3)) * s + off + rng.normal(size=3) * s * rng.uniform(0, 1.5)
        if i % 2:
            a[:, 2] = off[2]  # flat
        w = rng.dirichlet(np.full(len(a), 0.3), size=4000)
        samples = w @ a
        samples = samples[_inside(b, samples)]
        if len(samples) == 0:
            continue
        out = hull.intersect_hulls(a, b)
        assert len(out) > 0, i
        tol = 1e-9 * max(np.abs(samples).max(), 1.0)
        dirs = rng.normal(size=(500, 3))
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        assert np.all((samples @ dirs.T).max(axis=0) <= (out @ dirs.T).max(axis=0) + tol), i
        checked += 1
    assert checked >= 15


def test_clip_hull_touching_and_disjoint():
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    face = hull.intersect_hulls(cube, cube + [1, 0, 0])
    assert len(face) > 0
    np.testing.assert_allclose(face.min(axis=0), [1, 0, 0], atol=1e-9)
    np.testing.assert_allclose(face.max(axis=0), [1, 1, 1], atol=1e-9)
    assert len(hull.intersect_hulls(cube, cube + [1 + 1e-6, 0, 0])) == 0
    segment = np.array([[-1, 0.5, 0.5], [2, 0.5, 0.5]])
    out = hull.intersect_hulls(segment, cube)
    np.testing.assert_allclose(out.min(axis=0), [0, 0.5, 0.5], atol=1e-9)
    np.testing.assert_allclose(out.max(axis=0), [1, 0.5, 0.5], atol=1e-9)


@pytest.mark.parametrize("thickness", [1e-10, 1e-8, 1e-6])
def test_intersect_hulls_of_thin_clouds_is_conservative(thickness):
    # Regression: manifold3d misplaced hulls thinner than ~1e-6 of their width (the result
    # missed up to 60 % of the true intersection); thin clouds now go to exact clipping.
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(25):
        a = rng.normal(size=(20, 3)) * [1, 1, thickness]
        a = a @ np.linalg.qr(rng.normal(size=(3, 3)))[0].T
        b = rng.normal(size=(20, 3)) + rng.normal(size=3) * 0.7
        samples = rng.dirichlet(np.full(len(a), 0.3), size=3000) @ a
        samples = samples[_inside(b, samples)]
        if len(samples) == 0:
            continue
        out = hull.intersect_hulls(a, b)
        dirs = rng.normal(size=(300, 3))
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        assert np.all((samples @ dirs.T).max(axis=0) <= (out @ dirs.T).max(axis=0) + 1e-9)
        checked += 1
    assert checked >= 10


def test_intersect_hulls_small_clouds_far_from_the_origin():
    # Regression: a 1e-5-wide cloud at 7e6 was taken for a single point (extent below
    # 1e-12 * |centre|) and its intersection with an overlapping cloud came out empty.
    rng = np.random.default_rng(19)
    off = np.array([6.8e6, -2e6, 3e6])
    a = rng.normal(size=(20, 3)) * 3e-6
    b = rng.normal(size=(20, 3)) * 3e-6 + 1e-6
    samples = rng.dirichlet(np.full(len(a), 0.3), size=3000) @ a
    samples = samples[_inside(b, samples)]
    assert len(samples) > 100
    out = hull.intersect_hulls(a + off, b + off) - off
    assert len(out) > 0
    dirs = rng.normal(size=(300, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    # Tolerance: 1e-12 of the coordinates (7e-6 absolute here is far above; use 1e-8).
    assert np.all((samples @ dirs.T).max(axis=0) <= (out @ dirs.T).max(axis=0) + 1e-8)


def test_intersect_hulls_of_a_tiny_set_and_a_large_one_keeps_the_tiny_one():
    # (review) manifold3d, given both scaled by the larger's size, collapsed a set 2**-270 of it:
    # a 5e-82 cube in a unit one came back as 4 of its corners, and a 5e-82 ball hung or crashed
    # the process. Such a pair is clipped now; the tiny set lies inside the larger one here, so
    # the intersection is the tiny set itself, every vertex kept.
    cube = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    for e in (-250, -270, -330, -495):
        s = 2.0 ** e
        for big in (cube, cube * 2.0 ** -e):  # the tiny one in a unit cube, and in a huge one
            for a, b in ((cube * s, big), (big, cube * s)):
                out = hull.intersect_hulls(a, b)
                assert len(out) >= 8, e
                for corner in cube * s:
                    assert np.abs(out - corner).max(axis=1).min() <= 1e-12 * s, (e, corner)
                assert np.abs(out).max() <= s * (1 + 1e-9), e
        # the ball of radius s in the unit cube: its bound holds the ball (support along any
        # direction at least s), and it stays that small
        r = intersection(PointCloud([[0.0, 0.0, 0.0]], s), PointCloud(cube))
        dirs = np.random.default_rng(3).normal(size=(200, 3))
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        support = (r.points @ dirs.T).max(axis=0) + r.radius
        assert support.min() >= s * (1 - 1e-12) and support.max() <= 2 * s, e


def test_intersect_hulls_of_a_small_ball_straddling_a_face_keeps_its_half():
    # (review) a ball 2**-40 the size of a box, straddling its face, went to manifold3d, whose
    # ~1e-13 of the box cost the half ball a third of its extent: (0, h, 0) lay 0.9 h outside
    box = np.array([[x, y, z] for x in (-2.0, 0.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])
    for e in (-12, -20, -40, -90):
        h = 2.0 ** e
        ball = hull.minkowski_ball(np.zeros((1, 3)), h, 2)
        for a, b in ((ball, box), (box, ball)):
            out = hull.intersect_hulls(a, b)
            for p in ([0.0, h, 0.0], [0.0, -h, 0.0], [0.0, 0.0, h], [0.0, 0.0, -h], [-h, 0.0, 0.0]):
                assert _in_hull(out / h, np.array([p]) / h), (e, p)  # (in units of h: the LP's tolerance)
            assert np.abs(out).max() <= 2 * h, e


def test_small_cloud_far_from_the_origin_is_not_a_single_point():
    # Regression: affine_basis called any spread below 1e-12 * |centre| a single point (7e-6 at
    # 7e6, thousands of ulps), so reduced() collapsed a 1e-5-wide cloud to one point.
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(20, 3)) * 3e-6 + [6.8e6, -2e6, 3e6]
    assert hull.affine_basis(pts)[2] == 3
    kept = hull.hull_vertices(pts)
    np.testing.assert_allclose(kept.min(axis=0), pts.min(axis=0), rtol=0, atol=1e-9)
    np.testing.assert_allclose(kept.max(axis=0), pts.max(axis=0), rtol=0, atol=1e-9)


def test_public_routines_check_their_input():
    # 2-D points were read as a single point, a negative radius shrank nothing, a negative level
    # was level 0: each is now refused, naming the argument.
    with pytest.raises(ValueError, match=r"points: expected shape \(n, 3\)"):
        hull.hull_vertices(np.zeros((5, 2)))
    with pytest.raises(ValueError, match="points"):
        hull.hull_indices([[0.0, np.nan, 0.0]])
    with pytest.raises(ValueError, match="radius: must be >= 0"):
        hull.minkowski_ball(np.zeros((1, 3)), -1.0)
    with pytest.raises(ValueError, match="level: must be >= 0"):
        hull.ball_polytope(-1)
    with pytest.raises(ValueError, match="b: must be a non-empty"):
        hull.intersect_hulls(np.zeros((1, 3)), np.zeros((0, 3)))
    with pytest.raises(ValueError, match="level"):
        PointCloud([[0, 0, 0]], 1.0).with_radius_as_points(-1)
    # lists are read like arrays
    assert hull.hull_vertices([[0, 0, 0], [1, 0, 0], [0.5, 0, 0]]).shape == (2, 3)
