"""Benchmark: OBB and sphere fitting (collide.volumes).

OBBs, on 1000-point clouds: for each kind of cloud, ``INSTANCES`` random instances (random
rotation and offset) are fitted by ``fit_obb(method="exact")``, ``"optimal"``, ``"pca"`` and
``trimesh.bounds.oriented_bounds``; volumes are divided by the exact box's. As a cross-check
of the exact box, a multistart search (``STARTS`` random rotations, each polished by a compass
search on SO(3), the best few refined by Nelder-Mead on a rotation vector) must never beat it.
Then the exact search alone on hulls of 20 to 2000 vertices (points on ellipsoids and spheres,
every point a hull vertex), beside ``"optimal"`` and trimesh; the radius (the exact box of
``hull ⊕ ball`` against the zero-radius optimum grown by the radius); and an ablation of the
``"optimal"`` fitter's settings.

Spheres: ``fit_sphere(method="exact")``, ``"ritter"`` and ``trimesh.nsphere.minimum_nsphere``.
Radii are divided by the minimal radius: the exact sphere checked by the optimality
certificate (centre in the convex hull of the farthest points, by NNLS) and against an
independent SLSQP minimax solution.

Times are CPU seconds of this process (``time.process_time``: the machine is shared, and
every method timed is single-threaded), medians over instances of the median of ``REPEATS``
calls, all measured in this run.

Run: ``python tests/bench/fitting.py > tests/bench/fitting.txt``
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import time

import numpy as np
import trimesh
from scipy.optimize import minimize, nnls

from collide import volumes as V
from collide.volumes import _fit_box as VF  # the "optimal" fitter's settings, for the ablation
from collide.volumes._axes import _hull_points, _rodrigues

N = 1000
INSTANCES = 10
REPEATS = 5
STARTS = 64


def _rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _sphere_surface(rng, n):
    p = rng.normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1)[:, None]


def _cloud(kind: str, rng) -> np.ndarray:
    if kind == "ellipsoid surface":
        return _sphere_surface(rng, N) * [3.0, 2.0, 1.0]
    if kind == "elongated (gaussian)":
        return rng.normal(size=(N, 3)) * [10.0, 1.0, 0.5]
    if kind == "flat":
        return np.c_[rng.uniform(-1, 1, (N, 2)) * [3.0, 1.0], np.zeros(N)] @ _rotation(rng)
    if kind == "elbow (two limbs)":
        upper = rng.uniform(size=(N // 2, 3)) * [4.0, 0.6, 0.6]
        fore = rng.uniform(size=(N - N // 2, 3)) * [4.0, 0.5, 0.5]
        bend = _rodrigues(np.array([[0.0, 0.0, rng.uniform(0.4, 1.6)]]))[0]
        return np.vstack([upper, fore @ bend.T])
    if kind == "trimesh icosphere (perturbed)":
        m = trimesh.creation.icosphere(subdivisions=4)
        v = m.vertices * (1.0 + 0.05 * rng.normal(size=(len(m.vertices), 1))) * [2.0, 1.0, 0.7]
        return v[rng.choice(len(v), N, replace=False)]
    if kind == "trimesh box surface":
        m = trimesh.creation.box([3.0, 2.0, 1.0])
        return trimesh.sample.sample_surface(m, N, seed=int(rng.integers(2**31)))[0]
    if kind == "trimesh capsule vertices":
        m = trimesh.creation.capsule(height=3.0, radius=0.6, count=[24, 24])
        return m.vertices[:N]
    raise ValueError(kind)


KINDS = ["ellipsoid surface", "elongated (gaussian)", "flat", "elbow (two limbs)",
         "trimesh icosphere (perturbed)", "trimesh box surface", "trimesh capsule vertices"]


def _timed(fn, *args):
    times, out = [], None
    for _ in range(REPEATS):
        t = time.process_time()
        out = fn(*args)
        times.append(time.process_time() - t)
    return out, float(np.median(times))


def _box_volume(points, rot):
    return float(np.prod(np.ptp(points @ rot, axis=0)))


def _multistart(points, rng) -> float:
    p = np.ascontiguousarray(points - points.mean(axis=0))
    found = []
    for _ in range(STARTS):
        rot, vol = VF._nb_polish(p, _rotation(rng), 0.0, 0.5, 1e-7, 5000, VF._COMPASS)
        found.append((vol, rot))
    found.sort(key=lambda x: x[0])
    best = found[0][0]
    for vol, rot in found[:3]:
        res = minimize(lambda w: _box_volume(p, rot @ _rodrigues(w[None])[0]), np.zeros(3),
                       method="Nelder-Mead", options={"xatol": 1e-9, "fatol": 1e-14, "maxiter": 4000})
        best = min(best, vol, float(res.fun))
    return best


def _trimesh_obb(points):
    try:
        _, extents = trimesh.bounds.oriented_bounds(points)
        return float(np.prod(extents))
    except Exception as exc:  # it needs networkx for flat input, absent here
        return f"{type(exc).__name__}"


def _trimesh_nsphere(points):
    try:
        return float(trimesh.nsphere.minimum_nsphere(points)[1])
    except Exception:  # Qhull refuses flat input there
        return None


def _slsqp_radius(points) -> float:
    c0 = points.mean(axis=0)
    p = points - c0
    r0 = float(np.max(np.sum(p * p, axis=1)))
    res = minimize(lambda z: z[3], np.r_[0.0, 0.0, 0.0, r0], method="SLSQP",
                   jac=lambda z: np.r_[0.0, 0.0, 0.0, 1.0],
                   constraints=[{"type": "ineq",
                                 "fun": lambda z: z[3] - np.sum((p - z[:3]) ** 2, axis=1),
                                 "jac": lambda z: np.c_[2.0 * (p - z[:3]), np.ones(len(p))]}],
                   options={"ftol": 1e-16, "maxiter": 1000})
    return float(np.sqrt(np.max(np.sum((p - res.x[:3]) ** 2, axis=1))))


def _certificate(points, center) -> float:
    d = np.linalg.norm(points - center, axis=1)
    far = points[d >= d.max() * (1 - 1e-9)]
    scale = max(1.0, float(np.abs(points).max()))
    _, res = nnls(np.vstack([far.T, np.full(len(far), scale)]), np.r_[center, scale])
    return res / scale


def _machine() -> str:
    try:
        lscpu = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        cpu = next(line.split(":", 1)[1].strip() for line in lscpu.splitlines() if "Model name" in line)
    except (OSError, subprocess.CalledProcessError, StopIteration):
        cpu = "?"
    import numba

    return (f"{os.cpu_count()} cores, Model name: {cpu}, load average {os.getloadavg()[0]:.1f} at the "
            f"start; Python {platform.python_version()}, numpy {np.__version__}, numba "
            f"{numba.__version__}, trimesh {trimesh.__version__}")


def _area(box) -> float:
    return float(np.prod(np.sort(box.half_extents)[1:] * 2))


def fmt_ratio(r):
    return f"{np.mean(r):7.4f} {np.max(r):7.4f}" if len(r) else f"{'n/a':>7s} {'n/a':>7s}"


def fmt_time(t):
    return f"{np.median(t) * 1e3:8.2f}" if len(t) else f"{'n/a':>8s}"


METHODS = ["optimal", "pca", "trimesh"]


def main() -> None:
    print("# OBB and sphere fitting (tests/bench/fitting.py), "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"# machine: {_machine()}")
    print(f"# times: CPU time of this process, median over instances of the median of {REPEATS} calls")
    rng = np.random.default_rng(2026)
    V.fit_obb(rng.normal(size=(50, 3)))  # numba compilation / cache load outside the timings
    V.fit_obb(rng.normal(size=(50, 3)), 0.0, "exact")
    all_ratio = {k: [] for k in METHODS}
    all_time = {k: [] for k in METHODS + ["exact"]}
    sph = {"exact": [], "ritter": [], "nsphere": []}
    sph_time = {"exact": [], "ritter": [], "nsphere": []}
    rows, srows = [], []
    worst_exact_vs_slsqp, worst_cert = -np.inf, 0.0
    least_search = np.inf
    kept = []  # (cloud, exact volume) of the non-flat instances, for the ablation
    for kind in KINDS:
        ratio = {k: [] for k in METHODS}
        times = {k: [] for k in METHODS + ["exact"]}
        sratio = {k: [] for k in sph}
        stimes = {k: [] for k in sph}
        hull_sizes = []
        for _ in range(INSTANCES):
            p = _cloud(kind, rng) @ _rotation(rng).T + rng.normal(size=3) * 10
            hull_sizes.append(len(_hull_points(p - p.mean(axis=0))[0]))
            ex, times_ex = _timed(V.fit_obb, p, 0.0, "exact")
            opt, t_opt = _timed(V.fit_obb, p)
            pca, t_pca = _timed(V.fit_obb, p, 0.0, "pca")
            tm, t_tm = _timed(_trimesh_obb, p)
            times["exact"].append(times_ex)
            if kind == "flat":
                # zero volume for every box with the plane's normal as an axis: compare areas
                ref = _area(ex)
                least_search = min(least_search, _flat_search(p, rng) / ref)
                vols = {"optimal": _area(opt), "pca": _area(pca), "trimesh": tm}
            else:
                ref = ex.volume()
                least_search = min(least_search, _multistart(p, rng) / ref)
                kept.append((p, ref))
                vols = {"optimal": opt.volume(), "pca": pca.volume(), "trimesh": tm}
            for k in METHODS:
                if isinstance(vols[k], float):
                    ratio[k].append(vols[k] / ref)
                    times[k].append({"optimal": t_opt, "pca": t_pca, "trimesh": t_tm}[k])
            sp, t_ex = _timed(V.fit_sphere, p)
            ri, t_ri = _timed(V.fit_sphere, p, 0.0, "ritter")
            ns_r, t_ns = _timed(_trimesh_nsphere, p)
            r_min = sp.radius
            worst_cert = max(worst_cert, _certificate(p, sp.center))
            worst_exact_vs_slsqp = max(worst_exact_vs_slsqp, (sp.radius - _slsqp_radius(p)) / r_min)
            for k, r, t in (("exact", sp.radius, t_ex), ("ritter", ri.radius, t_ri), ("nsphere", ns_r, t_ns)):
                if r is None:
                    continue
                sratio[k].append(r / r_min)
                stimes[k].append(t)
        for k in all_ratio:
            all_ratio[k] += ratio[k]
        for k in all_time:
            all_time[k] += times[k]
        for k in sph:
            sph[k] += sratio[k]
            sph_time[k] += stimes[k]
        rows.append((kind, int(np.median(hull_sizes)), ratio, times))
        srows.append((kind, sratio, stimes))

    print()
    print(f"## OBB volume / exact box's volume (mean, worst) and median time [ms], {N}-point clouds, "
          f"{INSTANCES} instances each (flat: area / exact area)")
    print(f"{'cloud':30s} {'hull':>5s} | {'optimal':>15s} {'pca':>15s} {'trimesh':>15s} | "
          f"{'t_exact':>8s} {'t_opt':>8s} {'t_pca':>8s} {'t_trim':>8s}")
    for kind, h, ratio, times in rows:
        print(f"{kind:30s} {h:5d} | {fmt_ratio(ratio['optimal'])} {fmt_ratio(ratio['pca'])} "
              f"{fmt_ratio(ratio['trimesh'])} | {fmt_time(times['exact'])} {fmt_time(times['optimal'])} "
              f"{fmt_time(times['pca'])} {fmt_time(times['trimesh'])}")
    print(f"{'all':30s} {'':5s} | {fmt_ratio(all_ratio['optimal'])} {fmt_ratio(all_ratio['pca'])} "
          f"{fmt_ratio(all_ratio['trimesh'])} | {fmt_time(all_time['exact'])} {fmt_time(all_time['optimal'])} "
          f"{fmt_time(all_time['pca'])} {fmt_time(all_time['trimesh'])}")
    print("# n/a: trimesh.bounds.oriented_bounds raised on flat clouds here (it needs networkx)")
    print(f"# cross-check: a {STARTS}-start search (compass polish + Nelder-Mead; flat: a dense angle search) "
          f"never beat the exact box: least search / exact = {least_search:.12f}")
    _by_hull_size(rng)
    _radius(rng)
    print()
    print("## Sphere radius / minimal radius (mean, worst) and median time [ms]")
    print(f"{'cloud':30s} | {'exact':>15s} {'ritter':>15s} {'tm nsphere':>15s} | "
          f"{'t_exact':>8s} {'t_ritter':>8s} {'t_nsph':>8s}")
    for kind, sratio, stimes in srows:
        print(f"{kind:30s} | {fmt_ratio(sratio['exact'])} {fmt_ratio(sratio['ritter'])} "
              f"{fmt_ratio(sratio['nsphere'])} | {fmt_time(stimes['exact'])} {fmt_time(stimes['ritter'])} "
              f"{fmt_time(stimes['nsphere'])}")
    print(f"{'all':30s} | {fmt_ratio(sph['exact'])} {fmt_ratio(sph['ritter'])} {fmt_ratio(sph['nsphere'])} | "
          f"{fmt_time(sph_time['exact'])} {fmt_time(sph_time['ritter'])} {fmt_time(sph_time['nsphere'])}")
    print(f"# exact sphere: worst optimality-certificate residual {worst_cert:.2e} (0 = centre in the hull "
          f"of the farthest points);")
    print(f"#   worst (exact - SLSQP minimax radius) / r = {worst_exact_vs_slsqp:.2e} "
          f"(rounding and the fitted sphere's 8-ulp pad included; target <= 1e-9)")
    print("# n/a: trimesh.nsphere.minimum_nsphere raised on flat clouds (Qhull: initial simplex is flat)")
    _ablation(kept)


SIZES = [20, 50, 100, 200, 500, 1000, 2000]
SIZE_INSTANCES = 3


def _by_hull_size(rng) -> None:
    # Points on an ellipsoid (3:2:1) and on a sphere: every point is a hull vertex. The sphere is
    # the hard case for the exact search's subset rounds (every orientation is nearly as good).
    print()
    print(f"## The exact search by hull size: median time [ms] over {SIZE_INSTANCES} instances, "
          "and volume / exact (mean, worst)")
    print(f"{'cloud':22s} {'hull':>5s} | {'t_exact':>8s} {'t_opt':>8s} {'t_trim':>8s} | "
          f"{'optimal':>15s} {'trimesh':>15s}")
    for name, axes in (("ellipsoid 3:2:1", [3.0, 2.0, 1.0]), ("sphere", [1.0, 1.0, 1.0])):
        for n in SIZES:
            times = {"exact": [], "optimal": [], "trimesh": []}
            ratio = {"optimal": [], "trimesh": []}
            for _ in range(SIZE_INSTANCES):
                p = _sphere_surface(rng, n) * axes @ _rotation(rng).T
                ex, t_ex = _timed(V.fit_obb, p, 0.0, "exact")
                opt, t_opt = _timed(V.fit_obb, p)
                tm, t_tm = _timed(_trimesh_obb, p)
                times["exact"].append(t_ex)
                times["optimal"].append(t_opt)
                times["trimesh"].append(t_tm)
                ratio["optimal"].append(opt.volume() / ex.volume())
                ratio["trimesh"].append(tm / ex.volume())
            print(f"{name:22s} {n:5d} | {fmt_time(times['exact'])} {fmt_time(times['optimal'])} "
                  f"{fmt_time(times['trimesh'])} | {fmt_ratio(ratio['optimal'])} {fmt_ratio(ratio['trimesh'])}")


def _radius(rng) -> None:
    # The box of hull ⊕ ball(r) minimises prod(e_i + 2r): the exact box against the r = 0
    # optimum grown by r, and "optimal" against the exact box; r = 10 % of the cloud's spread.
    print()
    print(f"## Radius r = 0.1 x the cloud's largest spread: volume / exact box's (mean, worst), "
          f"{INSTANCES} instances each")
    print(f"{'cloud':30s} | {'r=0 optimum+r':>15s} {'optimal':>15s}")
    for kind in KINDS:
        grown, opt = [], []
        for _ in range(INSTANCES):
            p = _cloud(kind, rng) @ _rotation(rng).T
            r = 0.1 * float(np.ptp(p, axis=0).max())
            ex = V.fit_obb(p, r, "exact").volume()
            grown.append(V.box_from_axes(p, r, V.fit_obb(p, 0.0, "exact").rotation).volume() / ex)
            opt.append(V.fit_obb(p, r).volume() / ex)
        print(f"{kind:30s} | {fmt_ratio(grown)} {fmt_ratio(opt)}")


ABLATION = [  # (exact up to hull size, subset rounds, seed supports, polished starts)
    (0, 0, 1, 3), (32, 0, 1, 3), (64, 0, 1, 3), (32, 1, 1, 3), (64, 1, 1, 3), (64, 1, 2, 3),
    (64, 1, 2, 5), (64, 2, 1, 3)]


def _ablation(kept) -> None:
    # The "optimal" fitter's settings, on the non-flat instances above (ratios to the exact box).
    names = ("_EXACT_HULL", "_SUBSET_ROUNDS", "_SEED_SUPPORTS", "_POLISH_STARTS")
    saved = tuple(getattr(VF, k) for k in names)
    print()
    print("## Ablation of fit_obb(method=\"optimal\") settings, non-flat instances above "
          "(volume / exact: mean, worst; median time [ms])")
    print(f"{'exact<=':>7s} {'rounds':>6s} {'seeds':>5s} {'starts':>6s} | {'mean':>7s} {'worst':>7s} | "
          f"{'time':>7s}")
    for setting in ABLATION:
        for k, v in zip(names, setting):
            setattr(VF, k, v)
        ratios, times = [], []
        for p, ref in kept:
            box, t = _timed(V.fit_obb, p)
            ratios.append(box.volume() / ref)
            times.append(t)
        mark = "  <- default" if setting == saved else ""
        print(f"{setting[0]:7d} {setting[1]:6d} {setting[2]:5d} {setting[3]:6d} | {np.mean(ratios):7.4f} "
              f"{np.max(ratios):7.4f} | {np.median(times) * 1e3:7.2f}{mark}")
    for k, v in zip(names, saved):
        setattr(VF, k, v)
    print("# exact<=: the exact box up to this hull size; rounds: subset rounds of the exact search above it;")
    print("# seeds: extreme vertices per axis of each polished start joining the subset; starts: polished")
    print("# starts. (0, 0, 1, 3) is the fitter before the exact search (no exact box, no subset round).")


def _flat_search(points, rng) -> float:
    # Minimal-area rectangle of a flat cloud by a dense angle search in its plane.
    c = points - points.mean(axis=0)
    _, _, vt = np.linalg.svd(c, full_matrices=False)
    xy = c @ vt[:2].T
    best = np.inf
    for a in np.linspace(0.0, np.pi / 2, 20001):
        d = np.array([np.cos(a), np.sin(a)])
        e = np.array([-d[1], d[0]])
        best = min(best, float(np.ptp(xy @ d) * np.ptp(xy @ e)))
    return best


if __name__ == "__main__":
    sys.exit(main())
