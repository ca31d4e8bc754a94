"""Which configurations of a manipulator are free, and by how much: many collision checks in one call.

    python demos/motion_planning.py [MODEL.xml] [--configs N | --full] [--seed S] [--out DIR]

What it does:

1. builds a MuJoCo model: a five-joint arm of capsules on a fixed base among random obstacles
   (boxes, spheres, cylinders) on a floor, made in code; or your MJCF file;
2. samples configurations uniformly inside the joint limits (``--configs``, default 5,000, small
   enough for a quick run; ``--full``: the issue's 100,000);
3. checks them all in one call, ``collide.mujoco.Collider(model).check_batch(qpos, distance=True)``:
   ``in_collision`` (a contact as MuJoCo would make one), ``min_distance`` and ``closest`` (the
   closest pair that passes MuJoCo's filters); and the robot against the world alone, a
   ``Collider(model, bodies=(robot, world))`` (a subset chosen once);
4. keeps the free configurations, prints the fraction free and the time per configuration, and
   writes under ``--out`` (demos/output by default) ``motion_planning_stats.png`` (the fraction
   free, overall and against the world only, and the distribution of clearance of the free ones)
   and ``motion_planning_configs.png`` (three free and three colliding configurations drawn from
   their geoms' point clouds, the closest pair's nearest points joined in red).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

import collide.mujoco as cm
from collide import testing

ROOT = Path(__file__).resolve().parent


def arm_scene(seed: int = 0, obstacles: int = 8) -> mujoco.MjModel:
    """A five-joint arm of capsules on a fixed base, with random obstacles around it on a floor."""
    rng = np.random.default_rng(seed)
    obs = []
    for i in range(obstacles):
        ang = rng.uniform(0, 2 * np.pi)
        r = rng.uniform(0.35, 0.7)
        x, y, z = r * np.cos(ang), r * np.sin(ang), rng.uniform(0.05, 0.7)
        kind = ("box", "sphere", "cylinder")[i % 3]
        size = {"box": f"{rng.uniform(.04, .12):.3f} {rng.uniform(.04, .12):.3f} {rng.uniform(.04, .2):.3f}",
                "sphere": f"{rng.uniform(.05, .12):.3f}",
                "cylinder": f"{rng.uniform(.03, .08):.3f} {rng.uniform(.05, .2):.3f}"}[kind]
        obs.append(f'<geom name="obstacle{i}" type="{kind}" size="{size}" pos="{x:.3f} {y:.3f} {z:.3f}" '
                   f'euler="{rng.uniform(0, 1.5):.2f} {rng.uniform(0, 1.5):.2f} 0" rgba=".8 .5 .2 1"/>')
    xml = f"""
<mujoco model="arm among obstacles">
  <compiler angle="radian"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 .1"/>
    {''.join(obs)}
    <body name="base" pos="0 0 0.05">
      <geom name="base" type="cylinder" size=".08 .05"/>
      <body name="link1" pos="0 0 .05">
        <joint name="j1" axis="0 0 1" range="-3.14 3.14"/>
        <geom type="capsule" fromto="0 0 .06 0 0 .3" size=".045"/>
        <body name="link2" pos="0 0 .3">
          <joint name="j2" axis="0 1 0" range="-2 2"/>
          <geom type="capsule" fromto="0 0 0 .3 0 0" size=".04"/>
          <body name="link3" pos=".3 0 0">
            <joint name="j3" axis="0 1 0" range="-2.6 2.6"/>
            <geom type="capsule" fromto="0 0 0 .25 0 0" size=".035"/>
            <body name="link4" pos=".25 0 0">
              <joint name="j4" axis="1 0 0" range="-3 3"/>
              <geom type="capsule" fromto="0 0 0 .08 0 0" size=".03"/>
              <body name="hand" pos=".08 0 0">
                <joint name="j5" axis="0 1 0" range="-2 2"/>
                <geom type="box" size=".03 .06 .02" pos=".03 0 0"/>
                <geom type="capsule" fromto=".06 .04 0 .12 .04 0" size=".012"/>
                <geom type="capsule" fromto=".06 -.04 0 .12 -.04 0" size=".012"/>
              </body>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <contact><exclude body1="base" body2="link1"/></contact>
</mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def robot_and_world(model: mujoco.MjModel) -> tuple[list, list]:
    """Bodies that joints move (the robot) and the others (the world, static bodies)."""
    moved = np.zeros(model.nbody, bool)
    for b in range(1, model.nbody):
        moved[b] = model.body_jntnum[b] > 0 or moved[model.body_parentid[b]]
    return np.flatnonzero(moved).tolist(), np.flatnonzero(~moved).tolist()


def _world_points(model, data, clouds, g):
    c = clouds[g]
    if not hasattr(c, "points"):
        return None  # a plane
    return data.geom_xpos[g] + c.points @ data.geom_xmat[g].reshape(3, 3).T, float(c.radius)


def draw_config(ax, model, data, clouds, col, q, closest, title):
    """The geoms of ``q`` as point clouds, the closest pair's nearest points joined in red."""
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    robot, _ = robot_and_world(model)
    for g in range(model.ngeom):
        wp = _world_points(model, data, clouds, g)
        if wp is None:
            continue
        pts, r = wp
        on_robot = model.geom_bodyid[g] in robot
        ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=8 + 2000 * r, alpha=0.35,
                   color="tab:blue" if on_robot else "tab:orange", depthshade=False)
        if len(pts) == 2:  # a capsule's segment
            ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], color="tab:blue", lw=2 + 60 * r, alpha=0.5)
    g1, g2 = (int(x) for x in closest)
    if g1 >= 0:
        d, ft = col.geom_distance(data, g1, g2, 10.0)
        ax.plot([ft[0], ft[3]], [ft[1], ft[4]], [ft[2], ft[5]], color="red", lw=2.5)
        ax.scatter([ft[0], ft[3]], [ft[1], ft[4]], [ft[2], ft[5]], color="red", s=25)
        title += f"\nclosest: geoms {g1}, {g2}, {d * 1000:.1f} mm"
    ax.set_title(title, fontsize=8)
    ax.set_xlim(-0.8, 0.8)
    ax.set_ylim(-0.8, 0.8)
    ax.set_zlim(0, 1.2)
    ax.set_box_aspect((1, 1, 0.75))
    ax.tick_params(labelsize=5)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model", nargs="?", help="an MJCF file (default: the arm among obstacles, made in code)")
    ap.add_argument("--configs", type=int, default=5000)
    ap.add_argument("--full", action="store_true", help="100,000 configurations (the issue's run)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=str(ROOT / "output"))
    a = ap.parse_args(argv)
    n = 100_000 if a.full else a.configs
    if a.model:
        model, name = cm.load_model(a.model)
    else:
        model, name = arm_scene(a.seed), "arm among obstacles"
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    robot, world = robot_and_world(model)
    q = testing.random_configurations(model, n, np.random.default_rng(a.seed))

    col = cm.Collider(model)
    col.check_batch(q[:8])  # the first calls compile or load the kernels (one set each way)
    col.check_batch(q[:8], distance=True)
    t0 = time.perf_counter()
    res = col.check_batch(q)
    t_check = time.perf_counter() - t0
    t0 = time.perf_counter()
    resd = col.check_batch(q, distance=True, distmax=1.0)
    t_dist = time.perf_counter() - t0
    vs_world = cm.Collider(model, bodies=(robot, world)).check_batch(q)

    free = ~res.in_collision
    print(f"{name}: {n} configurations, {free.mean():.1%} free ({(~vs_world.in_collision).mean():.1%} "
          f"against the world alone); check_batch {t_check / n * 1e6:.2f} us a configuration, "
          f"with distances {t_dist / n * 1e6:.2f} us")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    fr = [free.mean(), (~vs_world.in_collision).mean()]
    a1.bar(["all pairs", "robot vs world"], fr, color=["tab:blue", "tab:orange"])
    for i, v in enumerate(fr):
        a1.text(i, v, f"{v:.1%}", ha="center", va="bottom")
    a1.set_ylim(0, 1)
    a1.set_ylabel("fraction of configurations free")
    a1.set_title(f"{n} configurations inside the joint limits")
    clearance = resd.min_distance[free & np.isfinite(resd.min_distance)]
    a2.hist(clearance * 1000, bins=60, color="tab:green")
    a2.set_xlabel("clearance of the free configurations (mm): min_distance")
    a2.set_ylabel("configurations")
    a2.set_title("distance of the closest filtered pair")
    fig.suptitle(f"{name}: check_batch {t_check / n * 1e6:.2f} us a configuration")
    fig.tight_layout()
    fig.savefig(out / "motion_planning_stats.png", dpi=120)
    plt.close(fig)

    data = mujoco.MjData(model)
    clouds = cm.geom_clouds(model)
    fi = np.flatnonzero(free)
    ci = np.flatnonzero(~free)
    pick_free = fi[np.argsort(resd.min_distance[fi])[[0, len(fi) // 2, -1]]] if len(fi) >= 3 else fi
    pick_col = ci[:3]
    fig = plt.figure(figsize=(12, 7))
    for k, (i, label) in enumerate([(i, "free") for i in pick_free] + [(i, "in collision") for i in pick_col]):
        ax = fig.add_subplot(2, 3, k + 1, projection="3d")
        draw_config(ax, model, data, clouds, col, q[i], resd.closest[i], f"configuration {i}: {label}")
    fig.suptitle(f"{name}: free (top: least, median, most clearance) and colliding (bottom); red: closest pair")
    fig.tight_layout()
    fig.savefig(out / "motion_planning_configs.png", dpi=110)
    plt.close(fig)
    print(f"wrote {out / 'motion_planning_stats.png'} and {out / 'motion_planning_configs.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
