"""Measuring MuJoCo against us: its broad-phase timer on a native clock, its broad-phase
candidates, its contacts, and `compare` (the run behind ``python -m collide compare``) with the
contact agreement (`Collider.contacts` against MuJoCo's deepest contact of each geom pair)."""

from __future__ import annotations

import ctypes
import time
import warnings
from dataclasses import dataclass, field

import mujoco
import numba
import numpy as np

from .._kernels import _clock
from .._kernels import manifold as _km
from .._validate import as_count
from ..collider import Collider
from ._model import _geom_name, _model_mismatch
from ._adapter import BroadPhase

__all__ = ["Comparison", "candidate_counter", "compare", "contact_pairs", "mujoco_deepest", "mujoco_timer",
           "timer_clock"]

_TIMER_BROAD = int(mujoco.mjtTimer.mjTIMER_COL_BROAD)

def _native_clock():
    # MuJoCo's timers tick only when mjcb_time is set. A Python callable would add its own call
    # overhead to every interval (a sizeable part of a small model's broad phase), so on Linux we hand it a
    # numba C callback reading clock_gettime(CLOCK_MONOTONIC) (`_kernels._clock`); elsewhere, or if
    # that fails, the portable clock, with a warning: the benchmarks' MuJoCo figures then carry it.
    if _clock.AVAILABLE:
        try:
            @numba.cfunc("float64()", cache=True)
            def now_us():
                return _clock.now_us()

            return ctypes.cast(now_us.address, ctypes.CFUNCTYPE(ctypes.c_double)), now_us
        except Exception as exc:  # pragma: no cover - any failure: the portable clock
            warnings.warn(f"collide.mujoco: no native clock for MuJoCo's timers ({type(exc).__name__}: {exc}); "
                          "timing with a Python callback, which adds its call's overhead to each interval")
    return lambda: time.perf_counter() * 1e6


def timer_clock() -> str:
    """``"native"`` or ``"python"``: the clock `mujoco_timer` hands MuJoCo (for benchmark headers)."""
    global _CLOCK
    if _CLOCK is None:
        _CLOCK = _native_clock()
    return "native" if isinstance(_CLOCK, tuple) else "python"


_CLOCK = None


class mujoco_timer:
    """Context manager: MuJoCo's timers tick (``mjcb_time`` set, in microseconds) inside it."""

    def __enter__(self):
        global _CLOCK
        if _CLOCK is None:
            _CLOCK = _native_clock()
        self._old = mujoco.get_mjcb_time()
        fn = _CLOCK[0] if isinstance(_CLOCK, tuple) else _CLOCK
        mujoco.set_mjcb_time(fn)
        return self

    def __exit__(self, *exc):
        mujoco.set_mjcb_time(self._old)
        return False


class candidate_counter:
    """Context manager counting MuJoCo's broad-phase candidates without changing its result.

    A ``mjcb_contactfilter`` replaces MuJoCo's contype/conaffinity test for every geom pair its
    broad phase and midphase pass on (``filterCollisionPair``); ours counts the call and returns
    the bitmask verdict MuJoCo would have reached, so the simulation is unchanged.

    Attributes
    ----------
    count : int
        Calls since the last `reset`.
    """

    def __init__(self, model: mujoco.MjModel):
        self._contype = [int(v) for v in model.geom_contype]
        self._conaff = [int(v) for v in model.geom_conaffinity]
        self.count = 0

    def reset(self) -> None:
        self.count = 0

    def _filter(self, m, d, g1, g2):
        self.count += 1
        ct, ca = self._contype, self._conaff
        return int(not ((ct[g1] & ca[g2]) or (ct[g2] & ca[g1])))

    def __enter__(self):
        self._old = mujoco.get_mjcb_contactfilter()
        mujoco.set_mjcb_contactfilter(self._filter)
        return self

    def __exit__(self, *exc):
        mujoco.set_mjcb_contactfilter(self._old)
        return False


def contact_pairs(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """MuJoCo's current contacts as geom pairs: ``(K, 2) int32``, lower id first, sorted, unique.

    Contacts involving a flex (geom id -1) are left out: they are not geom pairs.
    """
    if data.ncon == 0:
        return np.zeros((0, 2), dtype=np.int32)
    g = np.sort(np.asarray(data.contact.geom[:data.ncon], dtype=np.int32), axis=1)
    g = g[g[:, 0] >= 0]
    return np.unique(g, axis=0)


_UNSTABLE = [int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                              mujoco.mjtWarning.mjWARN_BADQACC)]


def _unstable_warnings(data: mujoco.MjData) -> tuple:
    return tuple(data.warning[w].number for w in _UNSTABLE)


def _control_range(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    lo = np.full(model.nu, -1.0)
    hi = np.full(model.nu, 1.0)
    limited = np.asarray(model.actuator_ctrllimited, dtype=bool)
    rng = np.asarray(model.actuator_ctrlrange)
    lo[limited], hi[limited] = rng[limited, 0], rng[limited, 1]
    return lo, hi


@dataclass
class Comparison:
    """Per-step record of a comparison run (see `compare`)."""

    model_name: str
    seed: int
    contact_pairs: list = field(default_factory=list)
    candidates: list = field(default_factory=list)
    mujoco_candidates: list = field(default_factory=list)
    time_ours_us: list = field(default_factory=list)
    time_mujoco_broad_us: list = field(default_factory=list)
    missed: list = field(default_factory=list)


def _random_controls(model: mujoco.MjModel, steps: int, seed: int, hold: int) -> np.ndarray:
    # The controls of `compare`, one row per change (every ``hold`` steps), drawn before the runs
    # so that a second run replays the first.
    rng = np.random.default_rng(seed)
    lo, hi = _control_range(model)
    n = -(-steps // hold) if model.nu else 0
    return np.array([np.where(rng.random(model.nu) < 0.5, lo, hi) for _ in range(n)]).reshape(n, model.nu)


def compare(model: mujoco.MjModel, steps: int = 1000, seed: int = 0, name: str = "model",
            broadphase: BroadPhase | None = None, on_step=None, hold: int = 100, contacts: bool = True) -> dict:
    """Simulate ``model`` with random controls; every step, compare MuJoCo's contacts with ours.

    Controls are random and piecewise constant: every ``hold`` steps each actuator is set to
    one end of its control range (or of [-1, 1]), chosen at random. Held extremes drive joints
    to their limits, where self-contacts and floor contacts happen (per-step uniform noise
    averages out: a position-controlled arm such as kuka_iiwa_14 then never touches anything
    in 2000 steps). Each step: ``mj_step``; then, on the state MuJoCo just collided
    (``xpos``/``xmat`` and ``contact`` are left from the same ``mj_forward``, before
    integration), our candidates from `BroadPhase.pairs`, timed. MuJoCo's broad-phase
    candidates are counted in a second run with the same controls, through a contact-filter
    callback that returns MuJoCo's own verdict (in the timed run, its Python calls inside
    ``mj_step`` would evict our code and data from the caches before each of our calls).

    Parameters
    ----------
    model : mujoco.MjModel
    steps : int
        Number of simulation steps, ``>= 1``.
    seed : int
        Seed of the random controls.
    name : str
        Model name for the report.
    broadphase : BroadPhase, optional
        Reused when given (built from ``model`` otherwise).
    on_step : callable, optional
        ``on_step(step, data, candidates)`` after each step (the demo uses it to render).
    hold : int
        Steps between control changes, ``>= 1``.
    contacts : bool, default True
        Also compare contacts: `Collider.contacts` on the states of the counting run (below)
        against MuJoCo's, each geom pair's deepest contact.

    Returns
    -------
    dict
        JSON-ready: ``steps``, ``recall`` (share of MuJoCo contact pairs, over all steps, among
        our candidates; 1.0 when there were none), ``missed`` (list of ``{step, geom1, geom2,
        name1, name2}``), ``contact_pairs_per_step``, ``candidates_per_step``,
        ``mujoco_candidates_per_step`` (lists of ints, one per step; MuJoCo's are the geom
        pairs its broad phase and midphase pass to the contact filter, plus its explicit pairs), ``time_ours_us`` and
        ``time_mujoco_broad_us`` (medians), their ``ratio``, the per-step times
        (``time_ours_us_per_step``, ``time_mujoco_broad_us_per_step``), ``model``, ``seed``,
        ``unstable_resets`` (times MuJoCo reset an unstable simulation; such a step's MuJoCo
        time is that of the broad phase after the reset),
        ``mujoco_count_replayed`` (True when the counting run reproduced every step's contacts),
        ``contact_pairs_total`` (MuJoCo contact pairs summed over the steps),
        ``flex_contacts_total`` (MuJoCo contacts involving a flex, summed over the steps: not geom
        pairs, so left out of the comparison), ``nbody`` and ``ngeom``; ``contacts`` (None without
        ``contacts``): geom pairs in contact by MuJoCo (``mujoco_pairs``), by us (``our_pairs``),
        by both (``matched``), MuJoCo's pairs we made no contact for (``missed``) and ours it
        made none for (``extra``), MuJoCo's pairs ours left out uncollided (``skipped``: a height
        field or SDF geom, `collide.Contacts.skipped`), lists of ``{step, geom1, geom2, name1,
        name2, dist, threshold}`` (``threshold``: the pair's contact distance, margin + gap), and
        how many of each lie within MuJoCo's ``ccd_tolerance`` of it (``missed_near_touching``,
        ``extra_near_touching``, ``tolerance``: its GJK/EPA answers within it); contact
        counts (``mujoco_contacts``, ``our_contacts``); over the matched pairs' deepest contacts,
        the largest and median ``dist`` difference (``dist_error_max``, ``dist_error_median``; the
        pair with the largest, ``dist_error_worst``, with both answers) and
        angle between the normals (``normal_error_max_rad``, ``normal_error_median_rad``: large
        where the normal is not unique, a face on a face).
    """
    steps = as_count(steps, "steps", 1)
    seed = as_count(seed, "seed", 0)
    hold = as_count(hold, "hold", 1)
    bp = broadphase if broadphase is not None else BroadPhase(model)
    if not isinstance(bp, BroadPhase):
        raise ValueError(f"broadphase: expected a collide.mujoco.BroadPhase, got {type(bp).__name__}")
    diff = _model_mismatch(bp.model, model)
    if diff is not None:
        raise ValueError(f"broadphase: built from another model ({diff})")
    rec = Comparison(name, seed)
    perf = time.perf_counter_ns
    # Inside the loop only raw copies are kept: numpy's set routines (np.unique with an axis,
    # np.isin) between two calls made our next call much slower (evicting its code and data),
    # so the recall bookkeeping runs after the loop.
    raw_contacts, raw_candidates = [], []
    ctrls = _random_controls(model, steps, seed, hold)
    # Run 1, timed: MuJoCo's broad-phase timer and our call on the state it just collided.
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    bp.pairs(data)  # compile / warm up (and bind data) outside the timed loop
    timer = data.timer[_TIMER_BROAD]
    resets = 0
    with mujoco_timer():
        for step in range(steps):
            if step % hold == 0 and len(ctrls):
                data.ctrl[:] = ctrls[step // hold]
            dur0, num0, time0, warn0 = timer.duration, timer.number, data.time, _unstable_warnings(data)
            mujoco.mj_step(model, data)
            t0 = perf()
            cand = bp.pairs(data)
            t1 = perf()
            rec.time_ours_us.append((t1 - t0) * 1e-3)
            # An unstable simulation is reset inside mj_step (mj_resetData, then the forward pass
            # again): its time starts over and its timers and warnings restart from zero, so the
            # timer then holds only the intervals after the reset (found 2026-11-22: negative
            # times, and 1 reset reported for 3). A reset shows as time not advancing, or as a
            # new instability warning (the first step's reset).
            if not data.time > time0 or _unstable_warnings(data) != warn0:
                resets += 1
                dur0 = num0 = 0
            rec.time_mujoco_broad_us.append(float(timer.duration - dur0) / max(int(timer.number - num0), 1))
            raw_contacts.append(np.array(data.contact.geom[:data.ncon], dtype=np.int64))
            raw_candidates.append(cand)
            if on_step is not None:
                on_step(step, data, cand)
    # Run 2, the same controls again: MuJoCo's candidates, counted by a contact-filter callback.
    # Not in run 1: the callback runs Python for every candidate inside mj_step, between MuJoCo's
    # timed broad phase and our call, and evicts our kernel's code and data from the caches
    # (hundreds of calls a step on 22_humanoids, our call markedly slower). The callback returns MuJoCo's own
    # verdict, so both runs simulate the same states; `replayed` says whether every step's
    # contacts came out the same.
    replayed = True
    # Explicit pairs never reach the contact filter: MuJoCo tests each of them every step.
    npair = int(model.npair)
    data2 = mujoco.MjData(model)
    mujoco.mj_forward(model, data2)  # as run 1 did
    # Our contacts on the same states (`Collider`), against MuJoCo's: each geom pair's deepest.
    agreement = _ContactAgreement(model) if contacts else None
    with candidate_counter(model) as counter:
        for step in range(steps):
            if step % hold == 0 and len(ctrls):
                data2.ctrl[:] = ctrls[step // hold]
            counter.reset()
            mujoco.mj_step(model, data2)
            rec.mujoco_candidates.append(counter.count + npair)
            if replayed and not np.array_equal(data2.contact.geom[:data2.ncon], raw_contacts[step]):
                replayed = False
            if agreement is not None:
                agreement.add(step, data2)
    ng = np.int64(model.ngeom)
    flex_contacts = 0
    for step, (geoms, cand) in enumerate(zip(raw_contacts, raw_candidates)):
        rec.candidates.append(len(cand))
        geoms = np.sort(geoms, axis=1)
        flex_contacts += int(np.count_nonzero(geoms[:, 0] < 0))
        geoms = geoms[geoms[:, 0] >= 0]  # flex contacts are not geom pairs
        key_c = np.unique(geoms[:, 0] * ng + geoms[:, 1])
        rec.contact_pairs.append(len(key_c))
        if len(key_c):
            key_o = cand[:, 0].astype(np.int64) * ng + cand[:, 1]
            for key in key_c[~np.isin(key_c, key_o)]:
                g1, g2 = divmod(int(key), int(ng))
                rec.missed.append({"step": step, "geom1": g1, "geom2": g2,
                                   "name1": _geom_name(model, g1), "name2": _geom_name(model, g2)})
    total = int(np.sum(rec.contact_pairs))
    t_ours = float(np.median(rec.time_ours_us))
    t_mj = float(np.median(rec.time_mujoco_broad_us))
    return {
        "model": rec.model_name,
        "seed": seed,
        "steps": steps,
        "recall": 1.0 if total == 0 else (total - len(rec.missed)) / total,
        "missed": rec.missed,
        "contact_pairs_total": total,
        "flex_contacts_total": flex_contacts,
        "contact_pairs_per_step": rec.contact_pairs,
        "candidates_per_step": rec.candidates,
        "mujoco_candidates_per_step": rec.mujoco_candidates,
        "time_ours_us": t_ours,
        "time_mujoco_broad_us": t_mj,
        "ratio": t_ours / t_mj if t_mj > 0 else float("inf"),
        "time_ours_us_per_step": rec.time_ours_us,
        "time_mujoco_broad_us_per_step": rec.time_mujoco_broad_us,
        "nbody": int(model.nbody),
        "ngeom": int(model.ngeom),
        "unstable_resets": resets,
        "mujoco_count_replayed": replayed,
        "contacts": agreement.summary() if agreement is not None else None,
    }


def mujoco_deepest(data: mujoco.MjData) -> dict:
    """MuJoCo's deepest contact of each geom pair in ``data.contact`` (flex contacts left out).

    Returns
    -------
    dict
        ``{(g1, g2): (dist, normal, includemargin)}``, ``g1 < g2``, ``normal`` ``(3,) float64``
        from ``g1`` to ``g2`` (``contact.frame[:3]``, turned for that order).
    """
    out: dict = {}
    for i in range(data.ncon):
        c = data.contact[i]
        a, b = int(c.geom[0]), int(c.geom[1])
        if a < 0 or b < 0:
            continue
        n = np.array(c.frame[:3])
        if a > b:
            a, b, n = b, a, -n
        old = out.get((a, b))
        if old is None or c.dist < old[0]:
            out[(a, b)] = (float(c.dist), n, float(c.includemargin))
    return out


class _ContactAgreement:
    # `compare`'s contact check: per step, MuJoCo's deepest contact of each geom pair (flex
    # contacts left out) against ours (`Collider.contacts` on the same MjData).
    def __init__(self, model: mujoco.MjModel):
        self.model = model
        self.collider = Collider(model)
        # MuJoCo's GJK/EPA answers within opt.ccd_tolerance: a pair that near its contact distance may have
        # a contact in one answer and not in the other.
        self.tolerance = max(float(model.opt.ccd_tolerance), 0.0)
        self.mujoco_pairs = self.ours_pairs = self.matched = 0
        self.missed: list = []
        self.skipped: list = []  # MuJoCo's pairs ours left out: a height field or SDF (`Contacts.skipped`)
        self.extra: list = []
        self.dist_err: list = []
        self.normal_err: list = []
        self.contacts_mujoco = self.contacts_ours = 0
        self.worst_err, self.worst = -1.0, None  # the matched pair whose dist differs most

    def add(self, step: int, data: mujoco.MjData) -> None:
        theirs = mujoco_deepest(data)
        self.contacts_mujoco += int(np.count_nonzero(np.all(data.contact.geom[:data.ncon] >= 0, axis=1)))
        ours = self.collider.contacts(data)
        self.contacts_ours += len(ours)
        best = ours.deepest()
        left_out = set(map(tuple, ours.skipped.tolist())) if len(ours.skipped) else ()
        self.mujoco_pairs += len(theirs)
        self.ours_pairs += len(best)
        for key, (dist, n, _) in theirs.items():
            i = best.get(key)
            if i is None:
                (self.skipped if key in left_out else self.missed).append(self._entry(step, key, dist))
                continue
            self.matched += 1
            self.dist_err.append(abs(float(ours.dist[i]) - dist))
            if self.dist_err[-1] >= self.worst_err:
                self.worst_err = self.dist_err[-1]
                self.worst = dict(self._entry(step, key, dist), ours=float(ours.dist[i]))
            self.normal_err.append(float(np.arccos(np.clip(np.dot(ours.normal[i], n), -1.0, 1.0))))
        for key, i in best.items():
            if key not in theirs:
                self.extra.append(self._entry(step, key, float(ours.dist[i])))

    def _entry(self, step: int, key: tuple, dist: float) -> dict:
        g1, g2 = key
        return {"step": step, "geom1": g1, "geom2": g2, "name1": _geom_name(self.model, g1),
                "name2": _geom_name(self.model, g2), "dist": dist, "threshold": self._threshold(g1, g2)}

    def _threshold(self, g1: int, g2: int) -> float:
        # The pair's contact distance (margin + gap: a contact is made below it), by the kernels'
        # own rule (`manifold.pair_margins`, its Python source: no compile for these arguments);
        # the largest of a geom pair's explicit <pair>s.
        t = self.collider.table
        j, n, explicit = _km._pair_rows.py_func(t.pair_key, g1 * t.cls.shape[0] + g2)
        return max(float(_km.pair_margins.py_func(g1, g2, j + e, explicit, t.geom_margin, t.geom_gap,
                                                  t.pair_margin, t.pair_gap, t.override, t.o_margin)[1])
                   for e in range(n))

    def summary(self) -> dict:
        d, n = np.asarray(self.dist_err), np.asarray(self.normal_err)
        return {
            "mujoco_pairs": self.mujoco_pairs, "our_pairs": self.ours_pairs, "matched": self.matched,
            "missed": self.missed, "skipped": self.skipped, "extra": self.extra,
            "missed_near_touching": sum(abs(e["dist"] - e["threshold"]) <= self.tolerance for e in self.missed),
            "extra_near_touching": sum(abs(e["dist"] - e["threshold"]) <= self.tolerance for e in self.extra),
            "tolerance": self.tolerance,
            "mujoco_contacts": self.contacts_mujoco, "our_contacts": self.contacts_ours,
            "dist_error_max": float(d.max()) if len(d) else 0.0,
            "dist_error_median": float(np.median(d)) if len(d) else 0.0,
            "dist_error_worst": self.worst,
            "normal_error_max_rad": float(n.max()) if len(n) else 0.0,
            "normal_error_median_rad": float(np.median(n)) if len(n) else 0.0,
        }
