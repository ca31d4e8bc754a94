"""`BroadPhase` on a MuJoCo model: ``MjData`` in, candidate geom pairs out; many configurations
of a model in one call (`BroadPhase.pairs_batch`)."""

from __future__ import annotations

import mujoco
import numpy as np

from .._kernels.step import RET_SAME as _RET_SAME
from .._validate import as_array
from ..broadphase import BroadPhase as _BroadPhase
from ._model import _GEOM, _contacts_disabled, _model_mismatch, articulation
from ._kinematics import kinematic_tree, kinematics_batch

__all__ = ["BroadPhase"]

_NOT_BOUND = object()


class BroadPhase:
    """Our broad phase on a MuJoCo model: ``MjData`` in, candidate geom pairs out.

    Parameters
    ----------
    model : mujoco.MjModel
        Read once, here: geometry, filter rules and flags (``mjDSBL_CONTACT``,
        ``mjDSBL_CONSTRAINT``, ``mjDSBL_FILTERPARENT``, ``mjENBL_OVERRIDE``). Build a new
        BroadPhase after changing them (reading ``model.opt`` through the bindings is slow per call).
    coherent : bool, default True
        Keep the body pairs of fat boxes between steps (`collide.BroadPhase`'s ``coherent``):
        the same pairs, less time in a simulation loop; no effect on a model of at most 64
        positions (no tree is walked there).

    Attributes
    ----------
    articulation : Articulation
    broadphase : collide.BroadPhase

    Notes
    -----
    As `collide.BroadPhase`: calls from several threads are safe and take turns (one lock per
    instance); ``copy.copy`` gives another thread an instance of its own.
    """

    def __init__(self, model: mujoco.MjModel, coherent: bool = True):
        self.model = model
        self.articulation = articulation(model)
        self.broadphase = _BroadPhase(self.articulation, coherent)
        self._empty2 = np.zeros((0, 2), dtype=np.int32)
        self._empty2.flags.writeable = False
        self._empty3 = np.zeros((0, 3), dtype=np.int32)
        self._disabled = _contacts_disabled(model)
        self._views_of = _NOT_BOUND  # the MjData whose arrays are bound (none yet; None is not an MjData)
        self._views = None
        self._swept_views = []  # pairs_swept: (data, xpos, xmat as (nbody, 3, 3)) of the last MjData checked there
        self._tree = (None, None)  # (MjModel, its kinematic_tree): pairs_batch's, see there
        # MuJoCo has no collision function for plane-hfield and hfield-hfield (mjCOLLISIONFUNC
        # is NULL there): such pairs never make contacts and are removed after the kernel.
        types = np.asarray(model.geom_type)
        self._no_function = None
        self._null = (None, None)  # _drop_null's last input and output (pairs()), one tuple: one store
        if np.any(types == _GEOM.mjGEOM_HFIELD):
            self._no_function = (types == _GEOM.mjGEOM_HFIELD) | (types == _GEOM.mjGEOM_PLANE)

    def __repr__(self) -> str:
        return (f"collide.mujoco.BroadPhase({self.model.nbody} bodies, {self.model.ngeom} geoms"
                f"{'' if self.broadphase.coherent else ', coherent=False'})")

    def __reduce__(self):
        # Rebuilt from the model (see collide.BroadPhase.__reduce__): the kernel's context holds
        # raw addresses of this object's buffers and of the last MjData's arrays.
        return (BroadPhase, (self.model, self.broadphase.coherent))

    def _drop_null(self, pairs: np.ndarray, first: int) -> np.ndarray:
        if self._no_function is None or len(pairs) == 0:
            return pairs
        held, out = self._null
        if first == 0 and pairs is held:  # pairs() handed out its last result again
            return out
        nf = self._no_function
        out = pairs[~(nf[pairs[:, first]] & nf[pairs[:, first + 1]])]
        if first == 0:  # pairs(): read-only, and the same array again while its input is
            out.flags.writeable = False
            self._null = (pairs, out)  # another thread sees both or neither
        return out

    @property
    def stats(self):
        """Counters of the last call (see `collide.BroadPhase.stats`)."""
        return self.broadphase.stats

    def pairs(self, data: mujoco.MjData) -> np.ndarray:
        """Candidate geom pairs at the poses of ``data`` (after ``mj_kinematics`` or a step).

        Parameters
        ----------
        data : mujoco.MjData
            Its ``xpos`` ``(nbody, 3)`` and ``xmat`` ``(nbody, 9)`` are read.

        Returns
        -------
        pairs : (K, 2) int32, read-only
            Geom ids, lower first, rows sorted and unique; rows never written again, and the last
            non-empty call's array again when its pairs are the same, as in
            `collide.BroadPhase.pairs`.
        """
        bp = self.broadphase
        lock = bp._lock  # one call at a time per instance (collide.BroadPhase.pairs)
        lock.acquire()
        try:
            if data is not self._views_of or bp._bound is not self._views:
                self._check_data(data)  # once per MjData (here, where its arrays are bound), not per step
                if self._disabled:
                    return self._empty2
                # The bindings build new numpy views at every attribute access (a cost per call), and
                # an MjData's arrays never move: bind the last MjData's views to the kernel's context
                # (held there, so they stay valid), and each step is a call with one argument. Bound
                # again if someone bound other arrays to self.broadphase in between.
                bp._bind(data.xpos, data.xmat.reshape(-1, 3, 3))
                self._views_of = data
                self._views = bp._bound
            # BroadPhase.pairs() on the bound arrays, written out: one Python call less on the fast path.
            # Through bind + pairs (public) instead, the small models' calls were measurably slower
            # (tests/bench/ab.py; issue 42's note has the figures): this stays, and its bookkeeping
            # must follow BroadPhase.pairs'.
            k = bp._step_bound(bp._ctx_addr)
            if k < 0:  # a bad pose raises; full buffers are grown and the step rerun
                try:
                    k = bp._rerun(*bp._bound, k)
                except ValueError as exc:
                    if not np.any(bp._bound[1]):
                        raise ValueError("data: body poses are all zero; run mujoco.mj_kinematics, "
                                         "mj_forward or mj_step on it first") from exc
                    raise
            if k >= _RET_SAME:  # the pairs of the last non-empty result: its array again
                out = bp._last
            elif k == 0:
                return self._empty2
            else:
                o = bp._arena_used  # BroadPhase._take, written out
                e = o + k
                if e <= bp._arena_rows:
                    bp._arena_used = e
                    out = bp._last = bp._arena[o:e]
                else:
                    out = bp._take(k)
            return out if self._no_function is None else self._drop_null(out, 0)
        finally:
            lock.release()

    def world_bounds(self, data: mujoco.MjData, of: str = "geoms", inflate: bool = True):
        """World bounds of every geom (or body) at the poses of ``data``.

        `collide.BroadPhase.world_bounds` on ``data.xpos`` and ``data.xmat``; rows by MuJoCo geom
        (or body) id. Inflated geoms are grown by `geom_inflation` (margin + gap +
        ``opt.ccd_tolerance``, times ``1 + MARGIN_SLACK``: `Articulation.geom_bound_margin`); an
        explicit ``<pair>`` is tested with its own inflation instead.

        Returns
        -------
        collide.broadphase.WorldBounds
        """
        self._check_data(data)
        try:
            return self.broadphase.world_bounds(data.xpos, data.xmat.reshape(-1, 3, 3), of, inflate)
        except ValueError as exc:
            # a pose error (the arguments are checked first) on an MjData never moved
            if str(exc).startswith("body ") and not np.any(data.xmat):
                raise ValueError("data: body poses are all zero; run mujoco.mj_kinematics, mj_forward or mj_step "
                                 "on it first") from exc
            raise

    def _check_data(self, data) -> None:
        # An MjData of this model (checked where pairs() binds its arrays, and by world_bounds).
        if not isinstance(data, mujoco.MjData):
            raise ValueError(f"data: expected a mujoco.MjData, got {type(data).__name__}")
        if data.xpos.shape[0] != self.model.nbody:
            raise ValueError(f"data: made for a model with {data.xpos.shape[0]} bodies, this broad phase's "
                             f"has {self.model.nbody}")
        diff = _model_mismatch(self.model, getattr(data, "model", self.model))
        if diff is not None:
            raise ValueError(f"data: made for another model than this broad phase's ({diff}); "
                             "build a BroadPhase of that model")

    def pairs_batch(self, model: mujoco.MjModel, qpos) -> np.ndarray:
        """Candidate pairs of many configurations: kinematics per world, one batched call.

        Parameters
        ----------
        model : mujoco.MjModel
            The model this broad phase was built from.
        qpos : (B, nq) array_like of float
            One configuration per world (mocap bodies stay at their model poses).

        Returns
        -------
        pairs : (K, 3) int32
            ``(world, geom1, geom2)`` rows, sorted: those of `kinematics_batch` followed by
            `collide.BroadPhase.pairs_batch`, from one call,
            `collide.BroadPhase.pairs_batch_joints` on the model's `kinematic_tree` (on a model
            the lanes run, each thread computes a group's poses in its own workspace just before
            testing them, none of the batch's poses written out). A subclass that overrides the
            `kinematics_batch` method gets the two calls.
        """
        if not isinstance(model, mujoco.MjModel):
            raise ValueError(f"model: expected a mujoco.MjModel, got {type(model).__name__}")
        diff = _model_mismatch(self.model, model)
        if diff is not None:
            raise ValueError(f"model: not the model this BroadPhase was built from ({diff})")
        if self._disabled:
            as_array(qpos, "qpos", (None, model.nq))  # a bad qpos is refused all the same
            return self._empty3
        if type(self).kinematics_batch is not BroadPhase.kinematics_batch:  # kinematics of one's own
            out = self.broadphase.pairs_batch(*self.kinematics_batch(model, as_array(qpos, "qpos", (None, model.nq))))
        else:
            out = self.broadphase.pairs_batch_joints(self._model_tree(model), qpos)
        return out if self._no_function is None else self._drop_null(out, 1)

    def _model_tree(self, model: mujoco.MjModel):
        # The model's tree (`kinematic_tree`: views of its float arrays), made once per MjModel
        # and held with it (an id could be reused): the model's buffers never move, so the views
        # see every change made to them in place, as mj_kinematics would. Made afresh, it would
        # add ten binding accesses and the tree's checks to every call.
        held, tree = self._tree
        if model is not held:
            tree = kinematic_tree(model)
            self._tree = (model, tree)  # one store: another thread sees both or neither
        return tree

    def _lanes_joints(self, qpos: np.ndarray, kernel, extra: tuple):
        """``kernel`` (`collide._kernels.check_lanes.check_lanes_kin`'s signature: that of
        `collide._kernels.kinematics.step_lanes_kin`, then ``extra``) run as `pairs_batch` runs the
        lanes on ``qpos`` (``(B, nq)`` float64, C-contiguous, finite: not checked here), this
        model's: its status, or None where `pairs_batch` would not take that path (a subclass's
        own `kinematics_batch`, contacts disabled, the world-by-world path). Raises
        `pairs_batch`'s ValueError on a pose the broad phase refuses (not naming the entry)."""
        bp = self.broadphase
        if (type(self).kinematics_batch is not BroadPhase.kinematics_batch or self._disabled
                or bp.batch_path != "lanes"):
            return None
        return bp._run_batch(len(qpos), bp._batch.joints_launch(self._model_tree(self.model), qpos, kernel, extra))

    def pairs_swept(self, data0: mujoco.MjData, data1: mujoco.MjData) -> np.ndarray:
        """Candidate geom pairs at *some* time between the poses of ``data0`` and ``data1`` (a step).

        `collide.BroadPhase.pairs_swept` on ``xpos`` and ``xmat`` of both, with MuJoCo's filter
        rules, margins and gaps as in `pairs`: every pair `pairs` reports at any time of the
        motion between the two (each body's origin on a line, its rotation at a constant rate).

        Parameters
        ----------
        data0, data1 : mujoco.MjData
            The step's start and end (for instance a copy of ``data`` before ``mj_step``, then
            ``data``), of this broad phase's model.

        Returns
        -------
        pairs : (K, 2) int32
            Geom ids, lower first, rows sorted.
        """
        p0, r0 = self._swept_arrays(data0, "data0")
        p1, r1 = self._swept_arrays(data1, "data1")
        if self._disabled:
            return self._empty2
        try:
            out = self.broadphase.pairs_swept(p0, r0, p1, r1)
        except ValueError as exc:
            for name, d in (("data0", data0), ("data1", data1)):
                if not np.any(d.xmat):
                    raise ValueError(f"{name}: body poses are all zero; run mujoco.mj_kinematics, "
                                     "mj_forward or mj_step on it first") from exc
            raise
        if self._no_function is not None and len(out):
            out = out[~(self._no_function[out[:, 0]] & self._no_function[out[:, 1]])]
        return out

    def _swept_arrays(self, data, name: str):
        # ``xpos`` and ``xmat`` (as (nbody, 3, 3)) of an MjData of this model, named ``name`` in an
        # error. The bindings build new views at every attribute access and an MjData's arrays never
        # move: the views of the last two MjData checked here are kept with them (a loop passes
        # the same two, or its step's start as a new copy each time: then this checks as before).
        for item in self._swept_views:
            if item[0] is data:
                return item[1], item[2]
        try:
            self._check_data(data)
        except ValueError as exc:  # name the argument
            raise ValueError(name + str(exc)[len("data"):]) from None
        item = (data, data.xpos, data.xmat.reshape(-1, 3, 3))
        self._swept_views = [item] + self._swept_views[:1]
        return item[1], item[2]

    def kinematics_batch(self, model: mujoco.MjModel, qpos: np.ndarray):
        """Body poses of each configuration (see the module function `kinematics_batch`)."""
        return kinematics_batch(model, qpos)
