"""Where one broad-phase step spends its time, stage by stage: hot, replayed, and in the simulation loop.

    python tests/bench/stages.py [SCENE] [--steps N] [--calls N] [--stages entry,world,...] [--walk]

SCENE is a folder of ../shared/models (``humanoid``, ``22_humanoids``, ...) or an MJCF file; by
default the built-in scene (`collide.mujoco.default_scene`). A developer's tool for finding what to
speed up, not a benchmark of record: its output is not committed.

Method (sessions 10-12 of the speed work used it from scratch files; see the closing notes): for
each stage mark, a copy of the package is made with an early return inserted into the per-world
kernel (`collide._kernels.broadphase._world`) just before that mark, and the copies are timed
side by side with the unchanged package, in one process, on the same states:

- hot: ``_step_bound(addr)`` called ``--calls`` times on one pose (the minimum of 11 repeats;
  from the second call on the kernel finds the last result's pairs again and writes no rows);
- replay: the loop's poses (recorded in its first pass) copied into the ``MjData`` one after the
  other, one ``pairs(data)`` each, with no ``mj_step`` in between: the poses move as in the loop
  (the branches see the same data) but the caches and branch predictors stay ours. ``loop - replay``
  is what the engine's step leaves cold (22 humanoids, session 19: 48.6 us in the loop, 34.5
  replayed, 35.1 on one pose; warming all our arrays after each step recovered 3 us of the 14, the
  kernel's code 2 us);
- loop: one ``pairs(data)`` after each ``mj_step``, median over three passes of ``--steps`` steps per
  copy; each pass replays the same trajectory with one copy alone, so each call finds its code and
  data as a simulation loop leaves them.

The difference between consecutive rows is the cost of the stage between their marks (the first
row is the Python call, the numba entry and the unpacking of the buffers). The early return is
guarded by a test the compiler cannot decide (the position count is read from the model's
arrays), so the code after it stays compiled. The copies live in the temporary folder, keyed by
the kernel's text, so a second run reuses their compiled kernels; a mark no longer found in the
kernel stops the run with its name (update `MARKS` when the kernel changes).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import collide  # noqa: E402
import collide.mujoco as cm  # noqa: E402

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"
KERNEL = Path("_kernels") / "broadphase.py"
# (stage, the start of the kernel line it ends before): cutting there times everything up to its end.
MARKS = [
    ("entry", "    # 1. poses -> world bounds"),
    ("world bounds", "    # 2-4a. the body pairs"),
    # inside the tree walk's block: cut only in the calls that walk (all of them with --walk)
    ("subtree AABBs", "        # 3. candidate body pairs down the tree."),
    ("traversal", "        # 4a. the static filter"),
    ("body pairs", "    # 4. body pairs -> sphere and OBB"),
    ("sphere, OBB, geoms", "    k4 = min(k, keys.shape[0])"),
    ("planes", "    # 5b. explicit pairs"),
    ("explicit pairs", "    stats[ST_OUT] = k"),
]
GUARD = "if I[H_L] > 0:  # always true; the compiler cannot tell\n    return 0\n"  # at the mark's indentation


def _copy(stage: str, line: str, root: Path) -> str:
    lines = (Path(collide.__file__).parent / KERNEL).read_text().splitlines(keepends=True)
    at = [i for i, text in enumerate(lines) if text.startswith(line)]
    if len(at) != 1:
        sys.exit(f"stages.py: no single line of {KERNEL} starts with the mark of stage '{stage}' "
                 f"({line.strip()!r}); update MARKS")
    ind = line[:len(line) - len(line.lstrip())]
    guard = "".join(ind + g + "\n" for g in GUARD.splitlines())
    cut = "".join(lines[:at[0]] + [guard] + lines[at[0]:])
    name = "collide_cut_" + hashlib.sha1(cut.encode()).hexdigest()[:12]
    dst = root / name
    if not dst.is_dir():
        shutil.copytree(Path(collide.__file__).parent, dst, ignore=shutil.ignore_patterns("__pycache__"))
        (dst / KERNEL).write_text(cut)
    return name


def _load(scene: str | None) -> tuple[str, mujoco.MjModel]:
    if scene is None:
        return "default scene", cm.default_scene()
    path = Path(scene)
    if not path.is_file():
        path = MODELS / scene / "scene.xml"
    if not path.is_file():
        sys.exit(f"stages.py: no model file {scene}, nor {path}")
    return scene, mujoco.MjModel.from_xml_path(str(path))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default=None)
    ap.add_argument("--steps", type=int, default=1000, help="simulation steps timed in the loop")
    ap.add_argument("--calls", type=int, default=2000, help="calls per repeat, hot")
    ap.add_argument("--stages", default=None, help="comma-separated stage names (default: all)")
    ap.add_argument("--walk", action="store_true", help="coherent=False: every call walks the tree")
    args = ap.parse_args()
    name, model = _load(args.scene)
    marks = MARKS
    if args.stages:
        want = [s.strip() for s in args.stages.split(",")]
        unknown = sorted(set(want) - {s for s, _ in MARKS})
        if unknown:
            sys.exit(f"stages.py: unknown stage(s) {unknown}; known: {[s for s, _ in MARKS]}")
        marks = [m for m in MARKS if m[0] in want]
    root = Path(tempfile.gettempdir()) / "collide-stages"
    root.mkdir(exist_ok=True)
    sys.path.insert(0, str(root))
    mods = {stage: importlib.import_module(_copy(stage, line, root) + ".mujoco") for stage, line in marks}
    mods["full step"] = cm
    print(f"# {name}: {model.nbody} bodies, {model.ngeom} geoms{' (coherent=False)' if args.walk else ''}; "
          f"building and compiling {len(mods)} copies...", flush=True)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    bps = {stage: m.BroadPhase(model, coherent=not args.walk) for stage, m in mods.items()}
    for bp in bps.values():
        bp.pairs(data)
    hold = 100  # as `collide.mujoco.compare`: random extreme controls, held for 100 steps
    ctrls = cm._random_controls(model, args.steps, 0, hold)
    perf = time.perf_counter_ns
    # Each copy runs the same trajectory alone (between two of its calls only mj_step runs, as in a
    # simulation loop); three rounds of passes spread the machine's drift over the copies.
    loop = {stage: [] for stage in bps}
    poses = []
    for _ in range(3):
        for stage, bp in bps.items():
            mujoco.mj_resetData(model, data)
            mujoco.mj_forward(model, data)
            for step in range(args.steps):
                if len(ctrls):
                    data.ctrl[:] = ctrls[step // hold]
                mujoco.mj_step(model, data)
                t0 = perf()
                bp.pairs(data)
                loop[stage].append(perf() - t0)
                if len(poses) < args.steps:
                    poses.append((data.xpos.copy(), data.xmat.copy()))
    replay = {stage: [] for stage in bps}
    for _ in range(3):
        for stage, bp in bps.items():
            for pos, mat in poses:
                data.xpos[:] = pos
                data.xmat[:] = mat
                t0 = perf()
                bp.pairs(data)
                replay[stage].append(perf() - t0)
    hot = {stage: [] for stage in bps}
    for _ in range(11):
        for stage, bp in bps.items():
            f, ctx = bp.broadphase._step_bound, bp.broadphase._ctx_addr
            t0 = perf()
            for _ in range(args.calls):
                f(ctx)
            hot[stage].append((perf() - t0) / args.calls)
    print(f"{'cut after':<20}{'hot us':>9}{'+ stage':>9}{'replay us':>10}{'+ stage':>9}{'loop us':>10}{'+ stage':>9}")
    prev_h = prev_r = prev_l = 0.0
    for stage in bps:
        h = min(hot[stage]) / 1e3
        r = float(np.median(replay[stage])) / 1e3
        lo = float(np.median(loop[stage])) / 1e3
        print(f"{stage:<20}{h:>9.2f}{h - prev_h:>+9.2f}{r:>10.2f}{r - prev_r:>+9.2f}{lo:>10.2f}{lo - prev_l:>+9.2f}")
        prev_h, prev_r, prev_l = h, r, lo


if __name__ == "__main__":
    main()
