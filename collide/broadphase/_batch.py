"""The batch driver of `BroadPhase`: many worlds in one call, threaded over chunks of worlds.

`Batch` owns the per-chunk buffers (each chunk's workspace, body pairs, keys and kernel context;
on the lanes' path each worker's lane workspace and bitsets) and runs a batch kernel until no
buffer is short, growing what was short and running again (a pair is never dropped). Which
kernel: `Batch.path` is ``"lanes"`` for a model whose statically passing body pairs the lane
kernel takes (`collide._kernels.lanes`: eight worlds at a time in SIMD lanes), ``"worlds"``
otherwise (world by world through the single-world kernel); both give the single-world answers.
`poses_launch` runs either on given poses; `joints_launch` runs the lanes on the poses of joint
configurations computed in the call (`collide._kernels.kinematics.step_lanes_kin`).
"""

from __future__ import annotations

import numba
import numpy as np

from .._fork import require_parallel
from .._kernels import broadphase as _k
from .._kernels import batch as _kbatch
from .._kernels import keys as _kkeys
from .._kernels import step as _kstep
from .._kernels import kinematics as _kin
from .._kernels import lanes as _lanes
from .._kernels import layout as _layout
from ._kinematics import KinematicTree
from ._world_bounds import raise_pose_error

__all__ = ["CHUNKS", "CHUNKS_LANES", "Batch"]

# Chunks of a batch a thread (see Batch.run): the lane kernels' (their big workspaces are a
# worker's, a chunk keeps its keys, counts and the small per-world buffers of a bad group's
# fallback) and the world-by-world kernel's (whose workspace is the chunk's).
CHUNKS_LANES = 16
CHUNKS = 4


def _lane_rows_zeros(rows: int, n: int) -> np.ndarray:
    """Zeroed float64 ``(rows, >= n)`` whose rows start on 64-byte boundaries.

    The lane kernels read and write (LANES,) float64 rows, 64 bytes each, as vectors; numpy aligns
    its buffers to 16 bytes only, and a row straddling two cache lines costs two accesses.
    """
    n = -(-n // 8) * 8
    buf = np.zeros(rows * n + 8)
    o = (-buf.ctypes.data % 64) // 8
    return buf[o:o + rows * n].reshape(rows, n)


class Batch:
    """Buffers and driver of one `BroadPhase`'s batch calls (the caller holds its lock).

    Parameters
    ----------
    I, F : the packed model (`_kernels.broadphase.pack`)
    sap_init : the initial sweep-and-prune state of a workspace
    lane_tables : int64 array or None
        The lanes' static tables (`tables.lane_tables`); None: the world-by-world path.
    body_count, geom_count, position_count : int
    stats : (N_STATS,) int64
        The owner's counters, into which the kernels sum the chunks'.
    """

    def __init__(self, I, F, sap_init, lane_tables, body_count: int, geom_count: int, position_count: int,
                 stats: np.ndarray):
        self.I, self.F, self.sap_init = I, F, sap_init
        self.nW = _k.workspace_size(I)
        self.lane_tables = lane_tables
        self.body_count, self.geom_count, self.position_count = body_count, geom_count, position_count
        self.stats = stats
        self.buffers = None  # made by the first run, for its number of chunks (see run)
        self.kin_scratch = None  # joints_launch's kinematics scratch, a row a worker, kept between calls

    @property
    def path(self) -> str:
        """``"lanes"`` or ``"worlds"`` (see the module docstring)."""
        return "worlds" if self.lane_tables is None else "lanes"

    def poses_launch(self, body_pos: np.ndarray, body_rot: np.ndarray):
        """The launch of `run` for checked ``(B, L, 3)``, ``(B, L, 3, 3)`` C-contiguous float64 poses."""
        def launch(bt, world_count, world_info, chunk_info, S):
            if self.lane_tables is None:
                return _kbatch.step_batch(body_pos, body_rot, bt["ctx"], world_count, world_info, chunk_info, S,
                                     self.stats)
            return _lanes.step_lanes(body_pos, body_rot, bt["ctx"], self.lane_tables, bt["LW"], bt["LB"],
                                     world_count, world_info, chunk_info, S, self.stats)
        return launch

    def joints_launch(self, tree: KinematicTree, qpos: np.ndarray, kernel=None, extra: tuple = ()):
        """The launch of `run` (lanes' path only) for ``(B, nq)`` C-contiguous float64 configurations
        of ``tree``: each group's poses computed by the thread that tests them, in its workspace.
        ``kernel``: `_kernels.kinematics.step_lanes_kin` (None), or a kernel taking its arguments
        followed by ``extra`` (`_kernels.check_lanes.check_lanes_kin`, which uses each group's
        candidates in its pass and returns `_kernels.batch.gather_status`' status for rows)."""
        kernel = _kin.step_lanes_kin if kernel is None else kernel

        def launch(bt, world_count, world_info, chunk_info, S):
            shape = (bt["LW"].shape[0], _kin.lanes_scratch_size(tree.body_count, tree.joint_count))
            if self.kin_scratch is None or self.kin_scratch.shape != shape:
                self.kin_scratch = np.empty(shape)
            return kernel(qpos, *tree.arrays, bt["ctx"], self.lane_tables, bt["LW"], bt["LB"], self.kin_scratch,
                          world_count, world_info, chunk_info, S, self.stats, *extra)
        return launch

    def run(self, B: int, launch) -> np.ndarray:
        """The batch's chunks and buffers, then ``launch(bt, world_count, world_info, chunk_info, S)``
        (one of the batch kernels) until no buffer is short: its ``(K, 3)`` rows, or the first bad
        world's ``ValueError``."""
        # More chunks than threads, taken by the threads one at a time (`_kbatch.start_chunks`): a thread
        # that starts late or runs slower takes fewer. The lane kernels keep their big workspaces
        # (lanes, kinematics) a worker, a chunk its keys, counts and small buffers, so their chunks
        # can be small (CHUNKS_LANES a thread; the lane kernel takes worlds _lanes.LANES at a time:
        # no more chunks than groups of them); the world-by-world kernel's workspace is the chunk's
        # (CHUNKS a thread). Sized for numba's most threads, so that a call on fewer
        # (numba.set_num_threads) finds the same buffers: made afresh, they cost the next call
        # their first touch.
        require_parallel()  # not in a child forked from a GNU OpenMP parent (`collide._fork`)
        most = numba.config.NUMBA_NUM_THREADS
        if self.lane_tables is None:
            C = max(1, min(CHUNKS * most, B))
        else:
            C = max(1, min(CHUNKS_LANES * most, -(-B // _lanes.LANES)))
        rows = min(most, C)  # a workspace a worker
        nw = min(numba.get_num_threads(), rows)  # workers: one a thread
        per = (B + C - 1) // C
        if self.buffers is None or self.buffers["ctx"].shape[0] != C:  # rows follow from C
            L, G = self.body_count, self.geom_count
            self.buffers = {"W": np.zeros((C, self.nW)), "sap": np.tile(self.sap_init, (C, 1)),
                            "stats": np.zeros((C, _layout.N_STATS), np.int64), "info": np.zeros((C, 4), np.int64),
                            "ctx": np.zeros((C, _kstep.NCTX), np.int64)}
            if self.lane_tables is not None:
                # a worker's lane workspace (with room for a group's poses computed in the call) and bitsets
                self.buffers["LW"] = _lane_rows_zeros(rows, _layout.LANE_WORK.size(_k.model_dims(self.I)))
                self.buffers["LB"] = np.zeros((rows, _layout.LANE_BITS.size(_lanes.lane_dims(
                    self.lane_tables, self.position_count))), np.int64)
            self.set_buffers(4 * L + 64, max(256, 2 * G * per))
        bt = self.buffers
        # world_info is written for bad worlds only, and the kernel writes every world's count and
        # every chunk's row: nothing to clear.
        world_count = np.empty(B, np.int64)
        world_info = np.empty((B, 4), np.int64)
        chunk_info = np.empty((C + 1, _kbatch.N_CI), np.int64)  # the chunks', then (counter, workers)
        chunk_info[C, 1] = nw
        S = _kkeys.key_shift(self.geom_count)
        while True:
            # The kernels sum the chunks' stats into self.stats (`BroadPhase.stats` reads it) and
            # return the rows, or none when a chunk holds a bad world or ran out of room.
            out = launch(bt, world_count, world_info, chunk_info, S)
            if len(out):
                return out
            chunks = chunk_info[:C]
            bad = chunks[:, _kbatch.CI_BAD]
            if bad.max() >= 0:
                w = int(bad[bad >= 0].min())
                raise_pose_error(int(world_info[w, 0]), int(world_info[w, 1]), f"world {w}, ")
            need_bp = int(chunks[:, _kbatch.CI_NEED].max())
            need = int(chunks[:, _kbatch.CI_KEYS].max())
            if need_bp > 0:  # never drop a pair: grow and rerun
                self.set_buffers(2 * need_bp, bt["keys"].shape[1])
            elif need > bt["keys"].shape[1]:
                self.set_buffers(bt["bp"].shape[1], 2 * need)
            else:
                return out

    def set_buffers(self, body_pairs: int, keys: int) -> None:
        """Per-chunk body-pair and key buffers of these sizes, and their context rows (the kernel
        reaches them through addresses: replace them only here)."""
        bt = self.buffers
        C = bt["ctx"].shape[0]
        bt["bp"] = np.empty((C, max(1, body_pairs), 2), np.int64)
        bt["keys"] = np.empty((C, max(1, keys)), np.int64)
        bt["scr"] = np.empty((C, _kkeys.scratch_size(self.geom_count, bt["keys"].shape[1])), np.int64)
        for c in range(C):
            _kstep.context(self.I, self.F, bt["W"][c], bt["sap"][c], bt["bp"][c], bt["keys"][c], bt["scr"][c],
                       bt["stats"][c], bt["info"][c], out=bt["ctx"][c])
