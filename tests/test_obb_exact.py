"""The exact minimum-volume OBB (``fit_obb(method="exact")``, collide.volumes._obb_exact) against its
brute-force twins (collide.testing.obb), and the ``"optimal"`` fitter against the exact box.

On every cloud: the exact box is within 1e-9 of the twin's best box (or better), the twin finds
that box too (so the comparison is not vacuous), ``"optimal"`` is within 1 % of it, and every
box contains the cloud (the points themselves with no slack, and the points pushed out by the
radius in random directions with the usual 1e-9).
"""

import os
import warnings
from pathlib import Path

import numpy as np
import pytest

from collide import hull as H
from collide import volumes as V
from collide.testing import obb as twin
from collide.testing import random_rotation
from _threads import in_child

RTOL = 1e-9
MODELS = Path(__file__).resolve().parents[1] / ".." / "shared" / "models"


def _ball_surface(rng, n) -> np.ndarray:
    p = rng.normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1)[:, None]


def _is_rotation(r) -> bool:
    return np.allclose(r.T @ r, np.eye(3), atol=1e-12) and np.linalg.det(r) > 0


def _fits(points, radius, rng):
    # The exact and optimal boxes, checked for containment, rotations and order.
    exact = V.fit_obb(points, radius, "exact")
    opt = V.fit_obb(points, radius)
    pca = V.fit_obb(points, radius, "pca")
    pushed = points + radius * _ball_surface(rng, len(points))
    for box in (exact, opt):
        assert np.all(box.contains(points))
        assert np.all(box.contains(pushed, RTOL))
        assert _is_rotation(box.rotation)
    assert exact.volume() <= opt.volume() * (1 + RTOL)
    assert exact.volume() <= pca.volume() * (1 + RTOL)
    assert opt.volume() <= exact.volume() * 1.01, (opt.volume() / exact.volume())
    return exact, opt


def _tetrahedron_sample(rng, corners, n):
    return rng.dirichlet(np.ones(4), n) @ np.asarray(corners, dtype=float)


def _cloud(kind: str, rng) -> np.ndarray:
    # Small hulls (the twin's dense search costs hull edges^2 x vertices).
    if kind == "polytope":
        return rng.normal(size=(int(rng.integers(5, 30)), 3)) * rng.uniform(0.2, 2.0, 3)
    if kind == "tetrahedron":
        return _tetrahedron_sample(rng, rng.normal(size=(4, 3)), 300)
    if kind == "ellipsoid":
        return _ball_surface(rng, 40) * rng.uniform(0.3, 3.0, 3)
    if kind == "elongated":
        return rng.normal(size=(200, 3)) * [10.0, 1.0, 0.5]
    if kind == "clustered":
        centres = rng.normal(size=(4, 3)) * 3.0
        return np.vstack([c + rng.normal(size=(30, 3)) * 0.2 for c in centres])
    if kind == "near-flat":
        return np.c_[rng.normal(size=(40, 2)) * [3.0, 1.0], rng.normal(size=40) * 1e-3]
    if kind == "flat":
        return np.c_[rng.normal(size=(30, 2)) * [3.0, 1.0], np.zeros(30)]
    if kind == "box":
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        return np.vstack([corners, rng.uniform(-1, 1, (50, 3))]) * rng.uniform(0.2, 2.0, 3)
    raise ValueError(kind)


KINDS = ["polytope", "tetrahedron", "ellipsoid", "elongated", "clustered", "near-flat", "flat", "box"]


@pytest.mark.parametrize("kind", KINDS)
def test_exact_obb_equals_the_edge_pair_twin(kind):
    rng = np.random.default_rng(100 + KINDS.index(kind))
    for trial in range(3):
        radius = (0.0, 0.05, 0.5)[trial]
        if kind == "flat" and radius == 0.0:
            continue  # zero volume; the rectangle is tested below
        p = _cloud(kind, rng) @ random_rotation(rng).T + rng.normal(size=3) * 10
        exact, _ = _fits(p, radius, rng)
        found = twin.edge_pair_search(p, radius, samples=180, refine=32)[0]
        assert exact.volume() <= found * (1 + RTOL), (trial, exact.volume(), found)
        assert found <= exact.volume() * (1 + 1e-6), (trial, exact.volume(), found)


def test_the_issues_tetrahedron_is_now_within_one_percent():
    # 800 uniform points inside (0,0,0), (2,0.1,0), (0.3,1.5,0.2), (0.4,0.2,1.1): the
    # "optimal" fitter's box was 1.08 times the best box a 40-start search found (issue 45).
    rng = np.random.default_rng(45)
    corners = [(0, 0, 0), (2, 0.1, 0), (0.3, 1.5, 0.2), (0.4, 0.2, 1.1)]
    p = _tetrahedron_sample(rng, corners, 800)
    exact, opt = _fits(p, 0.0, rng)
    found = twin.edge_pair_search(p, 0.0, samples=180, refine=32)[0]
    assert exact.volume() <= found * (1 + RTOL)
    assert found <= exact.volume() * (1 + 1e-6)
    assert opt.volume() <= exact.volume() * 1.01


def test_optimal_within_one_percent_of_exact_on_many_clouds():
    # Larger hulls (up to ~1000 vertices, where "optimal" searches subsets and polishes): the
    # exact box is locally optimal (no small rotation improves it), "optimal" within 1 %.
    rng = np.random.default_rng(11)
    clouds = [_ball_surface(rng, 1000) * [3.0, 2.0, 1.0],
              rng.normal(size=(3000, 3)) * [10.0, 1.0, 0.5],
              _tetrahedron_sample(rng, rng.normal(size=(4, 3)), 5000),
              np.vstack([c + rng.normal(size=(200, 3)) * 0.3 for c in rng.normal(size=(5, 3)) * 3]),
              rng.uniform(-1, 1, (2000, 3)) * [3.0, 1.0, 0.2],
              np.c_[rng.normal(size=(500, 2)), rng.normal(size=500) * 0.05]]
    for k, p in enumerate(clouds):
        p = p @ random_rotation(rng).T
        for radius in (0.0, 0.3):
            exact, _ = _fits(p, radius, rng)
            local = twin.polish(p, radius, exact.rotation)[0]
            assert local >= exact.volume() * (1 - RTOL), (k, radius, local / exact.volume())


def test_radius_changes_the_optimal_orientation():
    # The box of hull ⊕ ball minimises prod(e_i + 2r): growing the r = 0 optimum by r is not
    # it. On these clouds it is up to 0.6 % larger; the exact box is never larger.
    rng = np.random.default_rng(7)
    gains = []
    for _ in range(20):
        p = rng.normal(size=(8, 3)) * [3.0, 1.0, 0.3]
        flat_optimum = V.fit_obb(p, 0.0, "exact").rotation
        for radius in (0.5, 2.0):
            exact, _ = _fits(p, radius, rng)
            grown = V.box_from_axes(p, radius, flat_optimum).volume()
            gains.append(grown / exact.volume())
    assert min(gains) >= 1 - RTOL
    assert max(gains) > 1.003


def test_flat_clouds_get_the_least_rectangle():
    rng = np.random.default_rng(12)
    for _ in range(5):
        p = np.c_[rng.normal(size=(40, 2)) * [3.0, 1.0], np.zeros(40)] @ random_rotation(rng).T + 5.0
        exact, opt = _fits(p, 0.0, rng)
        area = float(np.prod(np.sort(exact.half_extents)[1:] * 2))
        assert np.sort(exact.half_extents)[0] <= 1e-9
        found = twin.min_area_rectangle(p)
        assert area <= found * (1 + RTOL) and found <= area * (1 + 1e-6)


def test_degenerate_clouds():
    rng = np.random.default_rng(13)
    rot = random_rotation(rng)
    for radius in (0.0, 0.5):
        # a point and duplicates: a cube of side 2r
        for p in (np.array([[1.0, 2.0, 3.0]]), np.tile([[1.0, 2.0, 3.0]], (20, 1))):
            box = V.fit_obb(p, radius, "exact")
            assert np.allclose(box.half_extents, radius, atol=1e-12) and np.allclose(box.center, [1, 2, 3])
        # a segment: its axis, (L + 2r)(2r)^2
        seg = np.outer(np.linspace(-1.0, 2.0, 7), rot[:, 0]) + 4.0
        box = V.fit_obb(seg, radius, "exact")
        assert np.allclose(np.sort(box.half_extents), np.sort([radius, radius, 1.5 + radius]), atol=1e-9)
        assert np.all(box.contains(seg))
        # tiny and huge clouds (a radius 1e200 times the cloud's size: no overflow)
        for scale in (1e-200, 1e-12, 1e100):
            p = rng.normal(size=(12, 3)) * scale
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                box = V.fit_obb(p, radius, "exact")
            assert np.all(box.contains(p)) and _is_rotation(box.rotation)
        # two, three and four points
        for n in (2, 3, 4):
            p = rng.normal(size=(n, 3))
            exact, _ = _fits(p, radius, rng)
            if n == 4:
                found = twin.edge_pair_search(p, radius, samples=180, refine=32)[0]
                assert exact.volume() <= found * (1 + RTOL) and found <= exact.volume() * (1 + 1e-6)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="os.fork: POSIX only")
def test_a_collinear_or_flat_cloud_far_from_the_origin_is_collinear_or_flat():
    # 20 collinear points 1e6 from the origin: centred, their coordinates' rounding (~1e-10) made
    # them a needle 1e-9 thick, and the exact search, in proportion to 1 / thickness, did not end
    # (helper-78, 2026-12-02). A spread at the coordinates' own rounding is no shape. In a forked
    # child: an alarm ends a search that does not, which a signal handler cannot (numba's loops).
    rng = np.random.default_rng(21)
    base, u, v = rng.normal(size=3) * 1e6, rng.normal(size=3), rng.normal(size=3)
    clouds = (base + np.outer(rng.normal(size=20), u),  # a segment
              base + np.outer(rng.normal(size=30), u) + np.outer(rng.normal(size=30), v))  # a polygon

    def fits() -> bool:
        for p in clouds:
            for method in ("exact", "optimal"):
                box = V.fit_obb(p, 0.0, method)
                if not (np.all(box.contains(p)) and _is_rotation(box.rotation)
                        and np.sort(box.half_extents)[0] < 1e-8):  # as thin as the rounding
                    return False
        return True

    assert in_child(fits, seconds=300) == 0  # 2: a box wrong; -1: the alarm (no end)


def test_box_is_its_own_exact_box():
    rng = np.random.default_rng(14)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    for _ in range(5):
        half = rng.uniform(0.1, 3.0, 3)
        rot, centre = random_rotation(rng), rng.normal(size=3) * 100
        p = np.vstack([corners, rng.uniform(-1, 1, (100, 3))]) * half @ rot.T + centre
        box = V.fit_obb(p, 0.0, "exact")
        assert box.volume() == pytest.approx(8 * np.prod(half), rel=RTOL)
        assert np.allclose(np.abs(box.rotation.T @ rot).max(axis=1), 1.0, atol=1e-9)


def test_bad_input_names_the_problem():
    good = np.random.default_rng(0).normal(size=(10, 3))
    for bad in (np.array([[0.0, np.nan, 0.0]]), np.array([[np.inf, 0, 0]]), np.zeros((4, 2)), "abc"):
        with pytest.raises(ValueError, match="points"):
            V.fit_obb(bad, 0.0, "exact")
    with pytest.raises(ValueError, match="radius"):
        V.fit_obb(good, -1.0, "exact")
    with pytest.raises(ValueError, match="radius"):
        V.fit_obb(good, np.nan, "exact")
    with pytest.raises(ValueError, match="empty"):
        V.fit_obb(np.zeros((0, 3)), 0.0, "exact")
    with pytest.raises(ValueError, match="method"):
        V.fit_obb(good, 0.0, "minimal")


def _model_meshes():
    if not MODELS.is_dir():
        return []
    import mujoco

    meshes = []
    for scene in sorted(p for p in MODELS.iterdir() if (p / "scene.xml").is_file()):
        model = mujoco.MjModel.from_xml_path(str(scene / "scene.xml"))
        for i in range(min(model.nmesh, 2)):
            start, count = model.mesh_vertadr[i], model.mesh_vertnum[i]
            meshes.append((f"{scene.name}:{i}", np.array(model.mesh_vert[start:start + count], dtype=float)))
    return meshes


@pytest.mark.skipif(not MODELS.is_dir(), reason=f"the test models are not present at {MODELS} "
                    "(the team's shared checkout); nothing to fit")
def test_model_meshes():
    meshes = _model_meshes()
    assert len(meshes) >= 10  # the models hold meshes: the test really fits some
    rng = np.random.default_rng(15)
    for name, p in meshes:
        for radius in (0.0, 0.01):
            exact, _ = _fits(p, radius, rng)
            local = twin.polish(p, radius, exact.rotation)[0]
            assert local >= exact.volume() * (1 - RTOL), (name, radius)
            if len(H.hull_vertices(p)) <= 40:  # small enough for the dense twin
                found = twin.edge_pair_search(p, radius, samples=180, refine=32)[0]
                assert exact.volume() <= found * (1 + RTOL) and found <= exact.volume() * (1 + 1e-6), name
