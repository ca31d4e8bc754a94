"""Models for the comparison: an MJCF file (`load_model`), or the built-in scene (`default_scene`,
made with ``mujoco.MjSpec``: no files needed)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from .._validate import as_count

__all__ = ["default_scene", "load_model"]

_GEOM = mujoco.mjtGeom

def _add_limb(parent, name: str, pos, axes, segments) -> None:
    # A chain of capsules, each hinged to the previous one, each hinge with a motor added later.
    body = parent
    for k, (direction, length) in enumerate(segments):
        start = pos if k == 0 else np.asarray(segments[k - 1][0]) * segments[k - 1][1]
        child = body.add_body(name=f"{name}{k}", pos=list(start))
        for a, axis in enumerate(axes):
            child.add_joint(name=f"{name}{k}_j{a}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis,
                            range=[-1.2, 1.2], damping=0.5)
        end = np.asarray(direction) * length
        child.add_geom(name=f"{name}{k}", type=_GEOM.mjGEOM_CAPSULE, size=[0.045, 0, 0],
                       fromto=[0, 0, 0, *end], density=800)
        body = child


def load_model(path) -> tuple[mujoco.MjModel, str]:
    """A model from an MJCF file, and a short name for reports (the folder of a ``scene.xml``).

    Raises
    ------
    ValueError
        No such file, or MuJoCo cannot load it (its message included).
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"no such model file: {path}")
    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise ValueError(f"MuJoCo cannot load {path}: {exc}") from None
    return model, (path.parent.name if path.stem == "scene" else path.stem)


def default_scene(seed: int = 0, objects: int = 40) -> mujoco.MjModel:
    """The built-in comparison scene, made with ``mujoco.MjSpec``: no files needed.

    An articulated figure (a capsule torso on a free joint, head, two arms and two legs of
    hinged capsules with motors) falls onto a pile of random convex meshes and primitives
    (boxes, spheres, capsules, cylinders, ellipsoids) dropped on a floor.

    Parameters
    ----------
    seed : int
        Seed of the pile's shapes and positions.
    objects : int
        Number of loose objects in the pile.

    Returns
    -------
    mujoco.MjModel
    """
    seed = as_count(seed, "seed", 0)
    objects = as_count(objects, "objects", 0)
    rng = np.random.default_rng(seed)
    spec = mujoco.MjSpec()
    spec.modelname = "collide_default_scene"
    spec.option.timestep = 0.004
    spec.worldbody.add_geom(name="floor", type=_GEOM.mjGEOM_PLANE, size=[3, 3, 0.1],
                            rgba=[0.55, 0.6, 0.65, 1.0])
    spec.worldbody.add_light(pos=[0, -1, 3], dir=[0, 0.3, -1], diffuse=[0.8, 0.8, 0.8])
    side = int(np.ceil(np.sqrt(max(objects, 1) / 2.0)))
    kinds = ["mesh", "mesh", "box", "sphere", "capsule", "cylinder", "ellipsoid"]
    for i in range(objects):
        layer, cell = divmod(i, side * side)
        x, y = (np.array(divmod(cell, side)) - (side - 1) / 2.0) * 0.22
        pos = [x + rng.uniform(-0.03, 0.03), y + rng.uniform(-0.03, 0.03), 0.1 + 0.22 * layer]
        quat = rng.normal(size=4)
        body = spec.worldbody.add_body(name=f"obj{i}", pos=pos, quat=quat / np.linalg.norm(quat))
        body.add_freejoint()
        kind = kinds[i % len(kinds)]
        s = rng.uniform(0.035, 0.08, size=3)
        if kind == "mesh":
            pts = rng.normal(size=(int(rng.integers(8, 24)), 3)) * s
            spec.add_mesh(name=f"hull{i}", uservert=pts.ravel().tolist())
            body.add_geom(name=f"obj{i}", type=_GEOM.mjGEOM_MESH, meshname=f"hull{i}")
        else:
            gtype = {"box": _GEOM.mjGEOM_BOX, "sphere": _GEOM.mjGEOM_SPHERE,
                     "capsule": _GEOM.mjGEOM_CAPSULE, "cylinder": _GEOM.mjGEOM_CYLINDER,
                     "ellipsoid": _GEOM.mjGEOM_ELLIPSOID}[kind]
            body.add_geom(name=f"obj{i}", type=gtype, size=s.tolist())
    torso = spec.worldbody.add_body(name="torso", pos=[0, 0, 0.45 + 0.22 * (objects // (side * side) + 1)])
    torso.add_freejoint()
    torso.add_geom(name="torso", type=_GEOM.mjGEOM_CAPSULE, size=[0.07, 0, 0],
                   fromto=[0, -0.08, 0, 0, 0.08, 0], density=600)
    torso.add_geom(name="head", type=_GEOM.mjGEOM_SPHERE, size=[0.08, 0, 0], pos=[0, 0, 0.17])
    torso.add_geom(name="pelvis", type=_GEOM.mjGEOM_CAPSULE, size=[0.06, 0, 0],
                   fromto=[0, -0.06, -0.22, 0, 0.06, -0.22], density=600)
    xy = [[1, 0, 0], [0, 1, 0]]
    for sign, side_name in ((1, "left"), (-1, "right")):
        _add_limb(torso, f"{side_name}_arm", [0, sign * 0.13, 0.02], xy,
                  [([0, sign * 0.6, -0.8], 0.18), ([0, sign * 0.3, -0.95], 0.16)])
        _add_limb(torso, f"{side_name}_leg", [0, sign * 0.07, -0.25], [[0, 1, 0]],
                  [([0, 0, -1.0], 0.22), ([0, 0, -1.0], 0.2)])
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_HINGE:
            act = spec.add_actuator(name=f"motor_{joint.name}", target=joint.name,
                                    trntype=mujoco.mjtTrn.mjTRN_JOINT)
            act.gear[0] = 6.0
            act.ctrllimited = 1
            act.ctrlrange = [-1.0, 1.0]
    return spec.compile()
