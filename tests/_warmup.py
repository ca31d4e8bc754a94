"""Compile, in a second process, kernels that test files later in the run will need.

`tests/conftest.py` starts this at the beginning of a session with the names of the collected
test files. A cold run (a fresh clone: CI) spends about half its time in numba's compiler, one
kernel after another on one core; this process compiles the kernels of files the run reaches
later into numba's on-disk cache on the other core, so that the tests load them instead. It
changes no result: a kernel it has not saved yet is compiled by the tests as before, and numba
writes a cache file whole (a temporary file, then a rename). It only calls public entry points,
on scenes built in code or, where present, the shared models; any error here is ignored (the
tests report their own).
"""

from __future__ import annotations

import sys
from pathlib import Path

MODELS = Path(__file__).resolve().parent.parent.parent / "shared" / "models"


def _check() -> None:
    # test_check.py, test_check_trees.py, test_check_lanes.py: the three deciding kernels
    # (check_trees on a model of many trees, check_lanes_kin on the lanes' path, check_worlds
    # with distances).
    import mujoco
    import numpy as np

    import collide.mujoco as cm
    from collide import testing

    # in the order test_check.py first needs them (its scenes run alphabetically)
    for scene, dist in (("22_humanoids", False), ("agility_cassie", False), ("franka_emika_panda", True)):
        path = MODELS / scene / "scene.xml"
        if not path.is_file():
            continue
        model = mujoco.MjModel.from_xml_path(str(path))
        col = cm.Collider(model)
        col.check_batch(testing.random_configurations(model, 64, np.random.default_rng(0)), distance=dist)
    # the MuJoCo adapter's swept pairs (test_check's every-entry-point test)
    model = cm.default_scene(seed=1, objects=10)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cm.Collider(model).pairs_swept(data, data)


def _swept() -> None:
    # test_swept_pairs.py: the swept broad phase, one world and batched.
    import numpy as np

    import collide
    from collide import testing

    rng = np.random.default_rng(0)
    scene = testing.many_robots(3, links=4, seed=6, planes=1)
    bp = collide.BroadPhase(scene.articulation)
    p0, r0 = scene.poses(rng, worlds=3)
    p1, r1 = scene.poses(rng, worlds=3)
    bp.pairs_swept_batch(p0, r0, p1, r1)
    bp.pairs_swept(p0[0], r0[0], p1[0], r1[0])


def _mujoco() -> None:
    # test_mujoco.py, test_batch_models.py: the MuJoCo adapter's contacts and batched broad phase.
    # In CI's second run (the checked mode) test_broadphase.py compiles the per-step kernel
    # meanwhile: the narrow phase comes first here, through its own entry point (a Collider
    # compiles no step kernel when built), then the batch kernels, which load the step's callee
    # (`broadphase._world`) by then, and last the adapter's bound step (`contacts(data)`).
    import mujoco
    import numpy as np

    import collide.mujoco as cm
    from collide import contacts

    model = cm.default_scene(seed=1, objects=10)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    col = cm.Collider(model)
    G = model.ngeom
    pairs = np.array([(i, j) for i in range(G) for j in range(i + 1, G)], np.int32)
    contacts.narrow_phase(col.table, pairs, data.geom_xpos, data.geom_xmat)
    q = np.tile(model.qpos0, (4, 1))
    col.broadphase.pairs_batch(model, q)
    col.broadphase.broadphase.pairs_batch(*cm.kinematic_tree(model).poses(q))
    col.contacts(data)


# (the test files that need a warm-up's kernels, the warm-up), in the order they run. conftest.py
# runs these files after every other file, in this order, so that the warm-up has the time the
# others take to compile their kernels: a file that needs them and ran early (a new file sorts
# where its name puts it) would compile the same kernels beside this process, on both cores.
WARMUPS = (
    (frozenset({"test_check.py", "test_check_lanes.py", "test_check_trees.py", "test_adversary_decide.py",
                "test_adversary_lanes.py", "test_cli.py", "test_readme.py", "test_collider_threads.py"}), _check),
    # test_cli: the motion-planning demo; test_readme: the README's check_batch example;
    # test_collider_threads: the fork test's check_batch
    (frozenset({"test_swept_pairs.py", "test_swept_reuse.py"}), _swept),
    (frozenset({"test_mujoco.py", "test_batch_models.py"}), _mujoco),
)


def main(files: list[str]) -> None:
    for names, fn in WARMUPS:
        if names & set(files):
            try:
                fn()
            except Exception:  # noqa: BLE001 -- the tests report their own errors
                pass


if __name__ == "__main__":
    main(sys.argv[1:])
