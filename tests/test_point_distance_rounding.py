"""Regression (adversarial review of 0c6e553, collide._kernels.point_distance): the closed form's
certified bracket must hold, and not be inverted, near the centre of a primitive much larger in
one direction than the point's coordinates.

`point_distance`'s rounding slack is ``ROUNDING * eps * (scale + rk + rp)`` with ``scale`` the
largest coordinate of the point, the foot and the pose's translation; the separating-axis bound
``lower`` also reads ``n . w`` for the primitive's support point ``w``, whose coordinates are
the primitive's size (a rim or an end), and whose rounding the slack leaves out. GJK/EPA on the
same input (the point twice: no closed form) holds (not for the 1e12 ellipsoid: GJK/EPA's
bracket there is also off, by 0.76, a separate matter).
"""

import numpy as np
import pytest

import collide
from collide import Cone, Cylinder, Ellipsoid, PointCloud, testing
from collide.testing.surfaces import random_rotation

EPS = np.finfo(np.float64).eps


@pytest.mark.parametrize("shape, local", [
    (Cylinder(1e6, 1e-3), [0.0, 0.0, 1e-3]),  # on a wide disk's cap, at its centre
    (Cylinder(1e-3, 1e6), [0.0, 0.0, 0.0]),  # at the centre of a long needle
    (Cone(1e6, 1e-3), [0.0, 0.0, 0.0]),  # at a flat cone's base centre
    (Cylinder(0.16194707744044443, 8.757544314513606e-07), [0.0, 0.0, 8.757544314513606e-07]),
    (Ellipsoid([1e12, 1.0, 1.0]), [0.5, 0.2, -0.1]),  # inside a long ellipsoid, near its axis
])
def test_the_closed_form_bracket_holds_near_a_large_primitives_centre(shape, local):
    _bracket_holds(shape, local, 1)


@pytest.mark.parametrize("shape, local", [
    (Cylinder(1e6, 1e-3), [0.0, 0.0, 1e-3]),
    (Cylinder(1e-3, 1e6), [0.0, 0.0, 0.0]),
    (Cone(1e6, 1e-3), [0.0, 0.0, 0.0]),
    (Cylinder(0.16194707744044443, 8.757544314513606e-07), [0.0, 0.0, 8.757544314513606e-07]),
])
def test_gjk_epa_on_the_same_input_holds(shape, local):
    # the control: a two-point cloud never takes the closed form
    _bracket_holds(shape, local, 2)


def _bracket_holds(shape, local, points):
    rng = np.random.default_rng(53)
    local = np.asarray(local, float)
    true = testing.point_signed_distance(shape, local)
    allowance = 256 * EPS * max(float(np.abs(local).max()), abs(true))  # the oracle's and the pose's rounding
    for _ in range(100):
        R = random_rotation(rng)
        r = collide.distance(shape, PointCloud([R @ local] * points), (R, np.zeros(3)))
        assert r.lower <= r.upper, (r.lower, r.upper)
        assert r.lower - allowance <= true <= r.upper + allowance, (r.lower, true, r.upper, r.iterations)


@pytest.mark.parametrize("shape", [
    Ellipsoid([1e-60, 1.0, 1.0]),  # the secular function's e^3 underflows (any axis below ~1e-54)
    Ellipsoid([1e-60, 1e-60, 1e-60]),
    Cone(1e-170, 1e-170),  # the slant's squared length underflows
])
@pytest.mark.parametrize("local", [[0.5, 0.2, -0.1], [0.0, 0.0, 0.0], [2e-60, 0.0, 0.0]])
def test_tiny_primitives_against_a_ball_do_not_raise(shape, local):
    # collide._kernels.point_distance raised ZeroDivisionError (numba's float division by zero)
    # where GJK/EPA (the point twice) answers; through collide.mujoco.Collider too (contacts,
    # geom_distance; check_batch(distance=True) raised SystemError).
    ref = collide.distance(shape, PointCloud([local, local], 0.1))
    r = collide.distance(shape, PointCloud([local], 0.1))
    assert abs(r.distance - ref.distance) <= 1e-12 and r.lower <= ref.upper and ref.lower <= r.upper
