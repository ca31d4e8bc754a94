"""A run's geoms, bounds, candidate pairs and contacts, recorded to Rerun (``rerun-sdk``).

Robotics people look at a simulation on a timeline rather than in tables: `RerunLog` writes, per
step, what `collide` computes on a MuJoCo model, to an ``.rrd`` file or a live viewer
(``rerun out.rrd`` opens one). ``rerun`` is imported when a log is made, never by the library
(``pip install collide[viz]``). Like `collide.contacts`, this module reads the model through
MuJoCo's attribute names and never imports ``mujoco`` (DESIGN.md's layers); `record_compare`
drives `collide.mujoco.compare`, imported when it is called.

The entities (timeline ``step``; ``sim_time`` too, in seconds):

==================================  ========================================================
``world/geoms/<kind>``              the collidable geoms, MuJoCo's primitives by kind
                                    (Boxes3D, Ellipsoids3D, Capsules3D, Cylinders3D, planes
                                    as flat boxes), instances by geom id
``world/geoms/meshes``              the mesh geoms, when small (`RerunLog`'s ``merge_meshes``):
                                    one Mesh3D, vertices in world coordinates every step
``world/geoms/mesh/<id>_<name>``    else each mesh geom: its Mesh3D (static) and pose (Transform3D)
``world/visual/...``                the same for geoms that never collide (``contype`` and
                                    ``conaffinity`` 0, no explicit pair): a robot's visual meshes
``world/bounds/geom_obbs``          our world OBB of each collidable geom (the broad phase's,
                                    margins included: `BroadPhase.world_bounds`), wireframes:
                                    orange when the geom is in a candidate pair, blue otherwise
``world/bounds/geom_spheres``       our world sphere of each collidable geom
``world/bounds/body_obbs``,         our bounds of each body (its geoms together), what the
``world/bounds/body_spheres``       tree culls with
``world/pairs/candidates``          one line per candidate pair, between the two geoms
``world/pairs/missed``              MuJoCo contact pairs missing from our candidates (red)
``world/contacts/mujoco``           MuJoCo's contacts: Points3D at ``contact.pos`` and Arrows3D
                                    along ``contact.frame[:3]``
``world/contacts/collide``          ours (`collide.mujoco.Collider.contacts`), the same way
``world/contacts/missed``           MuJoCo's contacts of pairs we made no contact for (red)
``stats/pairs/<series>``            candidates, contact pairs, missed pairs per step
``stats/contacts/<series>``         contact points per step, MuJoCo's and ours
``stats/time_us/<series>``          time per step (see `RerunLog.log` and `record_compare`)
                                    (the series are sent in columns of several steps)
==================================  ========================================================

Geoms whose bounds are unbounded (planes) or empty (bodies without a collidable geom) have no
bound drawn; height fields and SDF geoms are not drawn (their bounds are), and as we make no
contacts for their pairs, MuJoCo's contacts there show in ``world/contacts/missed``. Flex objects
are not drawn and MuJoCo's flex contacts are left out (they are not geom pairs).
"""

from __future__ import annotations

import atexit
import time
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._validate import as_count
from ..collider import Collider
from ..contacts import GEOM_TYPES

__all__ = ["RerunLog", "StepRecord", "log_rerun", "record_compare"]

_T = GEOM_TYPES
_STEP_MAX = np.iinfo(np.int64).max  # Rerun's sequence timelines are int64
# The geom kinds drawn as one entity each (instances by geom id); meshes get an entity each.
_KINDS = {_T["plane"]: "planes", _T["sphere"]: "spheres", _T["capsule"]: "capsules",
          _T["ellipsoid"]: "ellipsoids", _T["cylinder"]: "cylinders", _T["box"]: "boxes"}
_IN_PAIR = (255, 140, 0, 255)  # orange: a geom in one of our candidate pairs
_NOT_IN_PAIR = (70, 130, 255, 110)  # blue, faint
_SPHERE = (150, 150, 150, 90)
_BODY = (170, 90, 220, 160)
_CANDIDATE = (255, 170, 40, 200)
_MISSED = (230, 20, 20, 255)
_MUJOCO = (40, 120, 255, 255)
_OURS = (30, 190, 80, 255)


def _rerun():
    try:
        import rerun
    except ImportError:
        raise ImportError("rerun-sdk is not installed: pip install 'collide[viz]' (or pip install rerun-sdk)") from None
    return rerun


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


def _quat_xyzw(rot: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(n, 4)`` as Rerun takes them, ``(x, y, z, w)``, of rotations ``(n, 3, 3)``.

    Shepperd's method (J. Guidance and Control 1(3), 1978): from the largest of ``w, x, y, z``,
    found on the diagonal, so no square root is taken of a small number; numpy over the batch
    (scipy's ``Rotation.from_matrix`` costs ~0.3 ms a call here, and a step makes several).
    """
    m = np.asarray(rot, dtype=np.float64).reshape(-1, 3, 3)
    d0, d1, d2 = m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]
    # 4 w^2, 4 x^2, 4 y^2, 4 z^2 from the trace and the diagonal
    sq = np.stack([1 + d0 + d1 + d2, 1 + d0 - d1 - d2, 1 - d0 + d1 - d2, 1 - d0 - d1 + d2], axis=1)
    k = np.argmax(sq, axis=1)
    big = 2.0 * np.sqrt(np.maximum(sq[np.arange(len(m)), k], 1e-300))  # 4 |q_k|
    a = m[:, 2, 1] - m[:, 1, 2]  # 4 w x
    b = m[:, 0, 2] - m[:, 2, 0]  # 4 w y
    c = m[:, 1, 0] - m[:, 0, 1]  # 4 w z
    e = m[:, 0, 1] + m[:, 1, 0]  # 4 x y
    f = m[:, 0, 2] + m[:, 2, 0]  # 4 x z
    g = m[:, 1, 2] + m[:, 2, 1]  # 4 y z
    # rows (x, y, z, w) times 4 q_k, for k = w, x, y, z
    num = np.stack([np.stack([a, b, c, sq[:, 0]], 1), np.stack([sq[:, 1], e, f, a], 1),
                    np.stack([e, sq[:, 2], g, b], 1), np.stack([f, g, sq[:, 3], c], 1)], axis=0)
    q = num[k, np.arange(len(m))] / big[:, None]
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _rgba8(rgba: np.ndarray) -> np.ndarray:
    return np.clip(np.round(np.asarray(rgba) * 255.0), 0, 255).astype(np.uint8)


def _vertex_normals(vert: np.ndarray, face: np.ndarray) -> np.ndarray:
    # Area-weighted face normals summed at the vertices (smooth shading of MuJoCo's meshes).
    n = np.zeros_like(vert)
    fn = np.cross(vert[face[:, 1]] - vert[face[:, 0]], vert[face[:, 2]] - vert[face[:, 0]])
    for k in range(3):
        np.add.at(n, face[:, k], fn)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(length > 0, length, 1.0)


def _as_flag(value, name: str) -> bool:
    # A bool, not a truthy object: bodies="no" would mean True.
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name}: expected True or False, got {value!r}")
    return bool(value)


def _send(rr, rec, series: dict, poses: dict) -> None:
    # The kept series and replayed mesh poses, sent as columns and cleared in place: also the
    # finalizer of a log never closed (`RerunLog.__init__`), so it holds these dicts, not the log.
    for entity, (steps, values) in series.items():
        if steps:
            rec.send_columns(entity, indexes=[rr.TimeColumn("step", sequence=np.asarray(steps, dtype=np.int64))],
                             columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)))
    series.clear()
    for entity, (steps, translation, mat) in poses.items():
        if steps:
            rec.send_columns(entity, indexes=[rr.TimeColumn("step", sequence=steps)],
                             columns=rr.Transform3D.columns(translation=translation, mat3x3=mat))
    poses.clear()


def _send_at_exit(rr, rec, series: dict, poses: dict) -> None:
    # A log dropped or left open at interpreter exit: its last series are sent, not lost (they go
    # every `series_every` steps).
    try:
        _send(rr, rec, series, poses)
        rec.flush()
    except Exception:  # noqa: BLE001 - at exit, with the sink perhaps gone: nothing to tell
        pass


_OPEN: set = set()  # the finalizers of the logs not closed yet
_hooked = False


def _at_exit() -> None:
    for f in list(_OPEN):
        f()  # a finalizer already run (its log collected) does nothing


def _watch(log, *args) -> weakref.finalize:
    # weakref.finalize's own exit hook runs after Rerun's shutdown whenever some module made a
    # finalizer before rerun was imported (it is registered once, with the first one), and the
    # file is closed by then (tried: the series were lost). So ours is an atexit hook of its own,
    # registered after rerun's (atexit runs last in, first out): the series reach the file.
    global _OPEN, _hooked
    if not _hooked:
        atexit.register(_at_exit)
        _hooked = True
    f = weakref.finalize(log, _send_at_exit, *args)
    f.atexit = False
    _OPEN = {g for g in _OPEN if g.alive}
    _OPEN.add(f)
    return f


def _pairs_key(pairs: np.ndarray, ngeom: int) -> np.ndarray:
    p = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    return p[:, 0] * ngeom + p[:, 1]


class RerunLog:
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

    # ------------------------------------------------------------------ set-up, once per model

    def _blueprint(self):
        rrb = self.rr.blueprint
        return rrb.Blueprint(
            rrb.Horizontal(
                rrb.Spatial3DView(origin="/world", name="scene"),
                rrb.Vertical(
                    rrb.TimeSeriesView(origin="/stats/pairs", name="geom pairs per step"),
                    rrb.TimeSeriesView(origin="/stats/contacts", name="contact points per step"),
                    rrb.TimeSeriesView(origin="/stats/time_us", name="time per step (us)"),
                ),
                column_shares=[3, 2],
            ),
        )

    def _static(self) -> None:
        rr, m, rec = self.rr, self.model, self.rec
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)  # MuJoCo's z is up
        gtype = np.asarray(m.geom_type)
        explicit = np.zeros(self.ngeom, bool)
        explicit[np.asarray(m.pair_geom1, dtype=np.int64)] = True
        explicit[np.asarray(m.pair_geom2, dtype=np.int64)] = True
        collides = (np.asarray(m.geom_contype) != 0) | (np.asarray(m.geom_conaffinity) != 0) | explicit
        self.geom_collides = collides
        rgba = np.array(m.geom_rgba, dtype=np.float64)
        matid = np.asarray(m.geom_matid)
        has_mat = matid >= 0
        rgba[has_mat] = np.asarray(m.mat_rgba)[matid[has_mat]]
        self._rgba = _rgba8(rgba)
        size = np.asarray(m.geom_size, dtype=np.float64)
        extent = float(m.stat.extent) if float(m.stat.extent) > 0 else 1.0
        self.normal_length = 0.05 * extent
        self._size, self._extent = size, extent
        self._groups = []  # (entity, kind, geom ids, static half sizes or (lengths, radii))
        self._meshes = []  # (entity, geom id): a mesh geom of its own, moved by a Transform3D
        self._merged = []  # (entity, vertex geom ids, local vertices, local normals): meshes merged
        for prefix, mask in (("world/geoms", collides), ("world/visual", ~collides if self.visual else None)):
            if mask is None:
                continue
            for t, kind in _KINDS.items():
                ids = np.flatnonzero(mask & (gtype == t))
                if len(ids):
                    self._groups.append((f"{prefix}/{kind}", t, ids))
                    self._static_group(f"{prefix}/{kind}", t, ids)
            mesh_geoms = np.flatnonzero(mask & (gtype == _T["mesh"]))
            parts = []  # (geom, vertices in the geom frame, faces, vertex normals)
            for g in mesh_geoms:
                mesh = int(m.geom_dataid[g])
                v0, nv = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
                f0, nf = int(m.mesh_faceadr[mesh]), int(m.mesh_facenum[mesh])
                vert = np.asarray(m.mesh_vert[v0:v0 + nv], dtype=np.float64)  # in the geom frame
                face = np.asarray(m.mesh_face[f0:f0 + nf], dtype=np.int64)
                parts.append((int(g), vert, face, _vertex_normals(vert, face)))
            if parts and sum(len(v) for _, v, _, _ in parts) <= self.merge_meshes:
                # Small meshes: one entity, its vertices moved here every step (one Rerun call a
                # step instead of a transform per mesh; a few KiB a step more in the file).
                entity = f"{prefix}/meshes"
                vg = np.concatenate([np.full(len(v), g) for g, v, _, _ in parts])
                offsets = np.cumsum([0] + [len(v) for _, v, _, _ in parts[:-1]])
                faces = np.concatenate([f + o for (_, _, f, _), o in zip(parts, offsets)])
                rec.log(entity, rr.Mesh3D.from_fields(triangle_indices=faces, vertex_colors=self._rgba[vg]),
                        static=True)
                self._merged.append((entity, vg, np.concatenate([v for _, v, _, _ in parts]),
                                     np.concatenate([n for _, _, _, n in parts])))
                continue
            for g, vert, face, normals in parts:  # large ones: static meshes, moved by a transform
                entity = f"{prefix}/mesh/{rr.escape_entity_path_part(self._name(g))}"
                rec.log(entity, rr.Mesh3D(vertex_positions=vert, triangle_indices=face, vertex_normals=normals,
                                          albedo_factor=self._rgba[g]), static=True)
                self._meshes.append((entity, g))
        # Series styles, static: names and colours of the lines in the plots.
        for entity, colour, name in (
                ("stats/pairs/candidates", _CANDIDATE, "our candidates"),
                ("stats/pairs/mujoco_candidates", (120, 120, 120, 255), "MuJoCo broad-phase candidates"),
                ("stats/pairs/mujoco_contact_pairs", _MUJOCO, "MuJoCo contact pairs"),
                ("stats/pairs/missed", _MISSED, "MuJoCo contact pairs missed"),
                ("stats/contacts/mujoco", _MUJOCO, "MuJoCo contact points"),
                ("stats/contacts/collide", _OURS, "our contact points"),
                ("stats/contacts/missed", _MISSED, "MuJoCo contact points of pairs we missed"),
                ("stats/time_us/collide_broad", _CANDIDATE, "our broad phase"),
                ("stats/time_us/collide_contacts", _OURS, "our broad + narrow phase"),
                ("stats/time_us/mujoco_broad", _MUJOCO, "MuJoCo broad phase")):
            if self.contacts or not entity.endswith(("contacts/collide", "contacts/missed", "collide_contacts")):
                rec.log(entity, rr.SeriesLines(colors=[colour], names=[name]), static=True)
        # Styles of the per-step entities, static: a step logs positions only.
        for prefix in ("world/bounds/geom", "world/bounds/body"):
            rec.log(f"{prefix}_obbs", rr.Boxes3D.from_fields(radii=0.001, fill_mode="majorwireframe"), static=True)
            rec.log(f"{prefix}_spheres", rr.Ellipsoids3D.from_fields(colors=_SPHERE, line_radii=0.0006,
                                                                     fill_mode="majorwireframe"), static=True)
        rec.log("world/pairs/candidates", rr.LineStrips3D.from_fields(radii=0.0015, colors=_CANDIDATE), static=True)
        rec.log("world/pairs/missed", rr.LineStrips3D.from_fields(radii=0.006, colors=_MISSED), static=True)
        for entity, colour, r in (("world/contacts/mujoco", _MUJOCO, 0.006), ("world/contacts/collide", _OURS, 0.0045)):
            if self.contacts or entity == "world/contacts/mujoco":
                rec.log(entity, rr.Points3D.from_fields(radii=r, colors=colour),
                        rr.Arrows3D.from_fields(radii=r / 3, colors=colour), static=True)
        if self.contacts:  # contacts=False: ours are not computed, so none are missed either
            rec.log("world/contacts/missed", rr.Points3D.from_fields(radii=0.012, colors=_MISSED), static=True)

    def _name(self, g: int) -> str:
        adr = int(self.model.name_geomadr[g])
        names = bytes(self.model.names)
        name = names[adr:names.index(b"\0", adr)].decode() if adr >= 0 else ""
        return f"{g}_{name or 'geom'}"  # the id first: unique even where names repeat or are missing

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
        # Points and normals on one entity, in one call (each call costs ~0.1 ms in Rerun's Python).
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

    def _static_group(self, entity: str, t: int, ids: np.ndarray) -> None:
        # What never changes (sizes, colours) is logged once, static; a step logs the poses only.
        rr, s, colours = self.rr, self._size[ids], self._rgba[ids]
        if t == _T["box"]:
            arch = rr.Boxes3D.from_fields(half_sizes=s, colors=colours, fill_mode="solid")
        elif t == _T["plane"]:
            # A plane's size is visual only (0: infinite); drawn as a flat box of that size.
            half = np.where(s[:, :2] > 0, s[:, :2], 2.0 * self._extent)
            arch = rr.Boxes3D.from_fields(half_sizes=np.column_stack([half, np.zeros(len(ids))]), colors=colours,
                                          fill_mode="solid")
        elif t == _T["sphere"]:
            arch = rr.Ellipsoids3D.from_fields(half_sizes=np.repeat(s[:, :1], 3, axis=1), colors=colours,
                                               fill_mode="solid")
        elif t == _T["ellipsoid"]:
            arch = rr.Ellipsoids3D.from_fields(half_sizes=s, colors=colours, fill_mode="solid")
        elif t == _T["cylinder"]:
            arch = rr.Cylinders3D.from_fields(lengths=2.0 * s[:, 1], radii=s[:, 0], colors=colours, fill_mode="solid")
        else:
            arch = rr.Capsules3D.from_fields(lengths=2.0 * s[:, 1], radii=s[:, 0], colors=colours, fill_mode="solid")
        self.rec.log(entity, arch, static=True)

    def _log_geoms(self, gpos: np.ndarray, gmat: np.ndarray) -> None:
        rr, rec, size = self.rr, self.rec, self._size
        quat = _quat_xyzw(gmat) if self._groups else None  # one call for every geom (numpy's per-call cost)
        for entity, t, ids in self._groups:
            pos, rot = gpos[ids], gmat[ids]
            q = quat[ids]
            if t in (_T["box"], _T["plane"]):
                arch = rr.Boxes3D.from_fields(centers=pos, quaternions=q)
            elif t in (_T["sphere"], _T["ellipsoid"]):
                arch = rr.Ellipsoids3D.from_fields(centers=pos, quaternions=q)
            elif t == _T["cylinder"]:
                arch = rr.Cylinders3D.from_fields(centers=pos, quaternions=q)
            else:  # capsule: Rerun's runs from its origin along +z; MuJoCo's is centred
                arch = rr.Capsules3D.from_fields(translations=pos - rot[:, :, 2] * size[ids, 1:2], quaternions=q)
            rec.log(entity, arch)
        for entity, vg, vert, normals in self._merged:
            rot = gmat[vg]
            rec.log(entity, rr.Mesh3D.from_fields(vertex_positions=np.einsum("vij,vj->vi", rot, vert) + gpos[vg],
                                                  vertex_normals=np.einsum("vij,vj->vi", rot, normals)))
        for entity, g in self._meshes:
            if self._deferred is None:
                rec.log(entity, rr.Transform3D(translation=gpos[g], mat3x3=gmat[g]))
            else:  # replayed states: sent as columns after them
                steps, translation, mat = self._poses.setdefault(entity, ([], [], []))
                steps.append(self._deferred)
                translation.append(gpos[g].copy())
                mat.append(gmat[g].copy())

    def _log_bounds(self, prefix: str, wb, keep: np.ndarray, colours) -> int:
        rr, rec = self.rr, self.rec
        rec.log(f"{prefix}_obbs", rr.Boxes3D.from_fields(half_sizes=wb.obb_half[keep], centers=wb.obb_center[keep],
                                                         quaternions=_quat_xyzw(wb.obb_rot[keep]), colors=colours))
        r = wb.sphere_radius[keep]
        rec.log(f"{prefix}_spheres", rr.Ellipsoids3D.from_fields(half_sizes=np.repeat(r[:, None], 3, axis=1),
                                                                 centers=wb.sphere_center[keep]))
        return int(np.count_nonzero(keep))

    def _segments(self, pairs: np.ndarray, gpos: np.ndarray, gmat: np.ndarray) -> np.ndarray:
        # A line between the two geoms' centres; a plane's end is the foot of the other centre on it.
        pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        a, b = gpos[pairs[:, 0]].copy(), gpos[pairs[:, 1]].copy()
        plane = np.asarray(self.model.geom_type) == _T["plane"]
        for end, other, col in ((a, b, 0), (b, a, 1)):
            rows = np.flatnonzero(plane[pairs[:, col]])
            if len(rows):
                g = pairs[rows, col]
                n = gmat[g, :, 2]
                end[rows] = other[rows] - n * np.einsum("ij,ij->i", other[rows] - gpos[g], n)[:, None]
        return np.stack([a, b], axis=1)

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


def log_rerun(model, path=None, *, spawn: bool = False, recording=None, **options) -> RerunLog:
    """A `RerunLog` of ``model``: call ``.log(data)`` after each step of your loop, then ``.close()``.

    Parameters
    ----------
    model : mujoco.MjModel
    path, spawn, recording, **options
        See `RerunLog`.

    Returns
    -------
    RerunLog

    Examples
    --------
    >>> import mujoco, collide.mujoco as cm                          # doctest: +SKIP
    >>> model = cm.default_scene(); data = mujoco.MjData(model)      # doctest: +SKIP
    >>> with cm.log_rerun(model, "run.rrd") as log:                  # doctest: +SKIP
    ...     for _ in range(300):
    ...         mujoco.mj_step(model, data)
    ...         log.log(data)
    """
    return RerunLog(model, path, spawn=spawn, recording=recording, **options)


def record_compare(model, path=None, *, spawn: bool = False, recording=None, steps: int = 1000, seed: int = 0,
                   name: str = "model", hold: int = 100, contacts: bool = True, **options) -> tuple[dict, list]:
    """`collide.mujoco.compare`, with every step recorded to Rerun.

    The timed run only keeps copies of each step's state (`RerunLog.snapshot`); they are logged
    after it, with our contacts computed on them, so the comparison's times are those of a run
    without a log. Then its per-step series: MuJoCo's broad-phase candidates
    (``stats/pairs/mujoco_candidates``), our broad phase's time and MuJoCo's
    (``stats/time_us/collide_broad``, ``stats/time_us/mujoco_broad``).

    Parameters
    ----------
    model : mujoco.MjModel
    path, spawn, recording, **options
        See `RerunLog`.
    steps, seed, name, hold, contacts
        See `collide.mujoco.compare`. ``contacts=False`` also leaves our contacts out of the
        recording (neither computed nor drawn; ``world/contacts/collide`` and
        ``world/contacts/missed`` absent).

    Returns
    -------
    result : dict
        `collide.mujoco.compare`'s.
    records : list of StepRecord
        What was logged at each step.

    Raises
    ------
    ValueError
        A bad argument (those of `RerunLog` and of `collide.mujoco.compare`), found before the
        file is opened: an existing file is left as it was.

    Notes
    -----
    Every step's state (body and geom poses, MuJoCo's contacts) is kept in memory until the run
    ends: ``96 * (nbody + ngeom)`` bytes a step (a position and a rotation matrix each, float64),
    plus 8 bytes a candidate pair and 64 a MuJoCo contact; for a model of 500 bodies and 1000
    geoms, 144 kB a step, 144 MB for 1000 steps.
    """
    from .. import mujoco as cm

    # compare's arguments, checked before RerunLog opens (and truncates) the file.
    steps = as_count(steps, "steps", 1)
    seed = as_count(seed, "seed", 0)
    hold = as_count(hold, "hold", 1)
    contacts = _as_flag(contacts, "contacts")
    if not isinstance(name, str):
        raise ValueError(f"name: expected a str, got {type(name).__name__}")
    with RerunLog(model, path, spawn=spawn, recording=recording, contacts=contacts, **options) as log:
        result = cm.compare(model, steps=steps, seed=seed, name=name, broadphase=log.broadphase,
                            on_step=log.snapshot, hold=hold, contacts=contacts)
        records = log.flush_snapshots()
        log.log_series("stats/pairs/mujoco_candidates", result["mujoco_candidates_per_step"])
        log.log_series("stats/time_us/collide_broad", result["time_ours_us_per_step"])
        log.log_series("stats/time_us/mujoco_broad", result["time_mujoco_broad_us_per_step"])
    return result, records
