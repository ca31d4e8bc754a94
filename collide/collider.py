"""`Collider`: broad phase, contacts and batch collision checks of a MuJoCo model (`collide.mujoco.Collider`).

The broad phase is `collide.mujoco.BroadPhase`, unchanged; the narrow phase
(`collide.contacts.narrow_phase`) takes its ``(K, 2)`` pairs and MuJoCo's geom poses
(``data.geom_xpos``, ``data.geom_xmat``), nothing of the broad phase's internals. This module does
not import ``mujoco`` (DESIGN.md's layers): the adapter `collide.mujoco`, imported when a
`Collider` is built, reads the model and checks the data.

`Collider.check_batch` answers "which of these configurations are in collision, and how close is
each to a collision?" for a batch ``qpos (B, nq)`` in one call: the batch broad phase
(`collide.mujoco.BroadPhase.pairs_batch`) gives each configuration's candidate pairs, and
`collide._kernels.check.check_worlds` (threads across configurations, the GIL released) computes
each configuration's poses and decides its pairs, stopping at the first active contact. Without
distances, where the batch broad phase runs the lanes on its own kinematics, the two are one pass
(`collide._kernels.check_lanes.check_lanes_kin`): each group of configurations' candidates decided
as the broad phase finds them, on the body poses it computed (the same answers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from . import contacts as _contacts
from ._fork import new_lock, require_parallel
from ._kernels import check as _kc
from ._kernels import check_lanes as _kl
from ._kernels import check_trees as _kt
from ._validate import _reject_complex

__all__ = ["CheckResult", "Collider"]

# Configurations per call of the broad phase and the check kernel: bounds the broad phase's
# candidate rows held at once (memory), large enough that a call's fixed costs are spread.
BLOCK = 4096
# check_batch's early exit by trees (`collide._kernels.check_trees`): used where its pairs are at most
# TREE_SHARE of the filtered pairs and it decides at least half of the first TREE_SAMPLE
# configurations; a configuration with a coordinate (or a model with a body offset) beyond TREE_QMAX
# in magnitude goes the full way (its poses could overflow, which the full path reports).
TREE_SHARE = 0.5
TREE_SAMPLE = 256
TREE_QMAX = 1e6

# `Collider._check_args`' margin and gap of a pair that never makes an active contact: its contact
# distance (margin + gap, or o_margin + gap) is below any signed distance, and finite.
_NEVER = -1e300

# MuJoCo's mjtSameFrame (tests/test_check.py checks them against the bindings).
_SAME_BODY, _SAME_INERTIA, _SAME_BODYROT, _SAME_INERTIAROT = 1, 2, 3, 4


@dataclass(frozen=True, eq=False)
class CheckResult:
    """Collision checks of a batch of configurations (`collide.mujoco.Collider.check_batch`).

    Attributes
    ----------
    in_collision : (B,) bool
        MuJoCo would make an active contact (``dist < margin``: not in the gap, MuJoCo's
        ``exclude == 0``) between a pair of checked geoms, with its filters, margins, gaps,
        excludes and explicit ``<pair>`` s; a contact only in the gap does not count. Decided as
        `Collider.contacts` decides, up to a tolerance: two convex geoms whose cores GJK finds
        within ``collide._kernels.manifold.CONTACT_TOL`` of their sizes of touching count as active
        (`collide._kernels.check.deepest_contact`). An explicit ``<pair>`` with no degree of
        freedom between its geoms never counts (MuJoCo's ``exclude == 3``), except in a model
        without dofs (``nv == 0``), as in MuJoCo.
    min_distance : (B,) float64 or None
        With ``distance=True``: the signed distance of the closest checked geom pair that
        passes the filters (negative: penetration; no margin subtracted), ``+inf`` when none is
        closer than ``distmax``. None otherwise. Explicit pairs without dofs between their geoms
        are left out, as from ``in_collision``: their distance never changes.
    closest : (B, 2) int32 or None
        With ``distance=True``: that pair, lower id first; ``-1`` where ``min_distance`` is
        ``inf``. None otherwise.
    skipped : (B,) bool
        A pair with a height field or SDF geom (no narrow phase: `collide.Contacts.skipped`)
        was left undecided, and no active contact was found elsewhere: ``in_collision`` may be
        False where MuJoCo would make a contact. With ``distance=True`` also wherever such a
        pair is among the filtered pairs, in collision or not: ``min_distance`` leaves them out.
        Reported, never dropped silently.
    """

    in_collision: np.ndarray
    min_distance: np.ndarray | None
    closest: np.ndarray | None
    skipped: np.ndarray

    def __len__(self) -> int:
        return len(self.in_collision)


def _names_to_ids(model, spec, what: str, count: int) -> np.ndarray:
    # One group of geoms or bodies: ids or names, checked, as an (n,) int64 array.
    arg = "geoms" if what == "geom" else "bodies"  # the argument's name, for the messages
    if isinstance(spec, (str, bytes)) or np.isscalar(spec):
        spec = [spec]
    ids = []
    for x in spec:
        if isinstance(x, str):
            try:
                ids.append(int(getattr(model, what)(x).id))
            except KeyError:
                raise ValueError(f"{arg}: no {what} named {x!r}") from None
        elif isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_)):
            if not 0 <= int(x) < count:
                raise ValueError(f"{arg}: {what} id {int(x)} is out of range [0, {count})")
            ids.append(int(x))
        else:
            raise ValueError(f"{arg}: expected {what} ids or names, got {x!r}")
    if not ids:
        raise ValueError(f"{arg}: an empty group")
    return np.asarray(ids, dtype=np.int64)


def _is_two_groups(spec) -> bool:
    return (isinstance(spec, (tuple, list)) and len(spec) == 2
            and all(not isinstance(x, (str, bytes)) and not np.isscalar(x) for x in spec))


def _subset(model, geoms, bodies) -> tuple[int, np.ndarray]:
    # (mode, label (G,) int8) of the checked subset (`collide._kernels.check.in_subset`).
    G = int(model.ngeom)
    label = np.zeros(G, np.int8)
    if geoms is None and bodies is None:
        return _kc.SUBSET_ALL, label
    if geoms is not None and bodies is not None:
        raise ValueError("geoms, bodies: give one of them, not both")
    spec, what = (geoms, "geom") if geoms is not None else (bodies, "body")
    count = G if what == "geom" else int(model.nbody)
    groups = list(spec) if _is_two_groups(spec) else [spec]
    geom_body = np.asarray(model.geom_bodyid, dtype=np.int64)
    for i, grp in enumerate(groups):
        ids = _names_to_ids(model, grp, what, count)
        member = np.zeros(G, bool)
        if what == "geom":
            member[ids] = True
        else:
            member = np.isin(geom_body, ids)
        label[member] |= np.int8(1 << i)
    return (_kc.SUBSET_TWO if len(groups) == 2 else _kc.SUBSET_ONE), label


def _geom_frames(model) -> tuple[np.ndarray, np.ndarray]:
    # Each geom's frame in its body's as mj_kinematics places it: (G, 3) positions, (G, 4) unit
    # quaternions; geom_sameframe applied (`collide.mujoco.geom_frames`, as quaternions: the
    # kernel composes them with the body's as mj_local2Global does).
    pos = np.array(model.geom_pos, dtype=np.float64).reshape(-1, 3)
    quat = np.array(model.geom_quat, dtype=np.float64).reshape(-1, 4)
    sf = np.asarray(model.geom_sameframe)
    bid = np.asarray(model.geom_bodyid)
    ident = np.array([1.0, 0.0, 0.0, 0.0])
    body = sf == _SAME_BODY
    pos[body] = 0.0
    quat[body | (sf == _SAME_BODYROT)] = ident
    inertia = sf == _SAME_INERTIA
    pos[inertia] = np.asarray(model.body_ipos, dtype=np.float64)[bid[inertia]]
    irot = inertia | (sf == _SAME_INERTIAROT)
    quat[irot] = np.asarray(model.body_iquat, dtype=np.float64)[bid[irot]]
    return np.ascontiguousarray(pos), np.ascontiguousarray(quat)


def filtered_pairs(articulation, no_function: np.ndarray | None = None, block: int = 256) -> np.ndarray:
    """Every geom pair that passes an articulation's filters, explicit pairs included.

    Parameters
    ----------
    articulation : collide.Articulation
        Its weld groups, parent rule, ``contype`` / ``conaffinity``, excluded body pairs and
        explicit pairs (planes never pair with planes), as `collide.mujoco.articulation` maps
        MuJoCo's filters.
    no_function : (G,) bool, optional
        Geoms that never collide with each other (MuJoCo's planes and height fields: no
        collision function for them); None: planes only.
    block : int
        Rows of geoms tested at once (bounds the memory: ``block * G`` pairs).

    Returns
    -------
    (P, 2) int32
        Lower id first, sorted, unique.
    """
    art = articulation
    G, L = art.geom_count, art.body_count
    nf = art.geom_is_plane if no_function is None else (np.asarray(no_function, bool) | art.geom_is_plane)
    excl = np.sort(art.exclude[:, 0] * L + art.exclude[:, 1]) if len(art.exclude) else np.zeros(0, np.int64)
    expl = np.sort(art.pairs[:, 0] * G + art.pairs[:, 1]) if len(art.pairs) else np.zeros(0, np.int64)
    body, weld, par = art.geom_body, art.body_weld, art.body_parent
    ct, ca = art.geom_contype, art.geom_conaffinity
    out = []
    every = np.arange(G, dtype=np.int64)
    for s in range(0, G, block):
        rows = every[s:s + block]
        g1 = np.repeat(rows, G)
        g2 = np.tile(every, len(rows))
        upper = g2 > g1
        g1, g2 = g1[upper], g2[upper]
        b1, b2 = body[g1], body[g2]
        ok = weld[b1] != weld[b2]
        if art.filter_parent:
            ok &= ~((par[b1] == b2) & (b2 != 0)) & ~((par[b2] == b1) & (b1 != 0))
        ok &= ((ct[g1] & ca[g2]) != 0) | ((ct[g2] & ca[g1]) != 0)
        ok &= ~(nf[g1] & nf[g2])
        if len(excl):
            ok &= ~np.isin(np.minimum(b1, b2) * L + np.maximum(b1, b2), excl, assume_unique=False)
        if len(expl):
            ok &= ~np.isin(g1 * G + g2, expl)
        out.append(np.stack([g1[ok], g2[ok]], axis=1))
    if len(art.pairs):
        p = np.sort(art.pairs, axis=1)
        out.append(p[~(nf[p[:, 0]] & nf[p[:, 1]])])
    pairs = np.concatenate(out) if out else np.zeros((0, 2), np.int64)
    pairs = np.unique(pairs, axis=0) if len(pairs) else pairs.reshape(0, 2)
    return np.ascontiguousarray(pairs, dtype=np.int32)


class Collider:
    """Contacts of a MuJoCo model at the poses of an ``MjData``.

    Parameters
    ----------
    model : mujoco.MjModel
        Read once (geometry, filters, margins, gaps, flags): build a new Collider after
        changing them.
    coherent : bool, default True
        Passed to `collide.mujoco.BroadPhase`.
    geoms, bodies : optional
        The pairs `check_batch` checks (not `pairs` or `contacts`, which stay the model's): a
        group of geom (or body) ids or names, for the pairs inside it (say a robot's
        self-collisions), or a tuple of two groups, for the pairs with one geom in each (say
        the robot against the world). A body stands for its geoms. One of the two at most.
        Chosen here, once: each call only tests a label per geom.

    Attributes
    ----------
    broadphase : collide.mujoco.BroadPhase
    table : collide.contacts.GeomTable

    Examples
    --------
    >>> import mujoco, collide.mujoco as cm
    >>> m = mujoco.MjModel.from_xml_string(
    ...     '<mujoco><worldbody><geom type="plane" size="1 1 1"/>'
    ...     '<body pos="0 0 0.09"><freejoint/><geom type="sphere" size="0.1"/></body>'
    ...     '</worldbody></mujoco>')
    >>> d = mujoco.MjData(m); mujoco.mj_forward(m, d)
    >>> c = cm.Collider(m).contacts(d)
    >>> c.geom.tolist(), [round(float(x), 12) for x in c.dist]
    ([[0, 1]], [-0.01])
    """

    def __init__(self, model, coherent: bool = True, geoms=None, bodies=None):
        from .mujoco import BroadPhase  # the adapter imports this module: not at import time

        self.broadphase = BroadPhase(model, coherent)
        self.model = model
        self.table = _contacts.GeomTable(model)
        # (the last MjData checked, its geom_xpos, geom_xmat as (G, 3), (G, 3, 3) views): one
        # tuple in one store, read once, so that a thread never pairs one MjData with another's
        # views (two stores did: tests/test_collider_threads.py). An MjData's arrays never move.
        self._posed = (None, None)
        self._subset_spec = (geoms, bodies)
        self._subset_mode, self._subset_label = _subset(model, geoms, bodies)
        # check_batch's model arrays: the kinematic tree's float arrays are views of the model's,
        # as the batch broad phase's are (`collide.mujoco.kinematic_tree`): a body pose or qpos0
        # changed in place reaches both alike, as it reaches mj_kinematics (a copy here once let
        # the narrow phase decide the broad phase's pairs at the old poses); the geom frames are
        # read here, once, as the broad phase and the geom table read the geometry
        self._check_setup = None
        self._geom_setup = (np.ascontiguousarray(model.geom_bodyid, dtype=np.int64),) + _geom_frames(model)
        self._distance_pairs = None  # check_batch's filtered pairs (distance=True), likewise
        self._tree_pairs = None  # check_batch's early exit by trees (`_trees`), likewise
        self._no_function = None  # (G,) bool: the broad phase's geoms that never pair (`_in_lanes`), likewise
        self._args = None  # the check kernels' table arguments (`_check_args`), likewise
        self._setup_lock = new_lock(self, "_setup_lock")  # a free one in a forked child

    def __repr__(self) -> str:
        return f"collide.mujoco.Collider({self.model.nbody} bodies, {self.model.ngeom} geoms)"

    def __reduce__(self):
        return (Collider, (self.model, self.broadphase.broadphase.coherent) + self._subset_spec)

    def pairs(self, data) -> np.ndarray:
        """Candidate geom pairs: `collide.mujoco.BroadPhase.pairs` (``(K, 2) int32``, read-only)."""
        return self.broadphase.pairs(data)

    def pairs_swept(self, data0, data1) -> np.ndarray:
        """Candidate geom pairs at some time of the step from ``data0`` to ``data1``:
        `collide.mujoco.BroadPhase.pairs_swept` (``(K, 2) int32``)."""
        return self.broadphase.pairs_swept(data0, data1)

    def _poses(self, data) -> tuple[np.ndarray, np.ndarray]:
        # The geom poses of data as the kernel takes them, (G, 3) and (G, 3, 3) views: an MjData's
        # arrays never move, and the bindings build new views at every attribute access, so the
        # last MjData's are kept (checked once).
        posed = self._posed
        if posed[0] is not data:
            self.broadphase._check_data(data)
            posed = (data, _contacts._poses(self.table, data.geom_xpos, data.geom_xmat))
            self._posed = posed
        return posed[1]

    def contacts(self, data) -> _contacts.Contacts:
        """Contacts at the poses of ``data`` (after ``mj_kinematics``, ``mj_forward`` or a step).

        Parameters
        ----------
        data : mujoco.MjData
            Its body poses (the broad phase) and ``geom_xpos`` ``(G, 3)``, ``geom_xmat``
            ``(G, 9)`` (the narrow phase) are read.

        Returns
        -------
        collide.Contacts
            Its arrays are views of rows that later calls never write again (a result may be
            kept; see `collide.Contacts`); a call without contacts returns the same empty one.
            Several contacts a pair for face contacts, as MuJoCo 4 makes them (box-box up to 8,
            box and mesh faces and a plane against a box, mesh, capsule or cylinder up to 4), one
            otherwise; pairs with a height field or SDF geom in ``skipped``. Where MuJoCo makes
            more than one for another pair (two for a capsule parallel to a capsule or along a
            box face; several for a cylinder's rim or face against a box), ours is one contact,
            at that pair's deepest point (its ``dist`` is MuJoCo's deepest).

        Raises
        ------
        ValueError
            ``data`` of another model, or a pose refused (naming the body or geom): non-finite, or
            a rotation in ``geom_xmat`` not proper orthonormal (as `collide.contacts.narrow_phase`).
        """
        pairs = self.broadphase.pairs(data)  # checks data on its first use
        posed = self._posed
        xpos, xmat = posed[1] if posed[0] is data else self._poses(data)
        # the broad phase's pairs are int32, C-contiguous, in range, lower first: not checked again
        return _contacts._contacts_of(self.table, pairs, xpos, xmat)

    def geom_distance(self, data, g1: int, g2: int, distmax: float) -> tuple[float, np.ndarray]:
        """Signed distance of geoms ``g1`` and ``g2``, like ``mujoco.mj_geomDistance``.

        Parameters
        ----------
        data : mujoco.MjData
        g1, g2 : int
        distmax : float

        Returns
        -------
        dist : float
            ``min(signed distance, distmax)`` (the exact distance: no margins are involved).
        fromto : (6,) float64
            Nearest point on ``g1`` then on ``g2``, world frame, when ``dist < distmax``; else zeros.

        Raises
        ------
        ValueError
            As `collide.contacts.geom_distance`: a bad id, a height field or SDF geom, a geom
            outside the narrow phase's sizes, a non-finite pose or ``distmax``, a rotation not
            proper orthonormal.
        """
        xpos, xmat = self._poses(data)
        g1, g2, distmax = _contacts._distance_args(self.table, g1, g2, distmax)
        try:
            return _contacts._geom_distance(self.table, g1, g2, xpos, xmat, distmax)
        except ValueError as exc:
            if not np.any(xmat):  # an MjData never posed: said as `pairs` and `contacts` say it
                raise ValueError("data: geom poses are all zero; run mujoco.mj_kinematics, mj_forward or "
                                 "mj_step on it first") from exc
            raise

    # ------------------------------------------------------------------------------------------
    # Many configurations: check_batch
    # ------------------------------------------------------------------------------------------

    def _setup_check(self) -> tuple:
        # The model arrays check_worlds reads (see __init__), the tree made at the first call.
        setup = self._check_setup
        if setup is None:
            from .mujoco import kinematic_tree

            setup = self._check_setup = kinematic_tree(self.model).arrays + self._geom_setup
        return setup

    def _filtered(self) -> np.ndarray:
        # The pairs min_distance is the minimum over: filtered, in the subset (made once).
        pairs = self._distance_pairs
        if pairs is None:
            with self._setup_lock:
                pairs = self._distance_pairs
                if pairs is None:
                    bp = self.broadphase
                    if bp._disabled:
                        pairs = np.zeros((0, 2), np.int32)
                    else:
                        gtype = self.table.gtype
                        nf = (gtype == _contacts.PLANE) | (gtype == _contacts.HFIELD)
                        pairs = filtered_pairs(bp.articulation, nf)
                        lab, mode = self._subset_label, self._subset_mode
                        if mode == _kc.SUBSET_ONE:
                            pairs = pairs[((lab[pairs[:, 0]] & 1) != 0) & ((lab[pairs[:, 1]] & 1) != 0)]
                        elif mode == _kc.SUBSET_TWO:
                            a, b = lab[pairs[:, 0]], lab[pairs[:, 1]]
                            pairs = pairs[(((a & 1) != 0) & ((b & 2) != 0)) | (((a & 2) != 0) & ((b & 1) != 0))]
                        pairs = pairs[~self._no_dofs(pairs[:, 0], pairs[:, 1])]  # as in_collision (`_no_dofs`)
                        pairs = np.ascontiguousarray(pairs, dtype=np.int32)
                    self._distance_pairs = pairs
        return pairs

    def _no_dofs(self, g1: np.ndarray, g2: np.ndarray) -> np.ndarray:
        # (n,) bool: geom pairs with no degree of freedom between them (their bodies welded to one
        # body, or both to the world or mocap bodies), whose contacts are never active:
        # mj_makeConstraint flags them exclude = 3 ("no dofs": mj_jacDifPair's merged dof chain is
        # empty) and makes no constraint, in every configuration; none in a model without dofs,
        # where it returns before and the contact stays included. MuJoCo 4.0.0, with dense, sparse
        # and automatic Jacobians (tests/test_check.py). Only explicit <pair>s give such contacts
        # (the filters drop the others); found by helper-77's fuzzing, 2026-12-02.
        m = self.model
        if m.nv == 0:
            return np.zeros(len(g1), np.bool_)
        weld = np.asarray(m.body_weldid)[np.asarray(m.geom_bodyid)]  # (G,) each geom's weld body
        fixed = np.asarray(m.body_dofnum)[weld] == 0
        return (weld[g1] == weld[g2]) | (fixed[g1] & fixed[g2])

    def _check_args(self) -> tuple:
        # The narrow phase's table as the check kernels take it (made once): a pair without dofs
        # (`_no_dofs`) gets a contact distance no signed distance reaches (`_NEVER`, finite: no
        # inf - inf below), so it never counts. `contacts` keeps it: mj_collision makes it.
        args = self._args
        if args is None:
            with self._setup_lock:
                args = self._args
                if args is None:
                    t = self.table
                    G = t.cls.shape[0]
                    none = self._no_dofs(t.pair_key // G, t.pair_key % G)
                    if none.any():
                        pm, pg = t.pair_margin.copy(), t.pair_gap.copy()
                        pm[none] = pg[none] = _NEVER
                        args = t.kernel_args(pm, pg)
                    else:
                        args = t._kargs
                    self._args = args
        return args

    def _trees(self):
        # check_trees' static arguments (`_tree_pairs`), made once, or False where that early exit
        # cannot pay: its pairs (inside one tree with joints, or with a static geom) must be at most
        # TREE_SHARE of the filtered pairs, so that most of the broad phase's work (the pairs between trees) is what a decided configuration
        # skips. A single robot among obstacles has every pair there and keeps the full path.
        # Nor where the model's body offsets are so large that poses could overflow: the full
        # path reports what it reports (read once, as the kinematic tree's arrays are).
        got = self._tree_pairs
        if got is None:
            if float(np.abs(self.model.body_pos).max(initial=0.0)) > TREE_QMAX:
                got = False
            else:
                got = _tree_pairs(self.model, self._filtered())
            self._tree_pairs = got
        return got

    def _qpos(self, qpos) -> np.ndarray:
        # (B, nq) float64, C-contiguous, finite: a ValueError naming the configuration otherwise.
        nq = int(self.model.nq)
        _reject_complex(qpos, "qpos")
        try:
            q = np.asarray(qpos)
            if q.dtype.kind not in "bUS":
                q = np.ascontiguousarray(q, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"qpos: cannot be read as a float64 array ({exc})") from None
        if q.dtype.kind in "bUS":  # numpy would read True as 1.0 and "0.5" as 0.5: a mistake here
            raise ValueError(f"qpos: expected numbers, got dtype {q.dtype}")
        if not q.flags.writeable:
            # a read-only array is another numba type: the kernels would compile again for it
            q = q.copy()
        if q.ndim != 2 or q.shape[1] != nq:
            raise ValueError(f"qpos: expected shape (B, {nq}) (one configuration a row, nq = {nq}), got {q.shape}")
        finite = np.isfinite(q).all(axis=1)
        if not finite.all():
            b = int(np.flatnonzero(~finite)[0])
            j = int(np.flatnonzero(~np.isfinite(q[b]))[0])
            raise ValueError(f"qpos: configuration {b} has a non-finite value (NaN or inf) at coordinate {j}")
        return q

    def check_batch(self, qpos, distance: bool = False, distmax: float = math.inf) -> CheckResult:
        """Collision checks of many configurations in one call: which collide, how close each is.

        Per configuration: its body and geom poses as ``mj_kinematics`` computes them, its
        candidate pairs from the batch broad phase (`collide.mujoco.BroadPhase.pairs_batch`),
        and for each candidate in the checked subset (``geoms`` / ``bodies`` of the
        constructor) the deepest contact MuJoCo would make (the rules of `contacts`: margins,
        gaps, explicit ``<pair>`` s, ``mjENBL_OVERRIDE``); the first active contact
        (``dist < margin``) ends the configuration's search. Threads across configurations
        (numba's threading layer, ``numba.set_num_threads``), the GIL released in the kernel.

        Parameters
        ----------
        qpos : (B, nq) array_like of float
            One configuration a row (joint limits are not enforced: configurations outside them
            are checked as they are). Mocap bodies stay at their model poses.
        distance : bool, default False
            Also the closest pair: ``min_distance`` and ``closest``, the minimum over every
            checked pair that passes the filters (near or not) of its signed distance
            (`geom_distance`'s, exact: no margin involved), by branch and bound on bounding balls.
        distmax : float, default inf
            With ``distance``: pairs at or beyond it are not reported (``inf`` and ``-1``
            where none is closer); a smaller one prunes more.

        Returns
        -------
        CheckResult

        Raises
        ------
        ValueError
            ``qpos`` not ``(B, nq)`` numbers, a non-finite value (naming the configuration and
            coordinate), a configuration whose poses come out non-finite (naming it), or a NaN
            ``distmax``. The Collider works as before after it.
        RuntimeError
            In a process forked from one that had run numba's threads on GNU OpenMP, which
            cannot run there: start workers with ``spawn`` or ``forkserver`` (docs/design.md).
        """
        q = self._qpos(qpos)
        if not isinstance(distance, (bool, np.bool_)):
            raise ValueError(f"distance: expected True or False, got {distance!r}")
        try:
            if isinstance(distmax, (bool, np.bool_, str, bytes)):
                raise TypeError
            distmax = float(distmax)
        except (TypeError, ValueError):
            raise ValueError(f"distmax: expected a number, got {distmax!r}") from None
        if math.isnan(distmax):
            raise ValueError("distmax: NaN")
        B = len(q)
        hit = np.zeros(B, np.bool_)
        skipped = np.zeros(B, np.bool_)
        dist = np.full(B, np.inf) if distance else None
        closest = np.full((B, 2), -1, np.int32) if distance else None
        if B == 0:
            return _result(hit, dist, closest, skipped)
        require_parallel()  # not in a child forked from a GNU OpenMP parent (`collide._fork`)
        kin = self._setup_check()
        workers = max(1, numba.get_num_threads())
        kargs = self._check_args()
        rest = None if distance else self._early_trees(q, hit, kin, kargs, workers)
        if rest is None:
            self._full(q, None, hit, skipped, dist, closest, distmax, kin, kargs, workers)
        elif len(rest):  # the configurations the trees left undecided, the full way
            h = np.zeros(len(rest), np.bool_)
            k = np.zeros(len(rest), np.bool_)
            self._full(np.ascontiguousarray(q[rest]), rest, h, k, None, None, distmax, kin, kargs, workers)
            hit[rest] = h
            skipped[rest] = k
        return _result(hit, dist, closest, skipped)

    def _early_trees(self, q, hit, kin, kargs, workers):
        # The early exit by trees (`_kernels.check_trees`): hit[i] set where it decided
        # configuration i; returns the indices left to the full path, or None (all of them: the
        # model's pairs are not worth it, see `_trees`). On a sample first, kept for the rest only
        # where it decided most of the sample: a decided configuration skips the broad phase, an
        # undecided one pays the trees' work on top of it.
        trees = self._trees()
        if not trees:
            return None
        B = len(q)
        n0 = min(B, TREE_SAMPLE)
        self._check_trees(q[:n0], trees, kin, kargs, workers, hit[:n0])
        if 2 * int(np.count_nonzero(hit[:n0])) < n0:
            return np.concatenate([np.flatnonzero(~hit[:n0]), np.arange(n0, B)])
        if B > n0:
            self._check_trees(q[n0:], trees, kin, kargs, workers, hit[n0:])
        return np.flatnonzero(~hit)

    def _check_trees(self, q, trees, kin, kargs, workers, hit) -> None:
        chunks = min(len(q), 16 * workers)
        _kt.check_trees(q, TREE_QMAX, *kin, *trees, chunks, min(workers, chunks), np.zeros(1, np.int64), *kargs, hit)

    def _full(self, q, index, hit, skipped, dist, closest, distmax, kin, kargs, workers) -> None:
        # The broad phase's candidates, then check_worlds, block by block, into hit, skipped and
        # (dist is not None: distances asked) dist, closest; q's row i is the caller's
        # configuration index[i] (None: i), named in an error.
        distance = dist is not None
        B = len(q)
        dpairs = self._filtered() if distance else np.zeros((0, 2), np.int32)
        err = np.zeros(min(B, BLOCK), np.int64)
        scratch_dist = dist if distance else np.empty(0)
        scratch_closest = closest if distance else np.empty((0, 2), np.int32)
        name = (lambda i: i) if index is None else (lambda i: int(index[i]))
        for s in range(0, B, BLOCK):
            qb = q[s:s + BLOCK]
            nb = len(qb)
            e = err[:nb]
            if not distance and self._in_lanes(qb, kin, kargs, hit[s:s + nb], skipped[s:s + nb], e, s, name):
                self._raise_pose(e, s, name)
                continue
            rows = self._candidates(qb, s, name)
            row_start = np.searchsorted(rows[:, 0], np.arange(nb + 1, dtype=np.int32)).astype(np.int64)
            chunks = min(nb, 16 * workers)
            _kc.check_worlds(qb, *kin, rows, row_start, self._subset_mode, self._subset_label, dpairs, distmax,
                             bool(distance), chunks, min(workers, chunks), np.zeros(1, np.int64), *kargs,
                             hit[s:s + nb], scratch_dist[s:s + nb] if distance else scratch_dist,
                             scratch_closest[s:s + nb] if distance else scratch_closest, skipped[s:s + nb], e)
            self._raise_pose(e, s, name)

    @staticmethod
    def _raise_pose(e, first, name) -> None:
        # check_worlds' (or check_lanes_kin's) errors of a block whose first configuration is first.
        if e.any():
            b = int(np.flatnonzero(e)[0])
            g = int(e[b] - _kc.ERR_POSE) // 8
            raise ValueError(f"qpos: configuration {name(first + b)} gives a non-finite pose (NaN or inf) of geom {g}")

    def _in_lanes(self, qb, kin, kargs, hit, skipped, err, first, name) -> bool:
        # check_worlds' answers of the configurations qb, without distances, decided in the batch
        # broad phase's own pass (`_kernels.check_lanes`: no second kinematics, no rows): False
        # (nothing done) where the broad phase does not take the lanes with its own kinematics.
        nf = self._no_function
        if nf is None:
            nfa = self.broadphase._no_function
            nf = self._no_function = np.zeros(int(self.model.ngeom), np.bool_) if nfa is None else \
                np.ascontiguousarray(nfa, dtype=np.bool_)
        try:
            status = self.broadphase._lanes_joints(qb, _kl.check_lanes_kin, kin[10:13] + (
                nf, self._subset_mode, self._subset_label) + kargs + (hit, skipped, err))
        except ValueError:
            self._candidates(qb, first, name)  # names the configuration the broad phase refuses
            raise
        return status is not None

    def _candidates(self, qb: np.ndarray, first: int, name=lambda i: i) -> np.ndarray:
        # The batch broad phase's (world, g1, g2) rows of these configurations; a pose it refuses
        # is traced to the configuration (one at a time: only on that error path).
        try:
            rows = self.broadphase.pairs_batch(self.model, qb)
        except ValueError:
            for i in range(len(qb)):
                try:
                    self.broadphase.pairs_batch(self.model, qb[i:i + 1])
                except ValueError as exc:
                    raise ValueError(f"qpos: configuration {name(first + i)} gives a pose the broad phase refuses "
                                     f"({exc})") from None
            raise
        return np.ascontiguousarray(rows, dtype=np.int32).reshape(-1, 3)


def _tree_pairs(model, pairs: np.ndarray):
    """`collide._kernels.check_trees`' static arguments, or False where its early exit cannot pay.

    Parameters
    ----------
    model : mujoco.MjModel
    pairs : (P, 2) int32
        The filtered geom pairs of the checked subset (`Collider._filtered`).

    Returns
    -------
    tuple or False
        ``(static_span (S, 2) int64, static_geom (Gs,) int32, tree_span (T, 4) int64,
        tree_geom (Gt,) int32, tree_geom_start (T + 1,) int64, tpairs (K, 2) int32,
        tpair_start (T + 1,) int64)``: the body spans of the trees without joints and their
        geoms (with the world body's) in the pairs, the body and joint spans of the trees with
        joints and their geoms in the pairs, and the pairs inside one of those trees (or with a
        static geom), grouped by tree. False when fewer than two trees have
        joints, a tree's bodies or joints are not contiguous, or those pairs are more than
        `TREE_SHARE` of ``pairs``.
    """
    root = np.asarray(model.body_rootid, np.int64)
    roots = np.unique(root[1:])
    jnt_body = np.asarray(model.jnt_bodyid, np.int64)
    static, trees = [], []
    group = np.full(model.nbody, -1, np.int64)  # a body's tree with joints (-1: none)
    for r in roots:
        bodies = np.flatnonzero(root == r)
        if bodies[0] != r or bodies[-1] - r + 1 != len(bodies):
            return False
        lo, hi = int(r), int(r) + len(bodies)
        joints = np.flatnonzero((jnt_body >= lo) & (jnt_body < hi))
        if len(joints) == 0:
            static.append((lo, hi))
            continue
        if joints[-1] - joints[0] + 1 != len(joints):
            return False
        group[lo:hi] = len(trees)
        trees.append((lo, hi, int(joints[0]), int(joints[-1]) + 1))
    if len(trees) < 2 or len(pairs) == 0:
        return False
    gt = group[np.asarray(model.geom_bodyid, np.int64)]
    t1, t2 = gt[pairs[:, 0]], gt[pairs[:, 1]]
    own = np.where(t1 >= 0, t1, t2)
    keep = ((t1 == t2) & (t1 >= 0)) | ((t1 < 0) != (t2 < 0))
    if np.count_nonzero(keep) > TREE_SHARE * len(pairs):
        return False
    order = np.argsort(own[keep], kind="stable")
    tpairs = np.ascontiguousarray(pairs[keep][order], dtype=np.int32)
    start = np.searchsorted(own[keep][order], np.arange(len(trees) + 1)).astype(np.int64)
    geoms = np.unique(tpairs)
    gtree = gt[geoms]
    tgeom = np.ascontiguousarray(geoms[gtree >= 0][np.argsort(gtree[gtree >= 0], kind="stable")], dtype=np.int32)
    tgeom_start = np.searchsorted(np.sort(gtree[gtree >= 0]), np.arange(len(trees) + 1)).astype(np.int64)
    sgeom = np.ascontiguousarray(geoms[gtree < 0], dtype=np.int32)
    return (np.array(static, np.int64).reshape(-1, 2), sgeom, np.array(trees, np.int64).reshape(-1, 4), tgeom,
            tgeom_start, tpairs, start)


def _result(hit, dist, closest, skipped) -> CheckResult:
    return CheckResult(in_collision=hit, min_distance=dist, closest=closest, skipped=skipped)
