"""Benchmark: one ``Collider.geom_distance`` call against ``mujoco.mj_geomDistance``, on every model.

    python tests/bench/geom_distance.py [--pairs N] [--scenes NAME ...] [--out FILE]

Per scene in ../shared/models: 100 steps of random controls (as tests/bench/contacts.py drives
them), then ``N`` random geom pairs that both libraries answer (any two geoms but height fields,
SDFs and two planes; the contact filters do not apply to a distance), each timed as the mean CPU
time of a call over ~10 ms (distance.py's `_per_call`), with ``distmax`` 1.0 (both return the
distance when it is below that). Printed per scene: the median over the pairs of ours and
MuJoCo's time per call, their ratio, the share of the pairs closer than ``distmax``, and the
largest |ours - MuJoCo| over those (MuJoCo's CCD stops at its ``ccd_tolerance``, ours at 1e-12 of
the sizes). The median of the ratios over the scenes closes the table.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

import collide.mujoco as cm
from _machine import cpu as _cpu  # noqa: E402 (tests/bench is the script's folder)
from distance import _per_call  # noqa: E402 (the mean CPU time of a call, as distance.py times it)

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"


def bench_scene(path: Path, pairs: int, seed: int = 0) -> dict:
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    col = cm.Collider(model)
    mujoco.mj_forward(model, data)
    ctrls = cm._random_controls(model, 100, seed, 10)
    for step in range(100):
        if step % 10 == 0 and len(ctrls):
            data.ctrl[:] = ctrls[step // 10]
        mujoco.mj_step(model, data)
    col.contacts(data)
    rng = np.random.default_rng(seed)
    gt = model.geom_type
    ok = np.flatnonzero((gt != mujoco.mjtGeom.mjGEOM_HFIELD) & (gt != mujoco.mjtGeom.mjGEOM_SDF))
    fromto = np.zeros(6)
    rows = []
    tries = 0
    while len(rows) < pairs and tries < 50 * pairs:
        tries += 1
        g1, g2 = (int(g) for g in rng.choice(ok, 2, replace=False))
        if gt[g1] == gt[g2] == mujoco.mjtGeom.mjGEOM_PLANE:
            continue
        d_ours, _ = col.geom_distance(data, g1, g2, 1.0)
        d_mj = mujoco.mj_geomDistance(model, data, g1, g2, 1.0, fromto)
        t_ours = _per_call(lambda: col.geom_distance(data, g1, g2, 1.0), 0.01)
        t_mj = _per_call(lambda: mujoco.mj_geomDistance(model, data, g1, g2, 1.0, fromto), 0.01)
        near = d_mj < 1.0
        rows.append((t_ours, t_mj, near, abs(d_ours - d_mj) if near else 0.0))
    a = np.array(rows)
    return {"model": path.parent.name, "pairs": len(rows), "ours_us": float(np.median(a[:, 0])) * 1e6,
            "mj_us": float(np.median(a[:, 1])) * 1e6, "ratio": float(np.median(a[:, 0] / a[:, 1])),
            "near": float(np.mean(a[:, 2])), "err": float(np.max(a[:, 3]))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=40)
    ap.add_argument("--scenes", nargs="*")
    ap.add_argument("--out", help="also write the table to this file")
    args = ap.parse_args(argv)
    if not MODELS.is_dir():
        print(f"no models at {MODELS}: nothing to measure", file=sys.stderr)
        return 1
    names = args.scenes or sorted(p.name for p in MODELS.iterdir() if (p / "scene.xml").is_file())
    lines = [f"# Collider.geom_distance against mujoco.mj_geomDistance {mujoco.__version__}, one call, distmax 1.0",
             f"# machine: {os.cpu_count()} cores, Python {platform.python_version()}, {_cpu()}; "
             f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start {os.getloadavg()[0]:.1f}",
             f"# command: python tests/bench/geom_distance.py{' ' + ' '.join(argv or sys.argv[1:]) if (argv or sys.argv[1:]) else ''}",
             "# medians over random geom pairs of the mean CPU time per call (us); near: share of pairs under distmax;",
             "# err: largest |ours - MuJoCo| over those",
             f"{'scene':<22}{'pairs':>6}{'ours us':>9}{'MJ us':>8}{'ratio':>7}{'near':>6}{'err':>10}"]
    print("\n".join(lines), flush=True)
    ratios = []
    for name in names:
        r = bench_scene(MODELS / name / "scene.xml", args.pairs)
        ratios.append(r["ratio"])
        line = (f"{r['model']:<22}{r['pairs']:>6}{r['ours_us']:>9.2f}{r['mj_us']:>8.2f}{r['ratio']:>7.2f}"
                f"{r['near']:>6.2f}{r['err']:>10.1e}")
        lines.append(line)
        print(line, flush=True)
    lines.append(f"median ratio over the scenes: {np.median(ratios):.2f}")
    print(lines[-1])
    if args.out:
        with open(args.out, "w") as f:
            f.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
