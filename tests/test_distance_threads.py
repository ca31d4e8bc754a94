"""collide.distance from several threads: the shape caches (`collide.signed_distance._shapes`,
`collide.support._cache`) evict while other threads insert and read.

Found by the adversarial review (2026-11-29): the eviction ``_shapes.pop(next(iter(_shapes)))``
raised ``RuntimeError: dictionary changed size during iteration`` when another thread inserted
between ``iter`` and ``next``, and the cache grew past its bound.
"""

from __future__ import annotations

import numpy as np

import collide.signed_distance as sd
import collide.support as sp
from collide import PointCloud, distance
from _threads import in_threads


def test_distance_threads_evicting_caches():
    rng = np.random.default_rng(0)
    base = [rng.normal(size=(int(rng.integers(1, 12)), 3)) for _ in range(16)]
    offs = rng.normal(size=(16, 3)) * 3
    expect = {(i, j): distance(PointCloud(base[i]), PointCloud(base[j], 0.05), None, (np.eye(3), offs[j])).distance
              for i in range(16) for j in range(16)}
    assert min(expect.values()) < 0.0 < max(expect.values())  # both overlapping and separated pairs

    def worker(seed):
        errors = []
        r = np.random.default_rng(seed)
        for _ in range(2500):
            i, j = (int(k) for k in r.integers(16, size=2))
            try:  # fresh shapes every call: each one is a cache miss, an insertion and (past 1024) an eviction
                d = distance(PointCloud(base[i]), PointCloud(base[j], 0.05), None, (np.eye(3), offs[j])).distance
            except Exception as exc:  # noqa: BLE001 - any exception is the failure being tested for
                errors.append(repr(exc))
                continue
            if d != expect[(i, j)]:
                errors.append(("mismatch", i, j, d, expect[(i, j)]))
        return errors

    # switch threads as often as possible: the race needs a switch mid-eviction
    assert in_threads(worker, 4, switch=1e-6) == [[], [], [], []]
    assert len(sd._shapes) <= sd._CACHE_SIZE
    assert len(sp._cache) <= sp._CACHE_SIZE
