"""Where the time goes inside numba's compiled code: sampled with ``perf``, by kernel function and by
instruction.

    python tests/bench/jitprof.py [SCENE] [--batch B | --replay] [--calls N] [--threads T]
                                  [--function NAME] [--stretches K] [--frequency HZ]

SCENE is a folder of ../shared/models (default ``humanoid``) or an MJCF file. Without ``--batch``: one
``BroadPhase.pairs(data)`` after each ``mj_step`` with random controls (``--calls`` steps), as in a
simulation loop; with ``--replay``, on the loop's poses (its first 2000 steps, recorded first, in
turn) copied into the ``MjData`` with no ``mj_step`` between, so that the samples fall on our code
warm (22 humanoids after ``mj_step``: 6 % of the samples in our code). With ``--batch B``:
``BroadPhase.pairs_batch(model, qpos)`` on B configurations, ``--calls`` times. A developer's tool for
finding what to speed up, not a benchmark of record.

Method. The virtual machines this project runs on expose no hardware counters, but ``perf record -e
cpu-clock`` (a timer interrupt) samples the instruction pointer anywhere, numba's code included;
``perf`` cannot name that code (it lives in anonymous memory). So the workload runs in a child
process that, at its end, writes the address of every function of the kernels it compiled (LLVM's
symbols, read from numba's code libraries) and copies out its executable anonymous memory; each
sample inside that memory is then given to the function whose start precedes it, and with
``--function`` the function's machine code is disassembled (``objdump``) and its hottest stretches
printed with the samples of each instruction. Only samples taken while the workload runs count
(``perf``'s clock is CLOCK_MONOTONIC, and the child writes its start and end on that clock).

numba's cache keeps machine code without the symbols, so the child compiles every kernel afresh
into a temporary cache folder: each run takes a few minutes before it samples anything. Needs
``perf`` (linux-tools) and ``objdump`` on the PATH, ``kernel.perf_event_paranoid`` <= 2, and an
x86-64 processor (the disassembly). Session 27 (2026-11-27, AMD EPYC, humanoid, 1024 worlds, one
thread, before `_simd.aabb_merge8` lost its masked stores): 62 % of the compiled code's samples in
`lanes._group`, 35 % in the parallel loop of `kinematics.step_lanes_kin` (the lane kinematics,
inlined there), 1.9 % in `batch.gather_batch`; in `_group`, the merge's stretches 8 % and the
walk's box test with its branch 5 %, nothing else above 3 %. Session 33 (2026-11-28, Intel Xeon, after
the bounds' fused dot products): the same batch 70 % `_group`, 28 % the kinematics; 22 humanoids with
``--replay`` (49.6 us a call, the poses' copy included), 67 % `broadphase._world` (the placing of the
bodies' rows and boxes about a third of it, ~30 ns a body), 20 % `_traverse`, 6 % `_subtree_pair`, 4 %
`_sweep`, 2 % the sort.
"""

from __future__ import annotations

import argparse
import bisect
import collections
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT / ".." / "shared" / "models"

# The workload, as a program of its own: argv = model path, batch (0: the loop), calls, threads, out folder.
CHILD = """
import ctypes, json, os, sys, time
import mujoco, numba, numpy as np
sys.path.insert(0, {root!r})
import collide.mujoco as cm
from numba.core.registry import CPUDispatcher
path, batch, calls, threads, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
replay = sys.argv[6] == "1"
numba.set_num_threads(threads)
model = mujoco.MjModel.from_xml_path(path)
data = mujoco.MjData(model)
mujoco.mj_forward(model, data)
bp = cm.BroadPhase(model)
lo, hi = cm._control_range(model)
ctrl = np.random.default_rng(0).uniform(lo, hi, (max(calls, batch), model.nu))
if batch:
    qpos = np.empty((batch, model.nq))
    for i in range(batch):
        data.ctrl[:] = ctrl[i]
        mujoco.mj_step(model, data)
        qpos[i] = data.qpos
    bp.pairs_batch(model, qpos)  # compiled here, before the samples that count
else:
    bp.pairs(data)
    if replay:  # the loop's poses (its first 2000 steps at most, replayed in turn), recorded first
        n = min(calls, 2000)
        xpos = np.empty((n,) + data.xpos.shape)
        xmat = np.empty((n,) + data.xmat.shape)
        for s in range(n):
            data.ctrl[:] = ctrl[s]
            mujoco.mj_step(model, data)
            xpos[s] = data.xpos
            xmat[s] = data.xmat
clock = time.clock_gettime
t0 = clock(time.CLOCK_MONOTONIC)
if batch:
    for _ in range(calls):
        bp.pairs_batch(model, qpos)
elif replay:
    pairs = bp.pairs
    for s in range(calls):
        data.xpos[:] = xpos[s % n]
        data.xmat[:] = xmat[s % n]
        pairs(data)
else:
    pairs = bp.pairs
    for s in range(calls):
        data.ctrl[:] = ctrl[s]
        mujoco.mj_step(model, data)
        pairs(data)
t1 = clock(time.CLOCK_MONOTONIC)
syms = []  # [address, LLVM name, the dispatcher whose library holds it]
seen = set()
for mname, mod in list(sys.modules.items()):
    if not mname.startswith("collide._kernels"):
        continue
    for name, d in vars(mod).items():
        if not isinstance(d, CPUDispatcher):
            continue
        for cres in d.overloads.values():
            lib = cres.library
            if id(lib) in seen:
                continue
            seen.add(id(lib))
            for fn in lib._final_module.functions:
                if not fn.is_declaration:
                    addr = lib.get_pointer_to_function(fn.name)
                    if addr:
                        syms.append([addr, fn.name, mname.rsplit(".", 1)[-1] + "." + name])
regions = []
for line in open("/proc/self/maps"):
    parts = line.split()
    if "r" in parts[1] and "x" in parts[1] and len(parts) < 6:  # readable, executable, anonymous
        a, b = (int(v, 16) for v in parts[0].split("-"))
        with open(os.path.join(out, f"{{a:x}}.bin"), "wb") as f:
            f.write(ctypes.string_at(a, b - a))
        regions.append([a, b])
with open(os.path.join(out, "child.json"), "w") as f:
    json.dump({{"t0": t0, "t1": t1, "syms": syms, "regions": regions}}, f)
"""


def _readable(name: str, owner: str = "") -> str:
    # numba's mangled names: _ZN, then length-prefixed parts (module path, function), then B<n>v...;
    # "cfunc." and a "cpython" part mark the C and Python entry wrappers
    i = name.find("_ZN")
    if i < 0:
        return name[:70]
    s, parts = name[i + 3:], []
    while s[:1].isdigit():
        n = re.match(r"\d+", s)
        k = int(n.group())
        parts.append(s[n.end():n.end() + k])
        s = s[n.end() + k:]
    wrapper = (" (C entry)" if name.startswith("cfunc.") else " (Python entry)" if "cpython" in parts
               else " (gufunc entry)" if name.startswith("__gufunc__.") else "")
    if any("parfor_gufunc" in p for p in parts):
        return f"parallel loop of {owner}{wrapper}"
    return ".".join(p for p in parts if p not in ("collide", "_kernels", "cpython")) + wrapper


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", default="humanoid")
    ap.add_argument("--batch", type=int, default=0, help="worlds a pairs_batch call (default: the loop)")
    ap.add_argument("--calls", type=int, default=None, help="calls sampled (default: 20000 steps or 2000 batches)")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--function", default=None, help="print the hottest code of this function (a name of the table: _group, lanes._group, "
                    "'parallel loop of kinematics.step_lanes_kin')")
    ap.add_argument("--frequency", type=int, default=4000, help="samples a second")
    ap.add_argument("--replay", action="store_true", help="the loop's poses recorded first, then pairs(data) on "
                    "each with no mj_step between (what the kernel costs warm; see stages.py)")
    ap.add_argument("--stretches", type=int, default=6, help="hottest 256-byte stretches printed with --function")
    args = ap.parse_args()
    for tool in ("perf", "objdump"):
        if shutil.which(tool) is None:
            sys.exit(f"jitprof: needs {tool} on the PATH")
    if platform.machine() not in ("x86_64", "AMD64"):
        sys.exit(f"jitprof: disassembles x86-64 code only (this is {platform.machine()})")
    path = Path(args.scene) if args.scene.endswith(".xml") else MODELS / args.scene / "scene.xml"
    if not path.is_file():
        sys.exit(f"jitprof: no model at {path}")
    for name in ("batch", "calls", "threads", "frequency"):
        v = getattr(args, name)
        if v is not None and (v < 0 or (v == 0 and name != "batch")):
            sys.exit(f"jitprof: --{name} must be {'>= 0' if name == 'batch' else '>= 1'}, got {v}")
    import numba

    if args.threads > numba.config.NUMBA_NUM_THREADS:
        sys.exit(f"jitprof: --threads at most {numba.config.NUMBA_NUM_THREADS} here, got {args.threads}")
    calls = args.calls or (2000 if args.batch else 20000)
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NUMBA_CACHE_DIR=os.path.join(tmp, "cache"), PYTHONHASHSEED="0")
        env.setdefault("OMP_WAIT_POLICY", "PASSIVE")
        child = os.path.join(tmp, "child.py")
        Path(child).write_text(CHILD.format(root=str(ROOT)))
        data = os.path.join(tmp, "perf.data")
        what = ("pairs_batch of %d worlds" % args.batch if args.batch else "pairs(data) on the loop's poses replayed"
                if args.replay else "pairs(data) after mj_step")
        print(f"# {args.scene}: {what}, "
              f"{calls} calls, {args.threads} thread(s); compiling the kernels afresh first...", flush=True)
        subprocess.run(["perf", "record", "-q", "-k", "CLOCK_MONOTONIC", "-e", "cpu-clock", "-F", str(args.frequency),
                        "-o", data, sys.executable, child, str(path), str(args.batch), str(calls), str(args.threads),
                        tmp, "1" if args.replay and not args.batch else "0"], env=env, check=True)
        info = json.loads(Path(tmp, "child.json").read_text())
        text = subprocess.run(["perf", "script", "-i", data, "-F", "time,ip,dso"], capture_output=True, text=True,
                              check=True).stdout
        t0, t1 = info["t0"], info["t1"]
        in_jit = [(a, b) for a, b in info["regions"]]
        starts = sorted({sym[0] for sym in info["syms"]})
        label: dict[int, str] = {0: "(unnamed)"}  # by start address: the function's readable name
        for a, n, o in info["syms"]:
            label.setdefault(a, _readable(n, o))
        region_of = {a: next((r for r in in_jit if r[0] <= a < r[1]), None) for a in starts}
        by_dso: collections.Counter = collections.Counter()
        by_fn: collections.Counter = collections.Counter()
        ips: collections.Counter = collections.Counter()
        total = 0
        for line in text.splitlines():
            m = re.match(r"\s*([\d.]+):\s+([0-9a-f]+)\s+\((.*)\)", line)
            if not m or not t0 <= float(m.group(1)) <= t1:
                continue
            total += 1
            ip = int(m.group(2), 16)
            region = next((r for r in in_jit if r[0] <= ip < r[1]), None)
            if region is not None:
                i = bisect.bisect_right(starts, ip) - 1
                # a function starting in another region is not this code's: unnamed (code compiled
                # outside collide._kernels)
                by_fn[starts[i] if i >= 0 and region_of[starts[i]] == region else 0] += 1
                ips[ip] += 1
                by_dso["numba's compiled code"] += 1
            else:
                by_dso[os.path.basename(m.group(3))] += 1
        if total == 0:
            sys.exit("jitprof: no samples in the workload (perf_event_paranoid?)")
        per = "us a call" if args.batch else "us a call, the poses' copy included" if args.replay else \
            "us a step, mj_step included"
        print(f"\n{total} samples over {t1 - t0:.2f} s ({(t1 - t0) / calls * 1e6:.1f} {per})\n")
        print(f"{'share':>7}  where")
        for k, v in by_dso.most_common(8):
            print(f"{100 * v / total:6.1f}%  {k}")
        jit = sum(by_fn.values())
        print(f"\n{'share':>7}  numba function (share of the compiled code's {jit} samples)")
        for a, v in by_fn.most_common(12):
            print(f"{100 * v / jit:6.1f}%  {label[a]}")
        if args.function:
            # the function itself (no entry wrapper), its name ending with the one asked for
            want = args.function
            hits = [a for a in starts if not label[a].endswith(")")
                    and (label[a] == want or label[a].endswith("." + want))]
            if not hits:
                sys.exit(f"jitprof: no compiled function named {want!r} (a name from the table above)")
            if len(hits) > 1:
                print(f"\n{len(hits)} functions named {want!r}: the one with the most samples")
            lo = max(hits, key=lambda a: by_fn[a])
            region = region_of[lo]
            if region is None:
                sys.exit(f"jitprof: {want!r} is not in the code the child copied out")
            k = starts.index(lo) + 1
            hi = min(starts[k] if k < len(starts) else region[1], region[1])
            blob = Path(tmp, f"{region[0]:x}.bin")
            code = blob.read_bytes()[lo - region[0]:hi - region[0]]
            fn_file = Path(tmp, "function.bin")
            fn_file.write_bytes(code)
            asm = subprocess.run(["objdump", "-D", "-b", "binary", "-m", "i386:x86-64", f"--adjust-vma={lo:#x}",
                                  str(fn_file)], capture_output=True, text=True, check=True).stdout
            rows = []
            for line in asm.splitlines():
                m = re.match(r"\s*([0-9a-f]+):\s+(?:[0-9a-f]{2} )+\s*(.*)$", line)
                if m:
                    rows.append((int(m.group(1), 16), m.group(2).strip()))
            fn_samples = by_fn[lo]
            window = collections.Counter()
            for ad, _ in rows:
                window[(ad - lo) // 256] += ips.get(ad, 0)
            print(f"\n{label[lo]}: {hi - lo} bytes, {fn_samples} samples; "
                  "the hottest 256-byte stretches:")
            for w, v in window.most_common(args.stretches):
                print(f"\n  +{w * 256:#x}: {100 * v / max(fn_samples, 1):.1f}% of the function")
                for ad, ins in rows:
                    if (ad - lo) // 256 == w and ips.get(ad, 0):
                        print(f"    {ips[ad]:5d}  +{ad - lo:#07x}  {ins}")


if __name__ == "__main__":
    main()
