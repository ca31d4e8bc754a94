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

Modules, each importing only those above it in this list:

============  ===========================================================================
``_convert``  rotations as Rerun's quaternions, colours, mesh normals, pair keys; constants
``_stream``   ``rerun`` imported on use; series sent as columns; the exit hook
``_scene``    what is drawn: the blueprint, the static geoms and styles, a step's geometry
``_log``      `RerunLog` (arguments, checks, a step's counts and series, replayed states)
              and `StepRecord`
``_compare``  `log_rerun` and `record_compare` (``python -m collide compare --rerun``)
============  ===========================================================================
"""

from __future__ import annotations

from ._compare import log_rerun, record_compare
from ._log import RerunLog, StepRecord

__all__ = ["RerunLog", "StepRecord", "log_rerun", "record_compare"]
