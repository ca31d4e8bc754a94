"""The compiled functions that numba's cache holds in more than one signature (a developer's tool).

    python tests/bench/signatures.py [FOLDER] [--all]

Each signature of a function is a compile of its own (with every callee whose arguments it changes),
so a function listed here with signatures that differ only by a ``Literal[int](-1)`` against an
``int64``, or a ``bool`` literal, costs a compile that one plain value would save (docs/design.md,
"The kernel cache"). Reads the cache index files (``*.nbi``) under ``FOLDER`` (default: the package
next to this script; or a ``NUMBA_CACHE_DIR``), so run it after the code paths of interest ran
once (the test suite, a benchmark), best on a fresh cache: an index whose stamp did not change keeps
the signatures of earlier runs. Of a function's index files, the newest is read. The index format
is numba's own (a pickled version, then a pickled ``(stamp, overloads)``, keyed by the signature
first): written for numba 0.68; a file it cannot read is named and skipped. ``--all``: every
argument, not only those that differ between signatures.
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
    sigs = []
    for key in overloads:  # (argument types, target, ...): a tuple, a Signature or the string given
        k0 = key[0]
        sig = (k0,) if isinstance(k0, str) else tuple(getattr(k0, "args", k0))
        if sig not in sigs:  # one signature for two CPUs is one compile here
            sigs.append(sig)
    return sigs


def _current(folder: Path) -> list[Path]:
    # Each function's newest index file: numba names it after the function's first line
    # (``module.function-LINE.py311.nbi``) and leaves the file of an older line where it was.
    newest: dict[tuple, Path] = {}
    for path in folder.rglob("*.nbi"):  # __pycache__ folders, or NUMBA_CACHE_DIR's own layout
        func, _, rest = path.name.rpartition("-")
        key = (path.parent, func, "_checked" in rest)
        if key not in newest or path.stat().st_mtime > newest[key].stat().st_mtime:
            newest[key] = path
    return sorted(newest.values())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", nargs="?", default=str(Path(__file__).resolve().parents[2] / "collide"))
    ap.add_argument("--all", action="store_true", help="print every argument, not only the differing ones")
    args = ap.parse_args()
    folder = Path(args.folder)
    rows = []
    for path in _current(folder):
        try:
            sigs = _signatures(path)
        except Exception as exc:  # noqa: BLE001 -- another numba's format: say so, go on
            print(f"unreadable: {path} ({type(exc).__name__}: {exc})", file=sys.stderr)
            continue
        if len(sigs) > 1:
            rows.append((len(sigs), str(path.relative_to(folder)), sigs))
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
