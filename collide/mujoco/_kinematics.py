"""Batched forward kinematics of a MuJoCo model: its `collide.broadphase.KinematicTree` (views of
the model's arrays) and the body poses of many configurations (``mj_kinematics``,
engine_core_smooth.c, body poses only)."""

from __future__ import annotations

import mujoco
import numpy as np

from ..broadphase import KinematicTree

__all__ = ["kinematic_tree", "kinematics_batch"]

def kinematic_tree(model: mujoco.MjModel) -> KinematicTree:
    """The bodies and joints ``mj_kinematics`` reads, as a `collide.broadphase.KinematicTree`.

    Its float arrays are views of the model's own (a body's pose or ``qpos0`` changed in place
    reaches the next call, as it reaches ``mj_kinematics``; `BroadPhase.pairs_batch` keeps the
    tree per ``MjModel``); its index arrays are checked copies.
    """
    return KinematicTree(model.qpos0, model.body_parentid, model.body_pos, model.body_quat, model.body_jntadr,
                         model.body_jntnum, model.jnt_type, model.jnt_qposadr, np.reshape(model.jnt_pos, (-1, 3)),
                         np.reshape(model.jnt_axis, (-1, 3)))


def kinematics_batch(model: mujoco.MjModel, qpos) -> tuple[np.ndarray, np.ndarray]:
    """Body poses of many configurations, as ``mj_kinematics`` computes them, in one numba call.

    Parameters
    ----------
    model : mujoco.MjModel
    qpos : (B, nq) array_like of float
        One configuration per world. Mocap bodies stay at their model poses.

    Returns
    -------
    body_pos : (B, nbody, 3) float64
    body_rot : (B, nbody, 3, 3) float64
        Equal to ``data.xpos`` / ``data.xmat`` after ``mj_kinematics`` up to rounding (the same
        formulas, engine_core_smooth.c; tested against MuJoCo on every test scene).
    """
    return kinematic_tree(model).poses(qpos)
