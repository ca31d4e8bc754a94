"""One `collide.mujoco.Collider`, two threads, two MjData: each thread gets its own data's contacts;
and a child forked while a thread of its parent was inside a call can call it (2026-11-30).

Found by the adversarial review (2026-11-29): ``Collider._poses`` published the last MjData's
views and the MjData itself in two stores (``_views``, then ``_checked``) and ``contacts`` read
them separately, so a thread switch between them handed one thread the other MjData's poses.
CPython's GIL switches threads only at calls and backward jumps, so without a Python-level
tracer the window is rarely hit; a tracer (a debugger, a line profiler, coverage's Python
tracer) puts a switch point on every line, which this test installs to make the race frequent.
"""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")
import collide.mujoco as cm  # noqa: E402
from _threads import in_threads, scattered_boxes  # noqa: E402


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
def test_a_forked_child_calls_while_its_parent_held_the_lock():
    # A thread inside `pairs` at an os.fork() holds the broad phase's lock, and does not exist in
    # the child: the child gets a new lock (`collide.broadphase._after_fork`), else its first call
    # waited forever. The parent's thread is played here by holding the lock across the fork.
    m, datas = scattered_boxes()
    col = cm.Collider(m)
    ref = _signature(col.contacts(datas[0]))
    lock = col.broadphase.broadphase._lock  # collide.mujoco.BroadPhase -> collide.BroadPhase
    lock.acquire()
    try:
        pid = os.fork()
        if pid == 0:  # the child: a call, its answer checked, then out without pytest's teardown
            code = 1
            try:
                signal.alarm(60)  # still waiting after a minute: killed, the test fails
                code = 0 if _signature(col.contacts(datas[0])) == ref else 2
            finally:
                os._exit(code)
    finally:
        lock.release()
    _, status = os.waitpid(pid, 0)
    assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0, f"the child: wait status {status}"

