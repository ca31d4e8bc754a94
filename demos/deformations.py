"""Demo: the paper's nonlinear deformations (§3.2) with a guarantee, and swept bounds.

    python demos/deformations.py [--out demos/output]

Writes two figures:

- ``deformations.png``: a bar (a box cloud) bent, twisted and tapered (Barr 1984,
  `collide.deformations`). Grey points: a dense sample of the truly deformed set; the wire frame:
  the hull of the cloud `collide.deform` returns (its radius shown by the title), which contains
  every deformed point; "before" shows the bar and its cloud's hull.
- ``swept.png``: one simulator step, seen from above: a rod turning by 179 degrees beside a small
  block, and a ball fired through a thin wall. The single-step broad phase (`BroadPhase.pairs`) at
  the step's two ends misses both contacts; `BroadPhase.pairs_swept` finds both (its candidate
  pairs are printed and drawn).

Prints each deformation's tightness (the volume of the returned set over that of the hull of the
deformed sample) and checks containment of the sample.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import collide
from collide import deformations, shapes
from collide.testing import cloud_volume, deformed_sample, signed_excess
from collide.testing.swept import motion_poses


def _hull_edges(points: np.ndarray):
    from scipy.spatial import ConvexHull
    h = ConvexHull(points)
    edges = set()
    for tri in h.simplices:
        for i in range(3):
            a, b = sorted((int(tri[i]), int(tri[(i + 1) % 3])))
            edges.add((a, b))
    return [points[[a, b]] for a, b in edges]


def deformation_figure(out: Path, rng: np.random.Generator) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.spatial import ConvexHull

    bar = shapes.box([0.15, 0.3, 1.0]).transform(np.eye(3), [0.0, 0.0, 1.0])  # z from 0 to 2
    maps = [("before", None), ("bend(0.6)", deformations.bend(0.6)), ("twist(1.2)", deformations.twist(1.2)),
            ("taper(-0.35)", deformations.taper(-0.35))]
    fig = plt.figure(figsize=(16, 5))
    for i, (name, f) in enumerate(maps):
        ax = fig.add_subplot(1, 4, i + 1, projection="3d")
        if f is None:
            cloud, sample = bar, deformed_sample(bar, lambda p: p, 4000, rng)
        else:
            cloud = collide.deform(bar, f, tolerance=1e-3)
            sample = deformed_sample(bar, f, 4000, rng)
            worst = float(signed_excess(sample, cloud).max())  # > 0: a deformed point outside the bound
            tight = cloud_volume(cloud) / ConvexHull(sample).volume
            print(f"{name:14s} cloud: {len(cloud.points):5d} points, radius {cloud.radius:.2e}; volume over the "
                  f"sample's hull {tight:.3f}; the sample point nearest its boundary {-worst:.2e} inside")
            if worst > 0.0:
                sys.exit(f"deformations.py: a deformed point lies {worst:.3g} outside the bound (a bug: report it)")
        ax.scatter(*sample.T, s=1, c="0.6", alpha=0.5)
        for e in _hull_edges(np.asarray(cloud.points)):
            ax.plot(*e.T, color="tab:blue", lw=0.4)
        ax.set_title(f"{name}\nradius {cloud.radius:.1e}" if f is not None else "before")
        ax.set_box_aspect((1, 1, 1))
        mid = 0.5 * (sample.min(0) + sample.max(0))
        half = 0.55 * float((sample.max(0) - sample.min(0)).max())
        ax.set_xlim(mid[0] - half, mid[0] + half)
        ax.set_ylim(mid[1] - half, mid[1] + half)
        ax.set_zlim(mid[2] - half, mid[2] + half)
    fig.suptitle("collide.deform: the hull of the returned cloud (blue) holds every deformed point (grey)")
    fig.tight_layout()
    fig.savefig(out / "deformations.png", dpi=110)
    plt.close(fig)


def swept_scene():
    """A rod turning 179 degrees about z beside a block; a ball through a thin wall; one step."""
    from scipy.spatial.transform import Rotation
    art = collide.Articulation(
        body_parent=[0, 0, 0, 0], geom_body=[0, 1, 2, 3],
        geom_cloud=[shapes.box([0.02, 1.0, 1.0]), shapes.capsule(0.03, 1.0), shapes.box([0.1, 0.1, 0.1]),
                    shapes.sphere(0.06)],
        geom_pos=[[5.0, 0.0, 0.0], [0, 0, 0], [0, 0, 0], [0, 0, 0]])
    along_x = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    p0 = np.array([[0, 0, 0], [0, 0, 0], [0, 0.95, 0], [3.5, -0.3, 0]], float)
    r0 = np.tile(np.eye(3), (4, 1, 1))
    r0[1] = along_x
    p1 = p0.copy()
    p1[3] = [6.5, -0.3, 0]
    r1 = r0.copy()
    r1[1] = Rotation.from_euler("z", 179, degrees=True).as_matrix() @ along_x
    return art, p0, r0, p1, r1


def swept_figure(out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    art, p0, r0, p1, r1 = swept_scene()
    bp = collide.BroadPhase(art)
    ends = {tuple(r) for r in bp.pairs(p0, r0).tolist()} | {tuple(r) for r in bp.pairs(p1, r1).tolist()}
    swept = {tuple(r) for r in bp.pairs_swept(p0, r0, p1, r1).tolist()}
    names = ["wall", "rod", "block", "ball"]
    print("single step at both ends:", sorted(ends) or "no pairs")
    print("pairs_swept over the step:", [f"{names[a]}-{names[b]}" for a, b in sorted(swept)])
    s = np.linspace(0, 1, 9)
    pos, rot = motion_poses(p0, r0, p1, r1, s)
    fig, ax = plt.subplots(figsize=(9, 4.5))
    for t in range(len(s)):
        alpha = 0.25 + 0.75 * (t in (0, len(s) - 1))
        d = rot[t, 1] @ np.array([0, 0, 1.0])  # the capsule's axis
        ax.plot([-d[0], d[0]], [-d[1], d[1]], color="tab:blue", lw=3, alpha=alpha)
        ax.add_patch(plt.Circle(pos[t, 3, :2], 0.06, color="tab:red", alpha=alpha))
    ax.add_patch(plt.Rectangle((-0.1, 0.85), 0.2, 0.2, color="tab:green"))
    ax.add_patch(plt.Rectangle((4.98, -1.0), 0.04, 2.0, color="0.3"))
    ax.set_aspect("equal")
    ax.set_xlim(-1.3, 7.0)
    ax.set_ylim(-1.2, 1.3)
    found = ", ".join(f"{names[a]}-{names[b]}" for a, b in sorted(swept))
    ax.set_title(f"one step, seen from above (faint: times in between)\nBroadPhase.pairs at both ends: "
                 f"{'none' if not ends else sorted(ends)}; pairs_swept: {found}")
    fig.tight_layout()
    fig.savefig(out / "swept.png", dpi=110)
    plt.close(fig)
    if not {(1, 2), (0, 3)} <= swept:
        sys.exit("deformations.py: pairs_swept missed a pair (a bug: please report it)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "output"))
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    deformation_figure(out, np.random.default_rng(0))
    swept_figure(out)
    print(f"wrote {out / 'deformations.png'} and {out / 'swept.png'}")


if __name__ == "__main__":
    main()
