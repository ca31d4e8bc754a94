"""The warm-start cache of the narrow phase across calls (numba): one row a penetrating geom pair.

Issue 46 expects warm-started queries where the poses barely moved. A penetrating pair of point
clouds (meshes, boxes as GJK/EPA sees them) in resting contact is the same pair at nearly the same
pose call after call, so its last EPA polytope, kept as vertex indices of the two clouds
(`collide._kernels.epa`'s ``E_*`` row), rebuilt at the new poses is usually still a certified
answer (`collide._kernels.epa.epa_warm`): no GJK, no EPA.

Only pairs that penetrated at their last call take the warm path (`distance_warm`); every other
pair runs the cold query exactly as without a cache, plus one look-up of its key. A pair enters
the cache when its cold query finds it penetrating (`warm_claim`: its key, an empty row), keeps
its polytope from its next call on, and leaves when it no longer penetrates; so a contact costs
one cold query more before its hits, and a pair that never penetrates never touches a row.

The cache is ``WARM_LEN`` int64: two counters (``WARM_HITS``: pairs answered from their row;
``WARM_TRIES``: pairs found with a polytope in their row), ``WARM_SLOTS`` keys (``g1 * G + g2 +
1``, 0: free), then ``WARM_SLOTS`` rows of ``ENTRY``. A pair's slot is a hash of its key; another
pair hashed to the same slot takes it over when it penetrates (the polytope is dropped). Whatever
a row holds (another pair's, another model's, a stale or a garbage one), `epa_warm` checks it
before use and certifies its answer or declines, so the cache costs time, never correctness.
"""

from __future__ import annotations

from numba import njit

from ._ptr import NO_NRT
from .distance import OUT_ITERATIONS, OUT_PENETRATING, pair_distance_within
from .epa import E_NV, ENTRY

__all__ = ["WARM_HITS", "WARM_KEYS", "WARM_LEN", "WARM_ROWS", "WARM_SLOTS", "WARM_TRIES", "distance_warm",
           "warm_claim", "warm_slot"]

WARM_SLOTS = 1024  # a power of two (`warm_slot` masks)
WARM_HITS, WARM_TRIES, WARM_KEYS = 0, 1, 2
WARM_ROWS = WARM_KEYS + WARM_SLOTS
WARM_LEN = WARM_ROWS + WARM_SLOTS * ENTRY


@njit(cache=True, inline="always")
def warm_slot(key):
    """The slot of pair key ``key`` (``g1 * G + g2 + 1``): a multiplicative hash (Knuth, TAOCP
    vol. 3, 6.4), its high bits, so that keys differing in their high bits spread too."""
    return ((key * 2654435761) >> 16) & (WARM_SLOTS - 1)


@njit(cache=True, inline="always")
def warm_claim(cache, key):
    """Give pair ``key`` its slot of ``cache`` (``WARM_LEN`` int64) with an empty row: its next
    query keeps its polytope (`distance_warm`)."""
    j = warm_slot(key)
    cache[WARM_KEYS + j] = key
    cache[WARM_ROWS + j * ENTRY + E_NV] = 0


@njit(**NO_NRT)
def distance_warm(sa, sb, tol, cutoff, d0, out, cache, key):
    """`collide._kernels.distance.pair_distance_within` (cold hill-climbs, 128 iterations) of the
    pair of key ``key``, which holds its slot of ``cache`` (``WARM_LEN`` int64), with its row:
    counts a polytope found in ``WARM_TRIES`` and an answer from it in ``WARM_HITS``; frees the
    slot when the pair no longer penetrates. Its own function, not inlined: the narrow phase's
    pair loop stays as small for the pairs that never use the cache."""
    j = warm_slot(key)
    o = WARM_ROWS + j * ENTRY
    row = cache[o:o + ENTRY]
    if row[E_NV] > 0:
        cache[WARM_TRIES] += 1
    pair_distance_within(sa, sb, tol, cutoff, d0, -1, -1, 128, out, row)
    if out[OUT_ITERATIONS] == 0:  # answered by its kept polytope
        cache[WARM_HITS] += 1
    elif out[OUT_PENETRATING] != 1.0:  # apart (or degenerate): back to the cold query
        cache[WARM_KEYS + j] = 0
