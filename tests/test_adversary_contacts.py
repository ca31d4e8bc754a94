"""Adversarial checks of the narrow phase's per-step path (e665341): `collide.contacts.contacts_of`
is public, and it calls `collide_bound`'s compiled entry point, which reads its arguments as its one
signature's types without checking them. Input of another layout, dtype or shape must give the
right answer or a ValueError (as the dispatcher's own specialisation or error did before), never a
silently wrong answer or a crash; the shared empty `Contacts` must not be changed through its
arrays; `narrow_phase` checks geom ids before narrowing them to int32.
"""

from __future__ import annotations

import copy
import pickle
import subprocess
import sys
import textwrap

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")
import collide.mujoco as cm  # noqa: E402
from _threads import in_threads  # noqa: E402
from collide import contacts as cc  # noqa: E402

FIELDS = ("geom", "dist", "pos", "normal", "margin", "skipped")


@pytest.fixture(scope="module")
def scene():
    model = cm.default_scene(seed=2, objects=12)
    data = mujoco.MjData(model)
    for _ in range(80):
        mujoco.mj_step(model, data)
    col = cm.Collider(model)
    pairs = col.pairs(data)
    ref = cc.narrow_phase(cc.GeomTable(model), pairs, data.geom_xpos, data.geom_xmat)
    assert len(ref) > 10 and len(pairs) > 10  # the scene has real contacts
    xpos, xmat = col._poses(data)
    return model, data, np.array(pairs), xpos, xmat, {f: np.array(getattr(ref, f)) for f in FIELDS}


def _same(c, ref: dict) -> bool:
    return all(np.array_equal(getattr(c, f), ref[f]) for f in FIELDS)


CASES = {
    "int64 pairs": lambda P, xp, xm: (P.astype(np.int64), xp, xm),
    "uint32 pairs": lambda P, xp, xm: (P.astype(np.uint32), xp, xm),
    "Fortran pairs": lambda P, xp, xm: (np.asfortranarray(P), xp, xm),
    "strided pairs": lambda P, xp, xm: (np.repeat(P, 2, axis=0)[::2], xp, xm),
    "reversed columns": lambda P, xp, xm: (np.ascontiguousarray(P[:, ::-1])[:, ::-1], xp, xm),
    "list pairs": lambda P, xp, xm: (P.tolist(), xp, xm),
    "writable pairs": lambda P, xp, xm: (P.copy(), xp, xm),
    "float32 xpos": lambda P, xp, xm: (P, xp.astype(np.float32), xm),
    "float32 xmat": lambda P, xp, xm: (P, xp, xm.astype(np.float32)),
    "xmat (G, 9)": lambda P, xp, xm: (P, xp, np.ascontiguousarray(xm.reshape(-1, 9))),
    "Fortran xpos": lambda P, xp, xm: (P, np.asfortranarray(xp), xm),
    "Fortran xmat": lambda P, xp, xm: (P, xp, np.asfortranarray(xm)),
    "strided xpos": lambda P, xp, xm: (P, np.repeat(xp, 2, axis=0)[::2], xm),
}


@pytest.mark.parametrize("case", list(CASES))
def test_contacts_of_any_layout_is_right_or_refused(scene, case):
    # Before: the dispatcher compiled a specialisation for these (the right answer) or refused
    # them; through the unchecked entry point, Fortran, strided and (G, 9) arrays were read as
    # the signature's C-contiguous ones (wrong contacts, no error).
    model, data, P, xpos, xmat, ref = scene
    args = CASES[case](P, xpos, xmat)
    try:
        c = cc.contacts_of(cc.GeomTable(model), *args)
    except ValueError:
        return
    if "float32" in case:  # poses rounded to float32: the contacts of those poses
        p64 = [np.asarray(a, np.float64) for a in args[1:]]
        r32 = cc.narrow_phase(cc.GeomTable(model), P, *p64)
        ref = {f: np.array(getattr(r32, f)) for f in FIELDS}
        assert len(r32) > 10
    assert _same(c, ref), case


@pytest.mark.parametrize("case", ["1-D pairs", "short xpos", "2-D xmat of 9 rows"])
def test_contacts_of_wrong_shapes_raise_not_crash(case):
    # A segfault (1-D pairs read as (K, 2)) or garbage read past the end (short xpos): run in a
    # subprocess so that a crash is a failure, not the end of the test run.
    code = textwrap.dedent(f"""
        import mujoco, numpy as np
        import collide.mujoco as cm
        from collide import contacts as cc
        model = cm.default_scene(seed=2, objects=12)
        data = mujoco.MjData(model)
        for _ in range(80):
            mujoco.mj_step(model, data)
        col = cm.Collider(model)
        P = np.array(col.pairs(data))
        xpos, xmat = col._poses(data)
        case = {case!r}
        args = {{"1-D pairs": (P.ravel(), xpos, xmat), "short xpos": (P, xpos[:3].copy(), xmat),
                "2-D xmat of 9 rows": (P, xpos, np.ascontiguousarray(xmat[:, :, :3].reshape(-1, 9)[:9]))}}[case]
        try:
            cc.contacts_of(cc.GeomTable(model), *args)
        except ValueError as exc:
            print("ValueError", exc)
        else:
            print("accepted")
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, (case, r.returncode, r.stderr[-2000:])
    assert r.stdout.strip().splitlines()[-1].startswith("ValueError"), r.stdout


def test_contacts_of_checks_geom_ids(scene):
    model, data, P, xpos, xmat, ref = scene
    t = cc.GeomTable(model)
    for bad in ([[0, model.ngeom]], [[-1, 1]], [[1, 0]], [[2, 2]]):
        with pytest.raises(ValueError, match="pairs"):
            cc.contacts_of(t, np.array(bad, np.int32), xpos, xmat)
    assert _same(cc.contacts_of(t, P.astype(np.int32), xpos, xmat), ref)  # still works after


def _sphere_sunk_in_plane():
    # (GeomTable, MjData) of a sphere 1 cm into a plane: geoms (0, 1) make one contact.
    m = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><geom type="plane" size="1 1 1"/>'
        '<body pos="0 0 0.09"><freejoint/><geom type="sphere" size="0.1"/></body></worldbody></mujoco>')
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return cc.GeomTable(m), d


def test_narrow_phase_checks_ids_before_narrowing_to_int32():
    # 2**32 + 1 narrowed to int32 is 1: checked after the cast, the pair (0, 1) was collided.
    t, d = _sphere_sunk_in_plane()
    assert len(cc.narrow_phase(t, np.array([[0, 1]]), d.geom_xpos, d.geom_xmat)) == 1  # a real contact
    for bad in ([[0, 2**32 + 1]], [[-2**32, 1]], [[2**32, 2**32 + 1]]):
        with pytest.raises(ValueError, match="pairs"):
            cc.narrow_phase(t, np.array(bad, np.int64), d.geom_xpos, d.geom_xmat)


def test_narrow_phase_of_no_pairs_is_the_empty_result():
    # An empty list of pairs (a user's broad phase found none) is no pairs, not a wrongly shaped
    # array; a wrongly shaped empty one still is.
    t, d = _sphere_sunk_in_plane()
    for empty in ([], (), np.zeros(0, np.int64), np.zeros((0, 2), np.int32)):
        c = cc.narrow_phase(t, empty, d.geom_xpos, d.geom_xmat)
        assert len(c) == 0 and c.geom.shape == (0, 2) and c.pos.shape == (0, 3)
    for bad in (np.zeros((0, 3), np.int32), [[]]):
        with pytest.raises(ValueError, match="pairs"):
            cc.narrow_phase(t, bad, d.geom_xpos, d.geom_xmat)
    assert len(cc.narrow_phase(t, [[0, 1]], d.geom_xpos, d.geom_xmat)) == 1  # and the real contact


def test_shared_empty_contacts_cannot_be_changed_through_its_arrays():
    # Every call without contacts returns the table's one empty Contacts: resizing one of its
    # arrays in place (it owned its data) made every later empty result 5 rows long.
    m = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><geom type="plane" size="1 1 1"/>'
        '<body pos="0 0 0.5"><freejoint/><geom type="sphere" size="0.1"/></body></worldbody></mujoco>')
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    col = cm.Collider(m)
    c = col.contacts(d)
    assert len(c) == 0
    for f in FIELDS:
        a = getattr(c, f)
        with pytest.raises(ValueError):
            a.resize(5, refcheck=False)
        assert not a.flags.writeable
    again = col.contacts(d)
    assert len(again) == 0 and all(getattr(again, f).size == 0 for f in FIELDS)
    assert again.pos.shape == (0, 3) and again.geom.shape == (0, 2) and again.geom.dtype == np.int32
    # an unpickled or copied table's empty result likewise (unpickled arrays own their data)
    for t in (pickle.loads(pickle.dumps(col.table)), copy.deepcopy(col.table), copy.copy(col.table)):
        e = cc.narrow_phase(t, np.array([[0, 1]]), d.geom_xpos, d.geom_xmat)
        assert len(e) == 0  # the pair tested, no contact
        for f in FIELDS:
            with pytest.raises(ValueError):
                getattr(e, f).resize(5, refcheck=False)


def test_threads_on_one_table_keep_their_rows(monkeypatch):
    # Two threads, one table, small arenas (replaced every few calls, by either thread): each
    # call's rows are its own, then and after every later call. A warm start across calls may
    # move a distance by its tolerance: dist within 1e-9 of the pair's size, rows equal.
    monkeypatch.setattr(cc, "OUT_ROWS", 24)
    model = cm.default_scene(seed=3, objects=14)
    base = mujoco.MjData(model)
    for _ in range(30):
        mujoco.mj_step(model, base)
    col = cm.Collider(model)
    size = col.table.size
    states = []
    for s in range(2):
        d = mujoco.MjData(model)
        d.qpos[:] = base.qpos
        d.qvel[:] = base.qvel + 0.05 * np.random.default_rng(s).normal(size=model.nv)
        traj = []
        for _ in range(60):
            mujoco.mj_step(model, d)
            traj.append((np.array(col.pairs(d)), d.geom_xpos.copy(), d.geom_xmat.copy()))
        states.append(traj)
    refs = [[cc.narrow_phase(cc.GeomTable(model), *st) for st in traj] for traj in states]
    refs = [[{f: np.array(getattr(c, f)) for f in FIELDS} for c in r] for r in refs]
    got = in_threads(lambda s: [cc.narrow_phase(col.table, *st) for st in states[s]], 2, switch=1e-6)
    n = 0
    for s in range(2):
        assert len(got[s]) == 60
        for c, r in zip(got[s], refs[s]):
            n += len(c)
            assert np.array_equal(c.geom, r["geom"]) and np.array_equal(c.margin, r["margin"])
            tol = 1e-9 * (size[r["geom"][:, 0]] + size[r["geom"][:, 1]]) if len(c) else 0.0
            assert np.all(np.abs(c.dist - r["dist"]) <= 2 * tol + 1e-15)
            assert np.allclose(c.pos, r["pos"], atol=1e-9) and np.allclose(c.normal, r["normal"], atol=1e-6)
    assert n > 1000  # the scene has real contacts
