"""Tightness and time of collide.deform and collide.swept (issue 44); output in tests/bench/deform.txt.

Tightness: volume of the result (hull ⊕ ball, Steiner's formula) over the volume of the hull of a
dense sample of the true set (200 000 points: true surface and cloud boundary points mapped by
``f``; for sweeps, 300 cloud points at 1001 times). Above 1 by the bound's slack and by what the
sample misses (both small at this density). Time: median of 5 calls, CPU time of this process.

    .venv/bin/python tests/bench/deform.py > tests/bench/deform.txt
"""

import math
import time

import numpy as np
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

import collide
from collide import PointCloud, deformations, shapes, testing
from _machine import cpu as _cpu  # noqa: E402 (tests/bench is the script's folder)


def _median_time(fn, reps=5):
    times = []
    for _ in range(reps):
        t = time.process_time()
        out = fn()
        times.append(time.process_time() - t)
    return out, float(np.median(times))


def _ratio(cloud, sample):
    return testing.cloud_volume(cloud) / ConvexHull(sample).volume


SHAPES = {
    "box": (shapes.box([0.4, 0.25, 0.9]), dict(half_extents=[0.4, 0.25, 0.9])),
    "cylinder": (shapes.cylinder(0.35, 0.8, planes=32), dict(radius=0.35, half_length=0.8)),
    "capsule": (shapes.capsule(0.25, 0.7), dict(radius=0.25, half_length=0.7)),
}
MAPS = [deformations.twist(1.5), deformations.twist(6.0), deformations.bend(0.8), deformations.bend(2.5),
        deformations.taper(0.5)]


def deform_table(rng):
    print("deform: volume over the hull of 200k true points (guaranteed / paper's unbounded version)")
    print(f"{'shape':10s} {'map':12s} {'tol':>7s} {'points':>7s} {'radius/size':>12s} {'ratio':>8s} "
          f"{'paper':>8s} {'ms':>8s}")
    for name, (cloud, params) in SHAPES.items():
        for f in MAPS:
            true = f(np.concatenate([testing.sample_surface(name, 150000, rng, **params),
                                     testing.sample_cloud(cloud, 50000, rng, interior=0.0)]))
            for tol in (1e-2, 1e-3):
                out, dt = _median_time(lambda: collide.deform(cloud, f, tolerance=tol))
                paper = collide.deform(cloud, f, tolerance=tol, guaranteed=False)
                size = np.linalg.norm(np.ptp(out.points, axis=0))
                print(f"{name:10s} {f!r:12s} {tol:7.0e} {len(out):7d} {out.radius / size:12.2e} "
                      f"{_ratio(out, true):8.4f} {_ratio(paper, true):8.4f} {dt * 1e3:8.1f}")


def mesh_time(rng):
    print("\ndeform of a 1000-vertex convex mesh (random points on an ellipsoid), bend(1/size), tol 1e-3")
    d = rng.normal(size=(1000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    cloud = PointCloud(d * [0.5, 0.3, 1.0])
    f = deformations.bend(0.5)
    out, dt = _median_time(lambda: collide.deform(cloud, f))
    true = f(testing.sample_cloud(cloud, 200000, rng, interior=0.0))
    print(f"  hull vertices {len(cloud.reduced())}, result points {len(out)}, {dt * 1e3:.1f} ms, "
          f"ratio {_ratio(out, true):.4f}")


def swept_table(rng):
    print("\nswept: volume over the hull of 300 cloud points at 1001 times (and the end clouds' hull alone)")
    print(f"{'cloud':10s} {'angle':>6s} {'steps':>6s} {'radius/size':>12s} {'ratio':>8s} {'ends only':>10s} {'ms':>7s}")
    clouds = {"box": shapes.box([0.3, 0.1, 1.2]), "capsule": shapes.capsule(0.05, 1.0),
              "hull": testing.random_hull(rng, 1.5, 40)}
    times = np.linspace(0, 1, 1001)
    for name, cloud in clouds.items():
        for angle in (0.05, 0.5, 1.5, math.pi):
            R0 = testing.random_rotation(rng)
            axis = rng.normal(size=3)
            axis /= np.linalg.norm(axis)
            R1 = Rotation.from_rotvec(angle * axis).as_matrix() @ R0
            p0, p1 = (R0, np.zeros(3)), (R1, rng.normal(scale=0.5, size=3))
            out, dt = _median_time(lambda: cloud.swept(p0, p1))
            pts = testing.sample_cloud(cloud, 300, rng, interior=0.0)
            true = testing.swept_sample(pts, p0, p1, times).reshape(-1, 3)
            ends = collide.union([cloud.transform(*p0), cloud.transform(*p1)])
            size = np.linalg.norm(np.ptp(out.points, axis=0))
            steps = max(1, math.ceil(angle / (math.pi / 4)))
            print(f"{name:10s} {angle:6.2f} {steps:6d} {(out.radius - cloud.radius) / size:12.2e} "
                  f"{_ratio(out, true):8.4f} {_ratio(ends, true):10.4f} {dt * 1e3:7.2f}")


if __name__ == "__main__":
    print(f"CPU: {_cpu()}; numpy {np.__version__}")
    rng = np.random.default_rng(0)
    deform_table(rng)
    mesh_time(rng)
    swept_table(rng)
