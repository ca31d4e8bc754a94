"""Test-suite configuration: the ``slow`` marker (registered in pyproject.toml).

``pytest -m "not slow"`` is the quick suite (a few minutes once the kernels are cached); plain
``pytest`` (what CI runs, ``.ci/run``) runs everything. The long runs are marked here, in one
place, by file and test name: simulations of hundreds or thousands of steps on the real MuJoCo
models, the command line's and the demos' full runs. A test marked slow must still be worth its
time: it is deselected from the quick loop, never from CI.

At the start of a session a second process (``tests/_warmup.py``) compiles into numba's cache the
kernels that test files later in the run need, so that a cold run (CI) compiles on both cores;
those files run after all others (`pytest_collection_modifyitems`), to leave it the time.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from _warmup import WARMUPS

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
    # The files whose kernels the warm-up compiles last, in WARMUPS' order (each file's tests in
    # their order): the warm-up compiles while the other files run (see _warmup.WARMUPS).
    late = {name: i + 1 for i, (names, _) in enumerate(WARMUPS) for name in names}
    items.sort(key=lambda item: late.get(item.path.name, 0))  # stable: the rest keep their order
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


def pytest_collection_finish(session):
    # A second process compiles kernels the run needs later (tests/_warmup.py: a cold run is half
    # numba's compiler, on one core); COLLIDE_NO_WARMUP=1 turns it off.
    if os.environ.get("COLLIDE_NO_WARMUP") or not session.items:
        return
    files = sorted({item.path.name for item in session.items})
    if not any(names & set(files) for names, _ in WARMUPS):
        return
    script = Path(__file__).with_name("_warmup.py")
    session.config._collide_warmup = subprocess.Popen(
        [sys.executable, str(script), *files], cwd=str(script.parent.parent), stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def pytest_unconfigure(config):
    proc = getattr(config, "_collide_warmup", None)
    if proc is not None and proc.poll() is None:
        proc.terminate()
        proc.wait()
