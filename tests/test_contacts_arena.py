"""`collide.Contacts` from `Collider.contacts` are views of an output arena (`GeomTable._new_out`):
a result kept by the caller is never written by a later call, through full arenas and calls
that need more rows than a new arena has; a call without contacts returns the table's one
empty `Contacts`; a copied or unpickled table writes an arena of its own; two threads calling one
table never get rows of the other's call.
"""

from __future__ import annotations

import copy
import pickle
import time

import mujoco
import numpy as np

import collide.mujoco as cm
from collide import contacts as cc
from collide._kernels import manifold as _km
from collide._kernels.warm import WARM_LEN
from _threads import in_threads, scattered_boxes

FIELDS = ("geom", "dist", "pos", "normal", "margin", "skipped")


def _stepped(seed: int = 2, objects: int = 12, steps: int = 50):
    model = cm.default_scene(seed=seed, objects=objects)
    data = mujoco.MjData(model)
    for _ in range(steps):
        mujoco.mj_step(model, data)
    return model, data


def _frozen(c) -> dict:
    return {f: np.array(getattr(c, f)) for f in FIELDS}


def _same(c, ref: dict) -> bool:
    return all(getattr(c, f).dtype == ref[f].dtype and np.array_equal(getattr(c, f), ref[f]) for f in FIELDS)


def test_kept_results_survive_later_calls(monkeypatch):
    # Small arenas: a call fills one within a few steps, and some calls need more rows than a
    # new arena of OUT_ROWS has (per_pair * K), so both ways of starting an arena run.
    monkeypatch.setattr(cc, "OUT_ROWS", 16)
    model, data = _stepped()
    col = cm.Collider(model)
    kept, copies, bases = [], [], set()
    needed = 0
    for _ in range(300):
        mujoco.mj_step(model, data)
        c = col.contacts(data)
        c2 = col.contacts(data)  # the same state again: rows of its own
        assert _same(c2, _frozen(c))
        kept.append(c)
        copies.append(_frozen(c))
        if len(c):
            assert c.dist.base is not None
            bases.add(id(col.table._out[1]))
        needed = max(needed, col.table._per_pair * len(col.pairs(data)))
    assert sum(len(c) for c in kept) > 300  # the scene makes contacts
    assert len(bases) > 10  # arenas were filled and replaced
    assert needed > cc.OUT_ROWS  # some call needed a larger arena than OUT_ROWS
    assert all(_same(c, ref) for c, ref in zip(kept, copies))


def test_kept_results_match_the_narrow_phase():
    # The arena's views hold what narrow_phase computes afresh for the same pairs and poses.
    model, data = _stepped()
    col = cm.Collider(model)
    for _ in range(40):
        mujoco.mj_step(model, data)
        # cold, as the fresh table's call: a warm start's answers (`collide._kernels.warm`) agree
        # within the contact tolerance, not bit for bit
        col.table._wsi[-WARM_LEN:] = 0
        c = col.contacts(data)
        ref = cc.narrow_phase(cm.Collider(model).table, col.pairs(data), data.geom_xpos, data.geom_xmat)
        assert _same(c, _frozen(ref))


def test_no_contacts_is_the_tables_empty_result():
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><geom type='plane' size='1 1 1'/>"
        "<body pos='0 0 0.5'><freejoint/><geom type='box' size='0.1 0.1 0.1'/></body>"
        "<body pos='0.19 0.19 0.5'><freejoint/><geom type='sphere' size='0.1'/></body>"
        "</worldbody></mujoco>")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    col = cm.Collider(model)
    assert len(col.pairs(data)) > 0  # the box's and the sphere's bounds overlap (not they): the kernel runs
    c = col.contacts(data)
    assert c is col.table._empty and len(c) == 0
    assert (c.geom.shape, c.geom.dtype, c.pos.shape, c.normal.shape, c.skipped.shape, c.skipped.dtype) == (
        (0, 2), np.int32, (0, 3), (0, 3), (0, 2), np.int32)
    assert c.dist.dtype == c.margin.dtype == np.float64
    data.qpos[2] = 0.05  # the box into the plane: contacts, a result of their own
    mujoco.mj_forward(model, data)
    c1 = col.contacts(data)
    assert len(c1) > 0 and c1 is not col.table._empty and len(col.table._empty) == 0


def test_copied_tables_write_arenas_of_their_own():
    model, data = _stepped()
    col = cm.Collider(model)
    pairs = col.pairs(data)
    xmat = data.geom_xmat.reshape(-1, 3, 3)
    ref = cc.narrow_phase(col.table, pairs, data.geom_xpos, xmat)
    assert len(ref) > 0
    frozen = _frozen(ref)
    for t in (copy.copy(col.table), copy.deepcopy(col.table), pickle.loads(pickle.dumps(col.table))):
        assert not np.shares_memory(t._out[1], col.table._out[1])
        assert t._out[6][_km.A_NEXT] == 0 and t._ctx_addr != col.table._ctx_addr
        c = cc.narrow_phase(t, pairs, data.geom_xpos, xmat)
        assert _same(c, frozen) and _same(ref, frozen)


def test_two_threads_one_table_through_new_arenas(monkeypatch):
    # The kernel writes the arena `_contacts_of` passes it, and `_contacts_of` reads the rows from
    # that arena, not from the table's: a thread that starts a new arena (a full one) between
    # another thread's call and its read cannot hand that thread rows of the wrong arena. Tiny
    # arenas (a new one every few calls), and a pause after each kernel call that lets the other
    # thread run its own calls there (reading the table's arena after the call instead, both
    # threads' results went wrong); every kept result must hold its own scene's contacts at the
    # end. Boxes on a plane: box-box and box-plane pairs, which no warm start answers, so every
    # call's answer is the cold reference's bit for bit.
    monkeypatch.setattr(cc, "OUT_ROWS", 16)
    model, datas = scattered_boxes()
    col = cm.Collider(model)
    pairs = [col.pairs(d).copy() for d in datas]
    ref = [_frozen(cc.narrow_phase(cm.Collider(model).table, p, d.geom_xpos, d.geom_xmat))
           for p, d in zip(pairs, datas)]
    assert min(len(r["dist"]) for r in ref) > 0 and not np.array_equal(ref[0]["pos"], ref[1]["pos"])
    table = col.table
    poses = [(d.geom_xpos, d.geom_xmat.reshape(-1, 3, 3)) for d in datas]
    cc.contacts_of(table, pairs[0], *poses[0])  # `_bound` is the compiled entry point from here on
    kernel = cc._bound

    def paused(*args):
        r = kernel(*args)
        time.sleep(2e-4)  # the GIL to the other thread, between this call and its rows' read
        return r

    monkeypatch.setattr(cc, "_bound", paused)

    def worker(k):
        return [cc.contacts_of(table, pairs[k], *poses[k]) for _ in range(300)]

    arena = table._out[1]
    got = in_threads(worker, 2)
    assert table._out[1] is not arena  # arenas were replaced during the run
    for k in range(2):
        assert all(_same(c, ref[k]) for c in got[k]), f"thread {k} got another scene's or a rewritten result"
