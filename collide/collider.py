"""`Collider`: broad phase and contacts of a MuJoCo model (`collide.mujoco.Collider`).

The broad phase is `collide.mujoco.BroadPhase`, unchanged; the narrow phase
(`collide.contacts.narrow_phase`) takes its ``(K, 2)`` pairs and MuJoCo's geom poses
(``data.geom_xpos``, ``data.geom_xmat``), nothing of the broad phase's internals. This module does
not import ``mujoco`` (DESIGN.md's layers): the adapter `collide.mujoco`, imported when a
`Collider` is built, reads the model and checks the data.
"""

from __future__ import annotations

import numpy as np

from . import contacts as _contacts

__all__ = ["Collider"]


class Collider:
    """Contacts of a MuJoCo model at the poses of an ``MjData``.

    Parameters
    ----------
    model : mujoco.MjModel
        Read once (geometry, filters, margins, gaps, flags): build a new Collider after
        changing them.
    coherent : bool, default True
        Passed to `collide.mujoco.BroadPhase`.

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

    def __init__(self, model, coherent: bool = True):
        from .mujoco import BroadPhase  # the adapter imports this module: not at import time

        self.broadphase = BroadPhase(model, coherent)
        self.model = model
        self.table = _contacts.GeomTable(model)
        self._checked = None  # the last MjData checked (an MjData's arrays never move)
        self._views = None  # its geom_xpos, geom_xmat as (G, 3), (G, 3, 3) views

    def __repr__(self) -> str:
        return f"collide.mujoco.Collider({self.model.nbody} bodies, {self.model.ngeom} geoms)"

    def __reduce__(self):
        return (Collider, (self.model, self.broadphase.broadphase.coherent))

    def pairs(self, data) -> np.ndarray:
        """Candidate geom pairs: `collide.mujoco.BroadPhase.pairs` (``(K, 2) int32``, read-only)."""
        return self.broadphase.pairs(data)

    def _poses(self, data) -> tuple[np.ndarray, np.ndarray]:
        # The geom poses of data as the kernel takes them, (G, 3) and (G, 3, 3) views: an MjData's
        # arrays never move, and the bindings build new views at every attribute access, so the
        # last MjData's are kept (checked once).
        if data is not self._checked:
            self.broadphase._check_data(data)
            self._views = _contacts._poses(self.table, data.geom_xpos, data.geom_xmat)
            self._checked = data
        return self._views

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
            Several contacts a pair for face contacts, as MuJoCo 4 makes them (box-box up to 8,
            box and mesh faces and a plane against a box, mesh, capsule or cylinder up to 4), one
            otherwise; pairs with a height field or SDF geom in ``skipped``.

        Raises
        ------
        ValueError
            ``data`` of another model, or a non-finite pose (naming the body or geom).
        """
        pairs = self.broadphase.pairs(data)  # checks data on its first use
        xpos, xmat = self._poses(data) if data is not self._checked else self._views
        # the broad phase's pairs are int32, C-contiguous, in range, lower first: not checked again
        return _contacts.contacts_of(self.table, pairs, xpos, xmat)

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
        """
        xpos, xmat = self._poses(data)
        return _contacts.geom_distance(self.table, g1, g2, xpos, xmat, distmax)
