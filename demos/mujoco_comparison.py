"""collide next to MuJoCo, step by step: the script a new user reads first.

    python demos/mujoco_comparison.py [MODEL.xml] [--steps N] [--seed S] [--out DIR]

What it does:

1. builds a MuJoCo model: the built-in scene (an articulated figure falling onto a pile of random
   convex meshes and primitives, made in code with ``mujoco.MjSpec``) or your MJCF file;
2. builds our broad phase from it once: ``collide.mujoco.BroadPhase(model)`` turns every geom into
   a hull-tight point cloud with local OBB and sphere, and MuJoCo's collision filter into ours;
3. simulates with random controls; every step, on the state MuJoCo just collided, calls
   ``bp.pairs(data)`` and checks that every contact MuJoCo generated is among our candidates;
4. prints the table (the same as ``python -m collide compare``), writes a per-step plot, and,
   when an OpenGL backend is available (``MUJOCO_GL=egl`` or ``osmesa``, see the README), a
   rendered image of the last step, the camera framed on the model: our OBBs drawn as outlines
   (orange for geoms in one of our candidate pairs, blue for the others), MuJoCo's contacts and
   ours, any missed pair in red; a title and a legend in the image. Without a backend it still
   writes the plot. To scrub through every step instead, record the run to Rerun:
   ``python -m collide compare MODEL.xml --rerun run.rrd`` (docs/visualising.md).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

# Headless Linux (no X display) and no backend chosen: try EGL, which works with a GPU driver or
# Mesa alone; MuJoCo reads MUJOCO_GL when it is imported. Any failure later only drops the image.
if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
    os.environ.setdefault("MUJOCO_GL", "egl")
# A backend whose library is missing makes `import mujoco` itself fail (PyOpenGL finds no GL):
# switch rendering off instead, so the comparison and the plot still happen.
_GL_LIBRARY = {"egl": "EGL", "osmesa": "OSMesa"}.get(os.environ.get("MUJOCO_GL", "").lower())
if _GL_LIBRARY:
    import ctypes.util

    if ctypes.util.find_library(_GL_LIBRARY) is None:
        print(f"note: MUJOCO_GL={os.environ['MUJOCO_GL']} but lib{_GL_LIBRARY} is not installed; "
              "rendering is off (see the README)")
        os.environ["MUJOCO_GL"] = "disable"

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import collide.mujoco as cm  # noqa: E402


# Colours of the rendered image, named in its legend.
IN_PAIR = (1.0, 0.5, 0.0, 1.0)        # our OBB of a geom in one of our candidate pairs
NOT_IN_PAIR = (0.4, 0.7, 1.0, 0.9)    # our OBB of a geom in none
MUJOCO_CONTACT = (0.1, 0.3, 1.0, 1.0)
OUR_CONTACT = (0.1, 0.85, 0.3, 0.45)
MISSED = (0.9, 0.0, 0.0, 1.0)         # a MuJoCo contact pair missing from our candidates
_EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]  # a box's 12


def frame_camera(bp: cm.BroadPhase, data) -> mujoco.MjvCamera:
    """A free camera looking at the collidable geoms' world AABB (planes left out), from a
    distance that fits it in a 45-degree field of view (MuJoCo's default ``fovy``)."""
    wb = bp.world_bounds(data, inflate=False)
    solid = ~bp.articulation.geom_is_plane & np.all(np.isfinite(wb.aabb_min), axis=1)
    lo, hi = wb.aabb_min[solid].min(axis=0), wb.aabb_max[solid].max(axis=0)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)
    cam.distance = 0.9 * radius / np.sin(np.radians(45.0 / 2))  # about the bounding ball in the view
    cam.azimuth, cam.elevation = 135.0, -30.0
    return cam


def _add(scene, gtype, size, pos, mat, rgba, emission: float = 0.0) -> None:
    if scene.ngeom < scene.maxgeom:
        geom = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(geom, gtype, np.asarray(size, float), np.asarray(pos, float),
                            np.asarray(mat, float).ravel(), np.asarray(rgba, np.float32))
        # No highlight: the legend's colours should be the image's.
        geom.emission, geom.specular, geom.shininess = emission, 0.0, 0.0
        scene.ngeom += 1


def _line(scene, a, b, rgba, width: float) -> None:
    if scene.ngeom < scene.maxgeom:
        # Lines take about twice their colour from the lights (orange came out yellow): halved here.
        dim = (rgba[0] / 2, rgba[1] / 2, rgba[2] / 2, rgba[3])
        _add(scene, mujoco.mjtGeom.mjGEOM_LINE, [1, 1, 1], [0, 0, 0], np.eye(3), dim)
        mujoco.mjv_connector(scene.geoms[scene.ngeom - 1], mujoco.mjtGeom.mjGEOM_LINE, width, a, b)


def render_with_obbs(renderer: mujoco.Renderer, bp: cm.BroadPhase, data, candidates, camera,
                     contacts=None) -> np.ndarray:
    """One frame of ``data`` with our world OBBs drawn as outlines (the robot stays visible),
    MuJoCo's contact points, ours (``contacts``: a `collide.Contacts`), and any MuJoCo contact
    pair missing from ``candidates`` as a red line between the two geoms."""
    option = mujoco.MjvOption()
    option.geomgroup[:] = 1  # every group: Menagerie's collision geoms are in group 3, hidden by default
    renderer.update_scene(data, camera=camera, scene_option=option)
    scene = renderer.scene
    in_pair = np.zeros(bp.articulation.geom_count, bool)
    in_pair[np.asarray(candidates, dtype=np.int64).ravel()] = True
    wb = bp.world_bounds(data)  # every geom's world OBB, inflated: what pairs() tests
    signs = np.array([[(k >> i & 1) * 2 - 1 for i in range(3)] for k in range(8)], float)
    for g in np.flatnonzero(~bp.articulation.geom_is_plane):
        corners = wb.obb_center[g] + (signs * wb.obb_half[g]) @ wb.obb_rot[g].T
        for a, b in _EDGES:
            _line(scene, corners[a], corners[b], IN_PAIR if in_pair[g] else NOT_IN_PAIR,
                  2.5 if in_pair[g] else 1.5)
    dot = 0.012 * renderer_extent(bp, data)
    # MuJoCo's contacts solid, ours a larger translucent ball around the point: both show where they agree.
    for i in range(data.ncon):
        _add(scene, mujoco.mjtGeom.mjGEOM_SPHERE, [0.6 * dot, 0, 0], data.contact.pos[i], np.eye(3), MUJOCO_CONTACT,
             emission=0.5)
    if contacts is not None:
        for p in contacts.pos:
            _add(scene, mujoco.mjtGeom.mjGEOM_SPHERE, [dot, 0, 0], p, np.eye(3), OUR_CONTACT, emission=0.5)
    ours = {tuple(p) for p in np.asarray(candidates).tolist()}
    for g1, g2 in cm.contact_pairs(bp.model, data).tolist():
        if (g1, g2) not in ours:
            _line(scene, data.geom_xpos[g1], data.geom_xpos[g2], MISSED, 6.0)
    return renderer.render()


def renderer_extent(bp: cm.BroadPhase, data) -> float:
    """The size of the collidable geoms' world AABB (planes left out): the scale of the markers."""
    wb = bp.world_bounds(data, inflate=False)
    solid = ~bp.articulation.geom_is_plane & np.all(np.isfinite(wb.aabb_min), axis=1)
    return float(np.linalg.norm(wb.aabb_max[solid].max(axis=0) - wb.aabb_min[solid].min(axis=0)))


def save_figure(image: np.ndarray, path: Path, title: str) -> None:
    """The rendered frame with its title and a legend of the colours, as a PNG (matplotlib)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    h, w = image.shape[:2]
    fig = plt.figure(figsize=(w / 100, h / 100 + 0.9), dpi=100)
    ax = fig.add_axes([0, 0, 1, h / (h + 90)])
    ax.imshow(image)
    ax.set_axis_off()
    fig.suptitle(title, y=0.985, fontsize=11)
    handles = [Line2D([], [], color=IN_PAIR, lw=2.5, label="our OBB, geom in a candidate pair"),
               Line2D([], [], color=NOT_IN_PAIR, lw=1.5, label="our OBB, geom in no pair"),
               Line2D([], [], color=MUJOCO_CONTACT, marker="o", ls="", ms=4, label="MuJoCo contact"),
               Line2D([], [], color=OUR_CONTACT, marker="o", ls="", ms=8, label="our contact (translucent)"),
               Line2D([], [], color=MISSED, lw=3, label="pair MuJoCo touched, not our candidate")]
    fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 1 - 30 / (h + 90)), ncol=3,
               fontsize=8.5, frameon=False)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def make_renderer(model: mujoco.MjModel):
    """A ``mujoco.Renderer``, or ``None`` with the reason when no OpenGL backend is available."""
    try:
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, 960)
        model.vis.global_.offheight = max(model.vis.global_.offheight, 720)
        return mujoco.Renderer(model, 720, 960, max_geom=20000), None
    except Exception as exc:  # no display, no EGL/OSMesa: any failure means "no image"
        return None, f"{type(exc).__name__}: {exc}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("model", nargs="?", help="MJCF file (default: the built-in scene)")
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="out", help="folder for the images (default: out/, git-ignored)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    # 1. The model.
    if args.model:
        try:
            model, name = cm.load_model(args.model)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
    else:
        model = cm.default_scene(seed=args.seed)
        name = "built-in scene"

    # 2. Our broad phase, built once per model.
    bp = cm.BroadPhase(model)
    print(f"{name}: {model.nbody} bodies, {model.ngeom} geoms -> {bp.articulation}")

    # 3. Simulate and compare; render the last step if we can.
    renderer, why = make_renderer(model)
    frame = {}

    collider = cm.Collider(model)  # our contacts, drawn beside MuJoCo's

    def on_step(step, data, candidates):
        if renderer is not None and step == args.steps - 1:
            frame["image"] = render_with_obbs(renderer, bp, data, candidates, frame_camera(bp, data),
                                              collider.contacts(data))
            frame["counts"] = (len(candidates), data.ncon, step)

    result = cm.compare(model, steps=args.steps, seed=args.seed, name=name, broadphase=bp,
                        on_step=on_step)

    # 4. Report, plot, image.
    print(cm.format_report(result))
    plot = out / "mujoco_comparison.png"
    cm.plot_comparison(result, plot)
    print(f"\nwrote {plot}")
    if "image" in frame:
        path = out / "mujoco_scene_obbs.png"
        pairs, ncon, step = frame["counts"]
        save_figure(frame["image"], path, f"{name}, step {step}: {pairs} candidate pairs, {ncon} MuJoCo "
                    f"contacts; recall {100 * result['recall']:.2f} % over {result['steps']} steps")
        print(f"wrote {path} (title and legend in the image)")
    else:
        # A backend chosen but unusable needs its library, not the advice to choose one.
        hint = (f"install lib{_GL_LIBRARY} (see the README)" if _GL_LIBRARY
                else "set MUJOCO_GL=egl or MUJOCO_GL=osmesa (see the README) to get one")
        print(f"no rendered image: no OpenGL backend ({why}); {hint}")
    return 0 if not result["missed"] else 1


if __name__ == "__main__":
    sys.exit(main())
