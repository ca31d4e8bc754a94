"""The command line: ``python -m collide compare [MODEL.xml] [--steps N] [--seed S] [--hold H]
[--json FILE] [--plot FILE.png] [--rerun FILE.rrd]``.

``compare`` simulates a MuJoCo model with random controls and, every step, checks that every
contact MuJoCo generated is among `collide`'s candidates, counts candidates on both sides and
times both broad phases (see `collide.mujoco.compare`). Without MODEL it uses the built-in scene
(`collide.mujoco.default_scene`). Exit status: 0 when recall is 100 %, 1 when a MuJoCo contact
pair was missed, 2 on bad usage.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m collide",
                                     description="collide: broad phase checked against MuJoCo")
    sub = parser.add_subparsers(dest="command", required=True)
    cmp_ = sub.add_parser("compare", help="simulate a MuJoCo model and compare broad phases "
                          "step by step (default: a built-in scene)")
    cmp_.add_argument("model", nargs="?", help="MJCF file (default: the built-in scene)")
    cmp_.add_argument("--steps", type=int, default=1000, help="simulation steps (default 1000)")
    cmp_.add_argument("--seed", type=int, default=0, help="seed of the random controls and "
                      "of the built-in scene (default 0)")
    cmp_.add_argument("--hold", type=int, default=100, help="steps between random control "
                      "changes (default 100)")
    cmp_.add_argument("--json", metavar="FILE", help="write the figures as JSON: steps, recall, missed, "
                      "contact_pairs_per_step, candidates_per_step, mujoco_candidates_per_step, "
                      "time_ours_us, time_mujoco_broad_us, ratio, the per-step times and more "
                      "(see collide.mujoco.compare)")
    cmp_.add_argument("--plot", metavar="FILE.png", help="write a per-step plot (matplotlib)")
    cmp_.add_argument("--rerun", metavar="FILE.rrd", help="record every step to Rerun (needs rerun-sdk: "
                      "pip install 'collide[viz]'): geoms, our bounds, candidate pairs, MuJoCo's contacts and "
                      "ours, missed pairs; open it with `rerun FILE.rrd` (see docs/visualising.md)")
    cmp_.add_argument("--no-contacts", action="store_true", help="compare candidate pairs only, not "
                      "contacts (our narrow phase against MuJoCo's contacts, each pair's deepest); "
                      "with --rerun, our contacts are left out of the recording too")
    return parser


def _plot_formats() -> set[str] | None:
    # The file types matplotlib can write here; None without matplotlib (the run then says so).
    try:
        from matplotlib.backend_bases import FigureCanvasBase
    except ImportError:
        return None
    return set(FigureCanvasBase.get_supported_filetypes())


def compare_main(args: argparse.Namespace) -> int:
    """Run ``compare``; returns the exit status."""
    from . import mujoco as cm

    if args.steps < 1:
        print("error: --steps must be >= 1", file=sys.stderr)
        return 2
    if args.hold < 1:
        print("error: --hold must be >= 1", file=sys.stderr)
        return 2
    if args.seed < 0:
        print("error: --seed must be >= 0", file=sys.stderr)
        return 2
    if args.plot and not Path(args.plot).suffix:
        args.plot += ".png"  # what matplotlib would write; said so, not guessed
    if args.plot:
        fmt = Path(args.plot).suffix[1:].lower()
        supported = _plot_formats()
        if supported is not None and fmt not in supported:
            print(f"error: --plot: matplotlib cannot write '.{fmt}' files (use one of: "
                  f"{', '.join(sorted(supported))})", file=sys.stderr)
            return 2
    if args.rerun:
        try:
            __import__("rerun")  # missing: said before the run, not after it
        except ImportError:
            print("error: --rerun needs rerun-sdk: pip install 'collide[viz]' (or pip install rerun-sdk)",
                  file=sys.stderr)
            return 2
    outputs = [(flag, out) for flag, out in (("--json", args.json), ("--plot", args.plot), ("--rerun", args.rerun))
               if out is not None]
    for flag, out in outputs:
        if not out:
            print(f"error: {flag}: empty file name", file=sys.stderr)
            return 2
    seen = {}
    for flag, out in outputs:
        # Two outputs to one file: the later would overwrite the former, silently.
        key = Path(out).resolve()
        if key in seen:
            print(f"error: {seen[key]} and {flag} name the same file ({out})", file=sys.stderr)
            return 2
        seen[key] = flag
    for flag, out in outputs:
        # The outputs are checked now, not after the whole run (and exit status 1 means a miss).
        if out:
            if Path(out).is_dir():
                print(f"error: {flag}: {out} is a folder; give a file name", file=sys.stderr)
                return 2
            try:
                Path(out).parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                print(f"error: cannot create the folder of {out}: {exc}", file=sys.stderr)
                return 2
            existed = Path(out).exists()
            try:  # can it be written? (opened to append: an existing file is left as it is)
                with open(out, "ab"):
                    pass
            except OSError as exc:
                print(f"error: {flag}: cannot write {out}: {exc}", file=sys.stderr)
                return 2
            if not existed:
                Path(out).unlink()
    if args.model:
        try:
            model, name = cm.load_model(args.model)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
    else:
        model = cm.default_scene(seed=args.seed)
        name = "built-in scene (figure falling on a pile)"
    # Said before the run: the first one also compiles the kernels (said on stderr as it goes).
    print(f"{name}: simulating {args.steps} steps with random controls (seed {args.seed})...", flush=True)
    if args.rerun:
        from .rerun_log import record_compare

        try:
            result, _ = record_compare(model, args.rerun, steps=args.steps, seed=args.seed, name=name,
                                       hold=args.hold, contacts=not args.no_contacts)
        except ValueError as exc:
            # The file is opened before the run: one that cannot be written after all (its
            # check above passed) is bad usage, not a miss.
            if not str(exc).startswith("path:"):
                raise
            print(f"error: --rerun: {exc}", file=sys.stderr)
            return 2
    else:
        result = cm.compare(model, steps=args.steps, seed=args.seed, name=name, hold=args.hold,
                            contacts=not args.no_contacts)
    print(cm.format_report(result))
    if args.rerun:
        print(f"\nwrote {args.rerun} (open it with: rerun {args.rerun})")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=1))
        print(f"\nwrote {args.json}")
    if args.plot:
        try:
            cm.plot_comparison(result, args.plot)
            print(f"wrote {args.plot}")
        except ImportError:
            print("note: matplotlib is not installed; no plot written (pip install matplotlib)",
                  file=sys.stderr)
    return 0 if not result["missed"] else 1


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``python -m collide``; returns the exit status."""
    args = _parser().parse_args(argv)
    if args.command == "compare":
        return compare_main(args)
    return 2  # pragma: no cover - argparse rejects unknown commands


if __name__ == "__main__":
    sys.exit(main())
