"""Run a test's worker in several Python threads at once (the thread-safety tests' one harness).

A worker's exception would die with its thread and a hung thread would hang the suite: `in_threads`
joins with a timeout, fails on a hang, and raises the first worker's exception in the test's own
thread (its traceback kept), so a test states only what each thread does and what it must get.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Callable
from typing import Any

__all__ = ["in_child", "in_threads", "scattered_boxes"]


def in_threads(work: Callable[[int], Any], n: int = 2, *, timeout: float = 600.0,
               switch: float | None = None) -> list:
    """``[work(0), ..., work(n - 1)]``, each called in a thread of its own, all started at once.

    Parameters
    ----------
    work : callable
        Called with the thread's index.
    n : int
        Number of threads.
    timeout : float
        Seconds each join waits; a thread still running after it fails the test ("hang").
    switch : float, optional
        ``sys.setswitchinterval`` while the threads run (restored after): a tiny one makes the
        threads hand the GIL over as often as possible, so that calls interleave.

    Returns
    -------
    list
        Each thread's return value, by index.

    Raises
    ------
    AssertionError
        A thread did not finish within ``timeout``.
    BaseException
        The first exception a worker raised (by thread index), re-raised here.
    """
    out: list = [None] * n
    errors: list = [None] * n

    def run(k: int) -> None:
        try:
            out[k] = work(k)
        except BaseException as exc:  # noqa: BLE001 - re-raised in the caller's thread below
            errors[k] = exc

    old = sys.getswitchinterval()
    if switch is not None:
        sys.setswitchinterval(switch)
    try:
        threads = [threading.Thread(target=run, args=(k,)) for k in range(n)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout)
    finally:
        sys.setswitchinterval(old)
    assert not any(t.is_alive() for t in threads), f"a thread ran past {timeout} s (hang)"
    for exc in errors:
        if exc is not None:
            raise exc
    return out


def in_child(check: Callable[[], bool], seconds: int = 60) -> int:
    """``check()`` in a forked child (POSIX): its exit code, 0 where it returned True, 2 where False,
    1 where it raised; -1 where a signal ended it (an alarm after ``seconds``: a hang; SIGTERM, ...).
    The child leaves without pytest's teardown."""
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            signal.alarm(seconds)
            code = 0 if check() else 2
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    return os.WEXITSTATUS(status) if os.WIFEXITED(status) else -1


def scattered_boxes(seeds=(0, 1)) -> tuple:
    """Six free boxes over a plane, and an ``MjData`` a seed with the boxes moved and turned at random
    into one another (after ``mj_kinematics``): box-box and box-plane contacts, which no warm start
    answers, different for each seed. Returns ``(model, datas)``."""
    import mujoco
    import numpy as np

    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><geom type='plane' size='5 5 .1'/>" + "".join(
            f"<body pos='{0.3 * (i % 3)} {0.3 * (i // 3)} 0.2'><freejoint/><geom type='box' size='.1 .12 .08'/></body>"
            for i in range(6)) + "</worldbody></mujoco>")
    datas = []
    for seed in seeds:
        d = mujoco.MjData(model)
        rng = np.random.default_rng(seed)
        for b in range(6):
            d.qpos[7 * b:7 * b + 3] += rng.normal(size=3) * 0.1
            q = rng.normal(size=4)
            d.qpos[7 * b + 3:7 * b + 7] = q / np.linalg.norm(q)
        mujoco.mj_kinematics(model, d)
        datas.append(d)
    return model, datas
