"""The compiled functions that numba's cache holds in more than one signature (a developer's tool).

    python tests/bench/signatures.py [FOLDER] [--all]

Each signature of a function is a compile of its own (with every callee whose arguments it changes),
so a function listed here with signatures that differ only by a ``Literal[int](-1)`` against an
``int64``, or a ``bool`` literal, costs a compile that one plain value would save (docs/design.md,
"The kernel cache"). Reads the cache index files (``*.nbi``) under ``FOLDER`` (default: the package
next to this script), so run it after the code paths of interest ran once (the test suite, a
benchmark). The index format is numba's own (a pickled version, then a pickled ``(stamp,
overloads)``, keyed by the signature first): written for numba 0.68; a file it cannot read is
named and skipped. ``--all``: every argument, not only those that differ between signatures.
"""

from __future__ import annotations

import argparse
import pickle
import sys
from pathlib import Path


def _short(t) -> str:
    # an argument type, compactly: arrays as dtype/ndim/layout, "ro" when read-only
    name = type(t).__name__
    if name == "Array":
        return f"{t.dtype}[{t.ndim}d{'' if t.layout == 'C' else ',' + t.layout}{'' if t.mutable else ',ro'}]"
    if name in ("Tuple", "UniTuple"):
        return "(" + ", ".join(_short(x) for x in t.types) + ")"
    return str(t)


def _signatures(path: Path) -> list[tuple]:
    with open(path, "rb") as f:
        pickle.load(f)  # numba's version
        _stamp, overloads = pickle.loads(f.read())
    # the key's first item: the argument types (a Signature where the dispatcher was given one)
    return [tuple(getattr(key[0], "args", key[0])) for key in overloads]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", nargs="?", default=str(Path(__file__).resolve().parents[2] / "collide"))
    ap.add_argument("--all", action="store_true", help="print every argument, not only the differing ones")
    args = ap.parse_args()
    rows = []
    for path in sorted(Path(args.folder).rglob("__pycache__/*.nbi")):
        try:
            sigs = _signatures(path)
        except Exception as exc:  # noqa: BLE001 -- another numba's format: say so, go on
            print(f"unreadable: {path} ({type(exc).__name__}: {exc})", file=sys.stderr)
            continue
        if len(sigs) > 1:
            rows.append((len(sigs), path.name, sigs))
    for n, name, sigs in sorted(rows, key=lambda r: (-r[0], r[1])):
        print(f"{n}  {name}")
        width = min(len(s) for s in sigs)
        differ = [i for i in range(max(len(s) for s in sigs))
                  if i >= width or len({_short(s[i]) for s in sigs}) > 1]
        for s in sigs:
            shown = range(len(s)) if args.all else [i for i in differ if i < len(s)]
            print("     " + " | ".join(f"{i}: {_short(s[i])}" for i in shown))


if __name__ == "__main__":
    main()
