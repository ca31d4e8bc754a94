"""Frame coherence of the per-step broad phase (`broadphase._body_pairs`, single-world calls only).

The body pairs whose *fat* boxes (each body's AABB grown by FAT_GROW of its largest extent on every
side) overlap and pass the static filter are kept between calls; while every body's AABB stays
inside its fat box, a call tests that list's exact AABBs instead of walking the tree: two AABBs
inside two fat boxes can only meet if the fat boxes do (the broad phase of Bullet's and Box2D's
dynamic trees: fat AABBs; Catto, "Dynamic AABB Trees", GDC 2019). The answer is the walk's, bit for
bit.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from .culling import _scan, _sweep
from .layout import (H_FLAT, H_L, I_PARENT_POS, N_COH, ST_BODY_AABB, ST_REUSED, W_COH, W_FAT_B, W_FAT_S, W_FAT_T,
                     view_f1, view_f2, view_i1)
from .walk import _walk


# FAT_GROW: the fat boxes' growth, of each body's largest extent. State, float64, in the workspace's
# ``coh`` field (`layout.W_COH`): the list is valid, its length, a decayed count of recent rebuilds
# (x COH_DECAY a call, +1 a rebuild), calls left on the exact walk, and the length of the next such
# spell.
FAT_GROW = 0.2
COH_VALID, COH_N, COH_SCORE, COH_SKIP, COH_BACKOFF = range(5)
assert COH_BACKOFF < N_COH
COH_DECAY = 0.875
# Above this decayed count (rebuilds in more than about a third of the calls, 8 x the rate in a
# steady state: bodies leave their fat boxes all the time, as 22 falling humanoids do), rebuilding
# costs more than the list saves: the exact walk runs for COH_BACKOFF calls (8, doubled each time
# up to COH_BACKOFF_MAX, halved by each call that reuses the list) before the list is tried again.
# The threshold weighs the two kinds of model, measured in alternating passes: set higher, the
# humanoid under the benchmark's extreme controls paid for rebuilds that did not pay off; at 2.5
# it stayed near the walk alone, while wonik_allegro and shadow_hand kept most of their gain.
COH_SCORE_MAX = 2.5
COH_BACKOFF_MIN = 8.0
COH_BACKOFF_MAX = 1024.0

# `_kept_pairs`: the list is not used in this call (the tree is walked)
NO_LIST = -2


@nb.njit(cache=True, inline="always")
def _fat_views(I, W):
    # The frame-coherence part of W: fat_b (L, 6), fat_s (L, 6), fat_t (6, L), state (N_COH).
    return view_f2(I, W, W_FAT_B), view_f2(I, W, W_FAT_S), view_f2(I, W, W_FAT_T), view_f1(I, W, W_COH)


@nb.njit(cache=True, inline="always")
def _kept_pairs(I, W, sap, bp, stats, info, cl, baabb):
    # `broadphase._body_pairs` from the list kept in cl by earlier calls while every body stays
    # inside its fat box: the body pairs into bp[:m] as the walk writes them; returns m, -1 when bp
    # is too short (info[3]: the count needed), or NO_LIST when this call walks the tree (the list
    # invalid, or a spell of the exact walk, see COH_SCORE_MAX).
    L = I[H_L]
    fat_b, fat_s, fat_t, cs = _fat_views(I, W)
    if cs[COH_SKIP] > 0.0:
        cs[COH_SKIP] -= 1.0
    else:
        out = False
        for x in range(L):  # branch-free: vectorised
            out |= ((baabb[x, 0] < fat_b[x, 0]) | (baabb[x, 1] < fat_b[x, 1]) | (baabb[x, 2] < fat_b[x, 2])
                    | (baabb[x, 3] > fat_b[x, 3]) | (baabb[x, 4] > fat_b[x, 4]) | (baabb[x, 5] > fat_b[x, 5]))
        if cs[COH_VALID] != 0.0 and not out:
            stats[ST_REUSED] = 1
            cs[COH_SCORE] *= COH_DECAY
            cs[COH_BACKOFF] *= 0.5
            n = np.int64(cs[COH_N])
            stats[ST_BODY_AABB] += n
            return _scan(cl, n, baabb, bp)
        score = cs[COH_SCORE] * COH_DECAY + 1.0
        cs[COH_VALID] = 0.0  # until rebuilt (an overflow below returns first)
        if score > COH_SCORE_MAX:
            back = min(max(2.0 * cs[COH_BACKOFF], COH_BACKOFF_MIN), COH_BACKOFF_MAX)
            cs[COH_SKIP] = back - 1.0  # this call is the spell's first
            cs[COH_BACKOFF] = back
            cs[COH_SCORE] = 0.0
        else:
            cs[COH_SCORE] = score
            # Rebuild: fat boxes (a body without bounds keeps its empty box), their subtree
            # boxes, the walk over them, the filter; the list kept, then tested as above.
            for x in range(L):
                g = max(FAT_GROW * max(baabb[x, 3] - baabb[x, 0], baabb[x, 4] - baabb[x, 1],
                                       baabb[x, 5] - baabb[x, 2]), 0.0)
                for i in range(3):
                    fat_b[x, i] = baabb[x, i] - g
                    fat_b[x, 3 + i] = baabb[x, 3 + i] + g
                for i in range(6):
                    fat_s[x, i] = fat_b[x, i]
            if I[H_FLAT] != 0:
                for i in range(6):
                    for x in range(L):
                        fat_t[i, x] = fat_b[x, i]
            _sweep(fat_s, view_i1(I, I, I_PARENT_POS), L)
            n = _walk(I, W, sap, bp, stats, fat_b, fat_s, fat_t)
            if n < 0:
                info[3] = -n
                cs[COH_SCORE] = score - 1.0  # the caller grows bp and reruns: one rebuild
                return -1
            for t in range(n):
                cl[t, 0] = bp[t, 0]
                cl[t, 1] = bp[t, 1]
            cs[COH_N] = n
            cs[COH_VALID] = 1.0
            stats[ST_BODY_AABB] += n
            return _scan(cl, n, baabb, bp)
    return NO_LIST
