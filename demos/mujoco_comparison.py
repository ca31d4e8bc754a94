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
   rendered image of the last step with our OBBs drawn into the scene: orange for geoms in one of
   our candidate pairs, blue for the others. Without a backend it still writes the plot.
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


def render_with_obbs(renderer: mujoco.Renderer, bp: cm.BroadPhase, data, candidates) -> np.ndarray:
    """One frame of ``data`` with our world OBBs added to the scene as translucent boxes."""
    renderer.update_scene(data, camera=-1)
    scene = renderer.scene
    in_pair = np.zeros(bp.articulation.geom_count, bool)
    in_pair[np.asarray(candidates, dtype=np.int64).ravel()] = True
    wb = bp.world_bounds(data)  # every geom's world OBB and sphere, inflated: what pairs() tests
    for g in np.flatnonzero(~bp.articulation.geom_is_plane):
        c, r, h = wb.obb_center[g], wb.obb_rot[g], wb.obb_half[g]
        if scene.ngeom >= scene.maxgeom:
            break
        rgba = np.array([1.0, 0.55, 0.0, 0.35] if in_pair[g] else [0.2, 0.5, 1.0, 0.18])
        mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_BOX, h, c,
                            r.ravel(), rgba.astype(np.float32))
        scene.ngeom += 1
    return renderer.render()


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

    def on_step(step, data, candidates):
        if renderer is not None and step == args.steps - 1:
            frame["image"] = render_with_obbs(renderer, bp, data, candidates)

    result = cm.compare(model, steps=args.steps, seed=args.seed, name=name, broadphase=bp,
                        on_step=on_step)

    # 4. Report, plot, image.
    print(cm.format_report(result))
    plot = out / "mujoco_comparison.png"
    cm.plot_comparison(result, plot)
    print(f"\nwrote {plot}")
    if "image" in frame:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        path = out / "mujoco_scene_obbs.png"
        plt.imsave(path, frame["image"])
        print(f"wrote {path} (our OBBs: orange = in a candidate pair, blue = not)")
    else:
        # A backend chosen but unusable needs its library, not the advice to choose one.
        hint = (f"install lib{_GL_LIBRARY} (see the README)" if _GL_LIBRARY
                else "set MUJOCO_GL=egl or MUJOCO_GL=osmesa (see the README) to get one")
        print(f"no rendered image: no OpenGL backend ({why}); {hint}")
    return 0 if not result["missed"] else 1


if __name__ == "__main__":
    sys.exit(main())
