"""One `collide.mujoco.Collider`, two threads, two MjData: each thread gets its own data's contacts;
and a child forked while threads of its parent held collide's locks can call it (2026-11-30, 2026-12-02).

Found by the adversarial review (2026-11-29): ``Collider._poses`` published the last MjData's
views and the MjData itself in two stores (``_views``, then ``_checked``) and ``contacts`` read
them separately, so a thread switch between them handed one thread the other MjData's poses.
CPython's GIL switches threads only at calls and backward jumps, so without a Python-level
tracer the window is rarely hit; a tracer (a debugger, a line profiler, coverage's Python
tracer) puts a switch point on every line, which this test installs to make the race frequent.
"""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")
import collide._fork as _fork  # noqa: E402
import collide.mujoco as cm  # noqa: E402
import collide.signed_distance as sd  # noqa: E402
import collide.support as sp  # noqa: E402
from collide import PointCloud, distance  # noqa: E402
from _threads import in_child, in_threads, scattered_boxes  # noqa: E402


def _signature(c) -> tuple:
    return c.geom.tobytes(), np.round(c.dist, 12).tobytes()


def test_two_threads_two_datas_one_collider():
    m, datas = scattered_boxes()
    ref = [cm.Collider(m).contacts(d) for d in datas]
    assert min(len(r.dist) for r in ref) > 0  # both scenes have contacts
    ref = [_signature(r) for r in ref]
    assert ref[0] != ref[1]  # and different ones: a mix-up shows
    col = cm.Collider(m)

    def worker(k):
        wrong, errors = 0, []
        for _ in range(10000):
            time.sleep(0)  # hand the GIL over: the other thread's call interleaves with this one's
            try:
                c = col.contacts(datas[k])
            except Exception as exc:  # noqa: BLE001 - any exception is a failure, counted on
                errors.append(repr(exc))
                continue
            wrong += _signature(c) != ref[k]
        return wrong, errors

    def tracer(frame, event, arg):  # a switch point on every line of Collider._poses
        return tracer if frame.f_code.co_name == "_poses" else None

    threading.settrace(tracer)
    try:
        got = in_threads(worker, 2, switch=1e-6)
    finally:
        threading.settrace(None)
    assert [e for _, e in got] == [[], []]
    assert [w for w, _ in got] == [0, 0]


@pytest.mark.skipif(not hasattr(os, "fork"), reason="os.fork: POSIX only")
def test_a_forked_child_calls_while_its_parent_held_the_locks():
    # A thread holding a lock at an os.fork() does not exist in the child, and the child's first
    # call that takes that lock waited forever. Each lock of collide is made by
    # `collide._fork.new_lock`, which gives a forked child a new, free one: the broad phase's
    # (inside `pairs`), a Collider's set-up lock (check_batch's pairs, made at its first call),
    # and the shape caches' and `collide.distance`'s loader (module locks). The parent's threads
    # are played here by holding every one of them across the fork.
    # The parent has run a batch (numba's threads started): on GNU OpenMP the child's batch calls
    # raise a RuntimeError (numba would SIGTERM the child at their launch), and the rest works.
    m, datas = scattered_boxes()
    col = cm.Collider(m)
    ref = _signature(col.contacts(datas[0]))
    qpos = np.stack([d.qpos for d in datas])
    other = cm.Collider(m)
    want = other.check_batch(qpos, distance=True).min_distance  # `col`'s pairs not made yet
    refused = _fork._gnu_openmp_started()  # the layer numba started here, read as the child reads it
    pts = np.random.default_rng(0).normal(size=(2, 12, 3))
    dref = distance(PointCloud(pts[0]), PointCloud(pts[1] + 3.0, 0.1)).distance

    def batch_ok() -> bool:
        if not refused:
            return np.array_equal(col.check_batch(qpos, distance=True).min_distance, want)
        for call in (lambda: col.check_batch(qpos), lambda: col.broadphase.pairs_batch(m, qpos),
                     lambda: cm.kinematics_batch(m, qpos)):
            with pytest.raises(RuntimeError, match="'spawn' or 'forkserver'"):
                call()
        return True

    def child() -> bool:  # fresh shapes: each a miss of both shape caches, an insertion under their locks
        return (_signature(col.contacts(datas[0])) == ref
                and np.array_equal(col._filtered(), other._filtered())
                and distance(PointCloud(pts[0]), PointCloud(pts[1] + 3.0, 0.1)).distance == dref
                and batch_ok()
                and _signature(col.contacts(datas[1])) == _signature(other.contacts(datas[1])))

    locks = [col.broadphase.broadphase._lock,  # collide.mujoco.BroadPhase -> collide.BroadPhase
             col._setup_lock, sd._load_lock, sd._shapes_lock, sp._cache_lock]
    assert col._distance_pairs is None and np.all(np.isfinite(want)) and dref > 0.0
    for lock in locks:
        lock.acquire()
    try:
        code = in_child(child)  # 1: it raised; -1: still waiting after a minute (an alarm), or killed
    finally:
        for lock in locks:
            lock.release()
    assert code == 0, f"the child's exit code {code}"
