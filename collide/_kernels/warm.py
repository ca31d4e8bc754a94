"""The narrow phase's caches across calls (numba): the warm-start cache, one row a penetrating geom
pair, and the separation cache, one row a pair found apart (its own section below).

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

import math

import numpy as np
from numba import njit

from ._ptr import NO_NRT
from .distance import (EPA_CAP, OUT_HINT_A, OUT_HINT_B, OUT_ITERATIONS, OUT_NORMAL, OUT_PENETRATING, ROUNDING,
                       pair_distance_within)
from .epa import E_NV, ENTRY
from .support import support

__all__ = ["SEP_LEN", "SEP_ROW", "SEP_SLOTS", "WARM_HITS", "WARM_KEYS", "WARM_LEN", "WARM_ROWS", "WARM_SLOTS",
           "WARM_TRIES", "distance_warm", "sep_forget", "sep_keep", "sep_test", "warm_claim", "warm_slot"]

_EPS = float(np.finfo(np.float64).eps)

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
def distance_warm(sa, sb, tol, cutoff, d0, out, cache, key, fws, iws):
    """`collide._kernels.distance.pair_distance_within` (cold hill-climbs, `EPA_CAP` iterations) of the
    pair of key ``key``, which holds its slot of ``cache`` (``WARM_LEN`` int64), with its row:
    counts a polytope found in ``WARM_TRIES`` and an answer from it in ``WARM_HITS``; frees the
    slot when the pair no longer penetrates. Its own function, not inlined: the narrow phase's
    pair loop stays as small for the pairs that never use the cache. ``fws``, ``iws``: the
    distance's scratch (`collide._kernels.distance.WS_F_EPA`, ``WS_I_EPA``: EPA's included)."""
    j = warm_slot(key)
    o = WARM_ROWS + j * ENTRY
    row = cache[o:o + ENTRY]
    if row[E_NV] > 0:
        cache[WARM_TRIES] += 1
    pair_distance_within(sa, sb, tol, cutoff, d0, -1, -1, EPA_CAP, out, fws, iws, row)
    if out[OUT_ITERATIONS] == 0:  # answered by its kept polytope
        cache[WARM_HITS] += 1
    elif out[OUT_PENETRATING] != 1.0:  # apart (or degenerate): back to the cold query
        cache[WARM_KEYS + j] = 0


# The separation cache: the pairs found apart beyond their contact distance, each with the
# direction that showed it (GJK's normal) and its climbs' end vertices. Two convex sets whose
# supports along one direction ``n`` leave a gap, ``min n.B - max n.A - r_a - r_b > thr``, are
# farther apart than ``thr`` (a separating plane; the bound holds for any ``n``), so a pair that
# barely moved since its last call is settled by two support points, without GJK: the
# separating-axis cache of Rabbitz ("Fast collision detection of moving convex polyhedra",
# Graphics Gems IV, 1994) on GJK's direction. A pair the direction no longer settles runs the
# cold query, as without the cache (so its contacts are the cold call's, bit for bit), and keeps
# its new direction if apart; a pair in contact frees its row. ``SEP_SLOTS`` rows of ``SEP_ROW``
# int64, a hash of the pair's key a slot (another pair hashed there takes it over): the key, the
# direction's three float64 (their bits), the climbs' start vertices (``hint_a | hint_b << 32``).
# Whatever a row holds, `sep_test` certifies what it answers: the cache costs time, never
# correctness.
SEP_SLOTS = 1024  # a power of two (`warm_slot` masks)
SEP_ROW = 5
SEP_LEN = SEP_SLOTS * SEP_ROW


@njit(**NO_NRT)
def sep_test(sep, key, sa, sb, thr, pa, pb):
    """Whether pair ``key``'s row in the separation cache shows it apart beyond ``thr``.

    Parameters
    ----------
    sep : (SEP_LEN,) int64
        The cache.
    key : int
        The pair's key (``g1 * G + g2 + 1``).
    sa, sb : tuple
        Shape tuples (`collide._kernels.support`), ``prm[3]`` the ball radius.
    thr : float
        The pair's contact distance.
    pa, pb : (3,) float64
        Scratch.

    Returns
    -------
    bool
        True when the row is the pair's and the support points along its direction leave a gap
        beyond ``thr``, less the rounding allowance of `collide._kernels.distance.ROUNDING`: the
        pair makes no contact. False otherwise (no row, another pair's, a garbage direction, or
        the gap too small): the caller decides the pair as without the cache.
    """
    o = warm_slot(key) * SEP_ROW
    if sep[o] != key:
        return False
    sepf = sep.view(np.float64)
    n0, n1, n2 = sepf[o + 1], sepf[o + 2], sepf[o + 3]
    nn = n0 * n0 + n1 * n1 + n2 * n2
    if not 0.25 < nn < 4.0:  # also NaN: a direction near unit length, as kept (a garbage row: none)
        return False
    code = sep[o + 4]
    ha = support(sa, n0, n1, n2, code & 0xFFFFFFFF, pa)
    hb = support(sb, -n0, -n1, -n2, code >> 32, pb)
    gap = (n0 * (pb[0] - pa[0]) + n1 * (pb[1] - pa[1]) + n2 * (pb[2] - pa[2])) / math.sqrt(nn)
    ra = sa[1][3]
    rb = sb[1][3]
    scale = max(abs(pa[0]), abs(pa[1]), abs(pa[2]), abs(pb[0]), abs(pb[1]), abs(pb[2])) + ra + rb
    if not gap - ra - rb - ROUNDING * _EPS * scale > thr:
        return False
    sep[o + 4] = (ha & 0xFFFFFFFF) | (hb << 32)  # the climbs' ends: next call's starts
    return True


@njit(**NO_NRT)
def sep_keep(sep, key, out):
    """Keep the direction and hints of a pair found apart (``out``: `pair_distance_within`'s)."""
    o = warm_slot(key) * SEP_ROW
    sepf = sep.view(np.float64)
    sep[o] = key
    for k in range(3):
        sepf[o + 1 + k] = out[OUT_NORMAL + k]
    ha = out[OUT_HINT_A]
    hb = out[OUT_HINT_B]
    sep[o + 4] = (int(ha) if 0.0 <= ha < 2.0 ** 31 else 0xFFFFFFFF) | ((int(hb) if 0.0 <= hb < 2.0 ** 31 else -1)
                                                                         << 32)


@njit(**NO_NRT)
def sep_forget(sep, key):
    """Free pair ``key``'s row of the separation cache (if it holds it): the pair is in contact."""
    o = warm_slot(key) * SEP_ROW
    if sep[o] == key:
        sep[o] = 0
