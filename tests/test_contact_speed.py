"""The narrow phase's shortcuts for contacts (issue 46, speed): they change no contact.

* `collide._kernels.gjk.gjk_within` / `collide._kernels.distance.pair_distance_within`: GJK stops
  once its certified lower bound passes a cutoff (a contact's caller needs no distance beyond its
  contact distance, as MuJoCo's GJK stops at its ``dist_cutoff``). Below the cutoff the answer is
  the full query's bit for bit; beyond it the distance still exceeds the cutoff and the bracket
  still holds the true distance.
"""

from __future__ import annotations

import numpy as np

from collide import Cylinder, Ellipsoid, PointCloud
from collide._kernels.distance import (OUT_DISTANCE, OUT_ITERATIONS, OUT_LOWER, OUT_SIZE, OUT_UPPER, WS_F, WS_I,
                                       pair_distance, pair_distance_within)
from collide.support import support_data
from collide.testing.surfaces import random_rotation


def _random_shape(rng, i):
    k = i % 4
    if k == 0:
        return support_data(PointCloud(rng.normal(size=(int(rng.integers(4, 60)), 3)), float(rng.uniform(0, 0.2))))
    if k == 1:
        return support_data(Cylinder(float(rng.uniform(0.2, 1.0)), float(rng.uniform(0.2, 1.0))))
    if k == 2:
        return support_data(Ellipsoid(rng.uniform(0.2, 1.0, 3)))
    return support_data(PointCloud(rng.normal(size=(2, 3)), float(rng.uniform(0.05, 0.3))))  # a capsule


def test_cutoff_changes_nothing_within_it_and_bounds_beyond():
    rng = np.random.default_rng(46)
    full = np.empty(OUT_SIZE)
    cut = np.empty(OUT_SIZE)
    fws, iws = np.empty(WS_F), np.empty(WS_I, np.int64)  # the scratch
    z = np.zeros(3)
    within = beyond = fewer = 0
    for i in range(600):
        a = _random_shape(rng, i)
        b = _random_shape(rng, i // 4 + 1)
        sa = a.posed(random_rotation(rng), rng.normal(size=3))
        sb = b.posed(random_rotation(rng), rng.normal(size=3) * rng.uniform(0.3, 2.5))
        tol = 1e-9 * (a.size + b.size)
        pair_distance(sa, sb, tol, z, -1, -1, 128, full)
        cutoff = full[OUT_DISTANCE] + rng.uniform(-1.0, 1.0)
        pair_distance_within(sa, sb, tol, cutoff, z, -1, -1, 128, cut, fws, iws)
        if full[OUT_UPPER] <= cutoff:
            # the truth is below the cutoff, so GJK's lower bound never passes it: the same answer
            assert np.array_equal(full, cut, equal_nan=True), (i, full, cut)
            within += 1
        elif full[OUT_LOWER] > cutoff:
            assert cut[OUT_DISTANCE] > cutoff, (i, full, cut)
            # both brackets hold the true distance, so they meet; and the cut one holds its value
            assert cut[OUT_LOWER] <= full[OUT_UPPER] and full[OUT_LOWER] <= cut[OUT_UPPER], (i, full, cut)
            assert cut[OUT_LOWER] <= cut[OUT_DISTANCE] <= cut[OUT_UPPER]
            beyond += 1
            fewer += cut[OUT_ITERATIONS] < full[OUT_ITERATIONS]
    # the scene had both cases, and the cutoff saved iterations on many of those beyond it
    assert within > 100 and beyond > 100 and fewer > beyond // 4, (within, beyond, fewer)
