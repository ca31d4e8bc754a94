"""Contact agreement with MuJoCo, step by step (used by tests/test_contacts.py and by hand).

    python tests/contact_check.py [--steps N] [--oracle K] [scene ...]

(``default`` names `collide.mujoco.default_scene`; no scene: it and every model in
../shared/models. The issue's run, 2,000 steps each, is committed as
tests/bench/contact_agreement.txt with its command and machine.)

For every geom pair MuJoCo made a contact for, ours must have made one; the deepest ``dist``
must agree within the tolerance of MuJoCo's function for the pair (`pair_tolerance`); the
normals of the deepest contacts within `NORMAL_TOL` rad unless the pair's normal is not unique
(MuJoCo's normal separates the two as far as ours, within the distance tolerance: both are
witnesses); and no pair of ours may be one MuJoCo left out because it is farther than its
contact distance. Every disagreement goes to an independent oracle
(`collide.testing.polytope_signed_distance`, the Minkowski difference's hull with Qhull, for
polytope pairs; the plane's support for plane pairs), which says who is right.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

import collide.mujoco as cm
from collide import contacts as cc
from collide.convex import Cylinder
from collide import testing
from collide._kernels import manifold as km
from collide._kernels.support import CYLINDER, support

MODELS = Path(__file__).resolve().parents[1] / ".." / "shared" / "models"
NORMAL_TOL = 1e-3
# MuJoCo's analytic collision functions (mjCOLLISIONFUNC): pairs of geom types, lower type first.
_T = mujoco.mjtGeom
ANALYTIC = {(int(a), int(b)) for a, b in [
    (_T.mjGEOM_PLANE, _T.mjGEOM_SPHERE), (_T.mjGEOM_PLANE, _T.mjGEOM_CAPSULE),
    (_T.mjGEOM_PLANE, _T.mjGEOM_CYLINDER), (_T.mjGEOM_PLANE, _T.mjGEOM_BOX),
    (_T.mjGEOM_PLANE, _T.mjGEOM_ELLIPSOID), (_T.mjGEOM_PLANE, _T.mjGEOM_MESH),  # a support point: exact
    (_T.mjGEOM_SPHERE, _T.mjGEOM_SPHERE), (_T.mjGEOM_SPHERE, _T.mjGEOM_CAPSULE),
    (_T.mjGEOM_SPHERE, _T.mjGEOM_CYLINDER), (_T.mjGEOM_SPHERE, _T.mjGEOM_BOX),
    (_T.mjGEOM_CAPSULE, _T.mjGEOM_CAPSULE), (_T.mjGEOM_CAPSULE, _T.mjGEOM_BOX),
    (_T.mjGEOM_BOX, _T.mjGEOM_BOX)]}


def pair_tolerance(model, g1: int, g2: int) -> float:
    """Agreement tolerance of the pair's distance: 1e-9 of the geoms' size for MuJoCo's analytic
    functions, ``opt.ccd_tolerance`` (GJK/EPA) otherwise, both floored at 1e-12 of the size."""
    t = tuple(sorted((int(model.geom_type[g1]), int(model.geom_type[g2]))))
    size = float(model.geom_rbound[g1] + model.geom_rbound[g2]) or 1.0
    if t in ANALYTIC:
        return 1e-9 * size
    return max(float(model.opt.ccd_tolerance), 1e-12 * size)


def mujoco_deepest(model, data) -> dict:
    """``{(g1, g2): (dist, normal from g1 to g2, includemargin)}``: MuJoCo's deepest contact per
    geom pair (lower id first), flex contacts left out (`collide.mujoco.mujoco_deepest`)."""
    return cm.mujoco_deepest(data)


def contact_distance(table: cc.GeomTable, g1: int, g2: int) -> tuple[float, float]:
    """The pair's ``(margin, margin + gap)`` under MuJoCo's rule (`collide.contacts`)."""
    key = min(g1, g2) * table.ngeom + max(g1, g2)
    j = int(np.searchsorted(table.pair_key, key))
    if j < len(table.pair_key) and table.pair_key[j] == key:
        margin, gap = table.pair_margin[j], table.pair_gap[j]
    else:
        margin = table.geom_margin[g1] + table.geom_margin[g2]
        gap = table.geom_gap[g1] + table.geom_gap[g2]
    if table.override:
        margin = table.o_margin
    return float(margin), float(margin + gap)


def undecided_from(table: cc.GeomTable, g1: int, g2: int) -> float:
    """Distance beyond which MuJoCo's answer is its broad phase's, not its rule's: with
    ``mjENBL_OVERRIDE`` its body boxes grow by ``o_margin / 2`` per geom without the gaps
    (``makeAAMM``), so a dynamic pair between ``o_margin`` and ``o_margin + gap`` makes contacts
    or not as its boxes in MuJoCo's sweep frame say; else the contact distance itself."""
    margin, thr = contact_distance(table, g1, g2)
    key = min(g1, g2) * table.ngeom + max(g1, g2)
    explicit = key in set(table.pair_key.tolist())
    return min(thr, table.o_margin) if table.override and not explicit else thr


def _posed_shape(table, data, g):
    a, n = table.pts_adr[g], table.pts_num[g]
    b, m = table.nbr_start_adr[g], table.nbr_start_num[g]
    c, e = table.nbr_adr[g], table.nbr_num[g]
    return (int(table.kind[g]), table.prm[g], table.pts[a:a + n], table.nbr_start[b:b + m], table.nbr[c:c + e],
            np.ascontiguousarray(data.geom_xmat[g].reshape(3, 3)), np.ascontiguousarray(data.geom_xpos[g]))


def separation(table, data, g1: int, g2: int, u: np.ndarray) -> float:
    """How far geom ``g2`` lies beyond ``g1`` along unit ``u`` (from g1 to g2): a lower bound of
    their signed distance, equal to it along a witness normal."""
    u = np.asarray(u, float) / np.linalg.norm(u)
    s = np.empty(3)
    vals = []
    for g, d in ((g1, u), (g2, -u)):
        if table.cls[g] == km.PLANE:
            if abs(abs(float(np.dot(data.geom_xmat[g].reshape(3, 3)[:, 2], u))) - 1.0) > 1e-12:
                return -math.inf  # a half-space reaches everywhere but along its normal
            s[:] = data.geom_xpos[g]
            vals.append(float(np.dot(s, d)))
            continue
        support(_posed_shape(table, data, g), d[0], d[1], d[2], -1, s)
        vals.append(float(np.dot(s, d)) + float(table.prm[g, 3]))
    return -(vals[0] + vals[1])


def _inner_points(table, g, samples: int = 512) -> np.ndarray:
    # Points on geom g's surface (geom frame) whose hull lies inside it: the cloud's own points
    # (with its radius added by the caller, `_inner_radius`), a cylinder's rims, an ellipsoid's
    # Fibonacci points.
    kind = int(table.kind[g])
    if kind == 0:
        a, n = table.pts_adr[g], table.pts_num[g]
        return table.pts[a:a + n]
    if kind == CYLINDER:
        return testing.inner_cloud(Cylinder(table.prm[g, 0], table.prm[g, 1]), samples)[0]
    i = np.arange(2 * samples) + 0.5
    z = 1.0 - 2.0 * i / (2 * samples)
    phi = math.pi * (1.0 + 5.0 ** 0.5) * i
    rho = np.sqrt(1.0 - z * z)
    return np.c_[rho * np.cos(phi), rho * np.sin(phi), z] * table.prm[g, :3]


def _inner_radius(table, g) -> float:
    # The ball `_inner_points` leaves to add: a cloud's radius. A cylinder's and an ellipsoid's
    # points are on the true surface already: the ellipsoid's prm[3] is the rolling ball of its
    # core (`collide.support.rolling_radius`), which these points do not shrink by (adding it
    # made hi too low by it, an inverted bracket: the adversarial review of 2026-12-01).
    return float(table.prm[g, 3]) if int(table.kind[g]) == 0 else 0.0


def oracle(table, data, g1: int, g2: int, normals=()) -> tuple[float, float]:
    """Independent bracket ``(lo, hi)`` of the pair's signed distance.

    Two point clouds: the exact value, twice (the Minkowski difference's hull,
    `collide.testing.polytope_signed_distance`); a plane and a cloud: the lowest point. With a
    curved geom: ``hi`` from inner polytopes (points on the true surface: shrinking a set never
    lowers a signed distance), ``lo`` the best separation along ``normals`` (support values of
    the true shapes: `separation`).
    """
    def world(g, pts):
        return pts @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]

    c1, c2 = table.cls[g1], table.cls[g2]
    if km.PLANE in (c1, c2):
        gp, gc = (g1, g2) if c1 == km.PLANE else (g2, g1)
        n = data.geom_xmat[gp].reshape(3, 3)[:, 2]
        hi = float(np.min((world(gc, _inner_points(table, gc)) - data.geom_xpos[gp]) @ n)) - _inner_radius(table, gc)
        if table.kind[gc] == 0:
            return hi, hi
        u = n if gp == g1 else -n
        return separation(table, data, g1, g2, u), hi
    p1, p2 = world(g1, _inner_points(table, g1)), world(g2, _inner_points(table, g2))
    if len(p1) * len(p2) > 20000:
        # Only the points facing the other geom (a subset is still inside: hi stays an upper
        # bound), within a generous band of the extreme along the first normal (or the centres').
        u = np.asarray(normals[0] if len(normals) else data.geom_xpos[g2] - data.geom_xpos[g1], float)
        u = u / (np.linalg.norm(u) or 1.0)
        band = 0.1 * float(table.rbound[g1] + table.rbound[g2])
        p1 = p1[p1 @ u >= np.max(p1 @ u) - band]
        p2 = p2[p2 @ -u >= np.max(p2 @ -u) - band]
    hi = testing.polytope_signed_distance(p1, p2, _inner_radius(table, g1), _inner_radius(table, g2))
    if table.kind[g1] == 0 and table.kind[g2] == 0:
        return hi, hi
    lo = max([separation(table, data, g1, g2, u) for u in normals] or [-math.inf])
    return lo, hi


@dataclass
class Tally:
    """What one scene's comparison found."""

    steps: int = 0
    mj_pairs: int = 0  # MuJoCo's contact pairs, summed over steps
    both: int = 0  # of those, pairs ours made too
    worst_dist: float = 0.0  # worst |ours - MuJoCo| over pairs in both, relative to the pair's tolerance
    worst_normal: float = 0.0  # rad, over non-degenerate pairs
    degenerate: int = 0  # pairs whose normal is not unique (normal not compared)
    skipped: int = 0  # pairs in Contacts.skipped that MuJoCo made a contact for
    boundary: int = 0  # pairs within the tolerance of their contact distance (either answer is right)
    ours_right: list = field(default_factory=list)  # disagreements the oracle settles for ours
    mujoco_right: list = field(default_factory=list)  # ... for MuJoCo's (failures)
    unsettled: list = field(default_factory=list)  # the oracle's bracket holds both answers (curved geoms)
    unchecked: list = field(default_factory=list)  # disagreements past `oracle_budget` (not settled)
    oracle_budget: int = 20  # oracle calls per group (pair kind, what differed) and scene: Qhull on
    # thousands of points, ~0.01-1 s each; the rest of a group is counted as not checked
    spent: dict = field(default_factory=dict)
    seconds: float = 0.0  # wall time of the scene's run
    mj_contacts: int = 0  # MuJoCo's geom-geom contacts, summed over steps
    our_contacts: int = 0  # ours, summed over steps

    def failures(self) -> list:
        return self.mujoco_right


def compare_step(model, data, collider: cm.Collider, tally: Tally, step: int) -> None:
    """Compare our contacts with MuJoCo's on ``data`` (MuJoCo's ``data.contact`` must be for
    the current poses: call after ``mj_forward`` or ``mj_collision``)."""
    table = collider.table
    ours = collider.contacts(data)
    mine = {k: i for k, i in ours.deepest().items()}
    skipped = {tuple(p) for p in ours.skipped.tolist()}
    mj = mujoco_deepest(model, data)
    tally.mj_contacts += int(np.count_nonzero(np.all(data.contact.geom[:data.ncon] >= 0, axis=1)))
    tally.our_contacts += len(ours)
    tally.steps += 1
    tally.mj_pairs += len(mj)

    brackets: dict = {}

    def bracket(g1, g2, normals, what):
        if (g1, g2) not in brackets:
            group = (_kind(model, g1, g2), what)
            if tally.spent.get(group, 0) >= tally.oracle_budget:
                return None
            tally.spent[group] = tally.spent.get(group, 0) + 1
            brackets[(g1, g2)] = oracle(table, data, g1, g2, normals)
        return brackets[(g1, g2)]

    def settle(key, what, mj_d, our_d, normals=()):
        # who is right: the value inside the oracle's bracket (within the pair's tolerance)
        g1, g2 = key
        b = bracket(g1, g2, normals, what)
        if b is None:
            tally.unchecked.append((step, g1, g2, what, mj_d, our_d))
            return
        lo, hi = b
        tol = pair_tolerance(model, g1, g2)
        row = (step, g1, g2, what, mj_d, our_d, (lo, hi))

        def inside(d):
            return lo - tol <= d <= hi + tol

        thr = contact_distance(table, g1, g2)[1]
        ours_ok = inside(our_d) if our_d is not None else lo > thr - tol
        mj_ok = inside(mj_d) if mj_d is not None else hi > undecided_from(table, g1, g2) - tol
        if ours_ok and not mj_ok:
            tally.ours_right.append(row)
        elif mj_ok and not ours_ok:
            tally.mujoco_right.append(row)
        elif not ours_ok:
            tally.mujoco_right.append(row)  # neither: a failure of ours all the same
        else:
            tally.unsettled.append(row)  # the bracket holds both

    for key, (d_mj, n_mj, _) in mj.items():
        g1, g2 = key
        tol = pair_tolerance(model, g1, g2)
        if key in skipped:
            tally.skipped += 1
            continue
        i = mine.get(key)
        if i is None:
            if d_mj > contact_distance(table, g1, g2)[1] - tol:
                tally.boundary += 1
            else:
                # our witness direction certifies a lower bound (the support values along it)
                _, ft = collider.geom_distance(data, g1, g2, 1e300)
                u = ft[3:] - ft[:3]
                settle(key, "missed", d_mj, None, (u,) if np.linalg.norm(u) > 0 else ())
            continue
        tally.both += 1
        d = float(ours.dist[i])
        err = abs(d - d_mj)
        if err > tol:
            settle(key, "dist", d_mj, d, (ours.normal[i], n_mj))
        else:
            tally.worst_dist = max(tally.worst_dist, err / tol)
        ang = math.acos(min(1.0, max(-1.0, float(np.dot(ours.normal[i], n_mj)))))
        if ang > NORMAL_TOL:
            # both normals are witnesses when each separates the pair as far as the distance
            if separation(table, data, g1, g2, n_mj) >= min(d, d_mj) - tol:
                tally.degenerate += 1
            else:
                # MuJoCo's normal is no witness (it separates the pair less than the distance):
                # ours is right if it is one, at the true distance
                b = bracket(g1, g2, (ours.normal[i], n_mj), "normal")
                if b is None:
                    tally.unchecked.append((step, g1, g2, f"normal {ang:.3g} rad", d_mj, d))
                    continue
                lo, hi = b
                row = (step, g1, g2, f"normal {ang:.3g} rad", d_mj, d, (lo, hi))
                sep = separation(table, data, g1, g2, ours.normal[i])
                if lo - tol <= d <= hi + tol and sep >= d - tol:
                    tally.ours_right.append(row)
                else:
                    tally.mujoco_right.append(row)
        elif err <= tol:
            tally.worst_normal = max(tally.worst_normal, ang)
    for key, i in mine.items():
        if key in mj:
            continue
        g1, g2 = key
        tol = pair_tolerance(model, g1, g2)
        if float(ours.dist[i]) > undecided_from(table, g1, g2) - tol:
            tally.boundary += 1
        else:
            settle(key, "extra", None, float(ours.dist[i]))


def load_scene(name: str):
    """A model by folder name in ../shared/models, or ``"default"``: `collide.mujoco.default_scene`."""
    if name == "default":
        return cm.default_scene()
    return mujoco.MjModel.from_xml_path(str(MODELS / name / "scene.xml"))


def run_scene(model, steps: int, seed: int = 0, data=None, hold: int = 100, oracle_budget: int = 20) -> Tally:
    """Simulate ``model`` with `collide.mujoco.compare`'s random controls (each actuator at one
    end of its range, redrawn every ``hold`` steps) and compare every step."""
    data = mujoco.MjData(model) if data is None else data
    collider = cm.Collider(model)
    ctrls = cm._random_controls(model, steps, seed, hold)
    tally = Tally(oracle_budget=oracle_budget)
    mujoco.mj_forward(model, data)
    for step in range(steps):
        if step % hold == 0 and len(ctrls):
            data.ctrl[:] = ctrls[step // hold]
        mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)  # data.contact for the poses after the step
        compare_step(model, data, collider, tally, step)
    return tally


_TYPES = ["plane", "hfield", "sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh", "sdf"]


def _kind(model, g1: int, g2: int) -> str:
    a, b = sorted((int(model.geom_type[g1]), int(model.geom_type[g2])))
    return f"{_TYPES[a]}-{_TYPES[b]}"


def _what(row) -> str:
    return row[3].split()[0]  # dist, normal, missed, extra


def report(name: str, model, t: Tally, examples: int = 3) -> list:
    """Lines of the report for one scene: the figures, then the disagreements by verdict, pair
    kind and what differed, with up to ``examples`` rows each (step, geoms, MuJoCo's dist,
    ours, the oracle's bracket)."""
    out = [f"{name:20s} {t.steps:5d} {t.mj_pairs:8d} {t.both:8d} {t.boundary:5d} {t.skipped:4d} "
           f"{t.worst_dist:9.3g} {t.worst_normal:9.2e} {t.degenerate:6d} {len(t.ours_right):6d} "
           f"{len(t.mujoco_right):6d} {len(t.unsettled):6d} {len(t.unchecked):6d} {t.mj_contacts:8d} "
           f"{t.our_contacts:8d} {t.seconds:6.0f}"]
    detail = []
    for verdict, rows in (("MuJoCo right (our failure)", t.mujoco_right), ("ours right", t.ours_right),
                          ("unsettled (the bracket holds both)", t.unsettled), ("not checked", t.unchecked)):
        groups: dict = {}
        for row in rows:
            groups.setdefault((_kind(model, row[1], row[2]), _what(row)), []).append(row)
        for (kind, what), rs in sorted(groups.items(), key=lambda kv: -len(kv[1])):
            detail.append(f"    {verdict}: {len(rs)} x {kind} {what}")
            for row in rs[:examples]:
                step, g1, g2, w, d_mj, d_us = row[:6]
                br = f" oracle [{row[6][0]:.10g}, {row[6][1]:.10g}]" if len(row) > 6 else ""
                fm = "none" if d_mj is None else f"{d_mj:.10g}"
                fo = "none" if d_us is None else f"{d_us:.10g}"
                detail.append(f"        step {step} geoms {g1},{g2} {w}: MuJoCo {fm} ours {fo}{br}")
    return out + detail


HEADER = ("scene                steps  mj-pairs     both bound skip  dist/tol    normal  degen  ours+ "
          "   mj+ unsett unchkd   mj-con  our-con      s")


def main(argv=None) -> int:
    import argparse
    import os
    import platform

    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--oracle", type=int, default=20, help="oracle calls per scene (the rest: not checked)")
    ap.add_argument("scenes", nargs="*")
    a = ap.parse_args(argv)
    scenes = a.scenes or ["default"] + sorted(p.name for p in MODELS.iterdir() if (p / "scene.xml").is_file())
    cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name")),
               platform.processor()) if os.path.exists("/proc/cpuinfo") else platform.processor()
    print(f"# contact agreement, collide vs MuJoCo {mujoco.__version__}: python tests/contact_check.py "
          f"{' '.join(argv if argv is not None else sys.argv[1:])}")
    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {cpu}, {os.cpu_count()} cores; load "
          f"average {os.getloadavg()[0]:.1f} at start; controls as collide.mujoco.compare (seed 0, hold 100)")
    print("# per scene: MuJoCo's contact pairs over the steps, those ours made too, boundary (within the "
          "tolerance of the contact distance: either answer right), skipped (height field / SDF), worst "
          "|dist| difference / tolerance and worst normal angle (rad) over agreeing pairs, degenerate "
          "normals (both witnesses), disagreements the oracle settled for ours / for MuJoCo, unsettled, not "
          "checked; contact counts (multi-contact) MuJoCo's and ours; seconds")
    print(HEADER)
    bad = 0
    details = []
    for s in scenes:
        model = load_scene(s)
        t0 = time.perf_counter()
        t = run_scene(model, a.steps, oracle_budget=a.oracle)
        t.seconds = time.perf_counter() - t0
        lines = report(s, model, t)
        print(lines[0], flush=True)
        details += [s] + lines[1:]
        bad += len(t.failures())
    print("\n# disagreements (beyond the pair's tolerance), by verdict of the oracle, pair kind and what differed")
    print("\n".join(details))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
