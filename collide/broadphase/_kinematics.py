"""A kinematic tree in MuJoCo's layout, and the body poses of many configurations of it.

`KinematicTree` holds the body and joint arrays forward kinematics reads (``mj_kinematics``,
engine_core_smooth.c, body poses only), checked once so that the kernels (`_kernels.kinematics`,
which read them through raw pointers) never index out of them. `BroadPhase.pairs_batch_joints`
takes one: on a small model each thread then computes a group of worlds' poses in its own lane
workspace just before testing them (`_kernels.kinematics.step_lanes_kin`), none of the batch's
poses written out; `KinematicTree.poses` writes them out (`_kernels.kinematics.kinematics_worlds`).
"""

from __future__ import annotations

import numba
import numpy as np

from .._fork import require_parallel
from .._kernels import kinematics as _kin
from .._validate import as_array

__all__ = ["KinematicTree"]

# qpos entries of each joint type (mjtJoint: free, ball, slide, hinge)
_WIDTH = {_kin.JNT_FREE: 7, _kin.JNT_BALL: 4, _kin.JNT_SLIDE: 1, _kin.JNT_HINGE: 1}


def _floats(x, name: str, shape: tuple) -> np.ndarray:
    # A view when x is C-contiguous float64 already (a change made in place reaches the kernels).
    try:
        a = np.ascontiguousarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: cannot be read as a float64 array ({exc})") from None
    if a.ndim != len(shape) or any(n is not None and a.shape[i] != n for i, n in enumerate(shape)):
        want = "(" + ", ".join("n" if n is None else str(n) for n in shape) + ("," if len(shape) == 1 else "") + ")"
        raise ValueError(f"{name}: expected shape {want}, got {a.shape}")
    return a


def _ints(x, name: str, n: int) -> np.ndarray:
    # A checked int32 copy (the kernels read MuJoCo's int32 index arrays). Writable, as the
    # kernels' compiled signatures take them (a read-only array is another numba type).
    a = np.asarray(x)
    if a.shape != (n,):
        raise ValueError(f"{name}: expected shape ({n},), got {a.shape}")
    if n and a.dtype.kind not in "iu":
        raise ValueError(f"{name}: expected integers, got dtype {a.dtype}")
    if n and (a.min() < np.iinfo(np.int32).min or a.max() > np.iinfo(np.int32).max):
        raise ValueError(f"{name}: values beyond int32")
    return np.array(a, dtype=np.int32)


class KinematicTree:
    """Bodies and joints of a kinematic tree in MuJoCo's layout (the ``mujoco.MjModel`` fields of
    the same names), for batched forward kinematics.

    Parameters
    ----------
    qpos0 : (nq,) float
        The reference configuration (a slide's or hinge's displacement is ``qpos - qpos0``).
    body_parent : (L,) int
        ``body_parentid``: each body's parent, before it (body 0, the world, has no joints).
    body_pos : (L, 3) float
    body_quat : (L, 4) float
        Each body's frame in its parent's, ``(w, x, y, z)``.
    body_jntadr, body_jntnum : (L,) int
        Each body's first joint and number of joints (``-1``, ``0``: none).
    jnt_type : (nj,) int
        ``mjtJoint``: 0 free, 1 ball, 2 slide, 3 hinge. A free joint is its body's only joint.
    jnt_qposadr : (nj,) int
        Each joint's first ``qpos`` entry (7 for a free joint, 4 for a ball, 1 otherwise).
    jnt_pos, jnt_axis : (nj, 3) float
        Each joint's anchor and (unit) axis in its body's frame.

    Notes
    -----
    The float arrays are kept as given where they are C-contiguous float64 (a ``mujoco.MjModel``'s
    are): a value changed in place there reaches the next call, as it reaches ``mj_kinematics``.
    The index arrays are checked here (parents before children, joints and ``qpos`` entries in
    range) and copied: the kernels trust them.
    """

    __slots__ = ("arrays", "body_count", "joint_count", "nq")

    def __init__(self, qpos0, body_parent, body_pos, body_quat, body_jntadr, body_jntnum, jnt_type, jnt_qposadr,
                 jnt_pos, jnt_axis):
        q0 = _floats(qpos0, "qpos0", (None,))
        nq = len(q0)
        L = np.shape(body_parent)[0] if np.ndim(body_parent) == 1 else -1
        if L < 1:
            raise ValueError(f"body_parent: expected shape (L,) with L >= 1 (body 0 is the world), got "
                             f"{np.shape(body_parent)}")
        nj = np.shape(jnt_type)[0] if np.ndim(jnt_type) == 1 else -1
        if nj < 0:
            raise ValueError(f"jnt_type: expected shape (nj,), got {np.shape(jnt_type)}")
        par = _ints(body_parent, "body_parent", L)
        adr, num = _ints(body_jntadr, "body_jntadr", L), _ints(body_jntnum, "body_jntnum", L)
        typ, qadr = _ints(jnt_type, "jnt_type", nj), _ints(jnt_qposadr, "jnt_qposadr", nj)
        bpos, bquat = _floats(body_pos, "body_pos", (L, 3)), _floats(body_quat, "body_quat", (L, 4))
        jpos, jaxis = _floats(jnt_pos, "jnt_pos", (nj, 3)), _floats(jnt_axis, "jnt_axis", (nj, 3))
        below = par[1:] >= np.arange(1, L)
        if np.any(par[1:] < 0) or np.any(below):
            b = 1 + int(np.flatnonzero((par[1:] < 0) | below)[0])
            raise ValueError(f"body_parent: body {b}'s parent {int(par[b])} is not a body before it")
        if num[0] != 0:
            raise ValueError("body_jntnum: body 0 (the world) has no joints")
        if np.any(num < 0):
            raise ValueError(f"body_jntnum: negative at body {int(np.flatnonzero(num < 0)[0])}")
        has = num > 0
        out = has & ((adr < 0) | (adr.astype(np.int64) + num > nj))
        if np.any(out):
            b = int(np.flatnonzero(out)[0])
            raise ValueError(f"body_jntadr: body {b}'s joints {int(adr[b])}..{int(adr[b]) + int(num[b]) - 1} "
                             f"are not among the {nj} joints")
        bad = ~np.isin(typ, list(_WIDTH))
        if np.any(bad):
            j = int(np.flatnonzero(bad)[0])
            raise ValueError(f"jnt_type: joint {j} has type {int(typ[j])}, not one of 0 (free), 1 (ball), 2 (slide), "
                             "3 (hinge)")
        width = np.array([_WIDTH[int(t)] for t in typ], dtype=np.int64)
        bad = (qadr < 0) | (qadr + width > nq)
        if np.any(bad):
            j = int(np.flatnonzero(bad)[0])
            raise ValueError(f"jnt_qposadr: joint {j}'s {int(width[j])} qpos entries from {int(qadr[j])} are not "
                             f"among the {nq}")
        for b in np.flatnonzero(has & (num > 1)):
            free = typ[adr[b]:adr[b] + num[b]] == _kin.JNT_FREE
            if free.any():
                raise ValueError(f"jnt_type: body {int(b)} has a free joint among {int(num[b])} joints (a free "
                                 "joint is its body's only joint)")
        self.arrays = (q0, par, bpos, bquat, adr, num, typ, qadr, jpos, jaxis)  # the kernels' argument order
        self.body_count, self.joint_count, self.nq = L, nj, nq

    def __repr__(self) -> str:
        return f"KinematicTree({self.body_count} bodies, {self.joint_count} joints, nq={self.nq})"

    def check_qpos(self, qpos) -> np.ndarray:
        """``qpos`` as a C-contiguous ``(B, nq) float64`` array, finite; ``ValueError`` naming the
        first bad entry otherwise."""
        return as_array(qpos, "qpos", (None, self.nq))

    def poses(self, qpos) -> tuple[np.ndarray, np.ndarray]:
        """Body poses of many configurations, as ``mj_kinematics`` computes them, in one numba call.

        Parameters
        ----------
        qpos : (B, nq) array_like of float
            One configuration per world.

        Returns
        -------
        body_pos : (B, L, 3) float64
        body_rot : (B, L, 3, 3) float64
            ``mj_kinematics``' formulas (engine_core_smooth.c) in the same order, so the same values
            up to rounding; a body with a mocap flag in MuJoCo is posed from ``body_pos`` /
            ``body_quat`` here.
        """
        return self._poses(self.check_qpos(qpos))

    def _poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # `poses` of a checked qpos (`check_qpos`)
        b, n = len(q), self.body_count
        pos, rot = np.empty((b, n, 3)), np.empty((b, n, 3, 3))
        chunks = max(1, min(4 * numba.get_num_threads(), b))
        scratch = np.empty((chunks, _kin.scratch_size(n, self.joint_count)))
        require_parallel()  # not in a child forked from a GNU OpenMP parent (`collide._fork`)
        _kin.kinematics_worlds(q, *self.arrays, pos, rot, scratch)
        return pos, rot
