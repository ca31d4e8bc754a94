"""The command line: ``python -m collide compare``, its exit status, JSON and plot."""

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import collide.mujoco as cm
from collide.__main__ import main

REPO = Path(__file__).resolve().parents[1]
MODELS = REPO / ".." / "shared" / "models"

KEYS = ("steps", "recall", "missed", "contact_pairs_per_step", "candidates_per_step",
        "mujoco_candidates_per_step", "time_ours_us", "time_mujoco_broad_us")


def test_compare_without_arguments_exits_0():
    # The main job, as a user runs it: the built-in scene, no files, default 1000 steps.
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "collide", "compare"], cwd=REPO,
                          capture_output=True, text=True, timeout=300)
    elapsed = time.perf_counter() - start
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "recall: 100.00 %" in proc.stdout
    assert "MuJoCo broad-phase candidates" in proc.stdout
    print(f"python -m collide compare: {elapsed:.1f} s")  # shown with -s; never asserted


def test_compare_writes_consistent_json_and_plot(tmp_path):
    out, png = tmp_path / "new" / "r.json", tmp_path / "plots" / "r.png"  # folders made by compare
    status = main(["compare", "--steps", "150", "--seed", "1", "--json", str(out),
                   "--plot", str(png)])
    assert status == 0
    result = json.loads(out.read_text())
    for key in KEYS:
        assert key in result, key
    assert result["steps"] == 150 and result["recall"] == 1.0 and result["missed"] == []
    contacts = np.asarray(result["contact_pairs_per_step"])
    ours = np.asarray(result["candidates_per_step"])
    assert len(contacts) == len(ours) == len(result["mujoco_candidates_per_step"]) == 150
    assert contacts.sum() > 0, "the built-in scene must have real contacts"
    assert np.all(ours >= contacts)
    assert png.is_file() and png.stat().st_size > 10_000
    # contact agreement, our narrow phase against MuJoCo's contacts on the same states
    ct = result["contacts"]
    assert ct["mujoco_pairs"] == int(contacts.sum())  # the pairs MuJoCo made contacts for, each step
    assert ct["matched"] + len(ct["missed"]) == ct["mujoco_pairs"]
    assert ct["matched"] > 0.99 * ct["mujoco_pairs"]
    assert ct["missed_near_touching"] == len(ct["missed"])  # any miss within MuJoCo's own tolerance
    assert ct["our_contacts"] > 0 and ct["mujoco_contacts"] > 0
    assert ct["dist_error_median"] < 1e-6


def test_compare_without_contacts(capsys):
    assert main(["compare", "--steps", "20", "--no-contacts"]) == 0
    out = capsys.readouterr().out
    assert "recall:" in out and "contacts:" not in out
    assert cm.compare(cm.default_scene(), steps=5, contacts=False)["contacts"] is None


def test_compare_on_a_model_file(tmp_path):
    path = MODELS / "humanoid" / "scene.xml"
    if not path.is_file():
        pytest.skip(f"test model not present at {path}")
    out = tmp_path / "h.json"
    assert main(["compare", str(path), "--steps", "200", "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["model"] == "humanoid" and sum(result["contact_pairs_per_step"]) > 0


def test_missed_pair_exits_1(monkeypatch, capsys):
    # A broad phase that proposes nothing must be caught: exit status 1 and the missed pairs
    # listed with step and geom names.
    monkeypatch.setattr(cm.BroadPhase, "pairs", lambda self, data: np.zeros((0, 2), np.int32))
    assert main(["compare", "--steps", "60"]) == 1
    out = capsys.readouterr().out
    assert "MISSED step" in out and "floor" in out


@pytest.mark.parametrize("argv", [["compare", "--steps", "0"], ["compare", "--seed", "-1"],
                                  ["compare", "--hold", "0"], ["compare", "/no/such/model.xml"]])
def test_bad_usage_exits_2(argv, capsys):
    assert main(argv) == 2
    assert "error:" in capsys.readouterr().err


def test_bad_outputs_are_refused_before_the_run(tmp_path, capsys):
    # Checked up front: after a whole run they were tracebacks with exit status 1 ("a miss").
    assert main(["compare", "--steps", "1", "--json", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err
    assert main(["compare", "--steps", "1", "--plot", str(tmp_path / "p.xyz")]) == 2
    assert "cannot write '.xyz'" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_plot_without_extension_is_a_png(tmp_path, capsys):
    assert main(["compare", "--steps", "5", "--plot", str(tmp_path / "noext")]) == 0
    assert (tmp_path / "noext.png").is_file()
    assert f"wrote {tmp_path / 'noext.png'}" in capsys.readouterr().out


def test_unknown_command_is_rejected():
    with pytest.raises(SystemExit) as exc:
        main(["frobnicate"])
    assert exc.value.code == 2


def test_demo_runs_without_a_gl_backend(tmp_path):
    env = dict(__import__("os").environ, MUJOCO_GL="disable")
    proc = subprocess.run([sys.executable, "demos/mujoco_comparison.py", "--steps", "40",
                           "--out", str(tmp_path)], cwd=REPO, env=env, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (tmp_path / "mujoco_comparison.png").is_file()
    assert "no rendered image" in proc.stdout


def test_motion_planning_demo_runs(tmp_path, capsys):
    # demos/motion_planning.py on its arm among obstacles (made in code), a few hundred
    # configurations: both figures written, and the scene had free and colliding configurations.
    import importlib.util
    spec = importlib.util.spec_from_file_location("motion_planning", REPO / "demos" / "motion_planning.py")
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    assert demo.main(["--configs", "300", "--out", str(tmp_path)]) == 0
    for f in ("motion_planning_stats.png", "motion_planning_configs.png"):
        assert (tmp_path / f).stat().st_size > 10_000
    out = capsys.readouterr().out
    free = float(out.split("configurations, ")[1].split("% free")[0])
    assert 0.0 < free < 100.0, out


def test_unloadable_model_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><geom type='nonsense'/></worldbody></mujoco>")
    assert main(["compare", str(bad)]) == 2
    assert "cannot load" in capsys.readouterr().err
