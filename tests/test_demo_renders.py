"""The demos' drawing helpers: flower.py's box outlines land where `csg.pinhole_rays` looks."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from collide import csg

ROOT = Path(__file__).resolve().parents[1]


def _flower():
    path = ROOT / "demos" / "flower.py"
    if not path.exists():
        pytest.skip(f"{path} is absent")
    spec = importlib.util.spec_from_file_location("flower_demo_renders", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_box_edges_project_onto_the_pixels_whose_rays_hit_them():
    demo = _flower()
    eye, target, size, fov = np.array([8.0, -9.5, 6.0]), np.array([-0.2, 0.0, 3.9]), 64, 40.0
    _, directions = csg.pinhole_rays(eye, target, size, size, fov_deg=fov)
    rng = np.random.default_rng(3)
    # Points in front of the camera, spread over its view: a ray through a pixel, pushed out.
    pix = rng.integers(0, size, size=(200, 2))
    pts = eye + directions[pix[:, 1] * size + pix[:, 0]] * rng.uniform(2.0, 30.0, size=(200, 1))
    seg = demo.box_edges_2d(pts, pts, eye, target, size, fov)  # a point's box: 12 edges on the point
    assert seg.shape == (200 * 12, 2, 2)
    np.testing.assert_allclose(seg[::12, 0], pix, atol=1e-6)  # (column, row) of that pixel's centre
    np.testing.assert_allclose(seg[:, 0], seg[:, 1], atol=1e-9)


def test_box_edges_behind_the_camera_are_cut():
    demo = _flower()
    eye, target = np.array([0.0, -10.0, 0.0]), np.zeros(3)
    # A box around the camera: every edge with an end behind it is cut at the near plane, none lost
    # whole unless it lies entirely behind.
    seg = demo.box_edges_2d(np.array([[-100.0, -100.0, -100.0]]), np.array([[100.0, 100.0, 100.0]]),
                            eye, target, 64, 40.0)
    assert np.all(np.isfinite(seg))
    assert 0 < len(seg) < 12  # the edges of the back face (y = -100) lie behind the camera
    assert np.all(np.abs(seg) <= 51 * 64)
    # A box entirely behind: nothing drawn.
    behind = demo.box_edges_2d(np.array([[-1.0, -30.0, -1.0]]), np.array([[1.0, -20.0, 1.0]]), eye, target, 64, 40.0)
    assert len(behind) == 0


def test_node_depths_match_a_recursive_walk():
    demo = _flower()
    plant, _ = demo.flower(levels=2, petals=4)
    bvh = csg.build_bvh(plant)
    depth = demo.node_depths(bvh)
    expected = {}

    def walk(n, d):
        expected[n] = d
        for k in bvh.node_child[bvh.node_first[n]:bvh.node_first[n] + bvh.node_count[n]]:
            walk(int(k), d + 1)

    walk(0, 0)
    assert len(expected) == bvh.n_nodes and depth.max() > 2
    assert [expected[n] for n in range(bvh.n_nodes)] == depth.tolist()
