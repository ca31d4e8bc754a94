"""Regression (second adversarial review of collide._kernels.point_distance, after d975bd2).

1. Eberly's degenerate case is detected by ``sx >= 1 - 1e-6`` (the foot at the final u nearly on the
   surface) instead of by the sign of F at the pole: for a point just inside a flat ellipsoid, on the plane
   of its shortest axis (0 there), deeper than that axis' curvature radius but with sx in [1 - 1e-6, 1),
   a non-root u is taken for the root and its foot, pushed onto the surface, is not the nearest point.
   With a tolerance the bracket meets (1e-6 here), the closed form answers: ``distance`` is clamped to the
   separating-axis lower bound but the witnesses keep the wrong foot, so ``point_b - point_a`` differs
   from ``distance * normal`` (the documented identity) by several times the certified bracket's width
   (2.2e-7 against 3.6e-8 for the first case): the witnesses imply a depth outside the certified bracket.
   GJK/EPA (the default tolerance) answers consistently.
2. `_ellipsoid`'s S-lemma depth ``phi = (b_m - u - 2 eps b_m) * (1 - S - 16 eps (1 + S))`` is positive when
   both factors are negative (a point within an ulp or so of the surface: u within 2 eps of b_m, S above
   1 - 32 eps): its "certified lower bound" of the depth then exceeds the true depth (3.0e-15 against
   9.8e-17 for a sphere of radius 1.96). `point_distance`'s 64 eps allowance hides it in `collide.distance`
   (the excess is at most about 9 eps times the shortest axis), so this is checked on the kernel.
"""

from decimal import Decimal, getcontext

import numpy as np
import pytest

import collide
from collide import Ellipsoid, PointCloud
from collide._kernels.point_distance import _ellipsoid

EPS = np.finfo(np.float64).eps

FLAT = [
    ([1.0, 0.000993052170048695, 0.5056430425755569], [0.8598322795533535, 0.0, 0.258167327431783]),
    ([1.0, 0.00044834368957073143, 1.8781320159277446], [0.6651882947665223, 0.0, 1.4023541237082426]),
    ([6.954870381830724, 0.012065813433473565, 8.794672863555525], [1.1349710129964466, -0.0, 8.676758035674712]),
]


@pytest.mark.parametrize("radii, local", FLAT)
@pytest.mark.parametrize("ball_first", [False, True])
def test_witnesses_agree_with_the_distance_on_a_flat_ellipsoids_symmetry_plane(radii, local, ball_first):
    sh, ball = Ellipsoid(radii), PointCloud([local], 0.0)
    r = collide.distance(ball, sh, tolerance=1e-6) if ball_first else collide.distance(sh, ball, tolerance=1e-6)
    assert r.lower <= r.distance <= r.upper
    gap = float(np.abs(r.point_b - r.point_a - r.distance * r.normal).max())
    # the witnesses' own separation within the certified bracket (rounding apart)
    assert gap <= (r.upper - r.lower) + 256 * EPS * max(radii), (r, gap)


def test_ellipsoid_kernels_depth_is_a_lower_bound_of_the_depth():
    a = 1.9609454894034843  # a sphere: the depth is a - |p| exactly
    p = [-0.08737399160641805, -1.3308136716255827, 1.4375701615632774]
    sd, inside, found, depth = _ellipsoid(np.array([a, a, a]), *p, np.zeros(3), np.zeros(3))
    getcontext().prec = 60
    true = float(Decimal(a) - sum(Decimal(x) ** 2 for x in p).sqrt())
    assert inside and found and 0.0 < true < 1e-15
    assert depth <= true * (1 + 4 * EPS), (depth, true)
