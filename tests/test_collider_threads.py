"""One `collide.mujoco.Collider`, two threads, two MjData: each thread gets its own data's contacts.

Found by the adversarial review (2026-11-29): ``Collider._poses`` published the last MjData's
views and the MjData itself in two stores (``_views``, then ``_checked``) and ``contacts`` read
them separately, so a thread switch between them handed one thread the other MjData's poses.
CPython's GIL switches threads only at calls and backward jumps, so without a Python-level
tracer the window is rarely hit; a tracer (a debugger, a line profiler, coverage's Python
tracer) puts a switch point on every line, which this test installs to make the race frequent.
"""

from __future__ import annotations

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
