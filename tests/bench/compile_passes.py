"""Where one entry point's cold compile goes: numba's passes, by function (a developer's tool).

    python tests/bench/compile_passes.py JOB [--package DIR] [--top N] [--checked]

``JOB`` is one of `compile_time.JOBS` (``contacts``, ``check_lanes``, ...). It runs alone in a
fresh process with an empty numba cache (so everything it reaches is compiled, the shared step and
contact kernels included) and prints each (pass, function)'s *self* time: a callee compiled inside
its caller's type inference is counted in the callee's passes, not the caller's. numba's
``numba:run_pass`` event names a pass ``"<pass> [<function>]"``; ``<llvm>`` is the time spent
holding numba's LLVM lock (code generation and optimisation, which overlaps ``native_lowering``
and the finalisation of each library). Then the totals by function and by pass.

Why: CI's time is mostly numba compiling (stop 76's note). A function with a large
``inline_inlinables`` and ``nopython_type_inference`` is paying for its ``inline="always"``
callees, each copy typed and lowered again; a large ``<llvm>`` with a small front end is LLVM's.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _machine import cpu
from compile_time import JOBS, MODELS, ROOT

_CHILD = """
import collections, json, time
from pathlib import Path
from numba.core import event
MODELS = Path({models!r})
self_t, stack = collections.Counter(), []
class Passes(event.Listener):
    def on_start(self, ev):
        stack.append([ev.data["name"], time.perf_counter(), 0.0])
    def on_end(self, ev):
        name, t0, inner = stack.pop()
        took = time.perf_counter() - t0
        self_t[name] += took - inner
        if stack:
            stack[-1][2] += took
class Llvm(event.Listener):
    def on_start(self, ev):
        self.t = time.perf_counter()
    def on_end(self, ev):
        self_t["<llvm> [all]"] += time.perf_counter() - self.t
event.register("numba:run_pass", Passes())
event.register("numba:llvm_lock", Llvm())
t = time.perf_counter()
{code}
print(json.dumps({{"seconds": time.perf_counter() - t, "passes": self_t}}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("job", choices=sorted(JOBS))
    ap.add_argument("--package", type=Path, default=ROOT, help="folder holding the collide package to compile")
    ap.add_argument("--top", type=int, default=25, help="rows of each table")
    ap.add_argument("--checked", action="store_true", help="compile the checked mode's kernels (COLLIDE_CHECKED=1)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(args.package))
        env.pop("COLLIDE_CHECKED", None)
        if args.checked:
            env["COLLIDE_CHECKED"] = "1"
        code = _CHILD.format(models=str(MODELS), code=JOBS[args.job][1])
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=7200,
                             cwd=cache)  # cwd: not a checkout's root, which would shadow --package
    if out.returncode != 0:
        sys.exit(f"{args.job}: failed\n{out.stderr[-3000:]}")
    r = json.loads(out.stdout.strip().splitlines()[-1])
    rows = []
    for key, s in r["passes"].items():
        name, _, fn = key.partition(" [")
        rows.append((s, name, fn.rstrip("]")))
    rows.sort(reverse=True)
    print(f"# collide: cold compile of job {args.job!r} by numba pass and function (self seconds)")
    print(f"# machine: {os.cpu_count()} cores, Python {platform.python_version()}, {cpu()}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start {os.getloadavg()[0]:.1f}")
    print(f"# command: python tests/bench/compile_passes.py {' '.join(sys.argv[1:])}")
    print(f"# the job's call: {r['seconds']:.1f} s")
    print(f"{'self s':>8s}  pass [function]")
    for s, name, fn in rows[:args.top]:
        print(f"{s:8.1f}  {name} [{fn}]")
    for title, col in (("function", 2), ("pass", 1)):
        tot: dict = {}
        for row in rows:
            if row[1] != "<llvm>":
                tot[row[col]] = tot.get(row[col], 0.0) + row[0]
        print(f"\nby {title} (passes' self seconds, <llvm> apart)")
        for k, s in sorted(tot.items(), key=lambda kv: -kv[1])[:args.top]:
            print(f"{s:8.1f}  {k}")


if __name__ == "__main__":
    main()
