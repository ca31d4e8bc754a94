"""A/B of package copies in the benchmark's own loop: which of two versions of the kernels is faster.

    python tests/bench/ab.py COPY [COPY ...] [--scenes a,b,...] [--rounds R] [--steps N]

Each COPY is a folder holding a copy of the ``collide`` package under a name of its own (made with
``cp -r collide /tmp/two/collide_A`` and its ``__pycache__`` folders removed; its imports are
relative, so it runs its own kernels). A developer's tool, like `stages.py`: its output is not
committed.

Method. Per scene and round, each copy runs `collide.mujoco.compare` (its own copy of it) for
``--steps`` steps of the same random controls: the loop of `mujoco_models.py`, whose Python
bookkeeping between steps leaves our call colder than a bare loop of ``mj_step`` and our call does
(robotis_op3, 2026-11-28: 3.8 us there, 2.5 bare). The rounds alternate the copies' order. Printed
per copy: the median over the rounds of our time per step, its ratio to the first copy's, and the
median of the rounds' ratios to MuJoCo's broad-phase timer measured in the same run (the figure the
benchmark reports; a drift of the machine moves both sides of it). Two copies interleaved step by
step in one loop (each step's second call finds its data warm) or one call a step by turns (each
copy evicted by the other) misjudged changes there by up to 10 %; single rounds of this one move
by ~3 % on the shared Intel machine: repeat before trusting a smaller effect.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("copies", nargs="+", help="folders of package copies, each under a name of its own")
    ap.add_argument("--scenes", default="robotis_op3,unitree_h1,anybotics_anymal_c,humanoid",
                    help="comma-separated folders of ../shared/models")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=2000)
    args = ap.parse_args()
    names = []
    for c in args.copies:
        path = Path(c).resolve()
        if not ((path / "mujoco.py").is_file() or (path / "mujoco" / "__init__.py").is_file()):  # module or package
            sys.exit(f"ab.py: {c} holds no copy of the collide package")
        if str(path.parent) not in sys.path:
            sys.path.insert(0, str(path.parent))
        names.append(path.name)
    if len(set(names)) != len(names):
        sys.exit("ab.py: give each copy a folder name of its own")
    mods = [importlib.import_module(n + ".mujoco") for n in names]
    print(f"# {args.rounds} rounds of {args.steps} steps per copy and scene (collide.mujoco.compare); "
          "time per step: median over rounds (ratio to the first copy); xR: median of the rounds' "
          "ratios to MuJoCo's broad-phase timer")
    for scene in args.scenes.split(","):
        model = mujoco.MjModel.from_xml_path(str(MODELS / scene / "scene.xml"))
        bps = [m.BroadPhase(model) for m in mods]
        ours = {n: [] for n in names}
        ratio = {n: [] for n in names}
        for r in range(args.rounds):
            for i in (range(len(mods)) if r % 2 == 0 else reversed(range(len(mods)))):
                out = mods[i].compare(model, steps=args.steps, seed=0, broadphase=bps[i])
                ours[names[i]].append(out["time_ours_us"])
                ratio[names[i]].append(out["time_ours_us"] / out["time_mujoco_broad_us"])
        base = np.median(ours[names[0]])
        print(f"{scene:20s} " + "  ".join(f"{n} {np.median(ours[n]):.2f} us ({np.median(ours[n]) / base:.3f}, "
                                          f"x{np.median(ratio[n]):.2f})" for n in names), flush=True)


if __name__ == "__main__":
    main()
