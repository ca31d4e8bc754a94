"""Benchmark: one signed distance of two convex meshes (100-1000 vertices), ours against coal's GJK.

For each hull size, 40 random pose pairs (about a quarter overlapping) of two random convex
meshes whose points are all hull vertices. Per pair, the time of one call (mean over repeats);
the tables give the median over pairs, in microseconds:

- ``collide.distance``: the public call (pose checks, result object included);
- ``kernel``: the public call's kernel, `collide._kernels.distance.query`, called from Python
  on its prebuilt arguments (numba's dispatch and the pose checks included);
- ``in numba``: the distance it computes (`collide._kernels.distance.pair_distance_within`, its
  scratch allocated once) in a compiled loop (no Python at all), cold (no hint) and warm (the
  previous normal and support vertices, the pose unchanged);
- ``coal``: ``coal.distance`` on ``coal.Convex`` hulls of the same points (its Python call
  and a ``DistanceResult.clear()`` included: a result keeps the minimum over calls, and coal
  returns at once when it is not cleared), at its default GJK tolerance (1e-6) and at 1e-12;
- ``mj_geomDistance``: MuJoCo's, on a model with the two meshes as mocap geoms.

A line gives each library's call floor (two spheres, closed forms in both), and a second table
times the support search policy: scan of every vertex against hill-climbing over
the hull's vertex graph, in the compiled loop, by hull size (where `collide.support.CLIMB_MIN`
comes from). Run: ``python tests/bench/distance.py [--out tests/bench/distance.txt]``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np
from numba import njit

import collide
from collide import signed_distance as sd
from collide._kernels import distance as kd
from collide.support import SupportData, support_data
from collide.testing.surfaces import random_rotation
from _machine import cpu as _cpu  # noqa: E402 (tests/bench is the script's folder)

PAIRS = 40
SIZES = (100, 300, 1000)

# CPU time of this process, not wall time: the machine is shared (2 cores, load 2-6 while the
# other sessions run), and a process waiting for a core is not charged for the wait. Every column
# is timed by this clock, in one process, so their ratios compare like with like.
_clock = time.process_time


@njit(cache=True)
def _loop(sa, sb, tol, d0, hint_a, hint_b, reps, out):
    # the scratch allocated once, as the contact kernel's workspace holds it
    fws, iws = np.empty(kd.WS_F), np.empty(kd.WS_I, np.int64)
    for _ in range(reps):
        kd.pair_distance_within(sa, sb, tol, np.inf, d0, hint_a, hint_b, 128, out, fws, iws)


def _per_call(fn, budget=0.02):
    # Mean seconds per call of fn(), repeated for about `budget` seconds (at least 5 calls).
    fn()
    reps = 5
    while True:
        t = _clock()
        for _ in range(reps):
            fn()
        dt = _clock() - t
        if dt > budget or reps > 1_000_000:
            return dt / reps
        reps *= 4


def _mesh(rng, n):
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d * rng.uniform(0.5, 1.0, 3)  # all on an ellipsoid: every point a hull vertex


def _coal_shape(coal, pts):
    v = coal.StdVec_Vec3s()
    for p in pts:
        v.append(p)
    return coal.Convex.convexHull(v, False, None)


def _coal_pose(coal, rot, pos):
    t = coal.Transform3s()
    t.setRotation(rot)
    t.setTranslation(pos)
    return t


def _mujoco(pa, pb):
    import mujoco
    verts = [" ".join(map(str, p.ravel())) for p in (pa, pb)]
    xml = (f'<mujoco><asset><mesh name="a" vertex="{verts[0]}"/><mesh name="b" vertex="{verts[1]}"/>'
           '</asset><worldbody><body mocap="true"><geom type="mesh" mesh="a"/></body>'
           '<body mocap="true"><geom type="mesh" mesh="b"/></body></worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    return mujoco, model, mujoco.MjData(model)


def _quat(rot):
    import mujoco
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, rot.ravel())
    return q


def bench_sizes(rng, lines):
    try:
        import coal
    except ImportError:
        coal = None
        lines.append("coal not installed: its columns are empty")
    head = (f"{'vertices':>8} {'collide.distance':>16} {'kernel':>8} {'in numba':>9} {'warm':>7} "
            f"{'coal 1e-6':>9} {'coal 1e-12':>10} {'mj_geomDist':>11} {'ours/coal':>9} {'|ours-coal|':>11}")
    lines.append(head)
    for n in SIZES:
        P, Q = _mesh(rng, n), _mesh(rng, n)
        a, b = collide.PointCloud(P), collide.PointCloud(Q)
        da, db = support_data(a), support_data(b)
        tol = 1e-12 * (da.size + db.size)
        if coal is not None:
            ca, cb = _coal_shape(coal, P), _coal_shape(coal, Q)
            req_default = coal.DistanceRequest()
            req_tight = coal.DistanceRequest()
            req_tight.gjk_tolerance = 1e-12
            res = coal.DistanceResult()
        mujoco, model, data = _mujoco(P, Q)
        fromto = np.zeros(6)
        rows = []
        overlapping = 0
        for _ in range(PAIRS):
            ra, rb = random_rotation(rng), random_rotation(rng)
            ta = np.zeros(3)
            tb = rng.normal(size=3)
            tb *= rng.uniform(1.0, 3.0) / np.linalg.norm(tb)
            pose_a, pose_b = (ra, ta), (rb, tb)
            r = collide.distance(a, b, pose_a, pose_b)
            overlapping += r.distance < 0
            t_public = _per_call(lambda: collide.distance(a, b, pose_a, pose_b))
            sa, sb = da.posed(ra, ta), db.posed(rb, tb)
            out = np.empty(kd.OUT_SIZE)
            zero = np.zeros(3)
            ea, eb = sd._described(a, "a"), sd._described(b, "b")
            t_kernel = _per_call(lambda: kd.query(ea[2], eb[2], ra, ta, rb, tb, ea[3], eb[3], sd.ORTHONORMAL_TOL,
                                                  sd._LIMIT, tol, sd._COLD, 128, out))
            reps = 2000
            _loop(sa, sb, tol, zero, -1, -1, 1, out)
            t0 = _clock()
            _loop(sa, sb, tol, zero, -1, -1, reps, out)
            t_loop = (_clock() - t0) / reps
            warm_dir = out[kd.OUT_NORMAL:kd.OUT_NORMAL + 3].copy()
            ha, hb = int(out[kd.OUT_HINT_A]), int(out[kd.OUT_HINT_B])
            t0 = _clock()
            _loop(sa, sb, tol, warm_dir, ha, hb, reps, out)
            t_warm = (_clock() - t0) / reps
            t_coal = t_coal_tight = np.nan
            err = np.nan
            if coal is not None:
                pa_, pb_ = _coal_pose(coal, ra, ta), _coal_pose(coal, rb, tb)
                if r.distance > 0:  # coal's default request reports no depth for overlaps
                    res.clear()
                    coal.distance(ca, pa_, cb, pb_, req_tight, res)
                    err = abs(res.min_distance - r.distance)
                # A DistanceResult keeps the minimum over calls: cleared each time, or coal
                # returns at once with the last pair's answer.
                t_coal = _per_call(lambda: (res.clear(), coal.distance(ca, pa_, cb, pb_, req_default, res)))
                t_coal_tight = _per_call(lambda: (res.clear(), coal.distance(ca, pa_, cb, pb_, req_tight, res)))
            data.mocap_pos[0], data.mocap_quat[0] = ta, _quat(ra)
            data.mocap_pos[1], data.mocap_quat[1] = tb, _quat(rb)
            mujoco.mj_kinematics(model, data)
            t_mj = _per_call(lambda: mujoco.mj_geomDistance(model, data, 0, 1, 10.0, fromto))
            rows.append((t_public, t_kernel, t_loop, t_warm, t_coal, t_coal_tight, t_mj, err))
        m = np.nanmedian(np.array(rows), axis=0)
        worst = np.nanmax(np.array(rows)[:, 7]) if coal is not None else np.nan
        us = m[:7] * 1e6
        lines.append(f"{len(da.points):>8d} {us[0]:>16.2f} {us[1]:>8.2f} {us[2]:>9.2f} {us[3]:>7.2f} "
                     f"{us[4]:>9.2f} {us[5]:>10.2f} {us[6]:>11.2f} {m[0] / m[4]:>9.2f} {worst:>11.1e}")
        lines.append(f"{'':>8} ({PAIRS} pairs, {overlapping} overlapping; |ours-coal| over the separated "
                     "ones, coal at 1e-12)")


def bench_floor(lines):
    # Each library's cost of a call whose geometry costs next to nothing: two spheres (closed
    # forms in both: our segment distance, coal's sphere-sphere), median of 5 repeats.
    a = collide.PointCloud([[0.0, 0.0, 0.0]], 0.5)
    pose = (np.eye(3), np.array([3.0, 0.2, 0.1]))
    ours = np.median([_per_call(lambda: collide.distance(a, a, None, pose)) for _ in range(5)]) * 1e6
    theirs = np.nan
    try:
        import coal
        s, ta, tb = coal.Sphere(0.5), coal.Transform3s(), coal.Transform3s()
        tb.setTranslation(pose[1])
        req, res = coal.DistanceRequest(), coal.DistanceResult()
        theirs = np.median([_per_call(lambda: (res.clear(), coal.distance(s, ta, s, tb, req, res)))
                            for _ in range(5)]) * 1e6
    except ImportError:
        pass
    lines.append("")
    lines.append(f"Call floor, two spheres (closed forms): collide.distance {ours:.2f} us, "
                 f"coal.distance {theirs:.2f} us")


def bench_policy(rng, lines):
    lines.append("")
    lines.append("Support search policy, in numba (median over 20 pose pairs, us per distance; the other "
                 "shape a 12-vertex cloud):")
    lines.append(f"{'vertices':>8} {'scan':>8} {'climb':>8}")
    other = collide.PointCloud(_mesh(rng, 12))
    do = support_data(other)
    for n in (8, 16, 32, 64, 128, 256):
        pts = _mesh(rng, n)
        climb = support_data(collide.PointCloud(pts))
        if len(climb.nbr_start) == 0:  # below CLIMB_MIN: build the graph here
            from collide.support import _adjacency
            p, s, nb = _adjacency(pts)
            climb = SupportData(climb.kind, climb.prm, p, s, nb, climb.size)
        scan = SupportData(climb.kind, climb.prm, climb.points, np.zeros(0, np.int32),
                           np.zeros(0, np.int32), climb.size)
        times = {"scan": [], "climb": []}
        for _ in range(20):
            ra, rb = random_rotation(rng), random_rotation(rng)
            tb = rng.normal(size=3)
            tb *= 2.5 / np.linalg.norm(tb)
            out = np.empty(kd.OUT_SIZE)
            zero = np.zeros(3)
            for name, d in (("scan", scan), ("climb", climb)):
                sa, sb = d.posed(ra, np.zeros(3)), do.posed(rb, tb)
                _loop(sa, sb, 1e-12, zero, -1, -1, 1, out)
                t0 = _clock()
                _loop(sa, sb, 1e-12, zero, -1, -1, 2000, out)
                times[name].append((_clock() - t0) / 2000)
        lines.append(f"{n:>8d} {np.median(times['scan']) * 1e6:>8.3f} {np.median(times['climb']) * 1e6:>8.3f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="also write the table to this file")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    lines = [f"collide.distance benchmark, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}",
             f"CPU: {_cpu()} ({platform.machine()}), Python {platform.python_version()}",
             "Median over pairs of the mean CPU time per call (time.process_time), microseconds; "
             "load average before the run "
             f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs (a shared machine: compare columns "
             "within a row, measured in one run).",
             f"Command: python tests/bench/distance.py {' '.join(sys.argv[1:])}".rstrip(), ""]
    bench_sizes(rng, lines)
    bench_floor(lines)
    bench_policy(rng, lines)
    text = "\n".join(lines)
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    sys.exit(main())
