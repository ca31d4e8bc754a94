"""Ablation of the per-step broad phase's speed mechanisms: what each one buys, measured by `ab.py`.

    python tests/bench/ablate.py --make [--commit C] [--dir D] [--only a,b,...]   # the copies
    python tests/bench/ablate.py --warm --check [--only ...]                       # compiled, same answers
    python tests/bench/ablate.py --run [--only ...] [--scenes a,b,...] [--rounds R] [--steps N]
    python tests/bench/ablate.py --summarize OUTPUT                                # the table

A developer's tool (issue 42: every mechanism that stays must earn it). It exports the package of
one commit (``git archive C collide``, pinned: the tree moves while others work in it) as
``D/collide_base``, then one copy per ablation, ``D/collide_<name>``, each the base with a list of
exact text patches applied (file, old text, new text): a patch whose old text is not found exactly
once stops the script, so that no ablation silently measures the base. Each ablation switches one
mechanism off and must leave the answers unchanged: ``--check`` steps MuJoCo scenes and compares
every copy's pairs with the base's, call by call. ``--warm`` compiles each copy's kernels (numba
caches them in the copy's own ``__pycache__``; the base's cache is copied into each copy before its
patch, and the package's cache locator, `collide._cache`, recompiles every kernel whose files or
their imports changed; a kernel loaded from that cache names ``collide_base``'s modules, so the base
stays in ``D``). A patch of `_kernels/broadphase.py` or `culling.py` recompiles the step's kernels:
minutes a copy on a busy machine. ``--run`` runs ``tests/bench/ab.py`` with the base first and the copies
after, over the scenes (all of ``../shared/models`` by default); its ratios are a copy's time over
the base's: above 1, the mechanism switched off bought that much.

The patches are written against ``COMMIT`` (the default ``--commit``) and apply there only. Seven of
the mechanisms they switch off have since been removed from the package (issue 42: the hash grid,
``FLAT_DESC``, ``_subtree_pair``'s flat lists, ``_sweep``'s register carry, the sphere cull before
``_bounds_ok``, ``pair_bits``, ``box_row8``; their ablations are ``grid``, ``flatdesc``, ``flatpairs``,
``sweepreg``, ``sphere``, ``pairbits``, ``rowsimd``): against a later commit those patches find no
text and the script stops, naming the patch. The committed output, ``ablate.amd-epyc.txt``, is the
record of the measurement.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT / ".." / "shared" / "models"
COMMIT = "84866f148f45ce3ed3360eb2e11800023eb073f6"  # main's HEAD when the ablation was written

K = "_kernels/broadphase.py"
C = "_kernels/culling.py"
T = "broadphase/tables.py"
M = "mujoco.py"

# name -> (what is switched off, [(file under the package, old text, new text), ...])
ABLATIONS = {
    "null": ("nothing (a copy of the base without a patch: the run's own noise, the control)", []),
    "coherence": ("frame coherence (the fat-box list of `_body_pairs`) off entirely", [
        (K, "    if coherent and not by_masks:  #", "    if False and coherent and not by_masks:  #")]),
    "backoff": ("coherence's back-off (COH_SCORE_MAX huge: the list is always rebuilt, never skipped)", [
        (K, "COH_SCORE_MAX = 2.5\n", "COH_SCORE_MAX = 1e300\n")]),
    "masks": ("the static masks up to MASK_MAX positions (MASK_MAX = -1: the tree, and coherence, on every model)", [
        (C, "MASK_MAX = 64  #", "MASK_MAX = -1  #")]),
    "flatroots": ("flat roots (tables.FLAT_BODIES = 0: no subtree is flat; the walk everywhere)", [
        (T, "FLAT_BODIES = 64  #", "FLAT_BODIES = 0  #")]),
    "flatdesc": ("a body against its small branching subtree flat (FLAT_DESC = -1: always the walk)", [
        (C, "FLAT_DESC = 16  #", "FLAT_DESC = -1  #")]),
    "flatpairs": ("`_subtree_pair`'s flat lists (FLAT_MAX = -1: always the walk)", [
        (C, "FLAT_MAX = 4096  #", "FLAT_MAX = -1  #")]),
    "grid": ("the hash grid (GRID_MIN huge: sweep-and-prune for every wide node)", [
        (C, "GRID_MIN = 64  #", "GRID_MIN = 1 << 62  #")]),
    "sap": ("sweep-and-prune of a node's children (SAP_MIN huge: all pairs of children; the grid too is off)", [
        (C, "SAP_MIN = 8  #", "SAP_MIN = 1 << 62  #")]),
    "same": ("RET_SAME (the kernel never reports the last call's pairs; the new rows are handed out)", [
        (K, "    if k == ctx[C_NLAST] and last >= 0:", "    if False and k == ctx[C_NLAST] and last >= 0:")]),
    "arena": ("the output arena's views (the adapter hands out a copy of the rows each call)", [
        (M, "                    out = bp._last = bp._arena[o:e]\n",
         "                    out = bp._last = bp._arena[o:e].copy()\n")]),
    "entry": ("step_bound's entry point (the bound call goes through numba's dispatcher)", [
        (K, "        _bound_entry = entry if callable(entry) else disp\n", "        _bound_entry = disp\n")]),
    "bound": ("bound pose arrays (the adapter passes xpos and xmat to the dispatcher, as pairs(pos, rot))", [
        (M, "            k = bp._step_bound(bp._ctx_addr)\n",
         "            k = bp._step(bp._bound[0], bp._bound[1], bp._ctx)\n")]),
    "sweepreg": ("`_sweep`'s register carry (the plain loop: every row loaded)", [
        (C, "        if x == L - 1 or parent_pos[x + 1] != x:  # else saabb[x] was merged last: a0..a5 hold it\n"
            "            a0, a1, a2, a3, a4, a5 =",
         "        a0, a1, a2, a3, a4, a5 =")]),
    "sphere": ("`_sphere_hit` as a cull before `_bounds_ok` in the geom pairs (straight to `_bounds_ok`)", [
        (K, "                        if not _sphere_hit(A, a, ma, B, b, mb):\n"
            "                            continue\n", "")]),
    "pairbits": ("`pair_bits` (four body pairs a vector) in the geom-pair stage (its scalar twin `_pairs_mask`)", [
        (K, "        for j in range(0, cnt, PAIR_LANES):\n"
            "            hits |= pair_bits(bw_at, bp_at, c0 + j, min(PAIR_LANES, cnt - j)) << np.uint64(j)\n",
         "        hits |= _pairs_mask(bw, bp, c0, cnt)\n")]),
    "rowsimd": ("`box_row8` in the masks' and flat roots' rows (`_row_hits`: one column at a time)", [
        (C, "        hits |= box_row8(bt_at, stride, base + i, l0, l1, l2, h0, h1, h2) << np.uint64(i)\n"
            "        i += LANES8\n",
         "        c = base + i\n"
         "        hits |= np.uint64((bt[0, c] <= h0) & (bt[1, c] <= h1) & (bt[2, c] <= h2) & (l0 <= bt[3, c])\n"
         "                          & (l1 <= bt[4, c]) & (l2 <= bt[5, c])) << np.uint64(i)\n"
         "        i += 1\n")]),
}

CHECK_SCENES = ("humanoid", "shadow_hand", "stonehenge", "humanoid100", "22_humanoids")


def export(commit: str, dest: Path) -> None:
    """The package of ``commit`` as ``dest`` (a folder named ``collide_base``)."""
    with tempfile.TemporaryDirectory() as tmp:
        tar = Path(tmp) / "c.tar"
        subprocess.run(["git", "-C", str(ROOT), "archive", "-o", str(tar), commit, "collide"], check=True)
        with tarfile.open(tar) as t:
            t.extractall(tmp, filter="data")
        shutil.move(str(Path(tmp) / "collide"), str(dest))


def make_copy(base: Path, dest: Path, patches) -> None:
    """``base`` copied to ``dest`` (its numba cache too, see the module docstring), patched."""
    if dest.exists():
        shutil.rmtree(dest)
    shutil.copytree(base, dest)
    for rel, old, new in patches:
        path = dest / rel
        text = path.read_text()
        n = text.count(old)
        if n != 1:
            sys.exit(f"ablate.py: {dest.name}: the old text is found {n} times in {rel}, not once:\n{old}")
        path.write_text(text.replace(old, new))


def scenes_all() -> list[str]:
    return sorted(p.name for p in MODELS.iterdir() if (p / "scene.xml").is_file())


WARM = """
import sys, mujoco
sys.path.insert(0, {parent!r})
m = __import__({name!r} + ".mujoco", fromlist=["x"])
for s in {scenes!r}:
    model = mujoco.MjModel.from_xml_path({models!r} + "/" + s + "/scene.xml")
    m.compare(model, steps=3, seed=0, broadphase=m.BroadPhase(model))
"""

CHECK = """
import sys, mujoco, numpy as np
sys.path.insert(0, {parent!r})
mods = [__import__(n + ".mujoco", fromlist=["x"]) for n in {names!r}]
bad = 0
for s in {scenes!r}:
    model = mujoco.MjModel.from_xml_path({models!r} + "/" + s + "/scene.xml")
    data = mujoco.MjData(model)
    bps = [m.BroadPhase(model) for m in mods]
    rng = np.random.default_rng(0)
    lo, hi = model.actuator_ctrlrange.T if model.nu else (np.zeros(0), np.zeros(0))
    total = 0
    work = np.zeros((len(bps), len(bps[0].broadphase._stats)), np.int64)  # the kernels' counters, summed
    for t in range({steps}):
        if model.nu:
            data.ctrl[:] = lo + (hi - lo) * rng.random(model.nu)
        mujoco.mj_step(model, data)
        ref = np.array(bps[0].pairs(data))
        total += len(ref)
        work[0] += bps[0].broadphase._stats
        for n, bp in zip({names!r}[1:], bps[1:]):
            got = bp.pairs(data)
            work[{names!r}.index(n)] += bp.broadphase._stats
            if not np.array_equal(ref, got):
                bad += 1
                print(f"DIFFERENT: {{n}} {{s}} step {{t}}: {{len(got)}} pairs, base {{len(ref)}}", flush=True)
    print(f"{{s}}: {steps} steps, {{total}} pairs in all (base), {{len({names!r}) - 1}} copies compared; "
          "their counted tests differ from the base's in: "
          + (", ".join(n for i, n in enumerate({names!r}) if (work[i] != work[0]).any()) or "none"), flush=True)
print("check:", "ALL THE SAME" if bad == 0 else f"{{bad}} DIFFERENCES")
sys.exit(1 if bad else 0)
"""


def summarize(path: str) -> str:
    """The table of an ab.py output (base first): per ablation, its time over the base's on each
    scene: the median over the scenes, the best and the worst scene, and the verdict of issue 42
    (kept where switching it off costs >= 5 % on the median or >= 15 % on some scene, and saves no
    scene more than 3 %: no ratio below 0.97). Then the same ratios of ``xR`` (each copy's time over
    MuJoCo's broad-phase timer in the same rounds: the machine's drift divided out), as a second
    reading; the ``null`` copy (no patch) shows the run's noise."""
    runs, text = [], Path(path).read_text().splitlines()
    for line in text:
        if line.startswith("# ") and "ab.py /" in line:  # each run's command line starts a table
            runs.append([])
        elif runs and " us (" in line and not line.startswith("#"):
            runs[-1].append(line)
    return "\n\n".join(_table(r) for r in runs if r)


def _table(lines: list[str]) -> str:
    rows, xrs = {}, {}
    for line in lines:
        scene, rest = line.split(None, 1)
        for part in rest.split(")")[:-1]:
            name, _, _, ratio, xr = part.replace("(", " ").replace(",", " ").split()
            rows.setdefault(name, {})[scene] = float(ratio)
            xrs.setdefault(name, {})[scene] = float(xr.lstrip("x"))
    names = list(rows)
    base = names[0]
    out = [f"{len(rows[base])} scenes",
           "| switched off | median | best (scene) | worst (scene) | verdict | xR median | xR best | xR worst |",
           "|---|---:|---:|---:|---|---:|---:|---:|"]
    for name in names[1:]:
        r = rows[name]
        v = np.array(list(r.values()))
        hi = max(r, key=r.get)
        lo = min(r, key=r.get)
        keep = (np.median(v) >= 1.05 or v.max() >= 1.15) and v.min() >= 0.97
        x = np.array([xrs[name][s] / xrs[base][s] for s in r])
        out.append(f"| {name.removeprefix('collide_')} | {np.median(v):.3f} | {r[hi]:.3f} ({hi}) | "
                   f"{r[lo]:.3f} ({lo}) | {'keep' if keep else 'remove'} | {np.median(x):.3f} | "
                   f"{x.max():.3f} | {x.min():.3f} |")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--commit", default=COMMIT)
    ap.add_argument("--dir", default="/tmp/ablate")
    ap.add_argument("--only", default=",".join(ABLATIONS), help="comma-separated ablations (of: "
                    + ", ".join(ABLATIONS) + ")")
    ap.add_argument("--make", action="store_true", help="export the base and make the copies (afresh)")
    ap.add_argument("--warm", action="store_true", help="compile each copy's kernels (3 steps of each scene)")
    ap.add_argument("--check", action="store_true", help="compare every copy's pairs with the base's")
    ap.add_argument("--check-steps", type=int, default=200)
    ap.add_argument("--run", action="store_true", help="run ab.py over the base and the copies")
    ap.add_argument("--scenes", default=None, help="comma-separated folders of ../shared/models (default: all)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--summarize", metavar="FILE", help="print the table of a saved ab.py output, and stop")
    args = ap.parse_args()
    if args.summarize:
        print(summarize(args.summarize))
        return
    only = [a for a in args.only.split(",") if a]
    for a in only:
        if a not in ABLATIONS:
            sys.exit(f"ablate.py: no ablation {a!r} (of: {', '.join(ABLATIONS)})")
    d = Path(args.dir)
    base = d / "collide_base"
    names = ["collide_base"] + ["collide_" + a for a in only]
    scenes = args.scenes.split(",") if args.scenes else scenes_all()
    py = sys.executable
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    if args.make:
        d.mkdir(parents=True, exist_ok=True)
        if not base.exists():  # (remove the folder to export afresh)
            export(args.commit, base)
            print(f"base: {args.commit} -> {base}", flush=True)
            # the base compiled first, so that each copy starts from its cache
            subprocess.run([py, "-c", WARM.format(parent=str(d), name="collide_base", scenes=scenes,
                                                  models=str(MODELS.resolve()))], check=True, env=env)
        for a in only:
            make_copy(base, d / ("collide_" + a), ABLATIONS[a][1])
            print(f"collide_{a}: {ABLATIONS[a][0]}", flush=True)
    if args.warm:
        for n in names[1:]:
            print(f"warm {n}", flush=True)
            subprocess.run([py, "-c", WARM.format(parent=str(d), name=n, scenes=scenes,
                                                  models=str(MODELS.resolve()))], check=True, env=env)
    if args.check:
        r = subprocess.run([py, "-c", CHECK.format(parent=str(d), names=names, scenes=list(CHECK_SCENES),
                                                   models=str(MODELS.resolve()), steps=args.check_steps)], env=env)
        if r.returncode:
            sys.exit("ablate.py: an ablation changed the answers")
    if args.run:
        cmd = [py, str(ROOT / "tests" / "bench" / "ab.py")] + [str(d / n) for n in names] + [
            "--scenes", ",".join(scenes), "--rounds", str(args.rounds), "--steps", str(args.steps)]
        print("#", " ".join(cmd[1:]), flush=True)
        subprocess.run(cmd, check=True, env=env)


if __name__ == "__main__":
    main()
