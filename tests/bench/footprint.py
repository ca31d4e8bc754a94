"""What one broad-phase step costs the processor after ``mj_step``: instructions, cache misses, branches.

    python tests/bench/footprint.py [SCENE] [--steps N] [--top K] [--root DIR]

A developer's tool, like `stages.py`, whose output is not committed. It runs the simulation loop
(random controls, ``BroadPhase.pairs(data)`` after every ``mj_step``) under valgrind's cachegrind
twice, with and without our call, and prints the difference per call: instructions executed, L1
instruction and data cache misses, conditional and indirect branch mispredictions (cachegrind's
simulated 32 KB L1s and simple predictors), in total and for the functions that differ most in L1
instruction misses. numba's compiled code has no symbols there: it is the ``???`` row, and that row
repeats from run to run (``PYTHONHASHSEED`` is fixed); the Python rows also carry the two runs'
import noise (up to ~2,000 instructions a call at 3000 steps), and the difference also holds what our
call costs the engine's next step (its code evicted by ours). Counts, not time: a change to the
kernel's code size or layout is judged on them, its speed still by timing.

What the timings alone did not show (humanoid, session 30, before the pointer views of
`broadphase._views`): a call after ``mj_step`` executes ~17,300 instructions of compiled code and
misses the L1 instruction cache ~590 times there (~810 with Python and numpy); ``_world`` is ~58 KB
of machine code, ~7,700 distinct instructions of it run per call, most of them once. The same call
repeated hot took ~3.4 us, in the loop ~8; but most of that gap is the loop's poses, not the cold
code (2026-11-28, `stages.py humanoid`: hot 2.43, replayed 3.00, loop 4.08 us; a prototype with a
quarter of the code lost as much in the loop as ours did). Judge a change by its replayed and loop
times, not by the counts alone.

numba compiles for the processor it detects, and under valgrind it detects another one (valgrind
emulates fewer features): the kernels would be compiled again inside valgrind, which takes hours.
Both runs therefore pin ``NUMBA_CPU_NAME`` and ``NUMBA_CPU_FEATURES`` to the host's, AVX-512 turned
off (valgrind 3.19 cannot run it), and a native run with the same settings fills numba's cache
first (on an AVX-512 host that compiles the kernels once more). SCENE is a folder of
../shared/models (default ``humanoid``). ``--root DIR``: import ``collide`` from DIR (a folder
holding a changed copy of the package) instead of this checkout. Needs ``valgrind`` on the PATH
(the table is read from 3.19's ``cg_annotate``; later versions print another layout); each run
takes a few minutes (and a copy's first native run compiles its kernels).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT / ".." / "shared" / "models"

# The loop, as a program of its own (run natively once, then twice under cachegrind).
LOOP = """
import sys
import mujoco, numpy as np
sys.path.insert(0, {root!r})
import collide.mujoco as cm
path, mode, steps = sys.argv[1], sys.argv[2], int(sys.argv[3])
model = mujoco.MjModel.from_xml_path(path)
data = mujoco.MjData(model)
mujoco.mj_forward(model, data)
bp = cm.BroadPhase(model)
bp.pairs(data)  # compiled or loaded from the cache, and bound, before the loop
lo, hi = cm._control_range(model)
ctrl = np.random.default_rng(0).uniform(lo, hi, (steps, model.nu))
pairs = bp.pairs
for s in range(steps):
    data.ctrl[:] = ctrl[s]
    mujoco.mj_step(model, data)
    if mode == "on":
        pairs(data)
"""

EVENTS = ["Ir", "I1mr", "D1mr", "Bcm", "Bim"]
LABELS = ["instructions", "I1 misses", "D1 read misses", "cond. mispredicts", "ind. mispredicts"]


def _env() -> dict:
    import llvmlite.binding as ll

    ll.initialize_native_target()
    env = dict(os.environ)
    env["NUMBA_CPU_NAME"] = ll.get_host_cpu_name()
    # AVX-512 off: valgrind (3.19) cannot execute it
    env["NUMBA_CPU_FEATURES"] = ",".join(("-" + f[1:]) if f.startswith("+avx512") else f
                                         for f in ll.get_host_cpu_features().flatten().split(","))
    env["PYTHONHASHSEED"] = "0"
    env.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    return env


def _per_function(out_file: str) -> dict[str, list[int]]:
    # cg_annotate's function table: the EVENTS columns, then "file:function".
    text = subprocess.run(["cg_annotate", f"--show={','.join(EVENTS)}", "--threshold=0", "--auto=no", out_file],
                          capture_output=True, text=True, check=True).stdout
    num = r"([\d,]+)(?:\s+\([^)]*\))?"
    row = re.compile(r"^\s*" + r"\s+".join([num] * len(EVENTS)) + r"\s+(\S.*)$")
    table: dict[str, list[int]] = {}
    for line in text.splitlines():
        m = row.match(line)
        if m and "PROGRAM TOTALS" not in line:
            name = m.group(len(EVENTS) + 1).split("/")[-1]
            vals = [int(v.replace(",", "")) for v in m.groups()[:len(EVENTS)]]
            table[name] = [a + b for a, b in zip(table.get(name, [0] * len(EVENTS)), vals)]
    return table


def main(argv=None) -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("scene", nargs="?", default="humanoid")
    parser.add_argument("--steps", type=int, default=3000)
    parser.add_argument("--top", type=int, default=12)
    parser.add_argument("--root", default=str(ROOT), help="folder holding the collide package to measure")
    args = parser.parse_args(argv)
    for tool in ("valgrind", "cg_annotate"):
        if shutil.which(tool) is None:
            print(f"footprint: needs {tool} on the PATH", file=sys.stderr)
            return 1
    folder = MODELS / args.scene
    path = folder / "scene.xml" if (folder / "scene.xml").is_file() else Path(args.scene)
    if not path.is_file():
        print(f"footprint: no scene {args.scene} (a folder of {MODELS} or an MJCF file)", file=sys.stderr)
        return 1
    env = _env()
    with tempfile.TemporaryDirectory() as tmp:
        prog = Path(tmp) / "loop.py"
        prog.write_text(LOOP.format(root=str(Path(args.root).resolve())))
        # numba's cache, filled natively for the pinned processor
        subprocess.run([sys.executable, str(prog), str(path), "on", "10"], env=env, check=True)
        runs = {}
        for mode in ("on", "off"):
            out = str(Path(tmp) / f"cg.{mode}")
            cmd = ["valgrind", "--tool=cachegrind", "--cache-sim=yes", "--branch-sim=yes",
                   "--smc-check=all-non-file", f"--cachegrind-out-file={out}", sys.executable, str(prog), str(path),
                   mode, str(args.steps)]
            runs[mode] = (subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL), out)
        for mode, (proc, _) in runs.items():
            if proc.wait() != 0:
                print(f"footprint: the {mode} run failed", file=sys.stderr)
                return 1
        on, off = (_per_function(runs[m][1]) for m in ("on", "off"))
    n = args.steps
    zero = [0] * len(EVENTS)
    diff = {k: [(a - b) / n for a, b in zip(on.get(k, zero), off.get(k, zero))] for k in set(on) | set(off)}
    total = [sum(v[i] for v in diff.values()) for i in range(len(EVENTS))]
    print(f"# {args.scene}: one pairs(data) after each mj_step, {n} steps; per call, cachegrind's counts "
          "with the call less without it (the Python rows also carry the two runs' import noise, up to "
          "~2,000 instructions a call at 3000 steps: compare the ??? row)")
    print("  ".join(f"{lab} {v:,.0f}" for lab, v in zip(LABELS, total)))
    print()
    print("".join(f"{e:>10}" for e in EVENTS) + "  function (??? = numba's compiled code), by I1 misses")
    for name, v in sorted(diff.items(), key=lambda t: -abs(t[1][1]))[:args.top]:
        print("".join(f"{x:>10.1f}" for x in v) + f"  {name[:90]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
