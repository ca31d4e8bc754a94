"""Test-suite configuration: the ``slow`` marker (registered in pyproject.toml).

``pytest -m "not slow"`` is the quick suite (a few minutes once the kernels are cached); plain
``pytest`` (what CI runs, ``.ci/run``) runs everything. The long runs are marked here, in one
place, by file and test name: simulations of hundreds or thousands of steps on the real MuJoCo
models, the command line's and the demos' full runs. A test marked slow must still be worth its
time: it is deselected from the quick loop, never from CI.
"""

from __future__ import annotations

import pytest

# file -> test functions (every parametrization of each) that are long runs.
SLOW: dict[str, frozenset[str]] = {
    "test_mujoco.py": frozenset({
        "test_scene_recall_is_complete",          # 2000 steps on each of the real models, with contacts
        "test_scene_batch_equals_single_worlds",  # 600 states on each of the real models
        "test_humanoid_variants_recall",          # 1000 steps, three rule variants
        "test_coherent_steps_equal_the_walk_in_a_simulation",  # 400 steps, two scenes
    }),
    "test_contacts.py": frozenset({
        "test_shared_models_agree",               # our contacts against MuJoCo's on each real model
    }),
    "test_cli.py": frozenset({
        "test_compare_without_arguments_exits_0",  # the main job in a fresh process, 1000 steps
        "test_compare_on_a_model_file",            # 200 steps of the humanoid
        "test_demo_runs_without_a_gl_backend",     # the MuJoCo demo in a fresh process
    }),
    "test_check.py": frozenset({
        "test_in_collision_is_mujocos",                  # 300 configurations of each real model against MuJoCo
        "test_in_collision_is_the_contacts_of_each_configuration",  # 120 of each, one MjData at a time
        "test_min_distance_is_the_brute_force_minimum",  # a Python call per filtered pair, each real model
    }),
    "test_obb_exact.py": frozenset({
        "test_model_meshes",                       # the exact OBB of every mesh of the real models
    }),
}


@pytest.hookimpl(tryfirst=True)  # before ``-m`` deselects by marker
def pytest_collection_modifyitems(config, items):
    checked = set()
    for item in items:
        names = SLOW.get(item.path.name)
        if not names or not hasattr(item, "originalname"):
            continue
        if item.path.name not in checked:
            # A renamed test would silently leave the quick suite: every name must be a test.
            checked.add(item.path.name)
            stale = sorted(n for n in names if not callable(getattr(item.module, n, None)))
            if stale:
                raise pytest.UsageError(f"tests/conftest.py marks tests {item.path.name} does not define: {stale}")
        if item.originalname in names:
            item.add_marker(pytest.mark.slow)
