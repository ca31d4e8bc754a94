"""The Rerun recording (`collide.rerun_log`), read back with Rerun's own reader.

A run is written to an ``.rrd`` file, read back through Rerun's dataframe API (``rerun.chunk``'s
reader, a DataFusion table indexed by the ``step`` timeline), and what it holds is compared with
what `collide.mujoco.compare` computed: a recording that logged nothing, or the wrong pairs,
fails. Skipped, with the reason, where ``rerun-sdk`` (and its ``catalog`` extra, DataFusion) is
not installed: ``pip install -e '.[test]'`` installs them.
"""

from __future__ import annotations

import sys

import mujoco
import numpy as np
import pytest

import collide.mujoco as cm
from collide.contacts import GEOM_TYPES

rr = pytest.importorskip("rerun", reason="rerun-sdk is not installed (pip install 'collide[viz]')")
pytest.importorskip("datafusion", reason="Rerun's dataframe reader needs DataFusion (pip install 'rerun-sdk[catalog]')")

from collide.rerun_log import RerunLog, StepRecord, log_rerun, record_compare  # noqa: E402

BALLS = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="ball" pos="0 0 0.095"><freejoint/><geom name="ball" type="sphere" size="0.1"/></body>
    <body name="cube" pos="0.5 0 0.09"><freejoint/><geom name="cube" type="box" size="0.1 0.1 0.1"/></body>
    <body name="far" pos="0 0 2"><freejoint/><geom name="far" type="capsule" size="0.05 0.1"/></body>
    <geom name="ghost" type="sphere" size="0.05" pos="1 1 1" contype="0" conaffinity="0"/>
  </worldbody>
</mujoco>
"""


def _table(path):
    """The recording as a ``{column: list per row}`` dict, rows by step, and its steps."""
    from rerun.chunk import RrdReader

    store = RrdReader(str(path)).stream().collect()
    # Semantically empty columns kept: a step with no missed pair logs an empty list, not nothing.
    table = store.reader(index="step", include_semantically_empty_columns=True).to_arrow_table().to_pydict()
    static = store.reader(index=None).to_arrow_table().to_pydict()
    return table, np.asarray(table["step"], dtype=np.int64), static


def _col(table, entity, component):
    key = f"/{entity}:{component}"
    assert key in table, f"{key} not in the recording ({sorted(table)})"
    return table[key]


def _lengths(column):
    return np.array([0 if v is None else len(v) for v in column])


def _scalars(column):
    return np.array([np.nan if v is None else v[0] for v in column])


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    model = cm.default_scene(seed=0, objects=24)
    path = tmp_path_factory.mktemp("rerun") / "scene.rrd"
    result, records = record_compare(model, path, steps=40, seed=0, name="scene", hold=20)
    return model, path, result, records


def test_recording_holds_what_compare_computed(recorded):
    model, path, result, records = recorded
    table, steps, static = _table(path)
    n = result["steps"]
    assert list(steps) == list(range(n))
    assert result["mujoco_count_replayed"]  # the logged states are the ones compare counted on
    cand = np.array(result["candidates_per_step"])
    # The scene really produced pairs and contacts (a recording of nothing cannot pass).
    assert cand.sum() > 0 and sum(result["contact_pairs_per_step"]) > 0
    assert result["contacts"]["our_contacts"] > 0
    # One line per candidate pair, per step, and the series says the same.
    assert list(_lengths(_col(table, "world/pairs/candidates", "LineStrips3D:strips"))) == list(cand)
    assert list(_scalars(_col(table, "stats/pairs/candidates", "Scalars:scalars"))) == list(cand)
    assert list(_scalars(_col(table, "stats/pairs/mujoco_contact_pairs", "Scalars:scalars"))) == \
        result["contact_pairs_per_step"]
    assert list(_scalars(_col(table, "stats/pairs/mujoco_candidates", "Scalars:scalars"))) == \
        result["mujoco_candidates_per_step"]
    np.testing.assert_array_equal(_scalars(_col(table, "stats/time_us/collide_broad", "Scalars:scalars")),
                                  result["time_ours_us_per_step"])
    np.testing.assert_array_equal(_scalars(_col(table, "stats/time_us/mujoco_broad", "Scalars:scalars")),
                                  result["time_mujoco_broad_us_per_step"])
    # Missed pairs: as many lines per step as compare listed (none on this scene).
    missed = np.bincount([m["step"] for m in result["missed"]], minlength=n)
    assert list(_lengths(_col(table, "world/pairs/missed", "LineStrips3D:strips"))) == list(missed)
    # Contact points: MuJoCo's and ours, summed over the steps, as compare counted them.
    mj = _lengths(_col(table, "world/contacts/mujoco", "Points3D:positions"))
    ours = _lengths(_col(table, "world/contacts/collide", "Points3D:positions"))
    assert mj.sum() == result["contacts"]["mujoco_contacts"]
    assert ours.sum() == result["contacts"]["our_contacts"]
    assert list(_lengths(_col(table, "world/contacts/mujoco", "Arrows3D:vectors"))) == list(mj)
    assert list(_lengths(_col(table, "world/contacts/collide", "Arrows3D:vectors"))) == list(ours)
    missed_c = _lengths(_col(table, "world/contacts/missed", "Points3D:positions"))
    assert missed_c.sum() == sum(1 for r in records for _ in range(r.missed_contacts))
    # The StepRecords say what went in, step by step.
    assert [r.candidates for r in records] == list(cand)
    assert [r.our_contacts for r in records] == list(ours)
    assert [r.mujoco_contacts for r in records] == list(mj)
    # Bounds: an OBB and a sphere per collidable non-plane geom, per body with a solid geom.
    gtype = np.asarray(model.geom_type)
    solid = int(np.count_nonzero(gtype != GEOM_TYPES["plane"]))
    assert set(_lengths(_col(table, "world/bounds/geom_obbs", "Boxes3D:half_sizes"))) == {solid}
    assert set(_lengths(_col(table, "world/bounds/geom_spheres", "Ellipsoids3D:half_sizes"))) == {solid}
    moving = len(set(np.asarray(model.geom_bodyid)[gtype != GEOM_TYPES["plane"]]))
    assert set(_lengths(_col(table, "world/bounds/body_obbs", "Boxes3D:half_sizes"))) == {moving}
    # The geoms: the (small) meshes merged, their vertices every step; primitives by kind.
    meshes = np.flatnonzero(gtype == GEOM_TYPES["mesh"])
    assert len(meshes) > 0
    nvert = int(sum(model.mesh_vertnum[model.geom_dataid[g]] for g in meshes))
    assert set(_lengths(_col(table, "world/geoms/meshes", "Mesh3D:vertex_positions"))) == {nvert}
    assert len(static["/world/geoms/meshes:Mesh3D:triangle_indices"][0]) == \
        int(sum(model.mesh_facenum[model.geom_dataid[g]] for g in meshes))
    boxes = _lengths(_col(table, "world/geoms/boxes", "Boxes3D:half_sizes"))
    assert set(boxes) == {int(np.count_nonzero(gtype == GEOM_TYPES["box"]))}


def test_recorded_poses_are_mujocos(recorded):
    # The boxes' centres at the last step are MuJoCo's geom positions in a replay of the run.
    model, path, result, _ = recorded
    table, steps, _ = _table(path)
    centres = _col(table, "world/geoms/boxes", "Boxes3D:centers")[-1]
    verts = np.array(_col(table, "world/geoms/meshes", "Mesh3D:vertex_positions")[-1])
    bounds = _col(table, "world/bounds/geom_obbs", "Boxes3D:centers")[-1]
    bp = cm.BroadPhase(model)
    states = []
    cm.compare(model, steps=result["steps"], seed=0, name="scene", hold=20, broadphase=bp, contacts=False,
               on_step=lambda s, d, c: states.append((np.array(d.geom_xpos), np.array(d.xpos), np.array(d.xmat),
                                                      np.array(d.geom_xmat))))
    gpos, xpos, xmat, _ = states[-1]
    boxes = np.flatnonzero(np.asarray(model.geom_type) == GEOM_TYPES["box"])
    np.testing.assert_allclose(np.array(centres), gpos[boxes], atol=1e-5)  # Rerun stores float32
    # The merged meshes' vertices: MuJoCo's mesh_vert moved by the geom poses MuJoCo computed.
    gmat = states[-1][3].reshape(-1, 3, 3)
    expected = []
    for g in np.flatnonzero(np.asarray(model.geom_type) == GEOM_TYPES["mesh"]):
        mesh = model.geom_dataid[g]
        v = model.mesh_vert[model.mesh_vertadr[mesh]:model.mesh_vertadr[mesh] + model.mesh_vertnum[mesh]]
        expected.append(v @ gmat[g].T + gpos[g])
    np.testing.assert_allclose(verts, np.concatenate(expected), atol=1e-5)
    # Orientations: each box's quaternion (x, y, z, w) is its geom's rotation; a capsule starts at
    # one end (Rerun's capsules run along +z from their origin), MuJoCo's is centred.
    from scipy.spatial.transform import Rotation

    quats = np.array(_col(table, "world/geoms/boxes", "Boxes3D:quaternions")[-1])
    np.testing.assert_allclose(Rotation.from_quat(quats).as_matrix(), gmat[boxes], atol=1e-5)
    caps = np.flatnonzero(np.asarray(model.geom_type) == GEOM_TYPES["capsule"])
    base = np.array(_col(table, "world/geoms/capsules", "Capsules3D:translations")[-1])
    half = np.asarray(model.geom_size)[caps, 1]
    np.testing.assert_allclose(base, gpos[caps] - gmat[caps][:, :, 2] * half[:, None], atol=1e-5)
    lengths = np.array(_col(table, "world/geoms/capsules", "Capsules3D:lengths")[-1])
    np.testing.assert_allclose(lengths, 2 * half, rtol=1e-6)
    wb = bp.broadphase.world_bounds(xpos, xmat.reshape(-1, 3, 3))
    solid = np.flatnonzero(np.asarray(model.geom_type) != GEOM_TYPES["plane"])
    np.testing.assert_allclose(np.array(bounds), wb.obb_center[solid], atol=1e-5)


def test_own_loop_and_a_missed_pair(tmp_path):
    model = mujoco.MjModel.from_xml_string(BALLS)
    data = mujoco.MjData(model)
    path = tmp_path / "loop.rrd"
    collider = cm.Collider(model)
    floor, ball = (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in ("floor", "ball"))
    records = []
    with log_rerun(model, path) as log:
        for step in range(6):
            mujoco.mj_step(model, data)
            if step == 5:
                # Candidates without the ball-floor pair: MuJoCo's contact there is a miss.
                cand = collider.pairs(data)
                assert [floor, ball] in cm.contact_pairs(model, data).tolist()
                cand = cand[~((cand[:, 0] == floor) & (cand[:, 1] == ball))]
                records.append(log.log(data, candidates=cand))
            else:
                records.append(log.log(data))
    assert [r.step for r in records] == list(range(6))
    table, steps, static = _table(path)
    assert list(steps) == list(range(6))
    ours = _lengths(_col(table, "world/contacts/collide", "Points3D:positions"))
    assert list(ours) == [r.our_contacts for r in records]
    expected = collider.contacts(data)
    assert ours[-1] == len(expected) > 0
    np.testing.assert_allclose(np.array(_col(table, "world/contacts/collide", "Points3D:positions")[-1]),
                               expected.pos, atol=1e-6)
    # Steps 0-4: nothing missed; step 5: the ball-floor pair, drawn as a red line down to the floor.
    missed = _col(table, "world/pairs/missed", "LineStrips3D:strips")
    assert list(_lengths(missed)) == [0] * 5 + [1]
    assert records[-1].missed_pairs == 1 and records[-1].candidates == records[-2].candidates - 1
    (a, b), = missed[-1]
    centre = data.geom_xpos[ball]
    np.testing.assert_allclose(a, [centre[0], centre[1], 0.0], atol=1e-6)  # its foot on the floor
    np.testing.assert_allclose(b, centre, atol=1e-6)
    assert list(_scalars(_col(table, "stats/pairs/missed", "Scalars:scalars"))) == [0] * 5 + [1]
    # Timed in a loop of one's own: our broad phase, and broad + narrow phase.
    assert np.all(_scalars(_col(table, "stats/time_us/collide_contacts", "Scalars:scalars")) > 0)
    # The visual-only geom is drawn apart; the far capsule has bounds but no pair.
    assert "/world/visual/spheres:Ellipsoids3D:half_sizes" in static or \
        "/world/visual/spheres:Ellipsoids3D:half_sizes" in table
    assert set(_lengths(_col(table, "world/bounds/geom_obbs", "Boxes3D:half_sizes"))) == {3}


def test_large_meshes_get_an_entity_each(tmp_path):
    # merge_meshes=0: every mesh geom static in its own frame, moved by a transform each step.
    model = cm.default_scene(seed=1, objects=7)
    data = mujoco.MjData(model)
    path = tmp_path / "meshes.rrd"
    with log_rerun(model, path, merge_meshes=0) as log:
        for _ in range(3):
            mujoco.mj_step(model, data)
            log.log(data)
    table, steps, static = _table(path)
    meshes = np.flatnonzero(np.asarray(model.geom_type) == GEOM_TYPES["mesh"])
    cols = sorted(k for k in static if k.endswith(":Mesh3D:vertex_positions"))
    assert len(meshes) == len(cols) > 0
    assert sorted(int(k.split("/mesh/")[1].split("_")[0]) for k in cols) == sorted(meshes)  # <id>_<name>
    for k in cols:
        g = int(k.split("/mesh/")[1].split("_")[0])
        pose = table[k.replace("Mesh3D:vertex_positions", "Transform3D:translation")]
        assert _lengths(pose).tolist() == [1, 1, 1]
        np.testing.assert_allclose(pose[-1][0] if np.ndim(pose[-1]) == 2 else pose[-1], data.geom_xpos[g],
                                   atol=1e-5)
    assert not any(k.startswith("/world/geoms/meshes:") for k in list(static) + list(table))


def test_bad_input(tmp_path):
    model = mujoco.MjModel.from_xml_string(BALLS)
    with pytest.raises(ValueError, match="path, spawn=True or a recording"):
        RerunLog(model)
    with pytest.raises(ValueError, match="folder"):
        RerunLog(model, tmp_path)
    with pytest.raises(ValueError, match="series_every"):
        RerunLog(model, tmp_path / "x.rrd", series_every=0)
    with pytest.raises(ValueError, match="merge_meshes"):
        RerunLog(model, tmp_path / "x.rrd", merge_meshes=-1)
    other = cm.default_scene(objects=2)
    with RerunLog(model, tmp_path / "bad.rrd") as log:
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        with pytest.raises(ValueError, match="step"):
            log.log(data, step=-1)
        with pytest.raises(ValueError, match="data"):
            log.log(mujoco.MjData(other))
        with pytest.raises(ValueError, match="steps"):
            log.log_series("stats/x", [1.0, 2.0], steps=[0])
        assert isinstance(log.log(data), StepRecord)  # still works after the errors


def test_command_line(tmp_path, capsys):
    from collide.__main__ import main

    out = tmp_path / "sub" / "run.rrd"
    assert main(["compare", "--steps", "5", "--no-contacts", "--rerun", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    table, steps, _ = _table(out)
    assert list(steps) == list(range(5))
    assert _lengths(_col(table, "world/pairs/candidates", "LineStrips3D:strips")).sum() > 0
    # The layout the viewer opens with: the 3D scene and the three plots.
    from rerun.chunk import RrdReader

    reader = RrdReader(str(out))
    (blueprint,) = reader.blueprints()
    views = {line.split()[0] for line in reader.stream(store=blueprint).collect().summary().splitlines()
             if line.startswith("/view/") and "/ViewContents" not in line.split()[0]}
    assert len(views) == 4


def test_without_rerun(monkeypatch, capsys):
    # Where rerun-sdk is missing: a clear ImportError, and the CLI refuses before running.
    from collide.__main__ import main

    monkeypatch.setitem(sys.modules, "rerun", None)
    model = mujoco.MjModel.from_xml_string(BALLS)
    with pytest.raises(ImportError, match="pip install"):
        log_rerun(model, "never.rrd")
    assert main(["compare", "--steps", "1", "--rerun", "never.rrd"]) == 2
    assert "rerun-sdk" in capsys.readouterr().err


def test_quaternions_match_scipy():
    # Rerun's (x, y, z, w) quaternions of rotation matrices, against scipy, on random rotations and
    # the half turns and near-half turns where a trace-only formula loses its digits.
    from scipy.spatial.transform import Rotation

    from collide.rerun_log._convert import _quat_xyzw

    rng = np.random.default_rng(7)
    rots = [Rotation.random(200, random_state=7)]
    axes = rng.normal(size=(50, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    for angle in (np.pi, np.pi - 1e-9, 1e-12, 0.0):
        rots.append(Rotation.from_rotvec(axes * angle))
    for r in rots:
        m = r.as_matrix()
        q = _quat_xyzw(m)
        ref = r.as_quat()
        sign = np.sign(np.sum(q * ref, axis=1))[:, None]  # q and -q are the same rotation
        np.testing.assert_allclose(q, sign * ref, atol=1e-12)
        np.testing.assert_allclose(Rotation.from_quat(q).as_matrix(), m, atol=1e-12)


# ---------------------------------------------------------------- adversarial review (issue 47)

LONE = BALLS.replace('<geom name="ghost"', '<body name="high" pos="0 0 3"><freejoint/>'
                     '<geom name="high" type="box" size="0.1 0.1 0.1"/></body>\n    <geom name="ghost"')


def _stepped(xml=BALLS, steps=2):
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    for _ in range(steps):
        mujoco.mj_step(model, data)
    return model, data


def test_a_closed_log_refuses_to_log(tmp_path):
    # Before: log() after close() (or in a second with-block) returned a StepRecord and wrote nothing.
    model, data = _stepped()
    log = log_rerun(model, tmp_path / "closed.rrd")
    with log:
        log.log(data)
    for call in (lambda: log.log(data), lambda: log.log_series("stats/x", [1.0]), log.flush,
                 lambda: log.snapshot(0, data, np.zeros((0, 2), int)), log.flush_snapshots):
        with pytest.raises(ValueError, match="closed"):
            call()
    with pytest.raises(ValueError, match="closed"):
        with log:
            pass
    log.close()  # a second close does nothing
    _, steps, _ = _table(tmp_path / "closed.rrd")
    assert list(steps) == [0]


def test_bad_arguments_leave_an_existing_file(tmp_path):
    # Before: the file was truncated (opened) and only then were steps/hold/seed refused.
    model = mujoco.MjModel.from_xml_string(BALLS)
    path = tmp_path / "run.rrd"
    record_compare(model, path, steps=3, hold=2, contacts=False)
    before = path.read_bytes()
    assert len(_table(path)[1]) == 3
    for bad in ({"steps": 0}, {"hold": 0}, {"seed": -1}, {"steps": 2.5}, {"contacts": "no"},
                {"bodies": "no"}, {"visual": 1}, {"series_every": 0}, {"recording": "rec"}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            record_compare(model, path, **{"steps": 3, **bad})
    assert path.read_bytes() == before
    assert list(_table(path)[1]) == [0, 1, 2]


def test_unwritable_path(tmp_path, capsys):
    # Before: rerun's RuntimeError from inside its bindings; the CLI printed a traceback, exit 1.
    from collide.__main__ import main

    model = mujoco.MjModel.from_xml_string(BALLS)
    blocker = tmp_path / "file.txt"
    blocker.write_text("a file, not a folder")
    with pytest.raises(ValueError, match="file.txt"):
        RerunLog(model, blocker / "x.rrd")
    with pytest.raises(ValueError, match="path: empty"):
        RerunLog(model, "")
    if sys.platform.startswith("linux"):  # sysfs refuses new files, even to root
        with pytest.raises(ValueError, match="path: cannot write /sys/x.rrd"):
            RerunLog(model, "/sys/x.rrd")
        assert main(["compare", "--steps", "1", "--rerun", "/sys/x.rrd"]) == 2
        assert "/sys/x.rrd" in capsys.readouterr().err


def test_cli_output_names(tmp_path, capsys):
    # Before: --rerun '' recorded nothing without a word; --rerun X --json X overwrote the recording.
    from collide.__main__ import main

    same = tmp_path / "same"
    assert main(["compare", "--steps", "1", "--rerun", str(same), "--json", str(same)]) == 2
    assert "same file" in capsys.readouterr().err
    assert main(["compare", "--steps", "1", "--rerun", ""]) == 2
    assert "empty" in capsys.readouterr().err
    assert not same.exists()


def test_candidates_are_checked(tmp_path):
    # Before: IndexError, negative ids wrapped, floats truncated, numpy's messages, self-pairs taken.
    model, data = _stepped()
    floor, ball = (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in ("floor", "ball"))
    assert [floor, ball] in cm.contact_pairs(model, data).tolist()  # the scene has a contact
    with RerunLog(model, tmp_path / "cand.rrd") as log:
        for bad, what in (([[0, 99]], "out of"), ([[-1, 0]], "out of"), ([[0.4, 1.6]], "integer"),
                          ([1, 2, 3], "shape"), ([[np.nan, 1]], "non-finite"), ([[1, 1]], "itself"),
                          ([["a", "b"]], "integer")):
            with pytest.raises(ValueError, match=f"candidates: .*{what}"):
                log.log(data, candidates=bad)
        # A pair given higher id first is the same pair: not a miss.
        touching = cm.contact_pairs(model, data)
        assert log.log(data, candidates=touching[:, ::-1]).missed_pairs == 0
        assert log.log(data, candidates=touching.astype(float)).missed_pairs == 0
        assert log.log(data, candidates=[]).missed_pairs == len(touching)


def test_non_finite_pose_of_a_geom_in_no_pair(tmp_path):
    # Before: logged (an inf centre, a NaN quaternion): the narrow phase checks only paired geoms.
    model, data = _stepped(LONE)
    high = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "high")
    assert high not in cm.Collider(model).pairs(data)
    with RerunLog(model, tmp_path / "nan.rrd") as log:
        for arr, index in ((data.geom_xpos, (high, 0)), (data.geom_xmat, (high, 4))):
            keep = arr[index]
            arr[index] = np.inf if arr is data.geom_xpos else np.nan
            with pytest.raises(ValueError, match=f"non-finite pose .* geom {high}_high"):
                log.log(data)
            arr[index] = keep
        with pytest.raises(ValueError, match="step"):
            log.log(data, step=2**63)
        assert log.log(data).step == 0  # still works


def test_series_reach_the_file_without_close(tmp_path):
    # Before: the series (sent every series_every steps) of a log never closed were lost.
    import subprocess

    path = tmp_path / "open.rrd"
    script = (f"import mujoco, collide.mujoco as cm\nm = mujoco.MjModel.from_xml_string({BALLS!r})\n"
              f"d = mujoco.MjData(m)\nlog = cm.log_rerun(m, {str(path)!r})\n"
              "for _ in range(10):\n    mujoco.mj_step(m, d); log.log(d)\n")
    subprocess.run([sys.executable, "-c", script], check=True, timeout=600)
    table, steps, _ = _table(path)
    assert list(steps) == list(range(10))
    assert len(_scalars(_col(table, "stats/pairs/candidates", "Scalars:scalars"))) == 10


def test_no_contacts_leaves_ours_out(tmp_path):
    # Before: record_compare(contacts=False) (the CLI's --no-contacts) still computed and drew ours.
    model = mujoco.MjModel.from_xml_string(BALLS)
    path = tmp_path / "nc.rrd"
    result, records = record_compare(model, path, steps=3, contacts=False)
    assert sum(result["contact_pairs_per_step"]) > 0  # MuJoCo made contacts
    assert all(r.our_contacts == 0 and r.missed_contacts == 0 for r in records)
    table, _, _ = _table(path)
    assert not any(k.startswith(("/world/contacts/collide", "/world/contacts/missed", "/stats/contacts/collide"))
                   for k in table)
    assert sum(_lengths(_col(table, "world/contacts/mujoco", "Points3D:positions"))) > 0


def test_height_field_contacts_show_as_missed_contacts(tmp_path):
    # What docs/visualising.md says: no narrow phase for height fields, so MuJoCo's contacts there
    # are "missed contacts", while the pair itself is among our candidates (no missed pair).
    xml = ('<mujoco><asset><hfield name="h" nrow="3" ncol="3" size="1 1 0.1 0.1" elevation="0 0 0 0 1 0 0 0 0"/>'
           '</asset><worldbody><geom type="hfield" hfield="h"/><body pos="0.3 0.3 0.12"><freejoint/>'
           '<geom type="sphere" size="0.1"/></body></worldbody></mujoco>')
    model, data = _stepped(xml, steps=1)
    assert data.ncon > 0
    with log_rerun(model, tmp_path / "hf.rrd") as log:
        r = log.log(data)
    assert r.candidates == 1 and r.missed_pairs == 0
    assert r.our_contacts == 0 and r.missed_contacts == r.mujoco_contacts == data.ncon
