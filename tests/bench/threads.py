"""What numba's threads are worth to `collide.mujoco.BroadPhase.pairs_batch` on this machine.

    python tests/bench/threads.py [SCENE] [--rounds R] > tests/bench/threads.<machine>.txt

SCENE is a folder of ../shared/models (default ``humanoid``) or an MJCF file. Configurations come
from a simulated trajectory with random controls (one per step, as in ``mujoco_models.py``'s batch),
tiled to 256 ... 16,384 worlds a call. Each round times one call per (thread count, batch size),
each right after an untimed call of the same shape (back to back, as batches in a loop run), the
thread counts and sizes in turn so that a drift of the machine's speed moves all of them; medians
over the rounds, per world, and the speed-up of all threads over one.

Why: issue 4's batch target compares our time per world, on the machine's threads, with MuJoCo's
single-world broad phase on one core. Where the speed-up stays well under the thread count even
at 16,384 worlds a call (where waking the threads and the last chunk's tail no longer count), the
machine's cores do not each give a core's throughput (virtual cores on shared physical ones), and
the target has to be met by less work a world on one thread.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

# As in mujoco_models.py: set before numba starts its OpenMP runtime and before numpy loads.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import mujoco  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402

import collide.mujoco as cm  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mujoco_models import MODELS, _cpu  # noqa: E402

SIZES = (256, 1024, 4096, 16384)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("scene", nargs="?", default="humanoid")
    parser.add_argument("--rounds", type=int, default=15)
    args = parser.parse_args(argv)
    if args.rounds < 1:
        parser.error(f"--rounds must be >= 1, got {args.rounds}")
    path = Path(args.scene) if args.scene.endswith(".xml") else MODELS / args.scene / "scene.xml"
    if not path.is_file():
        print(f"no model at {path}", file=sys.stderr)
        return 1
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(0)
    lo, hi = cm._control_range(model)
    base = np.empty((1024, model.nq))
    for i in range(len(base)):
        data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, data)
        base[i] = data.qpos
    qpos = {b: np.ascontiguousarray(np.resize(base, (b, model.nq))) for b in SIZES}
    bp = cm.BroadPhase(model)
    bp.pairs_batch(model, qpos[SIZES[0]])  # compile / warm up
    most = numba.get_num_threads()
    counts = sorted({1, most})
    per = {(t, b): [] for t in counts for b in SIZES}
    try:
        for r in range(args.rounds):
            for t in (counts if r % 2 else counts[::-1]):
                numba.set_num_threads(t)
                for b in SIZES:
                    bp.pairs_batch(model, qpos[b])
                    t0 = time.perf_counter_ns()
                    bp.pairs_batch(model, qpos[b])
                    per[(t, b)].append((time.perf_counter_ns() - t0) * 1e-3 / b)
    finally:
        numba.set_num_threads(most)
    print(f"# collide pairs_batch(model, qpos) on {path.parent.name if path.name == 'scene.xml' else path.name}: "
          f"{model.nbody} bodies, {model.ngeom} geoms; us a world, medians over {args.rounds} rounds")
    print(f"# machine: {numba.config.NUMBA_NUM_THREADS} cores, {_cpu()}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start "
          f"{os.getloadavg()[0]:.1f}; OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY')}")
    head = f"{'worlds a call':>14}" + "".join(f"{f'{t} thread' + ('s' if t > 1 else ''):>12}" for t in counts)
    print(head + (f"{'speed-up':>10}" if len(counts) > 1 else ""))
    for b in SIZES:
        med = [float(np.median(per[(t, b)])) for t in counts]
        line = f"{b:>14}" + "".join(f"{m:>9.3f} us" for m in med)
        print(line + (f"{med[0] / med[-1]:>9.2f}x" if len(counts) > 1 else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
