"""Benchmark: the signed distance of a ball and a cylinder, ellipsoid or cone, ours against coal and MuJoCo.

A sphere against a curved primitive is the query of sphere-approximated robots against primitive
obstacles. For each primitive, 200 random poses with the ball apart from it and 200 with the
ball's centre inside it. Per pose, the time of one call (mean over repeats, CPU time of this
process: the machine is shared); the table gives the medians over the poses, in microseconds,
and the largest error against `collide.testing.point_signed_distance` (the exact oracle):

- ``collide.distance``: the public call (pose checks and the result object included);
- ``coal``: ``coal.distance`` of a ``coal.Sphere`` and the ``coal.Cylinder``, ``coal.Ellipsoid``
  or ``coal.Cone`` (its Python call and a ``DistanceResult.clear()`` included), default request;
- ``mj_geomDistance``: MuJoCo's, on a model of the two geoms (mocap bodies; MuJoCo has no cone),
  the poses set beforehand (``distmax`` 10).

Run: ``python tests/bench/ball_primitive.py [--out tests/bench/ball_primitive.txt]``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np

import collide
from collide import Cone, Cylinder, Ellipsoid, PointCloud, testing
from collide.testing.surfaces import random_rotation
from _machine import cpu as _cpu  # noqa: E402 (tests/bench is the script's folder)
from distance import _coal_pose, _per_call  # noqa: E402 (tests/bench/distance.py: its timer and coal poses)

POSES = 200
RADIUS = 0.02  # the ball's
BUDGET = 0.005  # seconds of repeats per timed call (`distance._per_call`: CPU time of this process)
def _coal(coal, sh):
    if isinstance(sh, Cylinder):
        return coal.Cylinder(sh.radius, 2.0 * sh.half_height), 0.0
    if isinstance(sh, Ellipsoid):
        return coal.Ellipsoid(*sh.radii), 0.0
    return coal.Cone(sh.radius, sh.height), 0.5 * sh.height  # coal's is centred: base at -h/2


def _mujoco(sh):
    import mujoco
    if isinstance(sh, Cylinder):
        geom = f'type="cylinder" size="{sh.radius} {sh.half_height}"'
    elif isinstance(sh, Ellipsoid):
        geom = f'type="ellipsoid" size="{" ".join(map(str, sh.radii))}"'
    else:
        return None
    xml = (f'<mujoco><worldbody><body mocap="true"><geom {geom}/></body><body mocap="true">'
           f'<geom type="sphere" size="{RADIUS}"/></body></worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    return mujoco, model, mujoco.MjData(model)


def _poses(rng, sh, inside):
    # (rotation, translation, ball centre in the world, the oracle's signed distance)
    out = []
    while len(out) < POSES:
        rot, pos = random_rotation(rng), rng.normal(size=3)
        d = rng.normal(size=3)
        local = d / np.linalg.norm(d) * rng.uniform(0.0, 0.5 if not inside else 0.3)
        sd = testing.point_signed_distance(sh, local)
        if (sd < 0.0) != inside or (not inside and sd < 1e-3):
            continue
        out.append((rot, pos, rot @ local + pos, sd - RADIUS))
    return out


def bench(rng, lines):
    try:
        import coal
    except ImportError:
        coal = None
        lines.append("coal not installed: its columns are empty")
    lines.append(f"{'shape':<10} {'ball':<7} {'collide us':>10} {'coal us':>8} {'mj us':>7} {'ours/coal':>9} "
                 f"{'ours/mj':>7} {'|ours-exact|':>12} {'|coal-exact|':>12} {'|mj-exact|':>10}")
    for sh in (Cylinder(0.2, 0.3), Ellipsoid([0.3, 0.2, 0.1]), Cone(0.2, 0.4)):
        mj = _mujoco(sh)
        for inside in (False, True):
            rows = []
            for rot, pos, centre, true in _poses(rng, sh, inside):
                ball = PointCloud([centre], RADIUS)
                pose = (rot, pos)
                r = collide.distance(sh, ball, pose)
                t_ours = _per_call(lambda: collide.distance(sh, ball, pose), BUDGET)
                t_coal = e_coal = t_mj = e_mj = np.nan
                if coal is not None:
                    cs, lift = _coal(coal, sh)
                    ball_c = coal.Sphere(RADIUS)
                    pa, pb = _coal_pose(coal, rot, pos + rot @ np.array([0.0, 0.0, lift])), _coal_pose(
                        coal, np.eye(3), centre)
                    req, res = coal.DistanceRequest(), coal.DistanceResult()
                    coal.distance(cs, pa, ball_c, pb, req, res)
                    e_coal = abs(res.min_distance - true)
                    t_coal = _per_call(lambda: (res.clear(), coal.distance(cs, pa, ball_c, pb, req, res)), BUDGET)
                if mj is not None:
                    mujoco, model, data = mj
                    q = np.zeros(4)
                    mujoco.mju_mat2Quat(q, rot.ravel())
                    data.mocap_pos[0], data.mocap_quat[0] = pos, q
                    data.mocap_pos[1], data.mocap_quat[1] = centre, [1.0, 0.0, 0.0, 0.0]
                    mujoco.mj_kinematics(model, data)
                    ft = np.zeros(6)
                    e_mj = abs(mujoco.mj_geomDistance(model, data, 0, 1, 10.0, ft) - true)
                    t_mj = _per_call(lambda: mujoco.mj_geomDistance(model, data, 0, 1, 10.0, ft), BUDGET)
                rows.append((t_ours, t_coal, t_mj, abs(r.distance - true), e_coal, e_mj))
            a = np.array(rows)
            med = np.median(a[:, :3], axis=0) * 1e6
            lines.append(f"{type(sh).__name__:<10} {'inside' if inside else 'apart':<7} {med[0]:>10.2f} {med[1]:>8.2f} "
                         f"{med[2]:>7.2f} {med[0] / med[1]:>9.2f} {med[0] / med[2]:>7.2f} {a[:, 3].max():>12.1e} "
                         f"{np.nanmax(a[:, 4]) if coal is not None else np.nan:>12.1e} "
                         f"{np.nanmax(a[:, 5]) if mj is not None else np.nan:>10.1e}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="also write the table to this file")
    args = ap.parse_args(argv)
    lines = [f"# ball ({RADIUS}) against a primitive, {POSES} poses each: medians of one call's time (CPU time), "
             "largest error against the exact oracle",
             f"# machine: {os.cpu_count()} cores, Python {platform.python_version()}, {_cpu()}; "
             f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average at start {os.getloadavg()[0]:.1f}",
             "# command: python tests/bench/ball_primitive.py"]
    bench(np.random.default_rng(0), lines)
    text = "\n".join(lines)
    print(text)
    if args.out:
        with open(args.out, "a") as f:
            f.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
