"""`RerunLog`: a MuJoCo model's run recorded step by step (arguments, checks, series, replayed states)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._validate import as_count
from ..collider import Collider
from ._convert import _BODY, _IN_PAIR, _NOT_IN_PAIR, _STEP_MAX, _as_flag, _pairs_key
from ._scene import _Scene
from ._stream import _rerun, _send, _watch


@dataclass(frozen=True)
class StepRecord:
    """What `RerunLog.log` logged at one step (counts of instances, for checks and summaries).

    Attributes
    ----------
    step : int
    candidates : int
        Our candidate pairs (lines in ``world/pairs/candidates``).
    mujoco_pairs : int
        Geom pairs MuJoCo made contacts for (flex contacts left out).
    mujoco_contacts, our_contacts : int
        Contact points, MuJoCo's (flex contacts left out) and ours.
    missed_pairs : int
        MuJoCo contact pairs not among our candidates (``world/pairs/missed``).
    missed_contacts : int
        MuJoCo contact points of pairs we made no contact for (``world/contacts/missed``).
    geom_bounds, body_bounds : int
        OBBs (and as many spheres) drawn.
    """

    step: int
    candidates: int
    mujoco_pairs: int
    mujoco_contacts: int
    our_contacts: int
    missed_pairs: int
    missed_contacts: int
    geom_bounds: int
    body_bounds: int


class RerunLog(_Scene):
    """Records a MuJoCo model's run, step by step, to Rerun.

    Parameters
    ----------
    model : mujoco.MjModel
        Read once (geometry, colours, filters): the geoms are logged now, as static data.
    path : str or path-like, optional
        Write the recording to this ``.rrd`` file (open it with ``rerun FILE``).
    spawn : bool, default False
        Also start a Rerun viewer and stream to it.
    recording : rerun.RecordingStream, optional
        Log to this stream instead, to the sinks it has; ``path`` or ``spawn`` replace them
        (as ``RecordingStream.save`` and ``.spawn`` do).
    bodies : bool, default True
        Log the bodies' bounds too.
    visual : bool, default True
        Log the geoms that never collide (a robot's visual meshes) under ``world/visual``.
    application_id : str, default "collide"
        The recording's application id (the viewer groups recordings by it).
    merge_meshes : int, default 1000
        When the mesh geoms (of ``world/geoms``, and of ``world/visual``) have this many vertices
        or fewer in all, they are one entity (``.../meshes``) whose vertices are logged in world
        coordinates every step (fewer Rerun calls a step, 24 bytes a vertex more in the file);
        else each is an entity of its own, static, moved by a transform
        (``.../mesh/<id>_<name>``). 0: never merged.
    series_every : int, default 32
        The ``stats/...`` series are sent every this many steps (and by `flush` and `close`),
        as columns: one call instead of one a step and series.
    contacts : bool, default True
        Compute and log our contacts (``world/contacts/collide``, ``world/contacts/missed``
        and their series); False leaves them out (and untimed): candidate pairs only.

    Raises
    ------
    ImportError
        ``rerun-sdk`` is not installed.
    ValueError
        None of ``path``, ``spawn`` and ``recording`` given (the log would go nowhere); an
        empty ``path``, a folder, or one that cannot be written (naming it); ``recording`` not a
        ``rerun.RecordingStream``; a flag not a bool; ``series_every < 1``, ``merge_meshes < 0``.
        Every argument is checked before the file is opened (an existing file is left as it was).

    Notes
    -----
    Use it as a context manager, or call `close`, so that the file is complete. A log left
    open still sends its last series when it is garbage-collected or the interpreter exits.
    After `close`, the log is closed for good: `log` and the other calls raise ``ValueError``
    (make a new `RerunLog` to record again).
    """

    def __init__(self, model, path=None, *, spawn: bool = False, recording=None, bodies: bool = True,
                 visual: bool = True, application_id: str = "collide", series_every: int = 32,
                 merge_meshes: int = 1000, contacts: bool = True):
        rr = _rerun()
        # Every argument is checked before a sink is opened: `save` truncates the file.
        spawn = _as_flag(spawn, "spawn")
        self.bodies = _as_flag(bodies, "bodies")
        self.visual = _as_flag(visual, "visual")
        self.contacts = _as_flag(contacts, "contacts")
        self.series_every = as_count(series_every, "series_every", 1)
        self.merge_meshes = as_count(merge_meshes, "merge_meshes", 0)
        if not isinstance(application_id, str) or not application_id:
            raise ValueError(f"application_id: expected a non-empty str, got {application_id!r}")
        if recording is not None and not isinstance(recording, rr.RecordingStream):
            raise ValueError(f"recording: expected a rerun.RecordingStream, got {type(recording).__name__}")
        if path is None and not spawn and recording is None:
            raise ValueError("RerunLog: give a path, spawn=True or a recording (else nothing is recorded)")
        if path is not None:
            if not isinstance(path, (str, Path)) and not hasattr(path, "__fspath__"):
                raise ValueError(f"path: expected a file name, got {type(path).__name__}")
            if str(path) == "":
                raise ValueError("path: empty; give an .rrd file name")
            if Path(path).is_dir():
                raise ValueError(f"path: {path} is a folder; give an .rrd file name")
        self.rr = rr
        self.model = model
        self.collider = Collider(model)
        self.broadphase = self.collider.broadphase  # collide.mujoco.BroadPhase
        self.ngeom = int(model.ngeom)
        self._next_step = 0
        self._scratch = None  # an MjData for replayed states (`record_compare`)
        self._snapshots: list = []
        self._series: dict = {}  # entity -> (steps, values), sent every `series_every` steps and at the end
        self._poses: dict = {}  # mesh entity -> (steps, translations, matrices) of replayed states
        self._deferred = None  # the step being replayed (`flush_snapshots`), else None
        self._closed = False
        self._checked = None  # the last MjData checked to be of this model
        self._own = recording is None
        if path is not None:
            try:
                Path(path).parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise ValueError(f"path: cannot create the folder of {path} ({exc})") from None
            existed = Path(path).exists()
            try:  # tried before a stream exists (appending: the file is left as it is)
                with open(path, "ab"):
                    pass
            except OSError as exc:
                raise ValueError(f"path: cannot write {path} ({exc})") from None
            if not existed:
                Path(path).unlink()
        self.rec = rec = recording if recording is not None else rr.RecordingStream(application_id)
        blueprint = self._blueprint()
        try:
            if path is not None and spawn:  # both: one stream, two sinks (save and spawn each replace them)
                rr.spawn(connect=False)
                rec.set_sinks(rr.FileSink(str(path)), rr.GrpcSink(), default_blueprint=blueprint)
            elif path is not None:
                rec.save(str(path), default_blueprint=blueprint)
            elif spawn:
                rec.spawn(default_blueprint=blueprint)
        except RuntimeError as exc:  # rerun's bindings: "Failed to create file: Permission denied ..."
            if path is None:
                raise
            raise ValueError(f"path: cannot write {path} ({exc})") from None
        # Series not yet sent when the log is dropped or the interpreter exits are sent then.
        self._finalizer = _watch(self, rr, rec, self._series, self._poses)
        self._static()

    # ------------------------------------------------------------------ per step

    def log(self, data, step: int | None = None, candidates=None) -> StepRecord:
        """Log the state of ``data`` (after ``mj_step`` or ``mj_forward``) as one step.

        Parameters
        ----------
        data : mujoco.MjData
            Of the model the log was made for; read: body and geom poses, ``contact``, ``time``.
        step : int, optional
            The step's index on the ``step`` timeline (default: one more than the last).
        candidates : (K, 2) int array, optional
            Our candidate pairs, when the caller has them; computed here otherwise (and timed:
            ``stats/time_us/collide_broad``). Our contacts are computed here (timed:
            ``stats/time_us/collide_contacts``, the broad phase included).

        Returns
        -------
        StepRecord
            Counts of what was logged.

        Raises
        ------
        ValueError
            The log is closed; ``data`` of another model, a non-finite pose (of any geom, in a
            pair or not); ``step`` negative or beyond int64; ``candidates`` not ``(K, 2)``
            integers, out of ``[0, ngeom)``, or a geom paired with itself.
        """
        self._check_open()
        step = self._next_step if step is None else as_count(step, "step", 0, _STEP_MAX)
        if data is not self._checked:  # an MjData never changes model: checked once (a model compare)
            self.broadphase._check_data(data)
            self._checked = data
        self._check_poses(np.asarray(data.geom_xpos), np.asarray(data.geom_xmat))
        if candidates is not None:
            candidates = self._check_candidates(candidates)
        perf = time.perf_counter_ns
        times = {}
        if candidates is None:
            t0 = perf()
            candidates = self.collider.pairs(data)
            times["collide_broad"] = (perf() - t0) * 1e-3
        ours = None
        if self.contacts:
            t0 = perf()
            ours = self.collider.contacts(data)
            times["collide_contacts"] = (perf() - t0) * 1e-3
        n = int(data.ncon)
        c = data.contact
        theirs = (np.array(c.geom[:n], dtype=np.int64), np.array(c.pos[:n]), np.array(c.frame[:n, :3]))
        return self._log(step, float(data.time), data, candidates, ours, theirs, times)

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError("RerunLog: closed (by close() or the end of its with block); make a new log "
                             "to record again")

    def _check_poses(self, gpos: np.ndarray, gmat: np.ndarray) -> None:
        # Every geom's pose, not only those in a pair (the narrow phase checks those): a NaN
        # quaternion or an inf centre would be drawn, or dropped, without a word.
        ok = np.isfinite(gpos).all(axis=1) & np.isfinite(gmat.reshape(len(gmat), -1)).all(axis=1)
        if not ok.all():
            g = int(np.flatnonzero(~ok)[0])
            raise ValueError(f"data.geom_xpos/geom_xmat: non-finite pose (NaN or inf) of geom {self._name(g)}")

    def _check_candidates(self, candidates) -> np.ndarray:
        # (K, 2) geom ids in range, integers (not truncated floats), no geom with itself; each
        # pair lower id first, as the broad phase gives them and the missed-pair keys assume.
        name = "candidates"
        try:
            c = np.asarray(candidates)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{name}: cannot be read as an array ({exc})") from None
        if c.size == 0:
            return np.zeros((0, 2), np.int64)
        if c.ndim != 2 or c.shape[1] != 2:
            raise ValueError(f"{name}: expected shape (K, 2) (geom pairs), got {c.shape}")
        if c.dtype.kind not in "iu":
            if c.dtype.kind != "f":
                raise ValueError(f"{name}: expected integer geom ids, got dtype {c.dtype}")
            if not np.all(np.isfinite(c)):
                row = int(np.argwhere(~np.isfinite(c))[0, 0])
                raise ValueError(f"{name}: non-finite value (NaN or inf) at row {row}")
            if np.any(c != np.round(c)):  # not truncated: 0.4 is no geom id
                row = int(np.flatnonzero(np.any(c != np.round(c), axis=1))[0])
                raise ValueError(f"{name}: expected integer geom ids, got {c[row].tolist()} at row {row}")
        if np.any((c < 0) | (c >= self.ngeom)):
            row = int(np.flatnonzero(np.any((c < 0) | (c >= self.ngeom), axis=1))[0])
            raise ValueError(f"{name}: geom id out of [0, {self.ngeom}) at row {row}: {c[row].tolist()}")
        c = np.sort(c.astype(np.int64), axis=1)
        if np.any(c[:, 0] == c[:, 1]):
            row = int(np.flatnonzero(c[:, 0] == c[:, 1])[0])
            raise ValueError(f"{name}: geom {c[row, 0]} paired with itself at row {row}")
        return c

    def _log(self, step, sim_time, data, candidates, ours, theirs, times) -> StepRecord:
        rr, rec, ng = self.rr, self.rec, self.ngeom
        self._next_step = step + 1
        rec.set_time("step", sequence=step)
        rec.set_time("sim_time", duration=sim_time)
        gpos = np.asarray(data.geom_xpos)
        gmat = np.asarray(data.geom_xmat).reshape(-1, 3, 3)
        self._log_geoms(gpos, gmat)
        cand = np.asarray(candidates, dtype=np.int64).reshape(-1, 2)

        # Our bounds (what the broad phase tests).
        wb = self.broadphase.world_bounds(data)
        in_pair = np.zeros(ng, bool)
        in_pair[cand.ravel()] = True
        keep = self.geom_collides & np.all(np.isfinite(wb.obb_half), axis=1)
        colours = np.where(in_pair[keep, None], np.array(_IN_PAIR, np.uint8), np.array(_NOT_IN_PAIR, np.uint8))
        n_geom = self._log_bounds("world/bounds/geom", wb, keep, colours)
        n_body = 0
        if self.bodies:
            bb = self.broadphase.world_bounds(data, of="bodies")
            keep_b = np.all(np.isfinite(bb.obb_half), axis=1) & (bb.sphere_radius >= 0)
            n_body = self._log_bounds("world/bounds/body", bb, keep_b, np.array(_BODY, np.uint8))

        # Candidate pairs and MuJoCo's contact pairs we missed.
        rec.log("world/pairs/candidates", rr.LineStrips3D.from_fields(strips=self._segments(cand, gpos, gmat)))
        geom, cpos, cnormal = theirs
        solid = np.all(geom >= 0, axis=1)  # flex contacts are not geom pairs
        geom, cpos, cnormal = np.sort(geom[solid], axis=1), cpos[solid], cnormal[solid]
        keys = geom[:, 0] * ng + geom[:, 1]
        mj_keys = np.unique(keys)
        missed = mj_keys[~np.isin(mj_keys, _pairs_key(cand, ng))]
        missed_pairs = np.stack(np.divmod(missed, ng), axis=1)
        rec.log("world/pairs/missed", rr.LineStrips3D.from_fields(strips=self._segments(missed_pairs, gpos, gmat)))

        # Contacts: MuJoCo's, ours, and MuJoCo's of pairs we made no contact for.
        L = self.normal_length
        # Points and normals on one entity, in one call (each call has a fixed cost in Rerun's Python).
        rec.log("world/contacts/mujoco", rr.Points3D.from_fields(positions=cpos),
                rr.Arrows3D.from_fields(origins=cpos, vectors=cnormal * L))
        if ours is not None:  # contacts=False: ours neither computed nor drawn, none missed
            rec.log("world/contacts/collide", rr.Points3D.from_fields(positions=ours.pos),
                    rr.Arrows3D.from_fields(origins=ours.pos, vectors=ours.normal * L))
            no_ours = ~np.isin(keys, _pairs_key(ours.geom, ng))
            rec.log("world/contacts/missed", rr.Points3D.from_fields(positions=cpos[no_ours]))
        else:
            no_ours = np.zeros(len(keys), bool)

        counts = StepRecord(step=step, candidates=len(cand), mujoco_pairs=len(mj_keys),
                            mujoco_contacts=len(cpos), our_contacts=0 if ours is None else len(ours),
                            missed_pairs=len(missed),
                            missed_contacts=int(np.count_nonzero(no_ours)), geom_bounds=n_geom,
                            body_bounds=n_body)
        # The series are kept and sent as columns (`_send_series`): one call for many steps.
        series = [("stats/pairs/candidates", counts.candidates),
                  ("stats/pairs/mujoco_contact_pairs", counts.mujoco_pairs),
                  ("stats/pairs/missed", counts.missed_pairs),
                  ("stats/contacts/mujoco", counts.mujoco_contacts)]
        if ours is not None:
            series += [("stats/contacts/collide", counts.our_contacts),
                       ("stats/contacts/missed", counts.missed_contacts)]
        for entity, value in series:
            self._series.setdefault(entity, ([], []))
            self._series[entity][0].append(step)
            self._series[entity][1].append(float(value))
        for key, value in times.items():
            entity = f"stats/time_us/{key}"
            self._series.setdefault(entity, ([], []))
            self._series[entity][0].append(step)
            self._series[entity][1].append(value)
        if len(self._series["stats/pairs/candidates"][0]) >= self.series_every:
            self._send_series()
        return counts

    def _send_series(self) -> None:
        _send(self.rr, self.rec, self._series, self._poses)  # cleared in place: the finalizer holds them

    # ------------------------------------------------------------------ replayed states

    def snapshot(self, step: int, data, candidates) -> None:
        """Keep the state of ``data`` for `flush_snapshots` (for a timed loop: copies only).

        The ``on_step(step, data, candidates)`` hook of `collide.mujoco.compare`.
        """
        self._check_open()
        if self._scratch is None:  # an MjData to replay the states in (mujoco not imported here)
            self._scratch = type(data)(self.model)
        n = int(data.ncon)
        c = data.contact
        self._snapshots.append((int(step), float(data.time), np.array(data.xpos), np.array(data.xmat),
                                np.array(data.geom_xpos), np.array(data.geom_xmat), candidates,
                                (np.array(c.geom[:n], dtype=np.int64), np.array(c.pos[:n]),
                                 np.array(c.frame[:n, :3]))))

    def flush_snapshots(self) -> list[StepRecord]:
        """Log the states kept by `snapshot`, in order; our contacts computed on each."""
        self._check_open()
        out = []
        for step, sim_time, xpos, xmat, gpos, gmat, cand, theirs in self._snapshots:
            d = self._scratch
            d.xpos[:], d.xmat[:], d.geom_xpos[:], d.geom_xmat[:] = xpos, xmat, gpos, gmat
            self._check_poses(gpos, gmat)
            ours = self.collider.contacts(d) if self.contacts else None
            self._deferred = step
            try:
                out.append(self._log(step, sim_time, d, cand, ours, theirs, {}))
            finally:
                self._deferred = None
        self._snapshots = []
        self._send_series()
        return out

    def log_series(self, entity: str, values, steps=None) -> None:
        """Log a whole per-step series at once (``stats/...``), e.g. from `collide.mujoco.compare`.

        Parameters
        ----------
        entity : str
            Entity path, e.g. ``"stats/time_us/mujoco_broad"``.
        values : (n,) array_like of float
        steps : (n,) array_like of int, optional
            Their steps (default ``0 .. n - 1``).
        """
        self._check_open()
        rr = self.rr
        v = np.asarray(values, dtype=np.float64).ravel()
        s = np.arange(len(v)) if steps is None else np.asarray(steps, dtype=np.int64).ravel()
        if len(s) != len(v):
            raise ValueError(f"steps: {len(s)} given for {len(v)} values")
        self.rec.send_columns(entity, indexes=[rr.TimeColumn("step", sequence=s)],
                              columns=rr.Scalars.columns(scalars=v))

    def flush(self) -> None:
        """Send the series kept so far and flush the recording."""
        self._check_open()
        self._send_series()
        self.rec.flush()

    def close(self) -> None:
        """Flush the recording (and close it, when this log made it); a second call does nothing.

        The log cannot be used after it (``ValueError``).
        """
        if self._closed:
            return
        self.flush()
        self._closed = True
        self._finalizer.detach()
        if self._own:
            self.rec.disconnect()

    def __enter__(self) -> RerunLog:
        self._check_open()
        return self

    def __exit__(self, *exc) -> bool:
        self.close()
        return False
