"""CSG graphs, recursive unrolling, BVHs and ray queries (issue 5; Stürzlinger 1996, §3.3-§4)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import trimesh

from collide import csg
from collide.testing import csg as tcsg

ROOT = Path(__file__).resolve().parents[1]


def rot(axis, angle):
    c, s = np.cos(angle), np.sin(angle)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m = np.eye(4)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def move(x=0.0, y=0.0, z=0.0):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def exact_leaf_box(node):
    pts = np.concatenate([lf.cloud().points @ w[:3, :3].T + w[:3, 3] for lf, w in csg.leaves(node)])
    return pts.min(0), pts.max(0)


def assert_box_close(box, lo, hi, rtol=1e-9):
    scale = max(np.abs(lo).max(), np.abs(hi).max(), 1.0)
    assert np.abs(box.lo - lo).max() <= rtol * scale
    assert np.abs(box.hi - hi).max() <= rtol * scale


# ---------------------------------------------------------------------------------------------
# Point clouds of recursive graphs (paper §3.2-§3.3, §4)

def spiral(depth, leaf):
    # A chain: the leaf plus the whole chain rotated about a skew axis, shrunk and lifted: the
    # paper's case where a box of rotated boxes grows at every level.
    step = move(0.3, 0.1, 0.8) @ rot("z", 0.7) @ rot("x", 0.5) @ np.diag([0.93, 0.93, 0.93, 1.0])
    return csg.Recursive("s", csg.Union(leaf, csg.Transform(step, csg.Ref("s"))), depth)


@pytest.mark.parametrize("leaf", [csg.box([1.0, 0.4, 0.2]),
                                  csg.mesh(trimesh.creation.icosphere(1, radius=0.7))],
                         ids=["box", "mesh"])
def test_depth_30_point_cloud_root_box_is_exact_and_box_of_box_explodes(leaf):
    node = spiral(30, leaf)
    assert len(csg.leaves(node)) == 30
    lo, hi = exact_leaf_box(node)
    assert_box_close(node.point_cloud().aabb(), lo, hi)
    pc = csg.build_bvh(node, method="pointcloud").root_aabb()
    bob = csg.build_bvh(node, method="box_of_box").root_aabb()
    assert_box_close(pc, lo, hi)
    exact_volume = float(np.prod(hi - lo))
    assert bob.volume() > 100 * exact_volume
    # Every box contains the exact one (box of boxes is conservative too).
    assert np.all(bob.lo <= lo) and np.all(bob.hi >= hi)


def test_branching_recursion_exact_box_and_memoized_clouds():
    # Two branches per level, depth 10: 1023 stem boxes, each shared subgraph computed once.
    tops = [move(z=1.0) @ rot("z", a) @ rot("x", 0.6) @ np.diag([0.75, 0.75, 0.75, 1]) for a in (0.3, 3.4)]
    body = csg.Union(csg.Transform(move(z=0.5), csg.box([0.1, 0.1, 0.5])),
                     csg.Instances(csg.Ref("t"), tops))
    tree = csg.Recursive("t", body, 10)
    cache = {}
    cloud = tree.point_cloud(cache=cache)
    assert len(csg.leaves(tree)) == 2**10 - 1
    assert len(cache) <= 6 * 10  # per level: the few nodes of the body, not one per instance
    lo, hi = exact_leaf_box(tree)
    assert_box_close(cloud.aabb(), lo, hi)
    bob = csg.build_bvh(tree, method="box_of_box").root_aabb()
    assert bob.volume() > 2 * float(np.prod(hi - lo))


def test_deep_recursion_is_fast_through_memoization():
    # Depth 40 with two branches: 2^40 unrolled leaves; the cloud needs only 40 levels of work.
    tops = [move(z=1.0) @ rot("z", a) @ np.diag([0.6, 0.6, 0.6, 1]) for a in (0.0, 2.0)]
    tree = csg.Recursive("t", csg.Union(csg.box([0.2, 0.2, 0.5]), csg.Instances(csg.Ref("t"), tops)), 40)
    cache = {}
    box = tree.point_cloud(cache=cache).aabb()
    assert len(cache) <= 4 * 40
    # Top of level k: 1 + 0.6 * top of level k-1, from 0.5 at level 1.
    assert box.hi[2] == pytest.approx(2.5 - 2.0 * 0.6**39, abs=1e-9)


def test_every_box_contains_true_surface_samples_under_affine_recursion():
    # All primitive kinds in a spiral whose step is a general affine map (non-uniform scale):
    # radii become points, ellipsoids fold into the leaf map; nothing may poke out of a box.
    from collide.testing import sample_surface

    rng = np.random.default_rng(3)
    parts = [csg.box([0.3, 0.2, 0.1]), csg.sphere(0.3), csg.capsule(0.2, 0.3), csg.cylinder(0.25, 0.3),
             csg.cone(0.3, 0.6), csg.ellipsoid([0.4, 0.2, 0.1]),
             csg.mesh(trimesh.creation.torus(0.3, 0.1, major_sections=12, minor_sections=8))]
    group = csg.Union(*[csg.Transform(move(0.8 * i) @ rot("x", 0.3 * i), p) for i, p in enumerate(parts)])
    step = move(0.5, 0.2, 0.7) @ rot("z", 0.9) @ rot("y", 0.4) @ np.diag([0.9, 0.8, 1.1, 1.0])
    node = csg.Recursive("g", csg.Union(group, csg.Transform(step, csg.Ref("g"))), 8)
    samples = []
    for leaf, w in csg.leaves(node):
        params = dict(leaf.params)
        if leaf.kind == "mesh":
            params = {"vertices_or_trimesh": trimesh.Trimesh(leaf.vertices, leaf.faces)}
        pts = sample_surface(leaf.kind, 60, rng, **params)
        samples.append(pts @ w[:3, :3].T + w[:3, 3])
    for method in ("pointcloud", "box_of_box"):
        bvh = csg.build_bvh(node, method=method)
        assert np.all(bvh.root_aabb().contains(np.concatenate(samples), rtol=1e-9))
        for k in np.flatnonzero(bvh.node_kind == 0):
            pts = samples[bvh.node_leaf[k]]
            assert np.all(pts >= bvh.node_lo[k]) and np.all(pts <= bvh.node_hi[k])
    assert np.all(node.point_cloud().aabb().contains(np.concatenate(samples), rtol=1e-9))
    everything = np.concatenate(samples)
    for volume in ("obb", "sphere"):
        bvh = csg.build_bvh(node, volume=volume)
        for k in [0] + list(np.flatnonzero(bvh.node_kind == 0)):
            pts = everything if k == 0 else samples[bvh.node_leaf[k]]
            if volume == "obb":
                local = np.abs((pts - bvh.node_center[k]) @ bvh.node_rot[k])
                assert np.all(local <= bvh.node_hi[k] * (1 + 1e-9))
            else:
                dist = np.linalg.norm(pts - bvh.node_center[k], axis=1)
                assert np.all(dist <= bvh.node_radius[k] * (1 + 1e-9))


def test_shared_subgraph_without_references_is_computed_once():
    # A lens (an exact hull intersection) placed at every level of a 25-level spiral: its cloud
    # does not depend on the recursion level, so it is computed once and only moved.
    lens = csg.Intersection(csg.Transform(move(y=0.5), csg.sphere(1.0)),
                            csg.Transform(move(y=-0.5), csg.sphere(1.0)))
    node = spiral(25, csg.Transform(rot("x", 0.3), lens))
    cache = {}
    node.point_cloud(cache=cache)
    assert sum(1 for key in cache if key[0] is lens) == 1
    assert sum(1 for key in cache if key[0] is node.body) == 25  # the recursive part: per level


def test_operators_follow_the_paper():
    a = csg.box([1.0, 1.0, 1.0])
    b = csg.Transform(move(1.0), csg.box([1.0, 1.0, 1.0]))
    inter = csg.Intersection(a, b).point_cloud().aabb()
    np.testing.assert_allclose(inter.lo, [0, -1, -1], atol=1e-9)
    np.testing.assert_allclose(inter.hi, [1, 1, 1], atol=1e-9)
    fast = csg.Intersection(a, b).point_cloud(exact_intersection=False).aabb()
    np.testing.assert_allclose(fast.lo, [0, -1, -1], atol=1e-12)
    diff = csg.Difference(a, b).point_cloud()
    assert diff is a.point_cloud()  # a difference keeps its left operand
    far = csg.Intersection(a, csg.Transform(move(5.0), a)).point_cloud()
    assert far.is_empty
    many = csg.Union(*[csg.Transform(move(0.01 * i), csg.sphere(1.0)) for i in range(300)])
    assert len(many.point_cloud(threshold=256)) <= 256  # reduced past the threshold
    assert csg.Union().point_cloud().is_empty
    assert csg.Recursive("r", csg.Ref("r"), 0).point_cloud().is_empty


# ---------------------------------------------------------------------------------------------
# Ray tests of single primitives: known answers

PRIMS = [
    (csg.box([1.0, 2.0, 3.0]), 5 - 3.0),
    (csg.sphere(1.5), 5 - 1.5),
    (csg.ellipsoid([1.0, 2.0, 0.5]), 5 - 0.5),
    (csg.cylinder(1.0, 2.0), 5 - 2.0),
    (csg.capsule(0.5, 1.0), 5 - 1.5),
    (csg.cone(1.0, 2.0), 5 - 0.0),  # from below: the base at z = 0
    # Shifted so that the test rays miss the face diagonals: a ray through a shared edge is the
    # degenerate case of closed-mesh parity (documented in csg.Leaf).
    (csg.mesh(trimesh.creation.box([2.0, 2.0, 2.0]).apply_translation([0.1, 0.2, 0.0])), 5 - 1.0),
]


@pytest.mark.parametrize("leaf,expected", PRIMS, ids=[p[0].kind for p in PRIMS])
def test_primitive_known_hit_and_normal(leaf, expected):
    bvh = csg.build_bvh(leaf)
    hits = csg.raycast(bvh, [[0, 0, -5], [0, 0, 5], [7, 7, 7]], [[0, 0, 1], [0, 0, -2], [1, 0, 0]])
    assert hits.distance[0] == pytest.approx(expected, abs=1e-12)
    np.testing.assert_allclose(hits.normal[0], [0, 0, -1], atol=1e-12)
    assert hits.leaf[0] == 0 and hits.leaf[2] == -1 and np.isinf(hits.distance[2])
    top = {"box": 3.0, "sphere": 1.5, "ellipsoid": 0.5, "cylinder": 2.0, "capsule": 1.5,
           "cone": 2.0, "mesh": 1.0}[leaf.kind]
    assert hits.distance[1] == pytest.approx((5 - top) / 2, abs=1e-12)  # |direction| = 2
    np.testing.assert_allclose(hits.normal[1], [0, 0, 1], atol=1e-12)
    assert np.all(hits.primitive_tests[:2] == 1)


def test_cone_side_and_transformed_normals():
    # Cone radius 1, height 2: at z = 1 the radius is 0.5; the side normal is (2, 0, 1)/sqrt 5.
    bvh = csg.build_bvh(csg.cone(1.0, 2.0))
    hits = csg.raycast(bvh, [[-5, 0, 1]], [[1, 0, 0]])
    assert hits.distance[0] == pytest.approx(4.5, abs=1e-12)
    np.testing.assert_allclose(hits.normal[0], np.array([-2, 0, 1]) / np.sqrt(5), atol=1e-12)
    # An ellipsoid under a rotation and a translation: the normal is the gradient's direction.
    m = move(1, 2, 3) @ rot("z", 0.7)
    e = csg.Transform(m, csg.ellipsoid([2.0, 1.0, 1.0]))
    p_local = np.array([2 * np.cos(0.4), np.sin(0.4), 0.0])
    n_local = p_local / np.array([4.0, 1.0, 1.0])
    p = m[:3, :3] @ p_local + m[:3, 3]
    n = m[:3, :3] @ n_local
    n /= np.linalg.norm(n)
    hits = csg.raycast(csg.build_bvh(e), [p + 3 * n], [-n])
    assert hits.distance[0] == pytest.approx(3.0, abs=1e-9)
    np.testing.assert_allclose(hits.normal[0], n, atol=1e-9)


def test_span_arithmetic_hollow_sphere_and_inside_origin():
    shell = csg.Difference(csg.sphere(2.0), csg.sphere(1.0))
    bvh = csg.build_bvh(shell)
    hits = csg.raycast(bvh, [[0, 0, -5], [0, 0, 0], [0, 0, 1.5]], [[0, 0, 1]] * 3)
    # Outside: the outer surface. From the hole: the inner surface, normal facing the hole.
    # Inside the wall: the exit through the outer surface, normal along the ray.
    np.testing.assert_allclose(hits.distance, [3.0, 1.0, 0.5], atol=1e-12)
    np.testing.assert_allclose(hits.normal, [[0, 0, -1], [0, 0, -1], [0, 0, 1]], atol=1e-12)
    lens = csg.Intersection(csg.Transform(move(-0.5), csg.sphere(1.0)),
                            csg.Transform(move(0.5), csg.sphere(1.0)))
    hits = csg.raycast(csg.build_bvh(lens), [[-5, 0, 0], [5, 0, 0.1]], [[1, 0, 0], [-1, 0, 0]])
    assert hits.distance[0] == pytest.approx(4.5)  # enters through the right sphere at x = -0.5
    assert hits.leaf[0] == 1 and hits.leaf[1] == 0
    # Union of overlapping items with the origin inside both: the exit of the union (second pass).
    two = csg.Union(csg.box([1.0, 1.0, 1.0]), csg.Transform(move(1.5), csg.box([1.0, 1.0, 1.0])))
    hits = csg.raycast(csg.build_bvh(two), [[0.2, 0.1, 0.3]], [[1, 0, 0]])
    assert hits.distance[0] == pytest.approx(2.3) and hits.leaf[0] == 1
    np.testing.assert_allclose(hits.normal[0], [1, 0, 0])


def test_nonconvex_mesh_spans():
    torus = csg.mesh(trimesh.creation.torus(1.0, 0.25, major_sections=32, minor_sections=16))
    cut = csg.Difference(torus, csg.box([0.1, 2.0, 2.0]))
    # Off the mesh's symmetry planes: rays through edges or vertices are degenerate for parity.
    o = np.array([[-5, 0.013, 0.021], [0, 0.013, 0.021], [0, 0.013, 5]])
    hits = csg.raycast(csg.build_bvh(cut), o, [[1, 0, 0]] * 2 + [[0, 0, -1]])
    assert 3.74 < hits.distance[0] < 3.76  # outer rim of the torus near x = -1.25
    assert 0.74 < hits.distance[1] < 0.76  # from the hole to the inner rim at x = 0.75
    assert hits.leaf[2] == -1  # the hole of the torus


# ---------------------------------------------------------------------------------------------
# Hierarchy against the brute-force twin

def camera_for(node, size=128):
    pos = np.array([w[:3, 3] for _, w in csg.leaves(node)])
    ctr = np.median(pos, axis=0)
    rad = np.percentile(np.linalg.norm(pos - ctr, axis=1), 80) + 1.0
    eye = ctr + np.array([2.0, 1.4, 1.1]) / 2.7 * 3.0 * rad
    return csg.pinhole_rays(eye, ctr, size, size, fov_deg=45.0)


def assert_same_hits(hits, dist, leaf):
    assert np.array_equal(hits.leaf, leaf)
    hit = leaf >= 0
    assert np.all(np.isinf(hits.distance[~hit]))
    np.testing.assert_allclose(hits.distance[hit], dist[hit], rtol=1e-9, atol=1e-12)


def node_kinds(node):
    kinds = {type(node).__name__} | ({f"leaf:{node.kind}"} if isinstance(node, csg.Leaf) else set())
    for c in node.children():
        kinds |= node_kinds(c)
    return kinds


SEEDS = (0, 4, 7)


def test_random_scenes_use_every_node_and_leaf_kind():
    kinds = set().union(*(node_kinds(tcsg.random_scene(s)) for s in SEEDS))
    for k in ("Leaf", "Transform", "Union", "Intersection", "Difference", "Instances", "Recursive", "Ref"):
        assert k in kinds
    for k in csg.Leaf.KINDS:
        assert f"leaf:{k}" in kinds


@pytest.mark.parametrize("seed", SEEDS)
def test_bvh_raycast_equals_brute_force_on_128x128(seed):
    scene = tcsg.random_scene(seed)
    o, d = camera_for(scene)
    dist, leaf = tcsg.brute_force_raycast(scene, o, d)
    assert (leaf >= 0).mean() > 0.2  # the scene really is in view
    assert len(np.unique(leaf[leaf >= 0])) >= 10
    tight = csg.build_bvh(scene)
    loose = csg.build_bvh(scene, tighten=False)
    bob = csg.build_bvh(scene, method="box_of_box")
    obb = csg.build_bvh(scene, volume="obb")
    ball = csg.build_bvh(scene, volume="sphere")
    for bvh in (tight, loose, bob, obb, ball):
        hits = csg.raycast(bvh, o, d)
        assert_same_hits(hits, dist, leaf)
        assert np.all(np.abs(np.linalg.norm(hits.normal[hits.hit], axis=1) - 1) < 1e-9)
        # From outside, every first hit is an entry: the outward normal faces the ray.
        assert np.all(np.sum(hits.normal[hits.hit] * d[hits.hit], axis=1) <= 1e-12)
    # Top-down tightening clips boxes (never grows them) and never changes a hit (above).
    assert tight.n_nodes <= loose.n_nodes
    t_hits, l_hits = csg.raycast(tight, o, d), csg.raycast(loose, o, d)
    assert t_hits.bound_tests.sum() <= l_hits.bound_tests.sum() * 1.05


def test_mesh_rays_through_shared_edges_and_vertices_hit_once():
    # Review reproducer (2026-11-22): an axis ray through the centre of a box mesh's face runs
    # along the diagonal its two triangles share; Moller-Trumbore counted the entry (and the
    # exit) in both, the pairs of equal crossings made empty spans, and the ray missed the box.
    # The watertight test counts a crossing on a shared edge or vertex once. The twin classifies
    # such rays by the winding number, so it does not share the kernel's tie rule.
    box = csg.mesh(trimesh.creation.box([1.0, 1.0, 1.0]))
    g = np.linspace(-0.4, 0.4, 9)  # strictly inside each face: edges, diagonal, centre included
    o, d = [], []
    for ax in range(3):
        for sgn in (-1.0, 1.0):
            for a in g:
                for b in g:
                    p = np.zeros(3)
                    p[ax], p[(ax + 1) % 3], p[(ax + 2) % 3] = -5.0 * sgn, a, b
                    o.append(p)
                    d.append(np.eye(3)[ax] * sgn)
    o, d = np.array(o), np.array(d)
    hits = csg.raycast(csg.build_bvh(box), o, d)
    assert hits.hit.all()
    np.testing.assert_allclose(hits.distance, 4.5, rtol=0, atol=1e-12)
    dist, leaf = tcsg.brute_force_raycast(box, o, d)
    assert_same_hits(hits, dist, leaf)
    # Rays at an icosphere's vertices (a fan of five or six triangles), edge midpoints and face
    # centres, from 5x out towards the centre: every one enters at t = 4.
    ico = trimesh.creation.icosphere(2, radius=0.8)
    for pts in (ico.vertices, ico.vertices[ico.edges_unique].mean(axis=1), ico.triangles_center):
        o, d = 5.0 * pts, -pts
        hits = csg.raycast(csg.build_bvh(csg.mesh(ico)), o, d)
        assert hits.hit.all()
        np.testing.assert_allclose(hits.distance, 4.0, rtol=0, atol=1e-12)
        dist, leaf = tcsg.brute_force_raycast(csg.mesh(ico), o, d)
        assert_same_hits(hits, dist, leaf)
    # The twin's own classification: inside, outside, and on the surface.
    w, on = tcsg.winding_number(box.triangles(), np.array([[0.0, 0, 0], [3.0, 0, 0], [0.5, 0.1, 0.2]]))
    np.testing.assert_allclose(np.abs(w[:2]), [1.0, 0.0], atol=1e-12)
    assert on.tolist() == [False, False, True]


@pytest.mark.parametrize("seed", (1, 5))
def test_rays_from_inside_the_scene_equal_brute_force(seed):
    scene = tcsg.random_scene(seed)
    rng = np.random.default_rng(seed)
    box = csg.build_bvh(scene).root_aabb()
    o = rng.uniform(box.lo, box.hi, (3000, 3))
    d = rng.standard_normal((3000, 3))
    dist, leaf = tcsg.brute_force_raycast(scene, o, d)
    assert (leaf >= 0).mean() > 0.3
    for volume in ("aabb", "obb", "sphere"):
        hits = csg.raycast(csg.build_bvh(scene, volume=volume), o, d)
        assert_same_hits(hits, dist, leaf)
    # Some origins are inside the solid: their first hit is an exit, normal along the ray.
    exits = hits.hit & (np.sum(hits.normal * d, axis=1) > 0)
    assert exits.sum() > 20


def test_top_down_pass_removes_and_clips():
    big = csg.box([2.0, 2.0, 2.0])
    # The right operand of a difference lies outside the left one: removed by the empty clip.
    diff = csg.Difference(big, csg.Transform(move(10.0), csg.sphere(1.0)))
    assert csg.build_bvh(diff).n_nodes == 1
    assert csg.build_bvh(diff, tighten=False).n_nodes == 3
    # An intersection clips both operands to its own box.
    lens = csg.Intersection(big, csg.Transform(move(2.5), csg.sphere(1.0)))
    bvh = csg.build_bvh(lens)
    assert np.all(bvh.node_hi[1:, 0] <= 2.0 + 1e-6)
    assert np.all(bvh.node_lo[1:, 0] >= 1.5 - 0.075)  # the ball's polytope is <= 7.1 % wider
    # Operands whose hulls are disjoint: the intersection is empty, nothing is hit.
    none = csg.Intersection(big, csg.Transform(move(10.0), big))
    bvh = csg.build_bvh(none)
    assert bvh.n_nodes == 0
    assert not csg.raycast(bvh, [[-9, 0, 0]], [[1, 0, 0]]).hit.any()


# ---------------------------------------------------------------------------------------------
# The paper's experiment

def load_flower():
    path = ROOT / "demos" / "flower.py"
    if not path.exists():
        pytest.skip(f"{path} is absent")
    spec = importlib.util.spec_from_file_location("flower_demo", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_flower_point_clouds_need_fewer_bound_tests():
    demo = load_flower()
    plant, _ = demo.flower(levels=3, petals=30)
    o, d = csg.pinhole_rays([8.0, -9.5, 6.0], [-0.2, 0.0, 3.9], 64, 64, fov_deg=40.0)
    pc = csg.raycast(csg.build_bvh(plant), o, d)
    bob = csg.raycast(csg.build_bvh(plant, method="box_of_box"), o, d)
    assert pc.hit.mean() > 0.02
    assert np.array_equal(pc.leaf, bob.leaf)
    assert pc.bound_tests.sum() * 10 < bob.bound_tests.sum()
    assert pc.primitive_tests.sum() <= bob.primitive_tests.sum()
    lo, hi = demo.exact_box(plant)
    assert_box_close(csg.build_bvh(plant).root_aabb(), lo, hi)


# ---------------------------------------------------------------------------------------------
# Bad and degenerate input

def test_bad_input_raises_value_error():
    with pytest.raises(ValueError, match="kind"):
        csg.Leaf("torus", 1.0, 0.2)
    with pytest.raises(ValueError, match="radius"):
        csg.sphere(-1.0)
    with pytest.raises(ValueError, match="Ref"):
        csg.Union(csg.Ref("nowhere")).point_cloud()
    with pytest.raises(ValueError, match="child"):
        csg.Transform(np.eye(4), "not a node")
    with pytest.raises(ValueError, match="matrix"):
        csg.Transform(np.full((4, 4), np.nan), csg.sphere(1.0))
    with pytest.raises(ValueError, match="matrices"):
        csg.Instances(csg.sphere(1.0), np.zeros((2, 3, 3)))
    with pytest.raises(ValueError, match="depth"):
        csg.Recursive("r", csg.sphere(1.0), -1)
    with pytest.raises(ValueError, match="faces"):
        csg.mesh((np.zeros((3, 3)), [[0, 1, 7]]))
    with pytest.raises(ValueError, match="faces"):
        csg.mesh((np.zeros((3, 3)), [[0, 1, 1.5]]))
    bvh = csg.build_bvh(csg.sphere(1.0))
    with pytest.raises(ValueError, match="volume"):
        csg.build_bvh(csg.sphere(1.0), volume="kdop")
    with pytest.raises(ValueError, match="box_of_box"):
        csg.build_bvh(csg.sphere(1.0), volume="sphere", method="box_of_box")
    with pytest.raises(ValueError, match="directions"):
        csg.raycast(bvh, [[0, 0, 0]], [[0, 0, 0]])
    with pytest.raises(ValueError, match="origins"):
        csg.raycast(bvh, [[0, 0, np.nan]], [[0, 0, 1]])
    with pytest.raises(ValueError, match="different counts"):
        csg.raycast(bvh, [[0, 0, 0]] * 2, [[0, 0, 1]])


def test_degenerate_geometry_works():
    flat = csg.box([1.0, 1.0, 0.0])
    squash = np.diag([1.0, 1.0, 0.0, 1.0])  # a singular map: zero volume
    scene = csg.Union(flat, csg.Transform(squash, csg.sphere(1.0)), csg.ellipsoid([1.0, 0.0, 1.0]),
                      csg.cone(0.0, 1.0), csg.Transform(move(3.0), csg.sphere(0.5)))
    bvh = csg.build_bvh(scene)
    o = np.array([[0, 0, 5], [3, 0, 5], [0.3, 0.2, -5]])
    d = np.array([[0, 0, -1], [0, 0, -1], [0, 0, 1]])
    hits = csg.raycast(bvh, o, d)
    dist, leaf = tcsg.brute_force_raycast(scene, o, d)
    assert_same_hits(hits, dist, leaf)
    assert list(hits.leaf) == [-1, 4, -1]  # zero-volume solids are never entered
    assert csg.build_bvh(csg.Union()).n_nodes == 0
    assert csg.build_bvh(csg.Instances(csg.sphere(1.0), np.zeros((0, 4, 4)))).n_nodes == 0
    # Depth 0 is the base; a base ends the recursion at depth 1 too.
    assert csg.build_bvh(csg.Recursive("r", csg.Ref("r"), 0, base=csg.sphere(1.0))).n_leaves == 1
    assert csg.build_bvh(csg.Recursive("r", csg.Ref("r"), 1, base=csg.sphere(1.0))).n_leaves == 1
    assert not csg.raycast(csg.build_bvh(csg.Union()), o, d).hit.any()


def test_raycast_directions_of_extreme_length():
    # Regression: |d|^2 underflowed for a direction of length 1e-200 (t = 2.4e200, not 4e200).
    bvh = csg.build_bvh(csg.Union(csg.box([1, 1, 1]), csg.sphere(1.0)))
    o = np.array([[5.0, 0, 0]] * 4)
    d = np.array([[-1.0, 0, 0], [-1e-200, 0, 0], [-1e200, 0, 0], [-3e-150, 0, 3e-151]])
    hits = csg.raycast(bvh, o, d)
    unit = csg.raycast(bvh, o, d / np.linalg.norm(d / np.abs(d).max(axis=1)[:, None], axis=1)[:, None]
                       / np.abs(d).max(axis=1)[:, None])
    assert np.all(hits.hit)
    np.testing.assert_allclose(hits.distance[:3], [4.0, 4e200, 4e-200], rtol=1e-12)
    lengths = np.abs(d).max(axis=1) * np.linalg.norm(d / np.abs(d).max(axis=1)[:, None], axis=1)
    np.testing.assert_allclose(hits.distance * lengths, unit.distance, rtol=1e-12)
    np.testing.assert_allclose(hits.normal, unit.normal, atol=1e-12)
    # A hit beyond the float range along a direction of length 1e-320 is a miss, not leaf 0 at inf.
    far = csg.raycast(bvh, o[:1], np.array([[-1e-320, 0, 0]]))
    assert far.leaf.tolist() == [-1] and not far.hit.any() and np.isinf(far.distance[0])


def test_exact_intersection_flag_must_be_a_bool():
    node = csg.box([1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="exact_intersection"):
        node.point_cloud(exact_intersection="no")
    assert len(node.point_cloud(exact_intersection=False)) == 8
    with pytest.raises(ValueError, match="exact_intersection"):
        csg.build_bvh(node, exact_intersection="no")
    with pytest.raises(ValueError, match="tighten"):
        csg.build_bvh(node, tighten=None)


@pytest.mark.parametrize("volume", ["aabb", "obb", "sphere"])
def test_rays_from_far_away_hit_curved_solids(volume):
    # Review reproducer (2026-11-21): from 1e8 away the textbook discriminant b^2 - a c cancels,
    # and most rays through a unit sphere (and the sphere bounds of a hierarchy) missed. Every
    # ray below passes within 0.3 of a solid's centre: all must hit, as in the twin.
    rng = np.random.default_rng(0)
    scene = csg.Union(csg.sphere(1.0), csg.Transform(move(3.0), csg.capsule(0.5, 1.0)),
                      csg.Transform(move(-3.0), csg.ellipsoid([1.0, 0.7, 0.4])),
                      csg.Transform(move(0.0, 3.0), csg.cylinder(0.5, 1.0)),
                      csg.Transform(move(0.0, -3.0), csg.cone(0.8, 1.0)))
    bvh = csg.build_bvh(scene, volume=volume)
    centres = np.array([[0, 0, 0], [3, 0, 0], [-3, 0, 0], [0, 3, 0], [0, -3, 0.5]], float)
    for D in (1e6, 1e8, 1e10):
        d = rng.normal(size=(500, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        off = rng.normal(size=(500, 3))
        off -= np.sum(off * d, axis=1)[:, None] * d
        off *= (0.3 * rng.random(500) / np.linalg.norm(off, axis=1))[:, None]
        o = centres[np.arange(500) % 5] + off - D * d
        hits = csg.raycast(bvh, o, d)
        dist, leaf = tcsg.brute_force_raycast(scene, o, d)
        assert hits.hit.all() and np.isfinite(dist).all()
        assert np.all(np.abs(hits.distance - D) <= 8.0)  # the scene is less than 8 wide
        np.testing.assert_allclose(hits.distance, dist, rtol=0, atol=1e-12 * D + 1e-6)


def test_zero_radius_capsule_and_cylinder_are_never_entered():
    # A segment has no volume: an axis ray "hit" it at t = 4 (review reproducer, 2026-11-21).
    o = np.array([[0.0, 0.0, 5.0]])
    d = np.array([[0.0, 0.0, -1.0]])
    for leaf in (csg.capsule(0.0, 1.0), csg.cylinder(0.0, 1.0)):
        scene = csg.Union(leaf, csg.Transform(move(0, 0, -3.0), csg.sphere(0.5)))
        hits = csg.raycast(csg.build_bvh(scene), o, d)
        dist, _ = tcsg.brute_force_raycast(scene, o, d)
        assert hits.leaf.tolist() == [1] and hits.distance[0] == pytest.approx(7.5) == dist[0]


def test_leaf_counts_without_unrolling_and_exponential_graphs_are_refused():
    # A Recursive whose body refers to itself twice doubles per level: 40 levels are 2^40 leaves,
    # and build_bvh unrolled them for hours (review, 2026-11-22). Counted first, refused fast.
    half = csg.Transform(np.diag([0.5, 0.5, 0.5, 1.0]), csg.Ref("t"))
    body = csg.Union(csg.box([1.0, 1.0, 1.0]), half, csg.Transform(move(1.0), half))
    for depth in (1, 2, 5, 8):
        g = csg.Recursive("t", body, depth)
        assert csg.unrolled_leaf_count(g) == len(csg.leaves(g)) == 2 ** depth - 1 == csg.build_bvh(g).n_leaves
    for seed in SEEDS:
        scene = tcsg.random_scene(seed)
        assert csg.unrolled_leaf_count(scene) == len(csg.leaves(scene))
    huge = csg.Recursive("t", body, 40)
    assert csg.unrolled_leaf_count(huge) == 2 ** 40 - 1
    for unroll in (csg.build_bvh, csg.leaves):
        with pytest.raises(ValueError, match="MAX_LEAVES"):
            unroll(huge)
    assert huge.point_cloud().points.shape[1] == 3  # clouds are memoised per level: no unrolling


def test_too_deep_graphs_and_rewired_nodes_are_refused():
    # 7000 levels pass the 20000 frames unrolling may use: a clear ValueError, not RecursionError.
    tower = csg.Recursive("t", csg.Union(csg.box([1, 1, 0.1]), csg.Transform(move(0, 0, 0.2), csg.Ref("t"))),
                          7000)
    with pytest.raises(ValueError, match="nests deeper"):
        tower.point_cloud()
    with pytest.raises(ValueError, match="nests deeper"):
        csg.build_bvh(tower)
    # Nodes are immutable: rewiring one into a cycle of objects is refused.
    u = csg.Union(csg.box([1, 1, 1]))
    with pytest.raises(AttributeError, match="immutable"):
        u.items = (csg.box([1, 1, 1]), csg.Transform(move(0, 0, 1), u))


def test_shared_cache_keeps_settings_apart():
    # One cache over calls with other settings: each call gets the cloud its own settings make.
    boxes = csg.Union(*[csg.Transform(move(0.3 * i, 0.1 * i), csg.box([0.5, 0.5, 0.5])) for i in range(10)])
    ball = csg.Intersection(csg.box([1.0, 1.0, 1.0]), csg.sphere(1.2))
    cache = {}
    for node in (boxes, ball):
        for kw in ({"threshold": 1000}, {"threshold": 8}, {"exact_intersection": False},
                   {"exact_intersection": True}):
            got = node.point_cloud(cache=cache, **kw)
            fresh = node.point_cloud(**kw)
            assert np.array_equal(got.points, fresh.points) and got.radius == fresh.radius
    assert len(boxes.point_cloud(threshold=1000).points) > len(boxes.point_cloud(threshold=8).points)
    assert len(ball.point_cloud(exact_intersection=False).points) == 8


def test_pinhole_field_of_view_below_180():
    with pytest.raises(ValueError, match="fov_deg.*below 180"):
        csg.pinhole_rays([0, -5.0, 0], [0, 0, 0.0], 4, 4, fov_deg=180.0)
    with pytest.raises(ValueError, match="fov_deg"):
        csg.pinhole_rays([0, -5.0, 0], [0, 0, 0.0], 4, 4, fov_deg=270.0)
    o, d = csg.pinhole_rays([0, -5.0, 0], [0, 0, 0.0], 4, 4, fov_deg=179.0)
    assert np.all(np.isfinite(d)) and np.all(d[:, 1] > 0)  # every ray looks towards the target


def test_review_arguments_get_clear_errors():
    # Review, 2026-11-22: these raised AttributeError / TypeError from inside, or were accepted.
    b = csg.box([1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="cache: expected a dict"):
        b.point_cloud(cache=[])
    for bad in (5, "Union", ("Union",)):
        with pytest.raises(ValueError, match="stop_at: expected a tuple of Node subclasses"):
            csg.leaves(b, stop_at=bad)
    assert len(csg.leaves(b, stop_at=csg.Intersection)) == len(csg.leaves(b, stop_at=())) == 1
    with pytest.raises(ValueError, match=r"Leaf\('box', \.\.\.\): too many positional arguments"):
        csg.Leaf("box", [1, 1, 1], 5)
    with pytest.raises(ValueError, match="unexpected keyword argument 'foo'"):
        csg.Leaf("sphere", radius=1.0, foo=2)
