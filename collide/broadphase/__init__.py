"""BroadPhase: body poses in, candidate geom pairs out, every step; one world or many.

All per-step work is one numba kernel call (`collide._kernels.broadphase`); `tables` lays the
`Articulation` out as flat arrays once; this module owns the workspaces and turns the kernel's
status codes into ``ValueError`` s. See the kernel module's docstring for the pipeline: validated poses ->
world OBBs, spheres and AABBs (each OBB's cut to its capsule's) -> subtree AABBs -> culling down
the kinematic tree (a hash grid or sweep-and-prune at nodes with many children) -> body sphere and
OBB tests -> filter -> geoms.

Example
-------
>>> bp = BroadPhase(articulation)
>>> pairs = bp.pairs(data.xpos, data.xmat.reshape(-1, 3, 3))   # (K, 2) int32 geom ids

Batches of a small model (`pairs_batch`) run eight worlds at a time in SIMD lanes
(`_kernels.lanes`). Measurements live in ``tests/bench/*.txt`` and ``docs/performance.md``.

The package, in import order: `tables` lays the articulation out once (positions, the one static
filter and what derives from it); `_kinematics` holds a kinematic tree in MuJoCo's layout
(`KinematicTree`, for `BroadPhase.pairs_batch_joints`); `_world_bounds` the pose rules and the world
bounds in numpy; `_batch` the batch driver (chunks, their buffers, the lanes' or the world-by-world
kernel); this module owns the single world's buffers and the calls. `_kernels.layout` declares every
flat buffer; `_kernels.broadphase` and `_kernels.lanes` are the per-step kernels.

`BroadPhase.world_bounds` returns the world spheres and OBBs the broad phase tests (of geoms or
bodies) and their AABBs, for drawing them, debugging a pair, or feeding another spatial structure.
"""

from __future__ import annotations

import os
import weakref

import numpy as np

from .._fork import new_lock
from .._kernels import broadphase as _k
from .._kernels import culling as _kcull
from .._kernels import keys as _kkeys
from .._kernels import layout as _layout
from .._kernels import step as _kstep
from ..articulation import Articulation
from . import tables as _tables
from ._kinematics import KinematicTree
from ._world_bounds import WorldBounds, check_pose_values, raise_pose_error, world_bounds, world_planes
from ._batch import Batch
from .swept import SweptCalls

__all__ = ["BroadPhase", "KinematicTree", "WorldBounds", "check_pose_values", "world_planes"]

# Every BroadPhase, for a forked child to make each consistent again (the fork of a process with
# threads copies only the forking one). A thread of the parent inside `pairs` at the fork holds the
# lock, and does not exist in the child, whose calls would wait for it forever: `new_lock` gives
# the child a new one. That thread may also have returned from the kernel, which advanced the
# output arena in the context (C_OFF, C_LAST), and not yet updated `_arena_used` and `_last` (the
# kernel holds the GIL, so a fork lands right there more often than not), or have been between
# replacing the buffers and writing their addresses to the context (`_set_buffers`, `_bind`): the
# child would hand out another call's rows, or the kernel write to freed memory. So the child gives
# each its buffers, its context and a fresh arena again, and the swept broad phase's likewise
# (coherent mode keeps nothing across that: its kept list is rebuilt once). Registered at the end
# of `__init__`.
_instances: weakref.WeakSet = weakref.WeakSet()


def _after_fork() -> None:
    for bp in list(_instances):
        try:
            bp._set_buffers(bp._bp.shape[0], bp._keys.size)
            bp._new_arena(bp._arena_rows)
            if bp._bound is not None:
                bp._ctx[_kstep.C_POS] = bp._bound[0].ctypes.data
                bp._ctx[_kstep.C_ROT] = bp._bound[1].ctypes.data
            sp = bp.__dict__.get("_swept")
            if sp is not None:
                sp._set_keys(sp._nkeys)
                sp._new_arena(sp._arena_rows)
        except Exception:  # noqa: BLE001 -- one object's failure must not leave the others stale
            pass


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork)

_STAT_NAMES = ("subtree_tests", "body_aabb_tests", "body_sphere_tests", "body_obb_tests",
               "geom_sphere_tests", "geom_obb_tests", "plane_tests", "pairs", "geom_aabb_tests", "reused")


# Rows of a new output arena (32 KB: below malloc's mmap threshold, so arenas reuse freed heap
# memory instead of faulting fresh pages in); see BroadPhase._new_arena.
ARENA_ROWS = 4096


class BroadPhase(SweptCalls):
    """Per-step broad phase of an `Articulation`.

    Parameters
    ----------
    articulation : Articulation
    coherent : bool, default True
        Frame coherence for `pairs`: keep, from one call to the next, the body pairs whose *fat*
        boxes overlap (each body's AABB grown by 20 % of its largest extent on every side,
        ``_kernels.coherence.FAT_GROW``), and while every body's AABB stays inside its fat box test only those
        pairs' AABBs instead of culling down the tree. The answer is the same whatever the poses
        (any sequence of calls, unrelated poses included); only the time differs: a simulation
        step usually moves every body less than that (the MuJoCo models under moderate random
        controls rebuild the list on few of their steps), and a scene where bodies leave their
        boxes in more than about a third of the calls (22 falling humanoids) is detected and
        culled down the tree again. False: every call culls down the tree. `pairs_batch` never
        keeps a list (its worlds are unrelated). A model of at most 64 positions (bodies, and the
        world's geoms when it has several) has no tree to cull: every statically allowed body pair
        is a bit of a mask made at set-up, and a call tests them all, a row of AABB tests per body
        (cheaper there than keeping a list); ``coherent`` changes nothing.
    batch_path : {"auto", "lanes", "worlds"}, default "auto"
        How batches run (`batch_path`, the property): ``"auto"`` takes the lanes where the model
        fits them; ``"worlds"`` runs world by world whatever the model (to compare the two paths);
        ``"lanes"`` insists on the lanes (``ValueError`` when the model does not fit them).

    Attributes
    ----------
    stats : dict of str to int
        After a call: bounds tests done at each level (``subtree_tests``: AABB tests of tree
        culling and sweep-and-prune, where two leaf bodies' test is their body test;
        ``body_aabb_tests``: body against a non-leaf body in deeper subtrees, and, up to 64
        positions, where no tree is walked, every body pair that passes the static filter and has a
        geom pair whose masks match (explicit pairs aside); ``body_sphere_tests``,
        ``body_obb_tests``, ``geom_aabb_tests``, ``geom_sphere_tests``, ``geom_obb_tests`` (geoms of
        multi-geom bodies, AABB then sphere then OBB), ``plane_tests``) and ``pairs`` out; summed
        over worlds after `pairs_batch`. ``pairs`` is always the sum of the worlds' counts; the
        test counters are those of the path the batch took: small models go through a kernel that
        tests 8 worlds at once (``collide._kernels.lanes``). It counts per world too, but it culls
        differently (each body against the subtrees after it, no sweep, the static pair
        list instead of the parent rule and masks), so its test counts differ from the
        single-world counts summed. ``reused``: 1 when the call took its body pairs from the list
        kept by earlier calls (``coherent``; ``body_aabb_tests`` then counts that list's tests).

    Notes
    -----
    A pair of geoms is reported when their bounds overlap (both spheres, both OBBs and both world
    AABBs -- each the OBB's cut to the capsule's --, each inflated by its geom's margin; see
    `collide.articulation`) and the static filter passes:
    geoms of one weld group never pair, a body never pairs with its parent unless the parent is the
    world (``filter_parent``), excluded body pairs never pair, and the masks must match
    (``(ct1 & ca2) or (ct2 & ca1)``). Explicit pairs bypass the filter and are tested with their
    own inflation. Planes are halfspaces, tested against the other geom's bounds.

    One instance holds one workspace and one output arena, like a ``mujoco.MjData``: calls from
    several threads are safe but take turns (a lock per instance). For threads that should run
    at once, give each its own (``copy.copy(bp)`` builds an independent one from the same
    articulation); `pairs_batch` threads over worlds itself.
    """

    def __init__(self, articulation: Articulation, coherent: bool = True, batch_path: str = "auto"):
        if not isinstance(articulation, Articulation):
            raise ValueError(f"articulation: expected an Articulation, got {type(articulation).__name__}")
        if not isinstance(coherent, (bool, np.bool_)):
            raise ValueError(f"coherent: expected a bool, got {type(coherent).__name__}")
        if batch_path not in ("auto", "lanes", "worlds"):
            raise ValueError(f"batch_path: expected 'auto', 'lanes' or 'worlds', got {batch_path!r}")
        self.coherent = bool(coherent)
        a = self.articulation = articulation
        L, G = a.body_count, a.geom_count
        self.body_count, self.geom_count = L, G
        dims, fields, filt = _tables.model_tables(a)
        self._I, self._F = _k.pack(dims, **fields)
        Lp = dims["L"]
        self.position_count = Lp
        self._nW = _k.workspace_size(self._I)
        self._sap_init = _kcull.sap_state(fields["children"])
        self._W = np.zeros(self._nW)
        self._sap = self._sap_init.copy()
        self._stats = np.zeros(_layout.N_STATS, np.int64)
        self._info = np.zeros(4, np.int64)
        self._ctx = np.zeros(_kstep.NCTX, np.int64)
        self._ctx_addr = self._ctx.ctypes.data  # `_kstep.step_bound`'s argument: never replaced
        self._step_bound = None  # see bind
        self._lock = new_lock(self, "_lock")  # see pairs; a free one in a forked child (`collide._fork`)
        self._bound = None
        self._set_buffers(4 * L + 64, 4 * G + 64)
        self._new_arena(ARENA_ROWS)
        _instances.add(self)  # made consistent again in a forked child (`_after_fork`): built first
        lanes = None
        if batch_path != "worlds":
            lanes = _tables.lane_tables(filt, fields["gstart"], fields["pgeoms"], fields["planes"], fields["plane_ok"],
                                        a.pairs, a.geom_is_plane)
            if lanes is None and batch_path == "lanes":
                raise ValueError("batch_path: 'lanes' takes a model of at most collide._kernels.lanes.MAX_BODY_PAIRS "
                                 "statically passing body pairs; this one has more (use 'auto' or 'worlds')")
        self._batch_path_arg = batch_path
        self._batch = Batch(self._I, self._F, self._sap_init, lanes, L, G, Lp, self._stats)
        self._empty = np.zeros((0, 2), np.int32)
        self._empty.flags.writeable = False

    def _set_buffers(self, body_pairs: int, keys: int) -> None:
        # The kernel reaches every buffer through self._ctx (addresses): replace a buffer only here.
        self._bp = np.empty((max(1, body_pairs), 2), np.int64)
        self._keys = np.empty(max(1, keys), np.int64)
        self._scr = np.empty(_kkeys.scratch_size(self.geom_count, self._keys.size), np.int64)
        self._out = self._keys.view(np.int32).reshape(-1, 2)  # the kernel writes the pairs here
        # the body pairs kept between calls (coherent): bp's shape, so a list always fits bp
        self._cl = np.empty_like(self._bp) if self.coherent else None
        _kstep.context(self._I, self._F, self._W, self._sap, self._bp, self._keys, self._scr, self._stats,
                   self._info, out=self._ctx, cl=self._cl)

    def _check(self, body_pos, body_rot, lead: tuple):
        L = self.body_count
        shape_p, shape_r = lead + (L, 3), lead + (L, 3, 3)
        for name, arr, shape in (("body_pos", body_pos, shape_p), ("body_rot", body_rot, shape_r)):
            if not isinstance(arr, np.ndarray):
                raise ValueError(f"{name}: expected a numpy array of shape {shape}, got {type(arr).__name__}")
            if arr.shape != shape:
                raise ValueError(f"{name}: expected shape {shape}, got {arr.shape}")
            if arr.dtype.kind != "f":
                raise ValueError(f"{name}: expected a float array, got dtype {arr.dtype}")
        # The kernel's signature takes writable arrays only: a read-only one (a memory map, a
        # view of another framework's buffer) is copied, like a float32 or strided one.
        if body_pos.dtype != np.float64 or not body_pos.flags.c_contiguous or not body_pos.flags.writeable:
            body_pos = np.array(body_pos, np.float64, order="C")
        if body_rot.dtype != np.float64 or not body_rot.flags.c_contiguous or not body_rot.flags.writeable:
            body_rot = np.array(body_rot, np.float64, order="C")
        return body_pos, body_rot

    def pairs(self, body_pos: np.ndarray | None = None, body_rot: np.ndarray | None = None) -> np.ndarray:
        """Geom pairs whose bounds may touch, for one world.

        Parameters
        ----------
        body_pos : (L, 3) float64
            Body positions in the world (float32 is accepted and converted). With neither
            argument, or with the very arrays given to `bind`, the bound arrays' current values
            are read where they are.
        body_rot : (L, 3, 3) float64
            Body rotations in the world (body frame to world), proper orthonormal.

        Returns
        -------
        pairs : (K, 2) int32, read-only
            Geom ids, lower id first, rows sorted and unique. A read-only view of rows that this
            broad phase never writes again (later calls fill other rows), so it may be kept; its
            ``base`` is a larger arena, freed with the last view that holds it. When the pairs are
            those of the last call that found any, that call's array is returned again (``is``
            tells): most steps of most robots in a simulation loop, where a new view costs more
            than the test (``tests/bench/reuse.py``).
            Copy it (``np.array(pairs)``) to modify it.

        Raises
        ------
        ValueError
            Wrong shape or dtype, or a pose with a NaN/inf, a position beyond ``1e150``
            (`_kernels.bounds.MAX_POSITION`) or a rotation that is not orthonormal (naming the first offending
            body); the broad phase stays usable.
        """
        # One call at a time per instance (workspace, arena and bookkeeping are shared): a second
        # thread waits here instead of reading rows another call is writing.
        lock = self._lock
        lock.acquire()
        try:
            bound = self._bound
            if (body_pos is None and body_rot is None) or (
                    bound is not None and body_pos is bound[0] and body_rot is bound[1]):
                # the bound arrays' current values (see bind): the kernel's context holds them
                if bound is None:
                    raise ValueError("pairs: no pose arrays given and none bound (see BroadPhase.bind)")
                k = self._step_bound(self._ctx_addr)
                if k < 0:
                    k = self._rerun(*bound, k)
            else:
                # One call. The kernel checks the shapes; its dispatcher takes only C-contiguous
                # float64 arrays and raises TypeError for anything else (no new specialisation).
                try:
                    k = self._step(body_pos, body_rot, self._ctx)
                except TypeError:
                    k = _kstep.RET_BAD_SHAPE
                if k < 0:
                    body_pos, body_rot = self._check(body_pos, body_rot, ())
                    k = self._rerun(body_pos, body_rot, self._step(body_pos, body_rot, self._ctx))
            # The kernel recorded its rows (ctx C_OFF, C_LAST) before returning: _arena_used and _last
            # follow them here, with nothing in between that could raise but an asynchronous exception.
            if k >= _kstep.RET_SAME:  # the pairs of the last non-empty result: its array again
                return self._last
            if k > 0:
                o = self._arena_used  # `_take`, written out: a Python call costs more than these lines
                e = o + k
                if e <= self._arena_rows:
                    self._arena_used = e
                    out = self._last = self._arena[o:e]
                    return out
                return self._take(k)
            return self._empty
        finally:
            lock.release()

    def bind(self, body_pos: np.ndarray, body_rot: np.ndarray) -> None:
        """Read the poses from these arrays at every ``pairs()`` called without arguments.

        For an engine that keeps its body poses in arrays that stay put and are updated in place
        (a ``mujoco.MjData``'s ``xpos`` and ``xmat``, a simulator's preallocated state): the
        kernel keeps their addresses, and each step is one call with one argument (cheaper than
        passing the arrays). They are held here, so they stay alive while bound.

        Parameters
        ----------
        body_pos : (L, 3) float64, C-contiguous
        body_rot : (L, 3, 3) float64, C-contiguous
            No conversion is made: the kernel reads them where they are.

        Raises
        ------
        ValueError
            Wrong shape, dtype or layout.
        """
        with self._lock:
            self._bind(body_pos, body_rot)

    def _bind(self, body_pos: np.ndarray, body_rot: np.ndarray) -> None:
        # `bind`, for a caller holding the lock (`collide.mujoco.BroadPhase.pairs`).
        for name, arr in (("body_pos", body_pos), ("body_rot", body_rot)):
            if isinstance(arr, np.ndarray) and not (arr.dtype == np.float64 and arr.flags.c_contiguous):
                raise ValueError(f"{name}: bind needs a C-contiguous float64 array, got dtype {arr.dtype}"
                                 f"{'' if arr.flags.c_contiguous else ' (not C-contiguous)'}")
        self._check(body_pos, body_rot, ())
        if self._step_bound is None:
            self._step_bound = _kstep.step_bound()
        self._bound = (body_pos, body_rot)
        self._ctx[_kstep.C_POS] = body_pos.ctypes.data
        self._ctx[_kstep.C_ROT] = body_rot.ctypes.data

    def _new_arena(self, rows: int) -> None:
        # The (rows, 2) int32 output arena: each call's pairs are written by the kernel into the next
        # free rows and handed out as a read-only view. Rows are never written twice; a full arena
        # is left to the views that hold it (freed with the last of them) and a new one started.
        # The kernel writes through its address; _take through the writable array itself.
        self._arena_w = np.empty((rows, 2), np.int32)
        self._arena = self._arena_w.view()
        self._arena.flags.writeable = False
        self._arena_rows = rows
        self._arena_used = 0
        self._ctx[_kstep.C_OUT] = self._arena_w.ctypes.data
        self._ctx[_kstep.C_NOUT] = rows
        self._ctx[_kstep.C_OFF] = 0
        self._ctx[_kstep.C_LAST] = -1  # no result in this arena to compare with (see `_kstep._step`)
        self._ctx[_kstep.C_NLAST] = -1
        self._last = None

    def _take(self, k: int) -> np.ndarray:
        # The k > 0 pairs of the step just run, as fresh rows of the arena, recorded as the last
        # result (`_last`: the kernel's RET_SAME hands it out again). The kernel wrote them there
        # when they fitted (and advanced ctx[C_OFF] as this advances _arena_used), else over the
        # keys buffer: then they are copied into a new arena.
        o = self._arena_used
        e = o + k
        if e <= self._arena_rows:
            self._arena_used = e
            out = self._last = self._arena[o:e]
            return out
        self._new_arena(max(ARENA_ROWS, 4 * k))
        self._arena_w[:k] = self._out[:k]
        self._arena_used = k
        self._ctx[_kstep.C_OFF] = k
        self._ctx[_kstep.C_LAST] = 0
        self._ctx[_kstep.C_NLAST] = k
        out = self._last = self._arena[:k]
        return out

    def _step(self, body_pos, body_rot, ctx) -> int:
        # `_kstep._step`, compiled (or loaded from numba's cache) at this object's first
        # `pairs(body_pos, body_rot)`, not at construction: a caller that only binds its arrays
        # (the MuJoCo adapter: `_kstep.step_bound`, compiled at `bind`), batches or checks
        # configurations never compiles it (the test suite's warm-up process, tests/_warmup.py,
        # builds colliders for their batch kernels while the tests compile `_step`). The compiled
        # function then replaces this method on the instance.
        self._step = step = _kstep.step_function()
        return step(body_pos, body_rot, ctx)

    def _rerun(self, body_pos, body_rot, k: int) -> int:
        # A bad pose raises; a full buffer is grown and the step rerun (never drop a pair). The
        # bound arrays are rerun through the bound step (their addresses stay in the context across
        # `_set_buffers`), so that a bound caller never needs `_step` (compiled at its first use).
        info = self._info
        bound = self._bound is not None and body_pos is self._bound[0] and body_rot is self._bound[1]
        while k < 0:
            if k == _kstep.RET_BAD_POSE:
                raise_pose_error(int(info[0]), int(info[1]))
            if info[3] > 0:
                self._set_buffers(2 * int(info[3]), len(self._keys))
            else:
                self._set_buffers(self._bp.shape[0], 2 * int(info[2]))
            k = self._step_bound(self._ctx_addr) if bound else self._step(body_pos, body_rot, self._ctx)
        return k

    def world_bounds(self, body_pos: np.ndarray | None = None, body_rot: np.ndarray | None = None,
                     of: str = "geoms", inflate: bool = True) -> WorldBounds:
        """The world bounds of every geom (or body) at these poses: the spheres and OBBs `pairs`
        tests, their AABBs (cut to the spheres' and the capsules'), and the planes' halfspaces.

        For drawing the bounds, debugging a candidate pair, or feeding another spatial structure.
        Computed in numpy from the articulation's local bounds (not on the per-step path).

        Parameters
        ----------
        body_pos : (L, 3) float64
        body_rot : (L, 3, 3) float64
            As for `pairs`; with neither, the arrays given to `bind`.
        of : {"geoms", "bodies"}
            ``"geoms"``: G rows, by geom id. ``"bodies"``: L rows, by body id, each containing its
            geoms' bounds inflated by their margins (what the tree culls with, except the world
            when it holds two or more solid geoms: the tree takes each of those as a leaf of its
            own; a body without a solid geom is empty: ``aabb_min = inf``, ``aabb_max = -inf``,
            ``sphere_radius`` and ``obb_half = -inf``).
        inflate : bool, default True
            Geoms: inflate each by its margin (radius + margin, half extents + margin, a plane's
            offset + margin: `Articulation.geom_bound_margin`), as `pairs` does for every pair but
            an explicit one with its own ``pair_margin``. Bodies always are.

        Returns
        -------
        WorldBounds
            Planes are unbounded: infinite half extents, radius and AABB, centred on the point of
            their boundary nearest the origin; their halfspace is in ``plane``.

        Raises
        ------
        ValueError
            As `pairs`: wrong shape or dtype, a non-finite pose, a position beyond ``1e150`` or a
            rotation that is not orthonormal (naming the first offending body); ``of`` not one of
            the two.
        """
        if of not in ("geoms", "bodies"):
            raise ValueError(f"of: expected 'geoms' or 'bodies', got {of!r}")
        if not isinstance(inflate, (bool, np.bool_)):
            raise ValueError(f"inflate: expected True or False, got {inflate!r}")
        if body_pos is None and body_rot is None:
            if self._bound is None:
                raise ValueError("world_bounds: no pose arrays given and none bound (see BroadPhase.bind)")
            body_pos, body_rot = self._bound
        body_pos, body_rot = self._check(body_pos, body_rot, ())
        check_pose_values(body_pos, body_rot)
        return world_bounds(self.articulation, body_pos, body_rot, of, inflate)

    @property
    def stats(self) -> dict:
        """Bounds tests at each level and pairs out, of the last call (see the class docstring)."""
        return dict(zip(_STAT_NAMES, (int(v) for v in self._stats)))

    def pairs_batch(self, body_pos: np.ndarray, body_rot: np.ndarray) -> np.ndarray:
        """Geom pairs whose bounds may touch, for many worlds at once (threads over worlds).

        Parameters
        ----------
        body_pos : (B, L, 3) float64
        body_rot : (B, L, 3, 3) float64

        Returns
        -------
        pairs : (K, 3) int32
            Rows ``(world, geom1, geom2)``, geom1 < geom2, sorted; world ``w``'s rows equal
            ``pairs(body_pos[w], body_rot[w])``.

        Raises
        ------
        ValueError
            As `pairs`, naming the first bad world and body.
        RuntimeError
            In a process forked from one that had run numba's threads on GNU OpenMP, which
            cannot run there: start workers with ``spawn`` or ``forkserver`` (docs/design.md).

        Notes
        -----
        `batch_path` says how: eight worlds at a time in SIMD lanes, every test a vector operation
        over the eight (a small model), or world by world; both give exactly the single-world answers.
        Worlds are cut into chunks, which numba's threads take one at a time. On a machine shared
        with other work, set ``OMP_WAIT_POLICY=PASSIVE`` before numba starts its OpenMP runtime:
        spinning waiters can stall each call by a scheduler time slice. The second thread's worth
        (``tests/bench/threads.py``) depends on what the cores did just before: most back to back;
        a big numpy product before each call takes most of it; numpy's OpenBLAS threads, which
        spin on the cores for a while after each product (set ``OPENBLAS_NUM_THREADS=1`` before
        numpy loads where both share a loop), and a pause before each call (an idle core is slow
        to wake) leave the call slower than on one thread.
        """
        if not isinstance(body_pos, np.ndarray) or body_pos.ndim != 3:
            raise ValueError(f"body_pos: expected shape (B, {self.body_count}, 3), got "
                             f"{getattr(body_pos, 'shape', type(body_pos).__name__)}")
        B = body_pos.shape[0]
        body_pos, body_rot = self._check(body_pos, body_rot, (B,))
        return self._run_batch(B, self._batch.poses_launch(body_pos, body_rot))

    def pairs_batch_joints(self, tree: KinematicTree, qpos: np.ndarray) -> np.ndarray:
        """Geom pairs whose bounds may touch, for many joint configurations of a kinematic tree.

        `pairs_batch` on the body poses of `KinematicTree.poses`, in one call: on the lanes' path
        (`batch_path`) each thread computes a group of worlds' poses in its own workspace just
        before testing them (`collide._kernels.kinematics.step_lanes_kin`), none of the batch's
        poses written out; on the worlds' path the poses are computed, then tested.

        Parameters
        ----------
        tree : KinematicTree
            The bodies and joints that pose this broad phase's bodies (body ``b`` of the tree is
            body ``b`` of the articulation).
        qpos : (B, nq) array_like of float
            One configuration per world.

        Returns
        -------
        pairs : (K, 3) int32
            As `pairs_batch` on ``tree.poses(qpos)``, the same rows and `stats` bit for bit.

        Raises
        ------
        ValueError
            A tree of another body count; a ``qpos`` of the wrong shape or with a NaN or inf
            (naming the entry); a pose the broad phase refuses (naming the world and body).
        RuntimeError
            In a process forked from one that had run numba's threads on GNU OpenMP, which
            cannot run there: start workers with ``spawn`` or ``forkserver`` (docs/design.md).
        """
        if not isinstance(tree, KinematicTree):
            raise ValueError(f"tree: expected a collide.broadphase.KinematicTree, got {type(tree).__name__}")
        if tree.body_count != self.body_count:
            raise ValueError(f"tree: has {tree.body_count} bodies, this broad phase's articulation {self.body_count}")
        q = qpos
        lanes = self._batch.lane_tables is not None
        # The float64 C-contiguous (B, nq) array a simulation loop passes goes to the lane kernel
        # unchecked: a NaN or inf in it makes a non-finite body pose, which the kernel refuses, and
        # only then is qpos checked, to name the entry. The full check costs a few per cent of a
        # big batch's call.
        unchecked = (lanes and type(q) is np.ndarray and q.dtype == np.float64 and q.ndim == 2
                     and q.shape[1] == tree.nq and q.flags.c_contiguous)
        if not unchecked:
            q = tree.check_qpos(q)
        if not lanes:
            return self.pairs_batch(*tree._poses(q))
        try:
            return self._run_batch(len(q), self._batch.joints_launch(tree, q))
        except ValueError:
            if unchecked:
                try:
                    tree.check_qpos(q)
                except ValueError as named:  # a non-finite qpos is named as such, alone
                    raise named from None
            raise

    @property
    def batch_path(self) -> str:
        """``"lanes"`` or ``"worlds"``: how `pairs_batch` and `pairs_batch_joints` run.

        ``"lanes"``: eight worlds at a time in SIMD lanes (`collide._kernels.lanes`), for a model of
        at most ``collide._kernels.lanes.MAX_BODY_PAIRS`` statically passing body pairs (a robot, a
        creature, a chain); ``"worlds"``: world by world through the single-world kernel (a bigger
        model, or one built with ``batch_path="worlds"``). Both give exactly the single-world
        answers; the test counters of `stats` differ (see the class docstring).
        """
        return self._batch.path

    def _run_batch(self, B: int, launch) -> np.ndarray:
        # `_batch.Batch.run` under this instance's lock (one call at a time: the buffers are shared).
        with self._lock:
            return self._batch.run(B, launch)

    def __reduce__(self):
        # The kernel's context holds raw addresses of this object's own buffers: a copy sharing or
        # duplicating them would read another object's memory. Copies and pickles are rebuilt from
        # the articulation instead (unbound; see bind).
        return (BroadPhase, (self.articulation, self.coherent, self._batch_path_arg))

    def __repr__(self) -> str:
        return f"BroadPhase({self.articulation!r})"
