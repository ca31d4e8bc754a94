"""Cold compile time of collide's kernels, one entry point at a time (a developer's tool).

    python tests/bench/compile_time.py [--package DIR] [--only NAME ...]

Each job below runs in a fresh process with an empty numba cache (a temporary ``NUMBA_CACHE_DIR``),
the package imported from ``DIR`` (default: this checkout; give a ``git archive`` copy of another
revision to compare two). Every job but the first starts from the cache the first one left: the
single-world step (the MuJoCo adapter's bound step, `step._step_bound`, and its `broadphase._world`)
and the contact kernel, which most entry points share, are compiled once there.
For each job: the seconds of its call and of each outermost compile (numba's ``numba:compile``
event, which fires only on a real compile, not on a cache load). Run on a quiet machine; a compile
is one core's work.

Why: CI compiles every kernel of the package on a fresh clone, and compiling is most of its time.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _machine import cpu

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT.parent / "shared" / "models"

# (name, what the job compiles, its code): each runs in its own process.
JOBS = {
    "contacts": ("step._step_bound (with broadphase._world), manifold.collide_bound (the simulation loop's call)", """
import mujoco
import collide.mujoco as cm
model = cm.default_scene(seed=1, objects=10)
data = mujoco.MjData(model)
mujoco.mj_forward(model, data)
cm.Collider(model).contacts(data)
"""),
    "check_worlds": ("check.check_worlds with distances (franka_emika_panda)", """
import mujoco, numpy as np
import collide.mujoco as cm
from collide import testing
model = mujoco.MjModel.from_xml_path(str(MODELS / "franka_emika_panda" / "scene.xml"))
cm.Collider(model).check_batch(testing.random_configurations(model, 64, np.random.default_rng(0)), distance=True)
"""),
    "check_trees": ("check_trees.check_trees and what follows it (22_humanoids)", """
import mujoco, numpy as np
import collide.mujoco as cm
from collide import testing
model = mujoco.MjModel.from_xml_path(str(MODELS / "22_humanoids" / "scene.xml"))
cm.Collider(model).check_batch(testing.random_configurations(model, 64, np.random.default_rng(0)))
"""),
    "check_lanes": ("check_lanes.check_lanes_kin (agility_cassie)", """
import mujoco, numpy as np
import collide.mujoco as cm
from collide import testing
model = mujoco.MjModel.from_xml_path(str(MODELS / "agility_cassie" / "scene.xml"))
cm.Collider(model).check_batch(testing.random_configurations(model, 64, np.random.default_rng(0)))
"""),
    "batch_lanes": ("kinematics.step_lanes_kin, kinematics_worlds, lanes.step_lanes", """
import numpy as np
import collide.mujoco as cm
from collide import BroadPhase
model = cm.default_scene(seed=1, objects=10)
bp = BroadPhase(cm.articulation(model), batch_path="lanes")
tree = cm.kinematic_tree(model)
q = np.tile(model.qpos0, (16, 1))
bp.pairs_batch_joints(tree, q)
pos, rot = tree.poses(q)
bp.pairs_batch(pos, rot)
"""),
    "batch_worlds": ("batch.step_batch", """
import numpy as np
import collide.mujoco as cm
from collide import BroadPhase
model = cm.default_scene(seed=1, objects=10)
bp = BroadPhase(cm.articulation(model), batch_path="worlds")
pos, rot = cm.kinematic_tree(model).poses(np.tile(model.qpos0, (16, 1)))
bp.pairs_batch(pos, rot)
"""),
    "swept": ("swept.swept_batch and the one-world swept step", """
import numpy as np
import collide
from collide import testing
rng = np.random.default_rng(0)
scene = testing.many_robots(3, links=4, seed=6, planes=1)
bp = collide.BroadPhase(scene.articulation)
p0, r0 = scene.poses(rng, worlds=3)
p1, r1 = scene.poses(rng, worlds=3)
bp.pairs_swept_batch(p0, r0, p1, r1)
bp.pairs_swept(p0[0], r0[0], p1[0], r1[0])
"""),
    "raycast": ("ray.raycast_kernel", """
from collide import csg
csg.raycast(csg.build_bvh(csg.box([1.0, 2.0, 3.0])), [[0, 0, -5]], [[0, 0, 1]])
"""),
    "distance": ("distance.query (collide.distance)", """
import collide
collide.distance(collide.PointCloud([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], 0.0),
                 collide.PointCloud([[3, 0, 0]], 0.5))
"""),
}

_CHILD = """
import json, sys, time
from pathlib import Path
from numba.core import event
MODELS = Path({models!r})
log, depth, starts = [], [0], {{}}
class L(event.Listener):
    def on_start(self, ev):
        depth[0] += 1
        starts[depth[0]] = time.perf_counter()
    def on_end(self, ev):
        if depth[0] == 1:
            d = ev.data["dispatcher"].py_func
            log.append([d.__module__.removeprefix("collide._kernels.") + "." + d.__name__,
                        time.perf_counter() - starts[1]])
        depth[0] -= 1
event.register("numba:compile", L())
t = time.perf_counter()
{code}
import collide
print(json.dumps({{"seconds": time.perf_counter() - t, "compiles": log, "package": collide.__file__}}))
"""


def run_job(name: str, package: Path, cache: Path) -> dict | None:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(package))
    env.pop("COLLIDE_CHECKED", None)
    code = _CHILD.format(models=str(MODELS), code=JOBS[name][1])
    # cwd: `python -c` puts the current folder first on sys.path, ahead of PYTHONPATH (a checkout's
    # root would shadow the package asked for)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=3600,
                         cwd=cache)
    if out.returncode != 0:
        print(f"{name}: failed\n{out.stderr[-3000:]}", file=sys.stderr)
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--package", type=Path, default=ROOT, help="folder holding the collide package to compile")
    ap.add_argument("--only", nargs="*", choices=sorted(JOBS), help="these jobs only (after the first)")
    args = ap.parse_args()
    names = list(JOBS)
    if args.only:
        names = [names[0]] + [n for n in names[1:] if n in args.only]
    needs_models = {"check_worlds", "check_trees", "check_lanes"}
    print("# collide: cold compile time by entry point (a fresh numba cache, the first job's kernels shared)")
    print(f"# machine: {os.cpu_count()} cores, Python {platform.python_version()}, {cpu()}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start {os.getloadavg()[0]:.1f}")
    print(f"# command: python tests/bench/compile_time.py {' '.join(sys.argv[1:])}".rstrip())
    print(f"# package: {args.package}")
    print(f"{'job':14s} {'call s':>8s}  outermost compiles (s)")
    total = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "base"
        for i, name in enumerate(names):
            if name in needs_models and not MODELS.is_dir():
                print(f"{name:14s} skipped: {MODELS} is absent")
                continue
            cache = base if i == 0 else Path(tmp) / name
            if i > 0 and base.is_dir():
                shutil.copytree(base, cache)
            cache.mkdir(exist_ok=True)
            r = run_job(name, args.package, cache)
            if r is None:
                print(f"{name:14s} failed (its error on stderr)")
                continue
            if not r["package"].startswith(str(args.package.resolve())):
                raise SystemExit(f"{name}: imported {r['package']}, not the package of {args.package}")
            total += r["seconds"]
            comp = ", ".join(f"{k} {s:.1f}" for k, s in r["compiles"] if s >= 1.0)
            print(f"{name:14s} {r['seconds']:8.1f}  {comp}", flush=True)
    print(f"{'total':14s} {total:8.1f}")


if __name__ == "__main__":
    main()
