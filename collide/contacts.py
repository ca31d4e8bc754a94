"""Contacts of geom pairs: the narrow phase of a MuJoCo-style model, on flat arrays.

`GeomTable` reads a model's geoms once (any object with MuJoCo's ``MjModel`` attribute names:
this module does not import ``mujoco``, DESIGN.md's layers) into the flat per-geom arrays of
`collide._kernels.manifold`; `narrow_phase` takes a broad phase's ``(K, 2)`` pairs and the geoms'
world poses and returns `Contacts`. `collide.mujoco.Collider` wires the two to MuJoCo's data.

The shapes, as MuJoCo collides them (``src/engine/engine_collision_*.c``):

* sphere, capsule, box: `PointCloud` s (a point, a segment, eight corners; plus a radius), exact;
* mesh: the convex hull of its vertices (``mesh_vert``, in the geom frame);
* cylinder, ellipsoid: the exact `collide.Cylinder` and `collide.Ellipsoid` (a support function);
* plane: the half-space ``z <= 0`` of its frame (its size is visual only);
* height field and SDF: not collided; their pairs are reported in `Contacts.skipped`.

When a contact is made (MuJoCo 4, ``getMargin`` / ``getGap`` in engine_collision_driver.c, and
checked on this install by tests/test_contacts.py): a pair makes contacts when their signed
distance is at most ``margin + gap``, with ``margin`` the sum of the two geoms' ``geom_margin``
and ``gap`` the sum of their ``geom_gap``, or the ``<pair>``'s own ``margin`` and ``gap`` for an
explicit pair; with ``mjENBL_OVERRIDE`` every margin is ``opt.o_margin`` (the gaps stay). A
contact at or beyond ``margin`` lies in the gap (MuJoCo keeps it, flagged ``exclude``).
With ``mjENBL_OVERRIDE`` MuJoCo's broad phase grows its body boxes by ``o_margin / 2`` per geom
without the gaps (``makeAAMM``), so a dynamic pair between ``o_margin`` and ``o_margin + gap``
gets contacts from MuJoCo only where its boxes (in its sweep frame) still overlap; ours always.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import faces as _faces
from . import shapes as _shapes
from ._kernels import _pose
from ._kernels import manifold as _km
from ._kernels import plane as _kp
from ._validate import _as_finite
from .convex import Cylinder, Ellipsoid
from .support import SIZE_MAX, SIZE_MIN, support_data

__all__ = ["Contacts", "GEOM_TYPES", "GeomTable", "contacts_of", "geom_distance", "narrow_phase", "never_collides"]

# MuJoCo's geom types (mjtGeom; tests/test_contacts.py checks them against the bindings).
PLANE, HFIELD, SPHERE, CAPSULE, ELLIPSOID, CYLINDER, BOX, MESH, SDF = range(9)
GEOM_TYPES = {"plane": PLANE, "hfield": HFIELD, "sphere": SPHERE, "capsule": CAPSULE, "ellipsoid": ELLIPSOID,
              "cylinder": CYLINDER, "box": BOX, "mesh": MESH, "sdf": SDF}
# MuJoCo's mjENBL_OVERRIDE bit (mjtEnableBit; checked likewise).
ENBL_OVERRIDE = 1 << 0


@dataclass(frozen=True, eq=False)
class Contacts:
    """Contacts of a set of geom pairs, one row per contact point.

    Attributes
    ----------
    geom : (K, 2) int32
        The two geoms, lower id first.
    dist : (K,) float64
        Signed distance at the contact (negative: penetration).
    pos : (K, 3) float64
        Midway between the two surfaces, world frame (MuJoCo's ``contact.pos``).
    normal : (K, 3) float64
        Unit, from ``geom[:, 0]`` to ``geom[:, 1]`` (MuJoCo's ``contact.frame[:3]`` for that order).
    margin : (K,) float64
        The pair's margin (MuJoCo's ``includemargin``): a contact with ``dist >= margin`` lies
        in the gap, and MuJoCo flags it ``exclude``.
    skipped : (S, 2) int32
        Pairs not collided (a height field or SDF geom): reported, not dropped silently.

    Notes
    -----
    From `narrow_phase` and `collide.mujoco.Collider.contacts`, the arrays are views of rows of
    a larger output buffer that later calls never write again (they fill other rows), so a
    result may be kept; the buffer is freed with the last view that holds it. A call without
    contacts or skipped pairs returns one empty `Contacts` again (``is`` tells). Copy an array
    (``np.array(c.dist)``) to own it.
    """

    geom: np.ndarray
    dist: np.ndarray
    pos: np.ndarray
    normal: np.ndarray
    margin: np.ndarray
    skipped: np.ndarray

    def __len__(self) -> int:
        return len(self.dist)

    def deepest(self) -> dict:
        """``{(g1, g2): row}``: each pair's deepest contact (the row of its smallest ``dist``)."""
        best: dict = {}
        for i, (a, b) in enumerate(self.geom.tolist()):
            j = best.get((a, b))
            if j is None or self.dist[i] < self.dist[j]:
                best[(a, b)] = i
        return best


def _geom_shape(gtype: int, size: np.ndarray, vert: np.ndarray | None):
    # (shape for support_data, plane rule, below-centre flag), or None for a plane/skipped type.
    if gtype == SPHERE:
        return _shapes.sphere(float(size[0])), _kp.RULE_POINTS, False
    if gtype == CAPSULE:
        return _shapes.capsule(float(size[0]), float(size[1])), _kp.RULE_POINTS, False
    if gtype == BOX:
        return _shapes.box(np.asarray(size[:3], dtype=np.float64)), _kp.RULE_VERTICES, True
    if gtype == MESH:
        return _shapes.mesh(np.asarray(vert, dtype=np.float64)), _kp.RULE_VERTICES, False
    if gtype == CYLINDER:
        return Cylinder(float(size[0]), float(size[1])), _kp.RULE_CYLINDER, False
    if gtype == ELLIPSOID:
        return Ellipsoid(np.asarray(size[:3], dtype=np.float64)), _kp.RULE_SUPPORT, False
    raise ValueError(f"unsupported geom type {gtype}")


def _polytope(model, g: int, gtype: int, size: np.ndarray):
    # The hull faces of a box or mesh geom (geom frame), else None.
    if gtype == BOX:
        return _faces.polytope_faces(_shapes.box(np.asarray(size[:3], dtype=np.float64)).points)
    if gtype == MESH:
        mid = int(model.geom_dataid[g])
        adr, num = int(model.mesh_vertadr[mid]), int(model.mesh_vertnum[mid])
        return _faces.polytope_faces(np.asarray(model.mesh_vert[adr:adr + num], dtype=np.float64))
    return None


class GeomTable:
    """Per-geom narrow-phase data of a model, flat (the arrays `collide._kernels.manifold` reads).

    Parameters
    ----------
    model : mujoco.MjModel or an object with its attribute names
        Read once: ``geom_type``, ``geom_size``, ``geom_dataid``, ``mesh_vertadr``,
        ``mesh_vertnum``, ``mesh_vert``, ``geom_margin``, ``geom_gap``, ``pair_geom1``,
        ``pair_geom2``, ``pair_margin``, ``pair_gap``, ``opt.enableflags``, ``opt.o_margin``, and
        ``geom_contype``, ``geom_conaffinity`` where it has them.

    Raises
    ------
    ValueError
        For a geom the narrow phase cannot take, naming it: `collide.support.support_data`'s
        errors, or a size outside `collide.support.SIZE_MIN` .. ``SIZE_MAX`` (a geom that never
        collides is kept then, and refused only by the calls that query it).

    Attributes
    ----------
    ngeom : int
    cls : (G,) int8
        `collide._kernels.manifold.PLANE`, ``CONVEX`` or ``SKIPPED``.
    rule : (G,) int8
        Plane rule (`collide._kernels.plane`'s ``RULE_*``).
    below : (G,) bool
    kind : (G,) int64
    prm : (G, 4) float64
    pts : (N, 3) float64
    pts_adr, pts_num, nbr_start_adr, nbr_start_num, nbr_adr, nbr_num : (G,) int64
    nbr_start, nbr : int32 arrays
        Each geom's `collide.support.SupportData`, concatenated.
    rbound : (G,) float64
        A ball about the geom's origin holding the geom.
    size : (G,) float64
    geom_margin, geom_gap : (G,) float64
    pair_key : (P,) int64
        ``g1 * G + g2``, lower id first, sorted; ``pair_margin``, ``pair_gap`` : (P,) float64 in its order.
    pair_mult : int
        The most ``<pair>`` s naming one geom pair (each is collided, as MuJoCo does).
    override : bool
    o_margin : float
    gtype : (G,) int8
        MuJoCo's geom types (`GEOM_TYPES`).
    half : (G, 3) float64
        Half sizes of the boxes (zeros for other geoms).
    faces : collide.faces.FaceTable
        Hull faces of the boxes and meshes (face contacts, `collide._kernels.faces`).

    Notes
    -----
    The per-geom and support arrays above and the face arrays `kernel_args` hands out are views
    of four packed buffers, one a dtype; the kernel's scratch and an output arena are made here,
    once, and their addresses kept in a context (`collide._kernels.manifold.collide_bound` takes
    its address, not sixteen arrays). `contacts_of` runs the kernel with the GIL held, so calls on
    one table never share the scratch at once, and reads a call's rows from the arena it passed
    (rows handed out are never written again). Copies and unpickled tables rebind their views and
    context to their own buffers and get an arena of their own.

    Everything is read from the model once, margins and gaps included (copies, not views of the
    model's arrays): a model edited after the table was made is not seen, as the broad phase
    reads the geometry once too. Build a new table (or `collide.mujoco.Collider`) after editing.
    """

    def __init__(self, model):
        types = np.asarray(model.geom_type, dtype=np.int64)
        G = len(types)
        self.ngeom = G
        sizes = np.asarray(model.geom_size, dtype=np.float64).reshape(G, 3)
        self.cls = np.full(G, _km.CONVEX, np.int8)
        self.rule = np.zeros(G, np.int8)
        self.below = np.zeros(G, np.bool_)
        self.kind = np.zeros(G, np.int64)
        self.prm = np.zeros((G, 4))
        self.rbound = np.zeros(G)
        self.size = np.ones(G)
        pts, ns, nb = [], [], []
        self.pts_adr, self.pts_num = np.zeros(G, np.int64), np.zeros(G, np.int64)
        self.nbr_start_adr, self.nbr_start_num = np.zeros(G, np.int64), np.zeros(G, np.int64)
        self.nbr_adr, self.nbr_num = np.zeros(G, np.int64), np.zeros(G, np.int64)
        npts = nns = nnb = 0
        never = never_collides(model, G)
        self._outside = np.zeros(G, np.bool_)
        for g in range(G):
            t = int(types[g])
            if t == PLANE:
                self.cls[g] = _km.PLANE
                continue
            if t in (HFIELD, SDF):
                self.cls[g] = _km.SKIPPED
                continue
            vert = None
            if t == MESH:
                mid = int(model.geom_dataid[g])
                adr, num = int(model.mesh_vertadr[mid]), int(model.mesh_vertnum[mid])
                vert = np.asarray(model.mesh_vert[adr:adr + num], dtype=np.float64)
            try:
                shape, rule, below = _geom_shape(t, sizes[g], vert)
                sd = support_data(shape)
            except ValueError as exc:
                raise ValueError(f"model: geom {g}: {exc}") from None
            if not SIZE_MIN <= sd.size <= SIZE_MAX:  # (`collide.support.SIZE_MIN`'s comment)
                if not never[g]:
                    raise ValueError(f"model: geom {g}{_named(model, g)}: {_outside_message(sd.size)} "
                                     "(scale the model)")
                self._outside[g] = True  # a geom that never collides: refused only where queried
            self.rule[g], self.below[g], self.kind[g], self.prm[g] = rule, below, sd.kind, sd.prm
            self.size[g] = sd.size
            if t == CYLINDER:
                rb = math.hypot(sizes[g, 0], sizes[g, 1])
            elif t == ELLIPSOID:
                rb = float(np.max(sizes[g]))
            else:
                rb = float(np.sqrt(np.max(np.einsum("ij,ij->i", sd.points, sd.points)))) + float(sd.prm[3])
            self.rbound[g] = rb * (1.0 + 1e-12)
            self.pts_adr[g], self.pts_num[g] = npts, len(sd.points)
            self.nbr_start_adr[g], self.nbr_start_num[g] = nns, len(sd.nbr_start)
            self.nbr_adr[g], self.nbr_num[g] = nnb, len(sd.nbr)
            npts += len(sd.points)
            nns += len(sd.nbr_start)
            nnb += len(sd.nbr)
            pts.append(sd.points)
            ns.append(sd.nbr_start)
            nb.append(sd.nbr)
        self.pts = np.ascontiguousarray(np.concatenate(pts) if pts else np.zeros((0, 3)))
        self.nbr_start = np.ascontiguousarray(np.concatenate(ns) if ns else np.zeros(0, np.int32), dtype=np.int32)
        self.nbr = np.ascontiguousarray(np.concatenate(nb) if nb else np.zeros(0, np.int32), dtype=np.int32)
        self.geom_margin = np.ascontiguousarray(model.geom_margin, dtype=np.float64)
        self.geom_gap = np.ascontiguousarray(model.geom_gap, dtype=np.float64)
        p1 = np.asarray(model.pair_geom1, dtype=np.int64)
        p2 = np.asarray(model.pair_geom2, dtype=np.int64)
        key = np.minimum(p1, p2) * G + np.maximum(p1, p2)
        order = np.argsort(key, kind="stable")  # duplicate <pair>s: each collided, in model order
        self.pair_key = np.ascontiguousarray(key[order])
        self.pair_margin = np.ascontiguousarray(np.asarray(model.pair_margin, dtype=np.float64)[order])
        self.pair_gap = np.ascontiguousarray(np.asarray(model.pair_gap, dtype=np.float64)[order])
        self._override = bool(int(model.opt.enableflags) & ENBL_OVERRIDE)
        self._o_margin = float(model.opt.o_margin)
        # The most <pair>s naming one geom pair (MuJoCo collides each: contacts per pair multiply).
        self.pair_mult = int(np.max(np.unique(key, return_counts=True)[1])) if len(key) else 1
        # Face contacts (collide._kernels.faces): MuJoCo's types, box half sizes, hull faces.
        self.gtype = np.ascontiguousarray(types, dtype=np.int8)
        self.half = np.ascontiguousarray(np.where((types == BOX)[:, None], sizes, 0.0))
        self.faces = _faces.FaceTable([_polytope(model, g, int(types[g]), sizes[g]) for g in range(G)])
        self._pack()
        self._any_skipped = bool(np.any(self.cls == _km.SKIPPED))
        self._any_outside = bool(self._outside.any())
        self._no_skipped = _no_rows((2,), np.int32)  # a read-only view, never resized in place (`_empty_contacts`)
        self._per_pair = _km.MAX_PER_PAIR * self.pair_mult
        self._skip = np.empty(0, np.bool_)  # `contacts_of`'s skipped flags where no geom is skipped
        self._empty = _empty_contacts()
        self._new_ctx()

    def _new_ctx(self) -> None:
        # The kernel's context (`collide._kernels.manifold.CTX_FIELDS`) on this table's buffers
        # (made by `_pack`, or copied by `__setstate__`, before), and an output arena of its own.
        # The context holds addresses only: the buffers are this table's attributes, never
        # replaced once it is made.
        self._ctx = np.zeros(_km.NCTX, np.int64)
        self._ctx_addr = self._ctx.ctypes.data
        ctx = self._ctx
        for c, a in zip((_km.C_TF, _km.C_TI, _km.C_T8, _km.C_T32, _km.C_WSF, _km.C_WSI),
                        self._tables + (self._wsf, self._wsi)):
            ctx[c], ctx[c + 1] = a.ctypes.data, a.size
        ctx[_km.C_PER_PAIR] = self._per_pair
        ctx[_km.C_OVERRIDE] = int(self._override)
        ctx[_km.C_O_MARGIN] = np.float64(self._o_margin).view(np.int64)
        self._new_out(OUT_ROWS)

    def _pack(self) -> None:
        # The kernel's tables, one buffer a dtype (`collide._kernels.manifold.collide_bound` reads
        # them from a context of four addresses, not forty arrays); the attributes become views of
        # them (`_bind`: one copy, which `kernel_args` hands out too), and the kernel's scratch is
        # made here, once.
        fa = self.faces.kernel_args()
        slots = {_km.S_PRM: self.prm, _km.S_PTS: self.pts, _km.S_RBOUND: self.rbound, _km.S_SIZE: self.size,
                 _km.S_GEOM_MARGIN: self.geom_margin, _km.S_GEOM_GAP: self.geom_gap,
                 _km.S_PAIR_MARGIN: self.pair_margin, _km.S_PAIR_GAP: self.pair_gap, _km.S_HALF: self.half,
                 _km.S_HV: fa[2], _km.S_F_NORMAL: fa[5], _km.S_F_OFFSET: fa[6],
                 _km.S_KIND: self.kind, _km.S_PTS_ADR: self.pts_adr, _km.S_PTS_NUM: self.pts_num,
                 _km.S_NBR_START_ADR: self.nbr_start_adr, _km.S_NBR_START_NUM: self.nbr_start_num,
                 _km.S_NBR_ADR: self.nbr_adr, _km.S_NBR_NUM: self.nbr_num, _km.S_PAIR_KEY: self.pair_key,
                 _km.S_HV_ADR: fa[0], _km.S_HV_NUM: fa[1], _km.S_F_ADR: fa[3], _km.S_F_NUM: fa[4],
                 _km.S_F_VADR: fa[7], _km.S_F_VNUM: fa[8],
                 _km.S_CLS: self.cls, _km.S_RULE: self.rule, _km.S_BELOW: self.below.view(np.int8),
                 _km.S_GTYPE: self.gtype,
                 _km.S_NBR_START: self.nbr_start, _km.S_NBR: self.nbr, _km.S_F_VIDX: fa[9]}
        header = np.zeros(_km.TI_HEADER, np.int64)
        total = [0, _km.TI_HEADER, 0, 0]  # ti begins with the header
        for s, a in slots.items():
            b = _km.SLOT_BUFFER[s]
            if a.dtype != _km.BUFFER_DTYPES[b] or a.shape[1:] != ((_km.SLOT_COLS[s],) if _km.SLOT_COLS[s] > 1 else ()):
                raise AssertionError(f"slot {s}: {a.dtype} {a.shape} does not fit its buffer")  # a bug, not input
            header[2 * s], header[2 * s + 1] = total[b], len(a)
            total[b] += a.size
        bufs = [np.zeros(n, t) for t, n in zip(_km.BUFFER_DTYPES, total)]
        bufs[1][:_km.TI_HEADER] = header
        self._tables = tuple(bufs)
        for s, v in self._views().items():
            v[...] = slots[s]
        cap, fmax = _km.scratch_caps(slots[_km.S_PTS_NUM], slots[_km.S_F_VNUM])
        bufs[1][2 * _km.N_SLOTS], bufs[1][2 * _km.N_SLOTS + 1] = cap, fmax
        nf, ni = _km.scratch_sizes(cap, fmax)
        self._wsf, self._wsi = np.zeros(nf), np.zeros(ni, np.int64)
        self._bind()

    def _new_out(self, rows: int) -> None:
        # A new output arena of ``rows`` contacts (`collide_bound` writes each call's contacts into
        # its next free rows, `contacts_of` hands them out as views): the kernel's two buffers,
        # the per-field views cut from them, and the arena's state (`collide._kernels.manifold.
        # ARENA_FIELDS`: the buffers' addresses, the rows, the first free row) and its address, in
        # one tuple (one store: a call reads one arena's parts, never two arenas'). Rows once
        # handed out are never written again; a full arena is left to the views that hold it
        # (freed with the last).
        geom = np.empty((rows, 2), np.int32)
        f = np.empty(_km.F_END * rows)
        d, p, m, q = _km.F_DIST * rows, _km.F_POS * rows, _km.F_NORMAL * rows, _km.F_MARGIN * rows
        state = np.zeros(_km.NARENA, np.int64)
        state[_km.A_GEOM], state[_km.A_F], state[_km.A_ROWS] = geom.ctypes.data, f.ctypes.data, rows
        self._out = (geom, f, f[d:d + rows], f[p:p + 3 * rows].reshape(rows, 3), f[m:m + 3 * rows].reshape(rows, 3),
                     f[q:q + rows], state, state.ctypes.data)

    def _views(self) -> dict:
        # Each slot's view of the packed buffers, by the header in ``_tables[1]``.
        ti = self._tables[1]
        views = {}
        for s in range(_km.N_SLOTS):
            o, n, c = int(ti[2 * s]), int(ti[2 * s + 1]), _km.SLOT_COLS[s]
            v = self._tables[_km.SLOT_BUFFER[s]][o:o + n * c]
            views[s] = v.reshape(n, c) if c > 1 else v
        return views

    def _bind(self) -> None:
        # The attributes, `kernel_args` and ``_kargs`` as views of the packed buffers (after
        # `_pack`, and after a copy or unpickling, which copy the buffers and the views apart).
        views = self._views()
        for name, s in _SLOT_ATTR.items():
            setattr(self, name, views[s])
        self.below = views[_km.S_BELOW].view(np.bool_)
        self._face_args = tuple(views[s] for s in (_km.S_HV_ADR, _km.S_HV_NUM, _km.S_HV, _km.S_F_ADR, _km.S_F_NUM,
                                                   _km.S_F_NORMAL, _km.S_F_OFFSET, _km.S_F_VADR, _km.S_F_VNUM,
                                                   _km.S_F_VIDX))
        # Per step, `collide.mujoco.Collider.check_batch` reuses these (building the tuple costs a call).
        self._kargs = self.kernel_args()

    def __getstate__(self) -> dict:
        # The packed buffers and the scalars; the views are rebound on the copy (`__setstate__`).
        views = set(_SLOT_ATTR) | {"below", "_face_args", "_kargs", "_out", "_empty", "_no_skipped", "_ctx",
                                   "_ctx_addr"}
        return {k: v for k, v in self.__dict__.items() if k not in views}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        # a scratch of its own (`copy.copy` shares the rest): the kernel's warm-start cache in it
        # (`collide._kernels.warm`) is this table's alone, empty; sized by this version's layout, not
        # the pickled arrays' (a table pickled by an older version, whose scratch was shorter, made the
        # kernel write past its end)
        ti = self._tables[1]
        nf, ni = _km.scratch_sizes(ti[2 * _km.N_SLOTS], ti[2 * _km.N_SLOTS + 1])
        self._wsf, self._wsi = np.zeros(nf), np.zeros(ni, np.int64)
        self._bind()
        self._new_ctx()  # an arena of its own: a copy never writes into rows the original handed out
        # read-only views again (unpickled arrays own their data and are writeable)
        self._empty, self._no_skipped = _empty_contacts(), _no_rows((2,), np.int32)

    @property
    def override(self) -> bool:
        """Whether ``mjENBL_OVERRIDE`` was set (read once from ``model.opt.enableflags``)."""
        return self._override

    @property
    def o_margin(self) -> float:
        """``model.opt.o_margin``, read once."""
        return self._o_margin

    def kernel_args(self, pair_margin: np.ndarray | None = None, pair_gap: np.ndarray | None = None) -> tuple:
        """The per-geom arguments of `collide._kernels.manifold.collide_pairs`, in its order.

        Parameters
        ----------
        pair_margin, pair_gap : (P,) float64, optional
            In place of the table's (`collide.mujoco.Collider.check_batch`'s, see there).
        """
        pm = self.pair_margin if pair_margin is None else pair_margin
        pg = self.pair_gap if pair_gap is None else pair_gap
        return (self.cls, self.rule, self.below, self.kind, self.prm, self.pts, self.pts_adr, self.pts_num,
                self.nbr_start, self.nbr_start_adr, self.nbr_start_num, self.nbr, self.nbr_adr, self.nbr_num,
                self.rbound, self.size, self.geom_margin, self.geom_gap, self.pair_key, pm, pg, self.override,
                self.o_margin, self.gtype, self.half) + self._face_args

    def shape_args(self) -> tuple:
        """The per-geom arguments of `collide._kernels.manifold.pair_signed_distance`, in its order."""
        return (self.cls, self.kind, self.prm, self.pts, self.pts_adr, self.pts_num, self.nbr_start,
                self.nbr_start_adr, self.nbr_start_num, self.nbr, self.nbr_adr, self.nbr_num, self.size)


def _poses(table: GeomTable, geom_xpos, geom_xmat) -> tuple[np.ndarray, np.ndarray]:
    # Contiguous float64 (G, 3) and (G, 3, 3) views (copies only when needed), shapes checked.
    G = table.ngeom
    xpos = np.asarray(geom_xpos)
    xmat = np.asarray(geom_xmat)
    for name, a in (("geom_xpos", xpos), ("geom_xmat", xmat)):
        if a.dtype.kind == "c":  # numpy's cast to float64 would drop the imaginary part with a warning
            raise ValueError(f"{name}: complex values are not coordinates (got dtype {a.dtype})")
    if xpos.shape != (G, 3):
        raise ValueError(f"geom_xpos: expected shape ({G}, 3), got {xpos.shape}")
    if xmat.shape not in ((G, 9), (G, 3, 3)):
        raise ValueError(f"geom_xmat: expected shape ({G}, 9) or ({G}, 3, 3), got {xmat.shape}")
    xpos = np.ascontiguousarray(xpos, dtype=np.float64)
    xmat = np.ascontiguousarray(xmat, dtype=np.float64).reshape(G, 3, 3)
    return xpos, xmat


def narrow_phase(table: GeomTable, pairs, geom_xpos, geom_xmat) -> Contacts:
    """Contacts of the geom pairs ``pairs`` at the geoms' world poses.

    Parameters
    ----------
    table : GeomTable
    pairs : (K, 2) array_like of int
        Geom ids (a broad phase's output), lower first; an empty list is no pairs.
    geom_xpos : (G, 3) array_like of float
    geom_xmat : (G, 9) or (G, 3, 3) array_like of float
        World poses of every geom (MuJoCo's ``data.geom_xpos``, ``data.geom_xmat``).

    Returns
    -------
    Contacts

    Raises
    ------
    ValueError
        Wrong shapes, a geom id out of range or a pair not lower-id first, a geom the table keeps
        outside `collide.support.SIZE_MIN` .. ``SIZE_MAX`` (one that never collides), or the pose
        of a geom in a pair non-finite, its rotation not proper orthonormal (within
        `collide.articulation.POSE_ORTHO_TOL`) or its position beyond
        `collide.hull.MAX_COORDINATE` (naming it).
    """
    P = np.asarray(pairs)
    if P.ndim == 1 and P.size == 0:  # no pairs, as an empty list: the empty (0, 2)
        P = P.reshape(0, 2)
    if P.ndim != 2 or P.shape[1] != 2 or (P.size and not np.issubdtype(P.dtype, np.integer)):
        raise ValueError(f"pairs: expected a (K, 2) integer array, got shape {P.shape}, dtype {P.dtype}")
    _check_ids(table, P)  # before narrowing to int32 (2**32 + 1 would become 1)
    P = np.ascontiguousarray(P, dtype=np.int32)
    xpos, xmat = _poses(table, geom_xpos, geom_xmat)
    if P.flags.writeable:  # read-only as the broad phase's pairs are: one compiled `collide_bound`
        P = P.view()
        P.flags.writeable = False
    return _contacts_of(table, P, xpos, xmat)


def _check_ids(table: GeomTable, P: np.ndarray) -> None:
    if len(P) and (P.min() < 0 or P.max() >= table.ngeom or np.any(P[:, 0] >= P[:, 1])):
        raise ValueError(f"pairs: geom ids must be in [0, {table.ngeom}) with the lower id first")
    if table._any_outside and len(P) and table._outside[P].any():
        g = int(P[table._outside[P]][0])
        raise ValueError(f"pairs: geom {g}: {_outside_message(table.size[g])}")


def never_collides(model, G: int) -> np.ndarray:
    """The geoms no pair of MuJoCo's collides: contype and conaffinity 0, and in no ``<pair>``.

    Parameters
    ----------
    model : mujoco.MjModel or an object with its attribute names
    G : int
        The number of geoms.

    Returns
    -------
    (G,) bool
        All False for a model object without ``geom_contype`` and ``geom_conaffinity``.
    """
    contype, conaffinity = getattr(model, "geom_contype", None), getattr(model, "geom_conaffinity", None)
    if contype is None or conaffinity is None:
        return np.zeros(G, np.bool_)
    never = (np.asarray(contype).reshape(G) == 0) & (np.asarray(conaffinity).reshape(G) == 0)
    never[np.asarray(model.pair_geom1, dtype=np.int64)] = False
    never[np.asarray(model.pair_geom2, dtype=np.int64)] = False
    return never


def _named(model, g: int) -> str:
    # " ('name')" of geom g where the model names it, else "".
    try:
        name = model.geom(g).name
    except Exception:  # a model object without mujoco's accessors
        return ""
    return f" ('{name}')" if name else ""


def _outside_message(size: float) -> str:
    return (f"size {size:.3g} is outside [{SIZE_MIN:.3g}, {SIZE_MAX:.3g}], the sizes the narrow phase "
            "supports")


def contacts_of(table: GeomTable, pairs: np.ndarray, xpos: np.ndarray, xmat: np.ndarray) -> Contacts:
    """`narrow_phase` on input in the kernel's own types (no conversion on that path).

    Parameters
    ----------
    table : GeomTable
    pairs : (K, 2) int32, C-contiguous
        Geom ids in ``[0, G)``, lower first (checked).
    xpos : (G, 3) float64, C-contiguous
    xmat : (G, 3, 3) float64, C-contiguous
        Input of another dtype, layout or shape is converted and checked as `narrow_phase` does:
        the kernel is called through its compiled entry point, which reads its arguments as
        these types without checking them (a Fortran-ordered or strided array would be read
        wrongly, a 1-D one past its end).

    Returns
    -------
    Contacts
        Its arrays are views of rows of the table's output arena that are never written again
        (the views keep it alive); without contacts or skipped pairs, the table's one empty
        `Contacts`.

    Raises
    ------
    ValueError
        As `narrow_phase`: wrong shapes, a bad geom id, a pose refused (non-finite, not a
        rotation) of a geom in a pair.
    """
    G = table.ngeom
    if not (type(pairs) is np.ndarray and pairs.dtype == np.int32 and pairs.ndim == 2 and pairs.shape[1] == 2
            and pairs.flags.c_contiguous and type(xpos) is np.ndarray and xpos.dtype == np.float64
            and xpos.shape == (G, 3) and xpos.flags.c_contiguous and type(xmat) is np.ndarray
            and xmat.dtype == np.float64 and xmat.shape == (G, 3, 3) and xmat.flags.c_contiguous):
        return narrow_phase(table, pairs, xpos, xmat)
    _check_ids(table, pairs)
    return _contacts_of(table, pairs, xpos, xmat)


def _pose_problem(xpos: np.ndarray, xmat: np.ndarray, g: int) -> str | None:
    # What the kernels' pose test (`manifold._pose_refused`) refuses in geom g's pose, said for a
    # ValueError; None where it takes it. Run only once a kernel has refused a pose.
    p, r = xpos[g], xmat[g]
    if not (np.isfinite(p).all() and np.isfinite(r).all()):
        return f"geom_xpos/geom_xmat: non-finite pose (NaN or inf) of geom {g}"
    if not (np.abs(p) <= _pose.MAX_POSITION).all():
        return f"geom_xpos: the position of geom {g} is beyond {_pose.MAX_POSITION:g} (the coordinate limit)"
    if not _pose._pose_ok.py_func(*r.ravel(), *p):
        return (f"geom_xmat: the rotation of geom {g} is not a proper rotation (an entry of |R^T R - I| above "
                f"{_pose.ORTHO_TOL:g}, or a reflection)")
    return None


def _contacts_of(table: GeomTable, pairs: np.ndarray, xpos: np.ndarray, xmat: np.ndarray) -> Contacts:
    # `contacts_of` unchecked: pairs (K, 2) int32, xpos (G, 3), xmat (G, 3, 3) float64, all
    # C-contiguous, ids in range and lower first, as the broad phase's pairs and `_poses`' views
    # are by construction (`collide.mujoco.Collider.contacts`, `narrow_phase`). `_bound` reads
    # them as those types without a check: anything else is read wrongly or past its end.
    K = len(pairs)
    if K == 0:
        return table._empty
    any_skipped = table._any_skipped
    if any_skipped:
        skipped = np.empty(K, np.bool_)  # the kernel writes every entry
    else:
        skipped = table._skip
        if len(skipped) < K:
            skipped = table._skip = np.empty(2 * K, np.bool_)
    # The rows are read from the arena passed: another thread (or a signal handler) may start a
    # new one before they are read, never in the call (it holds the GIL).
    out = table._out
    # The compiled function's entry point, called directly (`_first_bound`): the arguments have
    # its types by construction (the broad phase's pairs, `_poses`' views, the table's buffers).
    r = _bound(pairs, xpos, xmat, skipped, table._ctx_addr, out[7])
    while r == _km.OUT_FULL:  # a new arena, large enough for this call
        table._new_out(max(OUT_ROWS, 4 * table._per_pair * K))
        out = table._out
        r = _bound(pairs, xpos, xmat, skipped, table._ctx_addr, out[7])
    if r < 0:
        g = -r - 2  # a refused pose of geom g (`manifold._collide`)
        raise ValueError(_pose_problem(xpos, xmat, g) or f"geom_xpos/geom_xmat: the pose of geom {g} is refused")
    n = r & 0xFFFFFFFF
    if n == 0 and not any_skipped:
        return table._empty
    o = r >> 32
    e = o + n
    # Built without the frozen dataclass's __init__ (a setattr per field): the same fields.
    c = _new(Contacts)
    c.__dict__.update(geom=out[0][o:e], dist=out[2][o:e], pos=out[3][o:e], normal=out[4][o:e], margin=out[5][o:e],
                      skipped=pairs[skipped[:K]] if any_skipped else table._no_skipped)
    return c


_new = object.__new__

# Rows of a new output arena (`GeomTable._new_out`): the contacts of many calls; a call needs
# ``per_pair * K`` free rows, and a larger arena is made when a call needs more.
OUT_ROWS = 4096


def _empty_contacts() -> Contacts:
    # No contacts, no skipped pair: one per table, handed out by every such call. Its arrays are
    # read-only views (zero rows of a one-row array): an array owning its data could be resized
    # in place (``c.dist.resize(5)``), which every later empty result would show.
    c = _new(Contacts)
    c.__dict__.update(geom=_no_rows((2,), np.int32), dist=_no_rows(()), pos=_no_rows((3,)), normal=_no_rows((3,)),
                      margin=_no_rows(()), skipped=_no_rows((2,), np.int32))
    return c


def _no_rows(cols: tuple, dtype=np.float64) -> np.ndarray:
    # A read-only (0, *cols) view (`_empty_contacts`).
    a = np.zeros((1,) + cols, dtype)[:0]
    a.flags.writeable = False
    return a


def _first_bound(*args):
    # `_bound` until the first call: compiles (or loads from numba's cache) `collide_bound` for
    # the types `_contacts_of` passes (pairs read-only, as the broad phase hands them out), then
    # binds `_bound` to that compiled function's entry point. The dispatcher checks every
    # argument's type on each call; the entry point behind it unboxes them as that signature's
    # types without checking, so only `_contacts_of`, whose arguments have them by construction,
    # calls it (the dispatcher where this numba does not expose the entry point).
    global _bound
    from numba import types as nt

    sig = (nt.Array(nt.int32, 2, "C", readonly=True), nt.Array(nt.float64, 2, "C"), nt.Array(nt.float64, 3, "C"),
           nt.Array(nt.boolean, 1, "C"), nt.int64, nt.int64)
    disp = _km.collide_bound
    disp.compile(sig)
    try:
        entry = disp.overloads[sig].entry_point
    except (AttributeError, KeyError):
        entry = None
    _bound = entry if callable(entry) else disp
    return _bound(*args)


_bound = _first_bound

# `GeomTable`'s attributes that are slots (``below`` is ``S_BELOW`` viewed as bool; the face slots
# are `GeomTable.faces`' arrays, handed to the kernel in ``_face_args``).
_SLOT_ATTR = {"prm": _km.S_PRM, "pts": _km.S_PTS, "rbound": _km.S_RBOUND, "size": _km.S_SIZE,
              "geom_margin": _km.S_GEOM_MARGIN, "geom_gap": _km.S_GEOM_GAP, "pair_margin": _km.S_PAIR_MARGIN,
              "pair_gap": _km.S_PAIR_GAP, "half": _km.S_HALF, "kind": _km.S_KIND, "pts_adr": _km.S_PTS_ADR,
              "pts_num": _km.S_PTS_NUM, "nbr_start_adr": _km.S_NBR_START_ADR, "nbr_start_num": _km.S_NBR_START_NUM,
              "nbr_adr": _km.S_NBR_ADR, "nbr_num": _km.S_NBR_NUM, "pair_key": _km.S_PAIR_KEY, "cls": _km.S_CLS,
              "rule": _km.S_RULE, "gtype": _km.S_GTYPE, "nbr_start": _km.S_NBR_START, "nbr": _km.S_NBR}


def geom_distance(table: GeomTable, g1: int, g2: int, geom_xpos, geom_xmat, distmax: float) -> tuple[float, np.ndarray]:
    """Signed distance of two geoms, capped at ``distmax``, and the segment between them.

    Parameters
    ----------
    table : GeomTable
    g1, g2 : int
        Two different geom ids, in any order.
    geom_xpos : (G, 3) array_like of float
    geom_xmat : (G, 9) or (G, 3, 3) array_like of float
    distmax : float

    Returns
    -------
    dist : float
        ``min(signed distance, distmax)``; ``distmax`` for two planes (no function, as in MuJoCo).
    fromto : (6,) float64
        The nearest point of ``g1`` then of ``g2`` (world frame) when ``dist < distmax``, else zeros
        (as ``mujoco.mj_geomDistance``).

    Raises
    ------
    ValueError
        A bad id, a height field or SDF geom (not supported), a geom outside
        `collide.support.SIZE_MIN` .. ``SIZE_MAX`` (one that never collides, kept by the table), a
        non-finite pose or ``distmax``, a rotation not proper orthonormal (as `narrow_phase`).
    """
    g1, g2, distmax = _distance_args(table, g1, g2, distmax)
    xpos, xmat = _poses(table, geom_xpos, geom_xmat)
    if not (xpos.flags.behaved and xmat.flags.behaved):  # the kernel's one signature: aligned, writable
        xpos, xmat = xpos.copy(), xmat.copy()
    return _geom_distance(table, g1, g2, xpos, xmat, distmax)


def _distance_args(table: GeomTable, g1, g2, distmax) -> tuple[int, int, float]:
    # `geom_distance`'s ids and cap checked: (g1, g2, distmax) as ints and a float, or the ValueError.
    G = table.ngeom
    if not (type(g1) is int and type(g2) is int and 0 <= g1 < G and 0 <= g2 < G and g1 != g2):
        for name, g in (("g1", g1), ("g2", g2)):
            if not (isinstance(g, (int, np.integer)) and not isinstance(g, bool) and 0 <= int(g) < G):
                raise ValueError(f"{name}: expected a geom id in [0, {G}), got {g!r}")
        g1, g2 = int(g1), int(g2)
        if g1 == g2:
            raise ValueError(f"g1, g2: the same geom ({g1})")
    if type(distmax) is not float or not math.isfinite(distmax):
        distmax = _as_finite(distmax, "distmax")
    if table._any_outside and (table._outside[g1] or table._outside[g2]):
        g = g1 if table._outside[g1] else g2
        raise ValueError(f"g1, g2: geom {g}: {_outside_message(table.size[g])} (scale the model)")
    return g1, g2, distmax


def _geom_distance(table: GeomTable, g1: int, g2: int, xpos: np.ndarray, xmat: np.ndarray,
                   distmax: float) -> tuple[float, np.ndarray]:
    # `geom_distance` unchecked: the arguments as `_distance_args` returns them, and xpos (G, 3),
    # xmat (G, 3, 3) float64, C-contiguous, aligned and writable (`_poses`' views of an MjData's
    # arrays are); the kernel reads the table's buffers through its context.
    out = np.empty(7)
    err = _km.pair_signed_distance_bound(g1, g2, xpos, xmat, table._ctx_addr, distmax, out)
    if err:
        if err == 2:
            raise ValueError(f"g1, g2: geom {g1 if table.cls[g1] == _km.SKIPPED else g2} is a height "
                             "field or SDF, which the narrow phase does not collide")
        if err == 3:
            raise ValueError(_pose_problem(xpos, xmat, g1) or _pose_problem(xpos, xmat, g2)
                             or f"geom_xpos/geom_xmat: the pose of geom {g1} or {g2} is refused")
        return distmax, np.zeros(6)  # two planes, or bounding balls beyond distmax
    if not out[0] < distmax:
        return distmax, np.zeros(6)
    return float(out[0]), out[1:7]
