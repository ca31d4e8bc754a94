"""Span arithmetic (numba): union, intersection and difference of sorted lists of disjoint ray
parameter intervals (Roth 1982, "Ray casting for modeling solids").

A span is a row of ``sp_t`` ``(m, 2) float64`` (entry and exit ``t``) and of ``sp_i``
``(m, 4) int64`` (leaf and surface part of each endpoint); a list is a run of rows at an offset.
"""

from __future__ import annotations

from numba import njit



@njit(cache=True)
def _put(sp_t, sp_i, o, t0, l0, s0, t1, l1, s1):
    sp_t[o, 0] = t0
    sp_t[o, 1] = t1
    sp_i[o, 0] = l0
    sp_i[o, 1] = s0
    sp_i[o, 2] = l1
    sp_i[o, 3] = s1


@njit(cache=True)
def span_union(sp_t, sp_i, a, na, b, nb, out):
    """Union of sorted disjoint span lists at ``a`` and ``b``,
    written at ``out``; returns the count."""
    i = 0
    j = 0
    n = 0
    while i < na or j < nb:
        if j >= nb or (i < na and sp_t[a + i, 0] <= sp_t[b + j, 0]):
            k = a + i
            i += 1
        else:
            k = b + j
            j += 1
        if n > 0 and sp_t[k, 0] <= sp_t[out + n - 1, 1]:
            if sp_t[k, 1] > sp_t[out + n - 1, 1]:
                sp_t[out + n - 1, 1] = sp_t[k, 1]
                sp_i[out + n - 1, 2] = sp_i[k, 2]
                sp_i[out + n - 1, 3] = sp_i[k, 3]
        else:
            _put(sp_t, sp_i, out + n, sp_t[k, 0], sp_i[k, 0], sp_i[k, 1], sp_t[k, 1], sp_i[k, 2],
                 sp_i[k, 3])
            n += 1
    return n


@njit(cache=True)
def span_intersection(sp_t, sp_i, a, na, b, nb, out):
    """Intersection of sorted disjoint span lists; returns the count written at ``out``."""
    i = 0
    j = 0
    n = 0
    while i < na and j < nb:
        ka = a + i
        kb = b + j
        if sp_t[ka, 0] >= sp_t[kb, 0]:
            t0, l0, s0 = sp_t[ka, 0], sp_i[ka, 0], sp_i[ka, 1]
        else:
            t0, l0, s0 = sp_t[kb, 0], sp_i[kb, 0], sp_i[kb, 1]
        if sp_t[ka, 1] <= sp_t[kb, 1]:
            t1, l1, s1 = sp_t[ka, 1], sp_i[ka, 2], sp_i[ka, 3]
            i += 1
        else:
            t1, l1, s1 = sp_t[kb, 1], sp_i[kb, 2], sp_i[kb, 3]
            j += 1
        if t0 < t1:
            _put(sp_t, sp_i, out + n, t0, l0, s0, t1, l1, s1)
            n += 1
    return n


@njit(cache=True)
def span_difference(sp_t, sp_i, a, na, b, nb, out):
    """``a`` minus ``b`` for sorted disjoint span lists; returns the count written at ``out``.

    Where a ``b`` span cuts an ``a`` span, ``b``'s entry becomes the result's exit and ``b``'s
    exit its entry (the normal flips; `raycast` orients normals from entry/exit).
    """
    j = 0
    n = 0
    for i in range(na):
        ka = a + i
        c0, cl, cs = sp_t[ka, 0], sp_i[ka, 0], sp_i[ka, 1]
        e1 = sp_t[ka, 1]
        while j < nb and sp_t[b + j, 1] <= c0:
            j += 1
        q = j
        alive = True
        while q < nb and sp_t[b + q, 0] < e1:
            kb = b + q
            if sp_t[kb, 0] > c0:
                _put(sp_t, sp_i, out + n, c0, cl, cs, sp_t[kb, 0], sp_i[kb, 0], sp_i[kb, 1])
                n += 1
            if sp_t[kb, 1] >= e1:
                alive = False
                break
            if sp_t[kb, 1] > c0:
                c0, cl, cs = sp_t[kb, 1], sp_i[kb, 2], sp_i[kb, 3]
            q += 1
        if alive and c0 < e1:
            _put(sp_t, sp_i, out + n, c0, cl, cs, e1, sp_i[ka, 2], sp_i[ka, 3])
            n += 1
    return n
