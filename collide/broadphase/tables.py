"""The broad phase's static tables: positions, the one static filter, and what derives from it.

`BroadPhase` lays an `Articulation` out once, here, in numpy: bodies by depth-first *position*
(every subtree one range; when the world has several solid geoms, each is a leaf of its own at
positions 1..V, posed by body 0: one box around all the scenery would meet every moving body), the
bounds rows, and the tables the kernels read. The static collision filter has one home,
`StaticFilter`: the per-step kernel's `_kernels.broadphase._filter` applies the same rule to the
pairs its walk finds (a test compares the two on every pair), and everything else derives from
`StaticFilter.bodies` and `StaticFilter.geoms`: the bit masks of small models (`static_masks`), the
flat roots' masks (`flat_lists`), the planes' flags (`plane_filter`) and the lanes' candidate lists
(`lane_tables`).
"""

from __future__ import annotations

import numpy as np

from .._kernels import culling as _kcull
from .._kernels import keys as _kkeys
from .._kernels import layout as _layout
from .._kernels import lanes as _lanes
from ..articulation import Articulation

__all__ = ["LOOSE", "FLAT_BODIES", "FLAT_PAIRS", "StaticFilter", "model_tables", "lane_tables"]

LOOSE = 4.0  # a multi-geom body whose OBB is more than this x its geoms' OBBs' volume is loose
FLAT_BODIES = 64  # see flat_lists
FLAT_PAIRS = 128


class StaticFilter:
    """The static collision filter of position pairs and geom pairs (MuJoCo's rules, see
    `collide.articulation`), vectorised.

    A pair of positions passes when both have bounds, they are not the same position nor of one
    weld group, their or-ed masks match (``ct_x & ca_y or ct_y & ca_x``), neither is the other's
    parent (unless the parent is the world) where ``filter_parent``, and the pair is not excluded. A
    geom pair then needs its own masks to match and must not be an explicit pair (those are tested
    on their own, filter bypassed).
    """

    def __init__(self, has_bounds, weld, contype, conaffinity, parent_pos, filter_parent, ex_start, ex_other,
                 geom_contype, geom_conaffinity, pair_keys, key_shift):
        self.has_bounds, self.weld, self.contype, self.conaffinity = has_bounds, weld, contype, conaffinity
        self.parent_pos, self.filter_parent = parent_pos, bool(filter_parent)
        self.ex_start, self.ex_other = ex_start, ex_other
        self.geom_contype, self.geom_conaffinity = geom_contype, geom_conaffinity
        self.pair_keys, self.key_shift = np.asarray(pair_keys, np.int64), key_shift
        L = len(has_bounds)
        x = np.repeat(np.arange(L), np.diff(ex_start))
        self._excluded = np.sort(x * L + ex_other)  # both directions are listed

    def bodies(self, x, y, contype_x=None, conaffinity_x=None, bounds_x: bool = True) -> np.ndarray:
        """Whether the position pairs ``(x[i], y[i])`` pass. ``contype_x``, ``conaffinity_x``
        replace x's or-ed masks (a plane geom's own, `plane_filter`); ``bounds_x`` False skips x's
        bounds (a plane's body has none)."""
        x = np.asarray(x, np.int64)
        y = np.asarray(y, np.int64)
        ct = self.contype[x] if contype_x is None else contype_x
        ca = self.conaffinity[x] if conaffinity_x is None else conaffinity_x
        ok = (x != y) & (self.has_bounds[y] != 0) & (self.weld[x] != self.weld[y])
        if bounds_x:
            ok &= self.has_bounds[x] != 0
        ok &= ((ct & self.conaffinity[y]) != 0) | ((self.contype[y] & ca) != 0)
        if self.filter_parent:
            p = self.parent_pos
            ok &= ~(((p[y] == x) & (x != 0)) | ((p[x] == y) & (y != 0)))
        ok &= ~np.isin(x * len(self.has_bounds) + y, self._excluded)
        return ok

    def geoms(self, g1, g2) -> np.ndarray:
        """Whether the geom pairs ``(g1[i], g2[i])`` of a passing position pair pass: their masks
        match and they are not an explicit pair."""
        g1 = np.asarray(g1, np.int64)
        g2 = np.asarray(g2, np.int64)
        ct, ca = self.geom_contype, self.geom_conaffinity
        ok = ((ct[g1] & ca[g2]) != 0) | ((ct[g2] & ca[g1]) != 0)
        if len(self.pair_keys):
            ok &= ~np.isin((np.minimum(g1, g2) << self.key_shift) | np.maximum(g1, g2), self.pair_keys)
        return ok


def _local_rows(center, rot, half, sc, sr) -> np.ndarray:
    # (n, ROW) bounds rows (`_kernels.layout.ROW`) from the articulation's local OBBs and spheres
    n = len(center)
    rows = np.empty((n, _layout.ROW))
    rows[:, 0:3] = center
    rows[:, 3:12] = rot.reshape(n, 9)
    rows[:, 12:15] = half
    rows[:, 15:18] = sc
    rows[:, 18] = sr
    return rows


def model_tables(a: Articulation) -> tuple[dict, dict, StaticFilter]:
    """The per-world model of ``a`` for `_kernels.broadphase.pack`: ``(dims, fields, filter)``,
    ``fields`` by the names of `_kernels.layout.INT` and `FLT` (plus ``n_virtual`` and
    ``filter_parent``)."""
    L, G = a.body_count, a.geom_count
    i64 = np.int64
    solid = np.flatnonzero(~a.geom_is_plane)
    world_geoms = solid[a.geom_body[solid] == 0]
    V = len(world_geoms) if len(world_geoms) > 1 else 0  # the world's solid geoms as leaves 1..V
    Lp = L + V
    order = np.concatenate([[0], np.zeros(V, i64), a.body_dfs_order[1:]]).astype(i64)  # position -> body
    pos_of = (a.body_dfs_pos + V).astype(i64)
    pos_of[0] = 0
    geom_pos = pos_of[a.geom_body].astype(i64)  # position of every geom (planes: their body's)
    geom_pos[world_geoms[:V]] = np.arange(1, V + 1)
    end = a.body_subtree_end[order].astype(i64) + V
    end[1:V + 1] = np.arange(2, V + 2)
    parent_pos = pos_of[a.body_parent[order]].astype(i64)
    parent_pos[0] = 0
    nchild = np.bincount(parent_pos[1:], minlength=Lp).astype(i64)
    children = np.argsort(parent_pos[1:], kind="stable").astype(i64) + 1  # a parent's children increase
    child_start = np.concatenate([[0], np.cumsum(nchild)[:-1]]).astype(i64)
    gpos = geom_pos[solid]
    srt = np.argsort(gpos, kind="stable")
    pgeoms = solid[srt].astype(i64)
    gstart = np.searchsorted(gpos[srt], np.arange(Lp + 1)).astype(i64)
    gcount = np.diff(gstart)
    # 1: one geom (its bounds are the body's); 0: several; -1: several whose body OBB is more than
    # LOOSE times the volume of their own OBBs (two geoms far apart): the kernel skips that body's
    # body-level sphere and OBB tests, which it passes against nearly everything.
    single = (gcount == 1).astype(i64)
    multi = np.flatnonzero(gcount > 1)
    if len(multi):
        gvol = np.prod(2 * (a.geom_obb_half + a.geom_margin[:, None]), axis=1)
        cs = np.concatenate([[0.0], np.cumsum(gvol[pgeoms])])
        own = cs[gstart[multi + 1]] - cs[gstart[multi]]
        bvol = np.prod(2 * a.body_obb_half[order[multi]], axis=1)
        single[multi[bvol > LOOSE * own]] = -1
    has_bounds = (gcount > 0).astype(i64)
    weld = a.body_weld[order].astype(i64)
    contype = np.zeros(Lp, i64)
    conaffinity = np.zeros(Lp, i64)
    np.bitwise_or.at(contype, gpos, a.geom_contype[solid])
    np.bitwise_or.at(conaffinity, gpos, a.geom_conaffinity[solid])
    pairflag = np.zeros(Lp, i64)
    if len(a.pairs):
        pairflag[geom_pos[a.pairs.ravel()]] = 1
    # Excluded partners per position, both directions; an exclusion of the world holds for each
    # of its leaves. A body has none or a few: a scan of its own list beats a search of all.
    world_at = np.arange(V + 1)
    ex = [(x, y) for b1, b2 in a.exclude
          for x in (world_at if b1 == 0 else (pos_of[b1],)) for y in (world_at if b2 == 0 else (pos_of[b2],))]
    ex = np.array(ex, i64).reshape(-1, 2)
    ex = np.concatenate([ex, ex[:, ::-1]]).astype(i64)
    ex = ex[np.lexsort((ex[:, 1], ex[:, 0]))]
    ex_start = np.searchsorted(ex[:, 0], np.arange(Lp + 1)).astype(i64)
    S = _kkeys.key_shift(G)
    pair_keys = (a.pairs[:, 0].astype(i64) << S) | a.pairs[:, 1]
    filt = StaticFilter(has_bounds, weld, contype, conaffinity, parent_pos, a.filter_parent, ex_start, ex[:, 1],
                        a.geom_contype, a.geom_conaffinity, pair_keys, S)
    planes = np.flatnonzero(a.geom_is_plane).astype(i64)
    blocal = _local_rows(a.body_obb_center, a.body_obb_rot, a.body_obb_half, a.body_sphere_center,
                         a.body_sphere_radius)[order]
    glocal = _local_rows(a.geom_obb_center, a.geom_obb_rot, a.geom_obb_half, a.geom_sphere_center,
                         a.geom_sphere_radius)
    # Capsules (half segment, radius) by position and by geom, for the world AABBs.
    bcap = np.column_stack([a.body_capsule_half, a.body_capsule_radius])[order]
    gcap = np.column_stack([a.geom_capsule_half, a.geom_capsule_radius])
    if V:
        # A leaf's bounds are its geom's, inflated, as for any single-geom body.
        blocal[1:V + 1] = glocal[world_geoms]
        blocal[1:V + 1, 12:15] += a.geom_bound_margin[world_geoms, None]
        blocal[1:V + 1, 18] += a.geom_bound_margin[world_geoms]
        bcap[1:V + 1] = gcap[world_geoms]
        bcap[1:V + 1, 3] += a.geom_bound_margin[world_geoms]
    flat_root, flat_n, flat_mask = flat_lists(filt, end, parent_pos, nchild)
    dims = {"L": Lp, "G": G, "Gs": len(pgeoms), "Q": len(planes), "E": len(ex), "P": len(pair_keys), "NB": L}
    fields = dict(
        n_virtual=V, filter_parent=a.filter_parent,
        order=order, pos_of=pos_of, end=end, parent_pos=parent_pos, weld=weld, nchild=nchild,
        child_start=child_start, single=single, has_bounds=has_bounds, pairflag=pairflag, contype=contype,
        conaffinity=conaffinity, children=children, gstart=gstart, pgeoms=pgeoms, ex_start=ex_start,
        ex_other=ex[:, 1], planes=planes, plane_ok=plane_filter(filt, planes, geom_pos[planes]),
        geom_bid=a.geom_body, geom_contype=a.geom_contype, geom_conaffinity=a.geom_conaffinity, pair_g=a.pairs,
        pair_keys=pair_keys, flat_root=flat_root, flat_n=flat_n, flat_mask=flat_mask,
        smask=static_masks(filt, gstart, pgeoms),
        blocal=blocal, glocal=glocal, gplane=a.geom_plane, gmargin=a.geom_bound_margin, pair_m=a.pair_bound_margin,
        bcap=bcap, gcap=gcap)
    return dims, fields, filt


def _pairs_of(f: StaticFilter, gstart, pgeoms, x: int, y: int) -> tuple[np.ndarray, np.ndarray]:
    # the geom pairs of the position pair (x, y) that pass the filter
    g1, g2 = np.meshgrid(pgeoms[gstart[x]:gstart[x + 1]], pgeoms[gstart[y]:gstart[y + 1]], indexing="ij")
    ok = f.geoms(g1.ravel(), g2.ravel())
    return g1.ravel()[ok], g2.ravel()[ok]


def static_masks(f: StaticFilter, gstart, pgeoms) -> np.ndarray:
    """(L + 1,) int64 for `_kernels.broadphase._scan_masks`: where L <= MASK_MAX, bit y of [x] the
    position pair (x, y), x < y, when it passes the filter and has a geom pair that does; [L]
    their count. Zeros beyond MASK_MAX positions."""
    L = len(f.has_bounds)
    out = np.zeros(L + 1, np.uint64)
    if L > _kcull.MASK_MAX:
        return out.view(np.int64)
    p, q = np.triu_indices(L, 1)
    ok = f.bodies(p, q)
    for x, y in zip(p[ok], q[ok]):
        if len(_pairs_of(f, gstart, pgeoms, x, y)[0]):
            out[x] |= np.uint64(1) << np.uint64(y)
            out[L] += np.uint64(1)
    return out.view(np.int64)


def flat_lists(f: StaticFilter, end, parent_pos, nchild) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Small branching subtrees whose position pairs the walk tests from static bit masks.

    Top-down from the world's children: a branching subtree of at most FLAT_BODIES positions whose
    pairs passing the filter number at most FLAT_PAIRS is flat (a robot, a hand); else its children
    are tried. A chain is never flat: the walk down it stops a few links below each body. Returns
    flat_root (L,) 0/1, flat_n (L,) the pair count of each flat root, and flat_mask (L,) int64: bit
    i of flat_mask[p] is the pair (p, r + i) of p's flat root r (p < r + i).
    """
    L = len(end)
    flat_root = np.zeros(L, np.int64)
    lists = {}
    todo = [x for x in range(1, L) if parent_pos[x] == 0]
    while todo:
        r = todo.pop()
        m = end[r] - r
        if m <= FLAT_BODIES and (nchild[r:end[r]] >= 2).any():
            p, q = np.triu_indices(m, 1)
            p, q = p + r, q + r
            ok = f.bodies(p, q)
            if ok.sum() <= FLAT_PAIRS:
                flat_root[r] = 1
                lists[r] = np.stack([p[ok], q[ok]], axis=1)
                continue
        todo.extend(x for x in range(r + 1, end[r]) if parent_pos[x] == r)
    flat_n = np.zeros(L, np.int64)
    flat_mask = np.zeros(L, np.uint64)
    for r, pq in lists.items():
        flat_n[r] = len(pq)
        for p, q in pq:
            flat_mask[p] |= np.uint64(1) << np.uint64(q - r)
    return flat_root, flat_n, flat_mask.view(np.int64)


def plane_filter(f: StaticFilter, planes, plane_pos) -> np.ndarray:
    """(Q, L) 0/1: may the position x pair with plane i at all (the filter with the plane geom's
    own masks; the kernel's plane walk reads one flag per body)."""
    L = len(f.has_bounds)
    x = np.arange(L)
    ok = np.zeros((len(planes), L), np.int64)
    for i, (qg, qx) in enumerate(zip(planes, plane_pos)):
        ok[i] = f.bodies(np.full(L, qx), x, f.geom_contype[qg], f.geom_conaffinity[qg], bounds_x=False)
    return ok


def lane_tables(f: StaticFilter, gstart, pgeoms, planes, plane_ok, pairs, is_plane) -> np.ndarray | None:
    """The static candidates of `pairs_batch`'s lane kernel (`_kernels.lanes`), packed: position
    pairs that pass the filter with their geom pairs, (plane, position) pairs with their geoms, the
    explicit pairs, each geom pair with its rank among all keys. None when the model has more than
    ``lanes.MAX_BODY_PAIRS`` position pairs (the per-world kernel's tree culls better)."""
    L = len(f.has_bounds)
    S = f.key_shift
    if L * (L - 1) // 2 > 16 * _lanes.MAX_BODY_PAIRS:
        return None
    p, q = np.triu_indices(L, 1)
    ok = f.bodies(p, q)
    if ok.sum() > _lanes.MAX_BODY_PAIRS:
        return None

    def key(g1, g2):
        return (min(g1, g2) << S) | max(g1, g2)

    body_pairs, pair_geoms, pair_gstart = [], [], [0]
    for x, y in zip(p[ok], q[ok]):
        g1, g2 = _pairs_of(f, gstart, pgeoms, x, y)
        if len(g1):
            body_pairs.append((x, y))
            pair_geoms.extend(zip(g1.tolist(), g2.tolist()))
            pair_gstart.append(len(pair_geoms))
    plane_pos, plane_start, plane_geoms, plane_gstart = [], [0], [], [0]
    for i, qg in enumerate(planes):
        for x in np.flatnonzero(plane_ok[i]):
            gs = pgeoms[gstart[x]:gstart[x + 1]]
            gs = gs[f.geoms(gs, np.full(len(gs), qg))]
            if len(gs):
                plane_pos.append(x)
                plane_geoms.extend((g, key(g, qg)) for g in gs.tolist())
                plane_gstart.append(len(plane_geoms))
        plane_start.append(len(plane_pos))
    explicit_keys = [key(g1, g2) if not (is_plane[g1] and is_plane[g2]) else -1 for g1, g2 in pairs]
    rank_keys = np.unique(np.array([key(g1, g2) for g1, g2 in pair_geoms] + [k for _, k in plane_geoms]
                                   + [k for k in explicit_keys if k >= 0], np.int64))

    def rank(k):
        return int(np.searchsorted(rank_keys, k)) if k >= 0 else -1

    body_pairs = np.array(body_pairs, np.int64).reshape(-1, 2)
    return _lanes.pack_lanes(
        L, len(planes), body_pairs=body_pairs, row_start=np.searchsorted(body_pairs[:, 0], np.arange(L + 1)),
        pair_gstart=pair_gstart,
        pair_geoms=np.array([(g1, g2, rank(key(g1, g2))) for g1, g2 in pair_geoms], np.int64).reshape(-1, 3),
        plane_start=plane_start, plane_pos=plane_pos, plane_gstart=plane_gstart,
        plane_geoms=np.array([(g, rank(k)) for g, k in plane_geoms], np.int64).reshape(-1, 2),
        explicit_rank=[rank(k) for k in explicit_keys], rank_keys=rank_keys)
