"""Values as Rerun takes them: rotations as quaternions, colours, mesh normals; the log's constants.

Numpy over whole batches (a step converts every geom at once); nothing here imports ``rerun``.
"""

from __future__ import annotations

import numpy as np

from ..contacts import GEOM_TYPES

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


def _quat_xyzw(rot: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(n, 4)`` as Rerun takes them, ``(x, y, z, w)``, of rotations ``(n, 3, 3)``.

    Shepperd's method (J. Guidance and Control 1(3), 1978): from the largest of ``w, x, y, z``,
    found on the diagonal, so no square root is taken of a small number; numpy over the batch
    (one call for every geom of a step, where scipy's ``Rotation.from_matrix`` costs more per call).
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


def _pairs_key(pairs: np.ndarray, ngeom: int) -> np.ndarray:
    p = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    return p[:, 0] * ngeom + p[:, 1]
