"""The paper's experiment (Stürzlinger 1996, §4, Table 1): ray tracing a recursive CSG plant.

A plant is a cyclic CSG graph: a stem segment with a leaf carries three rotated, shrunken copies
of the whole plant; at the end of the recursion sits a blossom, itself a cyclic graph (a petal
plus a copy of the blossom rotated by the golden angle, slightly shrunk and lifted). Unrolled, it
has a few thousand primitives. Built bottom-up from its children's transformed boxes, the root box
grows by up to 73 % per rotation and ends orders of magnitude too large (the paper: ±31700 against
[-4.3, 5.0; -3.0, 4.9; 0.0, 12.9]); built from point clouds it is the exact box of the plant's
primitive points. The demo prints the three root boxes, ray traces the plant with each hierarchy
(512 x 512; every hierarchy gives the same image) and prints a table like the paper's Table 1. Its
two PNGs in demos/output/ draw one level of each hierarchy's boxes over the plant, outlined: the
point clouds' boxes wrap the branches; the box-of-boxes' boxes at that level are larger than the view.

Run: python demos/flower.py   (writes demos/output/flower_*.png; its printout is flower.txt)
"""

from __future__ import annotations

import os
import platform
import sys
import time
import tracemalloc

import numpy as np

from collide import csg

GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))  # 137.5°: the phyllotaxis of real blossoms
OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "output")


def rot(axis: str, angle: float) -> np.ndarray:
    """(4, 4) rotation about a coordinate axis."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m = np.eye(4)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def move(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    """(4, 4) translation."""
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def scale(f: float) -> np.ndarray:
    """(4, 4) uniform scale."""
    return np.diag([f, f, f, 1.0])


def flower(levels: int = 4, petals: int = 40, branches: int = 3) -> tuple[csg.Node, dict]:
    """The recursive plant: its root, and its leaf nodes by part name (for colouring).

    Parameters
    ----------
    levels : int
        Depth of the branching recursion (``branches ** levels`` blossoms).
    petals : int
        Depth of the blossom's golden-angle recursion (petals per blossom).
    branches : int
        Copies of the plant on top of each stem segment.
    """
    # A petal is a lens, the intersection of two offset spheres, flattened: an intersection
    # node, whose operands' boxes the top-down pass clips to the lens's own box (§3.5).
    petal_ball = csg.sphere(1.0)
    lens = csg.Intersection(csg.Transform(move(y=0.6), petal_ball),
                            csg.Transform(move(y=-0.6), petal_ball))
    petal = csg.Transform(np.diag([1.1, 0.85, 0.08, 1.0]), lens)
    heart = csg.sphere(0.35)
    stem = csg.cylinder(0.12, 1.5)
    foliage = csg.ellipsoid([0.8, 0.3, 0.04])
    # One petal, tilted up and pushed out from the axis; the rest of the blossom is the same
    # blossom turned by the golden angle, 3 % smaller and a little higher (a cyclic graph).
    petal_placed = csg.Transform(move(0.85) @ rot("y", -0.35), petal)
    blossom = csg.Recursive("blossom", csg.Union(
        petal_placed,
        csg.Transform(move(z=0.03) @ rot("z", GOLDEN_ANGLE) @ scale(0.97), csg.Ref("blossom"))),
        petals)
    head = csg.Union(csg.Transform(move(z=0.2), heart), blossom)
    # A stem segment (z from 0 to 3) with a leaf; on top, `branches` copies of the whole plant,
    # spread around the axis, tilted out by 35° and shrunk to 70 %.
    tops = [move(z=3.0) @ rot("z", 2 * np.pi * k / branches + 0.4) @ rot("x", 0.6) @ scale(0.7)
            for k in range(branches)]
    segment = csg.Union(
        csg.Transform(move(z=1.5), stem),
        csg.Transform(move(z=1.2) @ rot("z", 0.9) @ move(0.75) @ rot("x", 0.5) @ rot("y", -0.3),
                      foliage))
    plant = csg.Recursive("plant", csg.Union(segment, csg.Instances(csg.Ref("plant"), tops)),
                          levels, base=head)
    return plant, {"petal": petal_ball, "heart": heart, "stem": stem, "foliage": foliage}


COLOURS = {"petal": (0.95, 0.45, 0.6), "heart": (1.0, 0.8, 0.15), "stem": (0.3, 0.6, 0.2),
           "foliage": (0.15, 0.5, 0.15)}


def shade(hits: csg.RayHits, bvh: csg.BVH, directions: np.ndarray, parts: dict,
          size: int) -> np.ndarray:
    """A Lambert-shaded RGB image ``(size, size, 3) float64`` in [0, 1]."""
    by_leaf = {id(v): COLOURS[k] for k, v in parts.items()}
    leaf_rgb = np.array([by_leaf.get(id(lf), (0.7, 0.7, 0.7)) for lf in bvh.leaf_source])
    img = np.tile(np.array([0.93, 0.95, 1.0]), (len(directions), 1))  # sky
    hit = hits.hit
    light = np.array([0.4, -0.5, 0.75])
    light /= np.linalg.norm(light)
    lam = np.clip(hits.normal[hit] @ light, 0.0, 1.0)
    img[hit] = leaf_rgb[hits.leaf[hit]] * (0.3 + 0.7 * lam)[:, None]
    return img.reshape(size, size, 3)


def node_depths(bvh: csg.BVH) -> np.ndarray:
    """Depth of every node of ``bvh`` (the root's is 0): ``(N,) int64``."""
    depth = np.full(bvh.n_nodes, -1, dtype=np.int64)
    depth[0] = 0
    order = [0]
    for n in order:  # breadth first: a parent before its children
        kids = bvh.node_child[bvh.node_first[n]:bvh.node_first[n] + bvh.node_count[n]]
        depth[kids] = depth[n] + 1
        order.extend(kids.tolist())
    return depth


def box_edges_2d(lo: np.ndarray, hi: np.ndarray, eye, target, size: int, fov_deg: float,
                 up=(0.0, 0.0, 1.0), near: float = 0.05) -> np.ndarray:
    """The 12 edges of each box ``[lo, hi]`` (``(n, 3)`` each) in the pixels of `csg.pinhole_rays`'
    camera: ``(m, 2, 2)`` (column, row) segments, cut where they pass behind the camera's near plane
    (a box larger than the view has edges behind it)."""
    eye = np.asarray(eye, float)
    fwd = np.asarray(target, float) - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, fwd)
    s = np.tan(np.radians(fov_deg) / 2)
    bits = np.array([[(k >> i) & 1 for i in range(3)] for k in range(8)])
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
    corners = np.where(bits[None], hi[:, None], lo[:, None])  # (n, 8, 3)
    p = corners[:, [a for a, _ in edges]].reshape(-1, 3)
    q = corners[:, [b for _, b in edges]].reshape(-1, 3)
    zp, zq = (p - eye) @ fwd, (q - eye) @ fwd
    keep = (zp > near) | (zq > near)
    p, q, zp, zq = p[keep], q[keep], zp[keep], zq[keep]
    # move the end behind the near plane onto it
    t = np.clip((near - zp) / np.where(zq != zp, zq - zp, 1.0), 0.0, 1.0)
    p = np.where((zp < near)[:, None], p + t[:, None] * (q - p), p)
    t = np.clip((near - zq) / np.where(zp != zq, zp - zq, 1.0), 0.0, 1.0)
    q = np.where((zq < near)[:, None], q + t[:, None] * (p - q), q)

    def pixels(x):
        v = x - eye
        z = v @ fwd
        col = ((v @ right) / z / s + 1) / 2 * size - 0.5  # a square image: the same scale both ways
        row = (1 - (v @ true_up) / z / s) / 2 * size - 0.5
        return np.stack([col, row], axis=1)

    seg = np.stack([pixels(p), pixels(q)], axis=1)
    # Far outside the image only its direction matters: a huge box's edges reach millions of pixels.
    return np.clip(seg, -50.0 * size, 51.0 * size)


def save_level(path: str, image: np.ndarray, bvh: csg.BVH, level: int, camera: tuple, title: str,
               colour) -> dict:
    """The plant ``image`` with the boxes of one ``level`` of ``bvh`` outlined over it, a title and a
    legend; returns the level's figures (boxes, their widths)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    eye, target, size, fov = camera
    nodes = np.flatnonzero(node_depths(bvh) == level)
    lo, hi = bvh.node_lo[nodes], bvh.node_hi[nodes]
    width = np.max(hi - lo, axis=1)
    fig = plt.figure(figsize=(size / 100, size / 100 + 0.95), dpi=100)
    ax = fig.add_axes([0, 0, 1, size / (size + 95)])
    ax.imshow(image)
    ax.add_collection(LineCollection(box_edges_2d(lo, hi, eye, target, size, fov), colors=[colour],
                                     linewidths=1.2))
    ax.set_xlim(-0.5, size - 0.5)
    ax.set_ylim(size - 0.5, -0.5)
    ax.set_axis_off()
    fig.suptitle(title, y=0.99, fontsize=10)
    handles = [Line2D([], [], color=colour, lw=1.5,
                      label=f"level {level}: {len(nodes)} boxes, {width.min():.3g} to {width.max():.3g} wide")]
    handles += [Patch(color=c, label=k) for k, c in COLOURS.items()]
    fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 1 - 26 / (size + 95)), ncol=3,
               fontsize=8, frameon=False)
    os.makedirs(os.path.dirname(path), exist_ok=True)  # a copy of the script elsewhere has none
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return {"boxes": len(nodes), "width_min": float(width.min()), "width_max": float(width.max())}


def exact_box(node: csg.Node) -> tuple[np.ndarray, np.ndarray]:
    """Box of every unrolled primitive's cloud moved by its world matrix, one by one (no
    hierarchy); an intersection (a petal's lens) counts as one primitive, its exact hull
    intersection, since the parts it cuts away are not part of the plant."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    clouds = {}
    for part, w in csg.leaves(node, stop_at=(csg.Intersection,)):
        c = clouds.setdefault(id(part), part.point_cloud())
        p = c.points @ w[:3, :3].T + w[:3, 3]
        ext = c.radius * np.linalg.norm(w[:3, :3], axis=1)
        lo, hi = np.minimum(lo, p.min(0) - ext), np.maximum(hi, p.max(0) + ext)
    return lo, hi


def fmt_box(lo, hi) -> str:
    return "[" + "; ".join(f"{a:.4g}, {b:.4g}" for a, b in zip(lo, hi)) + "]"


def run(size: int = 512, save: bool = True, level: int = 4) -> dict:
    """Build, render and time each hierarchy; print the paper-style report; return the figures."""
    plant, parts = flower()
    n_leaves = len(csg.leaves(plant))
    lo, hi = exact_box(plant)
    eye = np.array([8.0, -9.5, 6.0])
    target = np.array([-0.2, 0.0, 3.9])
    origins, directions = csg.pinhole_rays(eye, target, size, size, fov_deg=40.0)
    # Compile (or load) the kernels outside the timings.
    csg.raycast(csg.build_bvh(csg.sphere(1.0)), origins[:1], directions[:1])

    rows = {}
    for label, method, tighten, volume in (
            ("box of boxes", "box_of_box", True, "aabb"),
            ("point clouds, no top-down pass", "pointcloud", False, "aabb"),
            ("point clouds", "pointcloud", True, "aabb"),
            ("point clouds, OBBs", "pointcloud", True, "obb"),
            ("point clouds, spheres", "pointcloud", True, "sphere")):
        t0 = time.perf_counter()
        bvh = csg.build_bvh(plant, method=method, tighten=tighten, volume=volume)
        t1 = time.perf_counter()
        hits = csg.raycast(bvh, origins, directions)
        t2 = time.perf_counter()
        # Peak memory of the set-up, measured in a second build (tracemalloc slows it down).
        tracemalloc.start()
        csg.build_bvh(plant, method=method, tighten=tighten, volume=volume)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        rows[label] = dict(bvh=bvh, hits=hits, setup=t1 - t0, render=t2 - t1, peak=peak,
                           bound=int(hits.bound_tests.sum()), prim=int(hits.primitive_tests.sum()))

    bob, pc = rows["box of boxes"], rows["point clouds"]
    drawn = {}
    if save:
        # One image of the plant (every hierarchy gives the same), one level of each hierarchy over it.
        image = shade(pc["hits"], pc["bvh"], directions, parts, size)
        plant_width = float(np.max(hi - lo))
        for label, name, colour in (("box of boxes", "flower_box_of_box.png", "crimson"),
                                    ("point clouds", "flower_pointcloud.png", "royalblue")):
            drawn[label] = save_level(
                os.path.join(OUT, name), image, rows[label]["bvh"], level, (eye, target, size, 40.0),
                f"{label}: level {level} of the hierarchy's boxes over the plant ({plant_width:.3g} wide)",
                colour)
    hit = pc["hits"].hit
    same = all(np.array_equal(r["hits"].leaf, pc["hits"].leaf)
               and np.allclose(r["hits"].distance[hit], pc["hits"].distance[hit])
               for r in rows.values())
    cpu = platform.processor()
    if os.path.exists("/proc/cpuinfo"):
        cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo")
                    if ln.startswith("model name")), cpu)
    print("Recursive CSG plant (Stürzlinger 1996, §4), ray traced at "
          f"{size} x {size}; machine: {os.cpu_count()} cores, Python {sys.version.split()[0]}, {cpu}, "
          f"load average {os.getloadavg()[0]:.1f} (times grow with it; the test counts do not)")
    print(f"unrolled primitives: {n_leaves} (petal spheres, hearts, stem segments, leaves); "
          f"hierarchy nodes: {pc['bvh'].n_nodes}")
    print()
    print("root box                    [xmin, xmax; ymin, ymax; zmin, zmax]")
    bob_box, pc_box = bob["bvh"].root_aabb(), pc["bvh"].root_aabb()
    print(f"  box of boxes              {fmt_box(bob_box.lo, bob_box.hi)}")
    print(f"  point clouds              {fmt_box(pc_box.lo, pc_box.hi)}")
    print(f"  exact (all primitives)    {fmt_box(lo, hi)}")
    dev = float(np.max(np.abs(np.concatenate([pc_box.lo - lo, pc_box.hi - hi]))))
    print(f"  box-of-boxes volume / exact volume: {bob_box.volume() / float(np.prod(hi - lo)):.3g}; "
          f"point-cloud box deviates from exact by {dev:.1e}")
    print()
    print(f"{'hierarchy':32s} {'set-up s':>9s} {'render s':>9s} {'bound tests':>13s} "
          f"{'prim. tests':>12s} {'peak MiB':>9s}")
    for label, r in rows.items():
        print(f"{label:32s} {r['setup']:9.2f} {r['render']:9.2f} {r['bound']:13,d} {r['prim']:12,d} "
              f"{r['peak'] / 2**20:9.1f}")
    print()
    print(f"box of boxes / point clouds: bound tests x{bob['bound'] / pc['bound']:.1f}, "
          f"primitive tests x{bob['prim'] / pc['prim']:.1f}, "
          f"render time x{bob['render'] / pc['render']:.1f}")
    print(f"all hierarchies give the same image (same leaf and distance on every ray): {same}; "
          f"pixels covered: {pc['hits'].hit.mean():.1%}")
    for label, d in drawn.items():
        print(f"drawn ({label}): level {level}, {d['boxes']} boxes, {d['width_min']:.3g} to "
              f"{d['width_max']:.3g} wide")
    print("peak MiB: Python-side allocations of the set-up (tracemalloc, a second build); render "
          "adds the output arrays and the kernel's per-thread span buffers (not traced).")
    return rows


if __name__ == "__main__":
    run()
