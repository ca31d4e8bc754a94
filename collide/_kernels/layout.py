"""Every flat buffer of the per-step broad phase, declared once.

The per-step kernels take their static model and workspaces as a few flat arrays (see `_ptr`: an
array argument costs a numba call more than an integer, and views built from addresses carry no
reference count). Which part of a buffer holds what was once written out as offsets in several
places (the packer, the kernels' views, the workspace sizes): one wrong count there reads a
neighbouring buffer silently. Here each buffer is a `Layout`: an ordered list of fields, each a
name and a shape in the model's counts (``"L + 1"``, ``"Q, L"``). From that one declaration

- the Python side packs arrays *by name*, checking every shape (`Layout.pack`), and sizes the
  workspaces (`Layout.size`);
- `Tables.table` writes each field's offset and dimensions into a *field table*, at ``TABLE`` in
  the int64 array that carries the counts (``I`` for the per-world model, ``J`` for the lanes);
- a kernel takes a view of a field by its slot (``view_i1(I, I, ORDER)``, ``view_f2(I, W, BW)``):
  its offset and shape are read from that table, never computed.

Adding a field is one line in its layout; its order there is its order in the buffer.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ._ptr import check_span, f64_ptr, i64_ptr, view_of
from ._simd import LANES

TABLE = 16  # the field table starts here in its int64 carrier (the counts' header comes first)
SLOT = 5  # a table entry: offset, then up to four dimensions (unused ones 1)
MAX_DIMS = SLOT - 1

# A bounds record ("row") is ROW float64: OBB centre (3), OBB rotation (9, row-major, columns are
# the box axes), OBB half extents (3), sphere centre (3), sphere radius (1).
ROW = 19
N_COH = 8  # frame-coherence state slots (`coherence.FAT_GROW`)
CONSTANTS = {"ROW": ROW, "LANES": LANES, "N_COH": N_COH}


def _split(shape: str) -> tuple[str, ...]:
    # "max(Q, 1), 4" -> ("max(Q, 1)", "4"): split at the commas outside parentheses
    parts, depth, cur = [], 0, ""
    for ch in shape:
        depth += (ch == "(") - (ch == ")")
        if ch == "," and depth == 0:
            parts.append(cur.strip())
            cur = ""
        else:
            cur += ch
    return tuple(parts + [cur.strip()])


class Tables:
    """A group of layouts whose field table lives in one int64 carrier array (its first layout).

    Slots are numbered across the group, in the order fields are declared.
    """

    def __init__(self, name: str, header: int):
        if header > TABLE:
            raise ValueError(f"{name}: a header of {header} counts does not fit before the table at {TABLE}")
        self.name = name
        self.header = header
        self.layouts: list[Layout] = []
        self.slots = 0

    @property
    def start(self) -> int:
        """Where the carrier's first field starts: after the header's room and the table."""
        return TABLE + SLOT * self.slots

    def table(self, dims: dict) -> np.ndarray:
        """The field table ``(SLOT * slots,)`` int64 of every layout of the group for ``dims``."""
        out = np.ones(SLOT * self.slots, np.int64)
        for lay in self.layouts:
            for (name, _), slot, (off, shape) in zip(lay.fields, lay.slots, lay.spans(dims)):
                out[SLOT * slot] = off
                out[SLOT * slot + 1:SLOT * slot + 1 + len(shape)] = shape
        return out


class Layout:
    """One flat buffer: named fields, each a shape in counts, laid out in declaration order.

    Parameters
    ----------
    tables : Tables
        The group whose table holds this layout's slots; the group's first layout is its carrier
        (its fields start after the header and the table).
    name : str
    dtype : numpy dtype
    align : int, default 1
        The buffer's length is rounded up to a multiple of this.
    """

    def __init__(self, tables: Tables, name: str, dtype, align: int = 1):
        self.tables = tables
        self.carrier = not tables.layouts
        tables.layouts.append(self)
        self.name = name
        self.dtype = np.dtype(dtype)
        self.align = align
        self.fields: list[tuple[str, tuple[str, ...]]] = []
        self.slots: list[int] = []

    def field(self, name: str, shape: str) -> int:
        """Declare the next field; returns its slot (a module constant the kernels index with).

        ``shape``: comma-separated expressions in the counts (`Layout.spans`' ``dims``), e.g.
        ``"L - 1"`` or ``"max(Q, 1), 4"``.
        """
        if any(f[0] == name for f in self.fields):
            raise ValueError(f"{self.name}: field {name!r} declared twice")
        parts = _split(shape)
        if not 1 <= len(parts) <= MAX_DIMS:
            raise ValueError(f"{self.name}.{name}: 1 to {MAX_DIMS} dimensions")
        self.fields.append((name, parts))
        slot = self.tables.slots
        self.tables.slots += 1
        self.slots.append(slot)
        return slot

    def spans(self, dims: dict) -> list[tuple[int, tuple[int, ...]]]:
        """``(offset, shape)`` of every field for the counts ``dims`` (names to ints)."""
        env = {"max": max, "min": min, **CONSTANTS, **dims}
        off = self.tables.start if self.carrier else 0
        out = []
        for name, parts in self.fields:
            try:
                shape = tuple(int(eval(p, {"__builtins__": {}}, env)) for p in parts)  # our own declarations
            except NameError as exc:
                raise ValueError(f"{self.name}.{name}: count missing from dims ({exc})") from None
            if min(shape) < 0:
                raise ValueError(f"{self.name}.{name}: negative dimension {shape} for {dims}")
            out.append((off, shape))
            off += int(np.prod(shape))
        return out

    def size(self, dims: dict) -> int:
        """Length of the buffer for ``dims``: every field, then the alignment."""
        spans = self.spans(dims)
        end = spans[-1][0] + int(np.prod(spans[-1][1])) if spans else 0
        return -(-end // self.align) * self.align

    def offset(self, dims: dict, name: str) -> int:
        """Offset of field ``name`` for ``dims``."""
        for (fname, _), (off, _) in zip(self.fields, self.spans(dims)):
            if fname == name:
                return off
        raise KeyError(name)

    def view(self, carrier: np.ndarray, buf: np.ndarray, name: str) -> np.ndarray:
        """Field ``name`` of ``buf`` as a numpy view, read through the table in ``carrier`` (as the
        kernels read it): for tests and set-up code."""
        for (fname, parts), slot in zip(self.fields, self.slots):
            if fname == name:
                t = TABLE + SLOT * slot
                off = int(carrier[t])
                shape = tuple(int(d) for d in carrier[t + 1:t + 1 + len(parts)])
                return buf[off:off + int(np.prod(shape))].reshape(shape)
        raise KeyError(f"{self.name}: no field {name!r}")

    def pack(self, dims: dict, header=(), **arrays) -> np.ndarray:
        """The buffer for ``dims`` with every field from ``arrays`` (by name; each must have its
        declared shape, or its size for a flat array). The carrier gets ``header`` (its counts) at
        0 and the group's field table at ``TABLE``."""
        missing = [f[0] for f in self.fields if f[0] not in arrays]
        extra = sorted(set(arrays) - {f[0] for f in self.fields})
        if missing or extra:
            raise ValueError(f"{self.name}: fields missing {missing}, unknown {extra}")
        out = np.zeros(self.size(dims), self.dtype)
        if self.carrier:
            head = np.asarray(header, np.int64)
            if head.size > self.tables.header:
                raise ValueError(f"{self.name}: header of {head.size} counts, {self.tables.header} declared")
            out[:head.size] = head
            out[TABLE:self.tables.start] = self.tables.table(dims)
        for (name, _), (off, shape) in zip(self.fields, self.spans(dims)):
            a = np.asarray(arrays[name])
            n = int(np.prod(shape))
            if a.shape != shape and not (a.ndim <= 1 and a.size == n):
                raise ValueError(f"{self.name}.{name}: shape {a.shape}, declared {shape} for {dims}")
            out[off:off + n] = a.reshape(-1)
        return out


# ------------------------------------------------------------------------------- kernel views
# A view of the field in ``slot`` of the table in ``T`` (the int64 carrier) over the buffer ``buf``
# (which may be ``T`` itself): its offset and dimensions read from the table. One function a
# dtype and a number of dimensions: numba needs both when it compiles.

@nb.njit(cache=True, inline="always")
def _entry(T, buf_size, slot, n):
    t = TABLE + SLOT * slot
    check_span(t + SLOT, T.shape[0])
    check_span(T[t] + n, buf_size)
    return T[t]


@nb.njit(cache=True, inline="always")
def view_i1(T, buf, slot):
    """int64 field ``slot`` of ``buf`` as a 1-D view."""
    t = TABLE + SLOT * slot
    o = _entry(T, buf.shape[0], slot, T[t + 1])
    return view_of(i64_ptr(np.int64(buf.ctypes.data) + 8 * o), T[t + 1])


@nb.njit(cache=True, inline="always")
def view_i2(T, buf, slot):
    """int64 field ``slot`` of ``buf`` as a 2-D view."""
    t = TABLE + SLOT * slot
    o = _entry(T, buf.shape[0], slot, T[t + 1] * T[t + 2])
    return view_of(i64_ptr(np.int64(buf.ctypes.data) + 8 * o), (T[t + 1], T[t + 2]))


@nb.njit(cache=True, inline="always")
def view_f1(T, buf, slot):
    """float64 field ``slot`` of ``buf`` as a 1-D view."""
    t = TABLE + SLOT * slot
    o = _entry(T, buf.shape[0], slot, T[t + 1])
    return view_of(f64_ptr(np.int64(buf.ctypes.data) + 8 * o), T[t + 1])


@nb.njit(cache=True, inline="always")
def view_f2(T, buf, slot):
    """float64 field ``slot`` of ``buf`` as a 2-D view."""
    t = TABLE + SLOT * slot
    o = _entry(T, buf.shape[0], slot, T[t + 1] * T[t + 2])
    return view_of(f64_ptr(np.int64(buf.ctypes.data) + 8 * o), (T[t + 1], T[t + 2]))


@nb.njit(cache=True, inline="always")
def view_f3(T, buf, slot):
    """float64 field ``slot`` of ``buf`` as a 3-D view."""
    t = TABLE + SLOT * slot
    o = _entry(T, buf.shape[0], slot, T[t + 1] * T[t + 2] * T[t + 3])
    return view_of(f64_ptr(np.int64(buf.ctypes.data) + 8 * o), (T[t + 1], T[t + 2], T[t + 3]))


@nb.njit(cache=True, inline="always")
def view_f4(T, buf, slot):
    """float64 field ``slot`` of ``buf`` as a 4-D view."""
    t = TABLE + SLOT * slot
    o = _entry(T, buf.shape[0], slot, T[t + 1] * T[t + 2] * T[t + 3] * T[t + 4])
    return view_of(f64_ptr(np.int64(buf.ctypes.data) + 8 * o), (T[t + 1], T[t + 2], T[t + 3], T[t + 4]))


@nb.njit(cache=True, inline="always")
def address(T, buf, slot):
    """The address of field ``slot`` of ``buf`` (for the vector intrinsics, which take blocks by
    address)."""
    return np.int64(buf.ctypes.data) + 8 * T[TABLE + SLOT * slot]


# The stats buffer (N_STATS int64, `BroadPhase.stats`): its slots.
(ST_SUBTREE, ST_BODY_AABB, ST_BODY_SPHERE, ST_BODY_OBB, ST_GEOM_SPHERE, ST_GEOM_OBB, ST_PLANE, ST_OUT,
 ST_GEOM_AABB, ST_REUSED) = range(10)
N_STATS = 10

# =============================================================================== the declarations
# Counts (``dims``): L positions (bodies in depth-first order, then the world's geoms as leaves, see
# `collide.broadphase.BroadPhase`), NB bodies, G geoms, Gs solid geoms, Q planes, E excluded
# partner entries, P explicit pairs; for the lanes NP static body pairs, NLG their geom pairs, NPL
# (plane, position) pairs, NPLG their geoms, NR ranks (keys a world may report), NWd = ceil(NR / 64).

# Header of I: counts. Positions (``H_L``) are the bodies in depth-first order plus, when the world
# has several solid geoms, one leaf per world geom (``H_V`` of them, at positions 1..V; see
# BroadPhase): bodies (``H_NB``) index the pose arrays, positions everything else. ``H_FLAT``: 1 when
# some subtree is flat (``flat_root``), so that the step writes ``baabb_t`` (see `bounds._place`; it
# does too up to MASK_MAX positions). `broadphase.pack` writes it.
H_L, H_G, H_GS, H_Q, H_E, H_P, H_FP, H_KS, H_NB, H_V, H_FLAT = range(11)
HEADER = 11

MODEL = Tables("I", header=HEADER)  # the per-world model; its table lives in I (counts: H_*)

INT = Layout(MODEL, "I", np.int64)  # static model, int64
I_ORDER = INT.field("order", "L")  # position -> body
I_POS_OF = INT.field("pos_of", "NB")  # body -> position
I_END = INT.field("end", "L")  # subtree of position x: [x, end[x])
I_PARENT_POS = INT.field("parent_pos", "L")
I_WELD = INT.field("weld", "L")  # weld group (bodies of one group never pair)
I_NCHILD = INT.field("nchild", "L")
I_CHILD_START = INT.field("child_start", "L")  # position x's children: children[child_start[x]:][:nchild[x]]
I_SINGLE = INT.field("single", "L")  # 1: one geom; 0: several; -1: several, loose (see BroadPhase)
I_HAS_BOUNDS = INT.field("has_bounds", "L")  # has bounds (some solid geom)
I_PAIRFLAG = INT.field("pairflag", "L")  # some geom is in an explicit pair
I_CONTYPE = INT.field("contype", "L")  # the geoms' contype, or-ed per position
I_CONAFFINITY = INT.field("conaffinity", "L")  # and their conaffinity
I_CHILDREN = INT.field("children", "L - 1")
I_GSTART = INT.field("gstart", "L + 1")  # position x's solid geoms: pgeoms[gstart[x]:gstart[x + 1]]
I_PGEOMS = INT.field("pgeoms", "Gs")
I_EX_START = INT.field("ex_start", "L + 1")  # position x's excluded partners: ex_other[ex_start[x]:ex_start[x + 1]]
I_EX_OTHER = INT.field("ex_other", "E")
I_PLANES = INT.field("planes", "Q")  # plane geom ids
I_PLANE_OK = INT.field("plane_ok", "Q, L")  # (plane, position) passes the static filter
I_GEOM_BID = INT.field("geom_bid", "G")  # geom -> body
I_GEOM_CONTYPE = INT.field("geom_contype", "G")
I_GEOM_CONAFFINITY = INT.field("geom_conaffinity", "G")
I_PAIR_G = INT.field("pair_g", "P, 2")  # explicit pairs (g1 < g2)
I_PAIR_KEYS = INT.field("pair_keys", "P")  # their keys, sorted
I_FLAT_ROOT = INT.field("flat_root", "L")  # subtrees tested from static masks (`_traverse`)
I_FLAT_N = INT.field("flat_n", "L")
I_FLAT_MASK = INT.field("flat_mask", "L")
I_SMASK = INT.field("smask", "L + 1")  # up to MASK_MAX positions: the static body-pair masks, then their count

FLT = Layout(MODEL, "F", np.float64)  # static model, float64
F_BLOCAL = FLT.field("blocal", "L, ROW")  # bounds rows by position, body frame
F_GLOCAL = FLT.field("glocal", "G, ROW")  # bounds rows by geom, body frame
F_GPLANE = FLT.field("gplane", "G, 4")  # a plane geom's (normal, offset) in its body's frame
F_GMARGIN = FLT.field("gmargin", "G")  # bounds inflation by geom
F_PAIR_M = FLT.field("pair_m", "P")  # explicit pairs' inflation
F_BCAP = FLT.field("bcap", "L, 4")  # capsules (half segment, radius) by position, on the OBB centre
F_GCAP = FLT.field("gcap", "G, 4")  # and by geom

WORK = Layout(MODEL, "W", np.float64)  # one world's workspace
W_BW = WORK.field("bw", "L, ROW")  # world rows by position
W_GW = WORK.field("gw", "G, ROW")  # world rows by geom (multi-geom bodies, on first use)
W_BAABB = WORK.field("baabb", "L, 6")  # world AABBs by position: lo, hi
W_SAABB = WORK.field("saabb", "L, 6")  # subtree AABBs
W_BAABB_T = WORK.field("baabb_t", "6, L")  # baabb's columns, for the row tests (`culling._row_hits`)
W_PLW = WORK.field("plw", "max(Q, 1), 4")  # world planes
W_TMP = WORK.field("tmp", "2, ROW")  # two scratch rows (explicit pairs)
W_GAABB = WORK.field("gaabb", "G, 6")  # world AABBs by geom
W_GSTAMP = WORK.field("gstamp", "L + 1")  # call on which a position's geom rows were made; [L]: the call counter
W_FAT_B = WORK.field("fat_b", "L, 6")  # frame coherence (`FAT_GROW`): fat boxes
W_FAT_S = WORK.field("fat_s", "L, 6")  # their subtree boxes
W_FAT_T = WORK.field("fat_t", "6, L")  # fat_b's columns
W_COH = WORK.field("coh", "N_COH")  # coherence state (COH_VALID ...)

LANE_WORK = Layout(MODEL, "LW", np.float64, align=LANES)  # a batch worker's lanes (`lanes._group`)
LW_POSES = LANE_WORK.field("poses", "NB, 12, LANES")  # per body: position (3), rotation (9), over the lanes
LW_WB = LANE_WORK.field("wb", "L, ROW, LANES")  # world rows by position
LW_WA = LANE_WORK.field("wa", "L, 6, LANES")  # world AABBs by position
LW_GW = LANE_WORK.field("gw", "G, ROW, LANES")  # world rows by geom
LW_GA = LANE_WORK.field("ga", "G, 6, LANES")  # world AABBs by geom
LW_SA = LANE_WORK.field("sa", "L, 6, LANES")  # subtree AABBs
LW_PLN = LANE_WORK.field("pln", "max(Q, 1), 4, LANES")  # world planes
# a group's poses as computed by the kinematics (`kinematics.step_lanes_kin`) when it holds a bad pose
LW_GPOS = LANE_WORK.field("gpos", "LANES, NB, 3")
LW_GROT = LANE_WORK.field("grot", "LANES, NB, 3, 3")

LANE_TABLES = Tables("J", header=8)  # the lanes' static tables; its table lives in J (counts: lanes.J_*)

LTAB = Layout(LANE_TABLES, "J", np.int64)
J_BODY_PAIRS = LTAB.field("body_pairs", "NP, 2")  # static body pairs (x < y), sorted
J_ROW_START = LTAB.field("row_start", "L + 1")  # position x's pairs: [row_start[x], row_start[x + 1])
J_PAIR_GSTART = LTAB.field("pair_gstart", "NP + 1")  # pair p's geom pairs
J_PAIR_GEOMS = LTAB.field("pair_geoms", "NLG, 3")  # (g1, g2, rank)
J_PLANE_START = LTAB.field("plane_start", "Q + 1")  # plane i's positions
J_PLANE_POS = LTAB.field("plane_pos", "NPL")
J_PLANE_GSTART = LTAB.field("plane_gstart", "NPL + 1")  # (plane, position) e's geoms
J_PLANE_GEOMS = LTAB.field("plane_geoms", "NPLG, 2")  # (g, rank)
J_EXPLICIT_RANK = LTAB.field("explicit_rank", "P")  # -1: never reported
J_RANK_KEYS = LTAB.field("rank_keys", "NR")  # keys by rank, sorted

LANE_BITS = Layout(LANE_TABLES, "LB", np.int64)  # a batch worker's int64 scratch
LB_BITS = LANE_BITS.field("bits", "NWd, LANES")  # the lanes' bitsets over the ranks
LB_STAMP = LANE_BITS.field("stamp", "L")  # a position's geoms placed in this group
