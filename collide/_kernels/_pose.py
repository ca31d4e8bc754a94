"""The pose test: a rotation within `ORTHO_TOL` of proper orthonormal and a position within
`MAX_POSITION` (`_pose_ok`). One test for the broad phase's bodies (`bounds`, `lane_tests`,
`swept_motion` read it through `bounds`) and the narrow phase's geoms (`manifold._pose_refused`); a
module of its own so that the narrow-phase kernel's cache does not depend on the broad phase's
bounds and layout (`collide._cache` follows imports).
"""

from __future__ import annotations

import numba as nb

ORTHO_TOL = 1e-6  # max |R^T R - I| accepted for a body rotation (articulation.POSE_ORTHO_TOL: bounds carry the slack)
# Body positions are refused beyond this (= `collide.hull.MAX_COORDINATE`, the geoms' own limit;
# a test keeps the two equal):
# near the float range, sums of coordinates overflow to inf and an inf times a zero normal
# component is NaN, which no test passes (a ball touching a plane at 1e308 was lost; review,
# 2026-11-22).
MAX_POSITION = 1e150


@nb.njit(cache=True, inline="always")
def _pose_ok(r00, r01, r02, r10, r11, r12, r20, r21, r22, p0, p1, p2):
    # One test per body: R^T R = I within ORTHO_TOL, det > 0, a position within MAX_POSITION. Comparisons
    # with NaN are false, and an inf in R makes a product inf or NaN, so a non-finite pose
    # fails too (the caller tells which afterwards). det > 0 (no reflection): column 2 must
    # agree with column 0 x column 1 in sign.
    det = ((r10 * r21 - r20 * r11) * r02 + (r20 * r01 - r00 * r21) * r12
           + (r00 * r11 - r10 * r01) * r22)
    return ((abs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0) <= ORTHO_TOL)
            & (abs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0) <= ORTHO_TOL)
            & (abs(r02 * r02 + r12 * r12 + r22 * r22 - 1.0) <= ORTHO_TOL)
            & (abs(r00 * r01 + r10 * r11 + r20 * r21) <= ORTHO_TOL)
            & (abs(r00 * r02 + r10 * r12 + r20 * r22) <= ORTHO_TOL)
            & (abs(r01 * r02 + r11 * r12 + r21 * r22) <= ORTHO_TOL)
            & (det > 0.0) & (abs(p0) <= MAX_POSITION) & (abs(p1) <= MAX_POSITION) & (abs(p2) <= MAX_POSITION))
