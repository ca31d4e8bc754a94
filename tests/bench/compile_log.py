"""A pytest plugin that logs every numba compile: where CI's time goes (two thirds of it is compiling).

    PYTHONPATH=<copy>:tests/bench python -m pytest -p compile_log tests/test_check.py

run on a ``git archive`` copy of the package without ``__pycache__`` (``<copy>``), so that nothing is
loaded from numba's cache. Each line of ``$COMPLOG`` (default ``compile_log.txt``): seconds, the
dispatcher (indented by nesting: a callee compiled inside its caller's compile), the test that
triggered it. A dispatcher listed twice compiled a second signature: a literal argument
(``f(a, False)`` is typed ``Literal[bool](False)``), another writeable flag or layout of an array.
It listens to numba's ``numba:compile`` event (numba.core.event), broadcast only for a compile,
not for a cache load.
"""

from __future__ import annotations

import os
import time

from numba.core import event

_starts: dict = {}
_depth = [0]


class _Listener(event.Listener):
    def on_start(self, ev):
        _depth[0] += 1
        _starts[id(ev.data["dispatcher"]), _depth[0]] = time.perf_counter()

    def on_end(self, ev):
        disp = ev.data["dispatcher"]
        took = time.perf_counter() - _starts.pop((id(disp), _depth[0]), time.perf_counter())
        test = os.environ.get("PYTEST_CURRENT_TEST", "").split(" ")[0]
        with open(os.environ.get("COMPLOG", "compile_log.txt"), "a") as f:
            f.write(f"{took:8.2f} {'  ' * (_depth[0] - 1)}{disp.py_func.__module__}.{disp.py_func.__name__} [{test}]\n")
        _depth[0] -= 1


event.register("numba:compile", _Listener())
