"""What handing out the last result's array again is worth to `collide.mujoco.BroadPhase.pairs(data)`.

    python tests/bench/reuse.py [SCENE ...] [--steps N] > tests/bench/reuse.<machine>.txt

When a step's pairs are those of the last call that found any, the kernel writes no rows and
``pairs(data)`` returns that call's array again (`collide._kernels.step.RET_SAME`); before,
every call made a new numpy view of new rows. Here both run in one simulation loop (the controls
of `collide.mujoco.compare`, seed 0), each step timing one of them right after ``mj_step``, in turn:
ours, and a subclass that makes a new view of the same rows on every call, as the code before did
(``_NewView``; its kernel call and its result are the same). Medians over the steps each version
was timed on, their ratio, and the share of steps whose pairs were unchanged (non-empty, equal to
the last non-empty result) or empty. SCENE is a folder of ../shared/models (default: all of them)
or an MJCF file.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import mujoco  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402

import collide.mujoco as cm  # noqa: E402
from collide._kernels import step as _k  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mujoco_models import MODELS, _cpu  # noqa: E402


class _NewView(cm.BroadPhase):
    """`collide.mujoco.BroadPhase` as before results were handed out again: its ``pairs(data)``
    written out (bad poses aside) with, on `RET_SAME`, a new view of the last result's rows (the
    kernel wrote none): the kernel's work and the rows are ours, only the view is the old cost."""

    def pairs(self, data):
        bp = self.broadphase
        if data is not self._views_of or bp._bound is not self._views:
            self._check_data(data)
            bp.bind(data.xpos, data.xmat.reshape(-1, 3, 3))
            self._views_of = data
            self._views = bp._bound
        k = bp._step_bound(bp._ctx_addr)
        if k < 0:
            k = bp._rerun(*bp._bound, k)
        if k >= _k.RET_SAME:
            o = bp._ctx[_k.C_LAST]
            out = bp._arena[o:o + k - _k.RET_SAME]
        elif k == 0:
            return self._empty2
        else:
            o = bp._arena_used
            e = o + k
            if e <= bp._arena_rows:
                bp._arena_used = e
                out = bp._last = bp._arena[o:e]
            else:
                out = bp._take(k)
        return out if self._no_function is None else self._drop_null(out, 0)


def bench(path: Path, steps: int) -> dict:
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    ours, before = cm.BroadPhase(model), _NewView(model)
    hold = 100  # as compare's default
    ctrls = cm._random_controls(model, steps, 0, hold)
    times = {"ours": [], "before": []}
    same = empty = 0
    last = None
    perf = time.perf_counter_ns
    for step in range(steps):
        if model.nu:
            data.ctrl[:] = ctrls[step // hold]
        mujoco.mj_step(model, data)
        name, bp = ("ours", ours) if step % 2 == 0 else ("before", before)
        t0 = perf()
        out = bp.pairs(data)
        t1 = perf()
        times[name].append((t1 - t0) * 1e-3)
        if len(out) == 0:
            empty += 1
        else:
            same += last is not None and np.array_equal(out, last)
            last = out
    skip = 25  # the first calls of each (compilation is done before, caches are not)
    t_ours, t_before = (float(np.median(times[k][skip:])) for k in ("ours", "before"))
    return {"name": path.parent.name if path.name == "scene.xml" else path.name, "bodies": model.nbody,
            "unchanged": same / steps, "empty": empty / steps, "ours": t_ours, "before": t_before}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("scenes", nargs="*")
    parser.add_argument("--steps", type=int, default=2000)
    args = parser.parse_args(argv)
    if args.steps < 100:
        parser.error(f"--steps must be >= 100, got {args.steps}")
    names = args.scenes or sorted(p.name for p in MODELS.iterdir() if (p / "scene.xml").is_file())
    paths = [Path(n) if n.endswith(".xml") else MODELS / n / "scene.xml" for n in names]
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        print(f"no model at {', '.join(missing)}", file=sys.stderr)
        return 1
    rows = [bench(p, args.steps) for p in paths]
    print(f"# pairs(data) handing out the last result's array again (ours) against a new view every call "
          f"(before): {args.steps} steps of compare's random controls per scene, each step timing one of "
          f"the two right after mj_step, in turn; medians")
    print(f"# machine: {numba.config.NUMBA_NUM_THREADS} cores, {_cpu()}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start "
          f"{os.getloadavg()[0]:.1f}")
    print("# unchanged: steps whose pairs were the last non-empty result's; empty: steps without pairs")
    print()
    head = f"{'scene':<20}{'bodies':>7}{'unchanged':>10}{'empty':>7}{'before us':>10}{'ours us':>9}{'ratio':>7}"
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['name']:<20}{r['bodies']:>7}{100 * r['unchanged']:>9.0f}%{100 * r['empty']:>6.0f}%"
              f"{r['before']:>10.2f}{r['ours']:>9.2f}{r['ours'] / r['before']:>7.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
