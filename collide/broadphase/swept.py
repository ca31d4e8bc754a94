"""The swept broad phase's Python side: its static tables, made once, and the calls.

`BroadPhase.pairs_swept` and `BroadPhase.pairs_swept_batch` build a `SweptPairs` on first use (a
model that is never swept pays nothing). The kernel and what its answer contains:
`collide._kernels.swept`.
"""

from __future__ import annotations

import numba
import numpy as np

from .._fork import require_parallel
from .._kernels import keys as _keys
from .._kernels import swept as _ks
from . import tables as _tables

__all__ = ["SweptCalls", "SweptPairs"]

# Rows of the static filter's geom pairs examined at once while the bit matrix is made (memory).
_BLOCK = 256
_BAD_SHAPE = _ks.BAD_SHAPE
# Rows of a new output arena (`SweptPairs._new_arena`)
_ARENA_ROWS = 4096
# The fewest solid geoms a sweep group holds on average (`sweep_groups`)
_GROUP_MIN = 4


def allow_bits(filt: _tables.StaticFilter, gstart: np.ndarray, pgeoms: np.ndarray, planes: np.ndarray,
               plane_ok: np.ndarray, G: int) -> np.ndarray:
    """``(G, ceil(G / 64))`` int64: bit ``h`` of row ``g``, word ``w`` set when the geom pair
    ``(g, 64 w + h)`` passes the static filter (`tables.StaticFilter`, its one home): two solid
    geoms at positions that pass, whose own masks pass and that are not an explicit pair; a plane
    and a solid geom whose position the plane's filter row (`tables.plane_filter`) lets through.
    Symmetric."""
    NW = max(1, -(-G // 64))
    bits = np.zeros((G, NW), np.uint64)
    L = len(gstart) - 1
    gpos = np.zeros(G, np.int64)
    gpos[pgeoms] = np.repeat(np.arange(L), np.diff(gstart))

    def put(g1, g2):
        for a, b in ((g1, g2), (g2, g1)):
            np.bitwise_or.at(bits, (a, b >> 6), np.left_shift(np.uint64(1), (b & 63).astype(np.uint64)))

    n = len(pgeoms)
    for i0 in range(0, n, _BLOCK):
        i, j = np.nonzero(np.triu(np.ones((min(_BLOCK, n - i0), n), bool), 1 + i0))
        g1, g2 = pgeoms[i + i0], pgeoms[j]
        ok = filt.bodies(gpos[g1], gpos[g2]) & filt.geoms(g1, g2)
        put(g1[ok], g2[ok])
    for qi, q in enumerate(planes):
        ok = (plane_ok[qi, gpos[pgeoms]] != 0) & filt.geoms(np.full(n, q), pgeoms)
        put(np.full(int(ok.sum()), q, np.int64), pgeoms[ok])
    return bits.view(np.int64)


def sweep_groups(body_parent: np.ndarray, geom_body: np.ndarray, pgeoms: np.ndarray, G: int):
    """The groups of the swept kernel's sweep (`_kernels.swept._sweep_pairs`): the solid geoms
    ``pgeoms`` by the subtree of the world's child they hang from (a robot of a crowd; the world's
    own geoms one more group), or all in one group where the groups would hold fewer than
    ``_GROUP_MIN`` geoms on average (free bodies: a group each would only add work).

    Returns
    -------
    group : (G,) int64
        A solid geom's group (0 for the others).
    gstart : (R + 1,) int64
        Group r's members are ``gstart[r]:gstart[r + 1]`` of a list of the solid geoms by group.
    """
    L = len(body_parent)
    # each body's ancestor among the world's children (the world its own): pointer jumping, a
    # fixed point after log2(depth) rounds
    root = np.where((np.arange(L) == 0) | (body_parent == 0), np.arange(L), body_parent)
    while True:
        up = root[root]
        if np.array_equal(up, root):
            break
        root = up
    group = np.zeros(G, np.int64)
    roots, inverse = np.unique(root[geom_body[pgeoms]], return_inverse=True)
    if len(roots) > 1 and len(pgeoms) >= _GROUP_MIN * len(roots):
        group[pgeoms] = inverse
        counts = np.bincount(inverse, minlength=len(roots))
    else:
        counts = np.array([len(pgeoms)])
    return group, np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


class SweptPairs:
    """The swept pairs of one `BroadPhase`'s model: its tables and one world's workspace.

    Parameters
    ----------
    bp : collide.BroadPhase
        Its model tables (``bp._I``, ``bp._F``) are read, never written.
    """

    def __init__(self, bp):
        a = bp.articulation
        dims, fields, filt = _tables.model_tables(a)
        G, NB = a.geom_count, a.body_count
        planes = fields["planes"]
        group, gstart = sweep_groups(np.asarray(a.body_parent), np.asarray(a.geom_body), fields["pgeoms"], G)
        self.dims = {"G": G, "Gs": len(fields["pgeoms"]), "NB": NB, "Q": len(planes), "NW": max(1, -(-G // 64)),
                     "R": len(gstart) - 1}
        self.key_shift = _keys.key_shift(G)
        allow = allow_bits(filt, fields["gstart"], fields["pgeoms"], planes, fields["plane_ok"], G)
        d = self.dims
        self._X = _ks.XTAB.pack(d, header=(G, d["Gs"], NB, d["Q"], self.key_shift), allow=allow,
                                group=group, gstart=gstart)
        self._I, self._F = bp._I, bp._F
        self._XW = np.zeros(_ks.XWORK.size(d), np.int64)
        self._Y = np.zeros(_ks.YWORK.size(d))
        self._ctx = np.zeros(_ks.NSCTX, np.int64)
        self._set_keys(4 * G + 64)
        self._new_arena(_ARENA_ROWS)
        self._check = bp._check
        self._call = _ks.swept_call()

    def _new_arena(self, rows: int) -> None:
        # The (rows, 2) int32 output arena: each call's rows are written by the kernel into the next
        # free rows and handed out as a view. Rows are never written twice; a full arena is left
        # to the views that hold it (freed with the last of them) and a new one started.
        self._arena = np.empty((rows, 2), np.int32)
        self._arena_rows = rows
        self._arena_used = 0
        self._ctx[_ks.SC_OUT] = self._arena.ctypes.data
        self._ctx[_ks.SC_NOUT] = rows
        self._ctx[_ks.SC_OFF] = 0

    def _set_keys(self, n: int) -> None:
        # The kernel reaches the buffers through self._ctx (addresses): replace one only here.
        self._keys = np.empty(n, np.int64)
        self._nkeys = n
        self._scr = np.empty(_keys.scratch_size(self.dims["G"], n), np.int64)
        self._out = self._keys.view(np.int32).reshape(-1, 2)  # the kernel turns the keys into rows in place
        _ks.context(self._I, self._F, self._X, self._XW, self._Y, self._keys, self._scr, out=self._ctx)

    def _pairs_of(self, keys: np.ndarray) -> np.ndarray:
        S = self.key_shift
        out = np.empty((len(keys), 2), np.int32)
        out[:, 0] = keys >> S
        out[:, 1] = keys & ((1 << S) - 1)
        return out

    def _refuse(self, code: int, pos0, rot0, pos1, rot1, where: str = "") -> None:
        bt = _ks.BAD_POSE - code
        b, t = divmod(int(bt), 2)
        from ._world_bounds import check_pose_values  # the message of a single step's refusal
        pos, rot = (pos0, rot0) if t == 0 else (pos1, rot1)
        check_pose_values(pos, rot, f"{where}{'start' if t == 0 else 'end'} pose, ")  # its first bad body is b
        raise ValueError(f"{where}body {b}: {'start' if t == 0 else 'end'} pose refused")  # not reached

    def _check_end(self, pos, rot, lead: tuple, t: int):
        # `BroadPhase._check`, its message naming the argument (body_pos0 or body_pos1, ...)
        try:
            return self._check(pos, rot, lead)
        except ValueError as exc:
            msg = str(exc)
            for name in ("body_pos", "body_rot"):
                if msg.startswith(name + ":"):
                    msg = f"{name}{t}{msg[len(name):]}"
            raise ValueError(msg) from None

    def pairs(self, pos0, rot0, pos1, rot1) -> np.ndarray:
        """See `BroadPhase.pairs_swept` (the caller holds the lock)."""
        # The kernel checks the shapes; its dispatcher takes only C-contiguous writable float64
        # arrays and raises TypeError for anything else: then the arrays are checked and converted.
        try:
            k = self._call(pos0, rot0, pos1, rot1, self._ctx)
        except TypeError:
            k = _BAD_SHAPE
        if 0 <= k <= self._nkeys:  # (a longer answer did not fit the keys: grown and run again below)
            o = self._arena_used
            e = o + k
            if e <= self._arena_rows:  # the kernel wrote them there and advanced ctx[SC_OFF]
                self._arena_used = e
                return self._arena[o:e]
        if k == _BAD_SHAPE:
            pos0, rot0 = self._check_end(pos0, rot0, (), 0)
            pos1, rot1 = self._check_end(pos1, rot1, (), 1)
            k = self._call(pos0, rot0, pos1, rot1, self._ctx)
        while True:
            if k < 0:
                self._refuse(k, pos0, rot0, pos1, rot1)
            if k <= len(self._keys):
                o = self._arena_used
                e = o + k
                if e <= self._arena_rows:
                    self._arena_used = e
                    return self._arena[o:e]
                out = self._out[:k].copy()  # written over the keys: a new arena for the next calls
                self._new_arena(max(_ARENA_ROWS, 4 * k))
                return out
            self._set_keys(2 * k)
            k = self._call(pos0, rot0, pos1, rot1, self._ctx)

    def pairs_batch(self, pos0, rot0, pos1, rot1) -> np.ndarray:
        """See `BroadPhase.pairs_swept_batch`."""
        NB = self.dims["NB"]
        for name, arr in (("body_pos0", pos0), ("body_pos1", pos1)):
            if not isinstance(arr, np.ndarray) or arr.ndim != 3:
                raise ValueError(f"{name}: expected shape (B, {NB}, 3), got "
                                 f"{getattr(arr, 'shape', type(arr).__name__)}")
        B = pos0.shape[0]
        if pos1.shape[0] != B:
            raise ValueError(f"body_pos1: {pos1.shape[0]} worlds, body_pos0 has {B}")
        pos0, rot0 = self._check_end(pos0, rot0, (B,), 0)
        pos1, rot1 = self._check_end(pos1, rot1, (B,), 1)
        require_parallel()  # not in a child forked from a GNU OpenMP parent (`collide._fork`)
        T = max(1, min(numba.get_num_threads(), B))
        XWs = np.zeros((T, self._XW.size), np.int64)
        Ys = np.zeros((T, self._Y.size))
        counts = np.zeros(B, np.int64)
        none = np.zeros(0, np.int64)
        G = self.dims["G"]
        _ks.swept_batch(pos0, rot0, pos1, rot1, self._I, self._F, self._X, XWs, Ys, np.zeros((T, 1), np.int64),
                        np.empty((T, _keys.scratch_size(G, 0)), np.int64), counts, none, none)
        bad = np.flatnonzero(counts < 0)
        if len(bad):
            w = int(bad[0])
            self._refuse(int(counts[w]), pos0[w], rot0[w], pos1[w], rot1[w], f"world {w}, ")
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        keys = np.empty(max(1, int(offsets[-1])), np.int64)
        if offsets[-1]:
            XWs[:] = 0
            n = max(1, int(counts.max()))
            _ks.swept_batch(pos0, rot0, pos1, rot1, self._I, self._F, self._X, XWs, Ys, np.empty((T, n), np.int64),
                            np.empty((T, _keys.scratch_size(G, n)), np.int64), counts, offsets, keys)
        out = np.empty((int(offsets[-1]), 3), np.int32)
        out[:, 0] = np.repeat(np.arange(B, dtype=np.int32), counts)
        out[:, 1:] = self._pairs_of(keys[:offsets[-1]])
        return out


class SweptCalls:
    """`BroadPhase`'s swept calls (a base class of it: its lock, its tables)."""

    def _swept_pairs(self):
        # The swept broad phase's tables, made on first use (`swept.SweptPairs`); under the lock.
        if getattr(self, "_swept", None) is None:
            self._swept = SweptPairs(self)
        return self._swept

    def pairs_swept(self, body_pos0: np.ndarray, body_rot0: np.ndarray, body_pos1: np.ndarray,
                    body_rot1: np.ndarray) -> np.ndarray:
        """Geom pairs that may touch at *some* time of a step (a continuous broad phase).

        The motion between the two poses is one step at constant velocity: each body's origin on
        the line between its positions, its rotation turning at a constant rate about the fixed
        axis of ``R1 R0ᵀ`` (the angle in ``[0, pi]``; `collide.swept` bounds the same motion).

        Parameters
        ----------
        body_pos0, body_rot0 : (L, 3), (L, 3, 3) float64
            Body poses at the step's start.
        body_pos1, body_rot1 : (L, 3), (L, 3, 3) float64
            And at its end.

        Returns
        -------
        pairs : (K, 2) int32
            Lower id first, rows sorted; the same static filter as `pairs`. They contain every
            pair `pairs` reports at any time of the motion, hence every pair whose geoms touch
            during the step. A view of rows that this broad phase never writes again (later calls
            fill other rows), so it may be kept and modified; its ``base`` is a larger arena,
            freed with the last view that holds it. A plane whose body moves pairs with every geom its filter lets
            through (a fixed plane is tested as a half-space). See `collide._kernels.swept`.

        Raises
        ------
        ValueError
            As `pairs`, naming the pose (``start`` or ``end``) and the body.
        """
        lock = self._lock  # (the lock and the first-use check written out: a call a step)
        lock.acquire()
        try:
            sp = self.__dict__.get("_swept")
            if sp is None:
                sp = self._swept_pairs()
            return sp.pairs(body_pos0, body_rot0, body_pos1, body_rot1)
        finally:
            lock.release()

    def pairs_swept_batch(self, body_pos0: np.ndarray, body_rot0: np.ndarray, body_pos1: np.ndarray,
                          body_rot1: np.ndarray) -> np.ndarray:
        """`pairs_swept` for many worlds at once (threads over worlds).

        Parameters
        ----------
        body_pos0, body_pos1 : (B, L, 3) float64
        body_rot0, body_rot1 : (B, L, 3, 3) float64

        Returns
        -------
        pairs : (K, 3) int32
            Rows ``(world, geom1, geom2)``, sorted; world ``w``'s rows equal
            ``pairs_swept(body_pos0[w], body_rot0[w], body_pos1[w], body_rot1[w])``.

        Raises
        ------
        ValueError
            As `pairs_swept`, naming the first bad world.
        RuntimeError
            In a process forked from one that had run numba's threads on GNU OpenMP, which
            cannot run there: start workers with ``spawn`` or ``forkserver`` (docs/design.md).
        """
        with self._lock:
            return self._swept_pairs().pairs_batch(body_pos0, body_rot0, body_pos1, body_rot1)
