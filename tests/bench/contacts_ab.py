"""A/B of two copies of the package on tests/bench/contacts.py, alternating runs (a developer's tool).

    python tests/bench/contacts_ab.py ROUNDS STEPS A=DIR_A B=DIR_B [SCENE ...]

Each ``DIR`` holds a copy of the ``collide`` package (``git archive <commit> collide | tar -x -C DIR``,
or a copy of the working tree), put first on ``PYTHONPATH`` for its runs. Each round runs
contacts.py once per copy, the order alternating between rounds (A B, B A, ...), so a drift of the
shared machine hits both. Printed per scene: the ratio to MuJoCo (ours / ``mj_collision``, measured
in the same run) of every run of A and of B, then B's over A's (medians over the rounds), our time
per step and the contacts per step of each; the median ratio over the scenes per run; the median,
least and largest of B's over A's; and ``uptime`` before and after each round. A mechanism is kept
when it buys >= 5 % on the median or >= 15 % on some scene and costs no scene > 3 % (brief of issue
46's speed work); a smaller effect wants more rounds.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def _uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def _run(folder: str, steps: int, scenes: list[str]) -> dict:
    # One contacts.py run with the copy in ``folder``: {scene: (ratio, ours us, our contacts, MuJoCo's)}.
    cmd = [sys.executable, str(HERE / "contacts.py"), "--steps", str(steps)] + (["--scenes", *scenes] if scenes else [])
    out = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=folder), cwd=HERE,
                         check=True).stdout
    rows = {}
    for line in out.splitlines():
        f = line.split()
        if len(f) == 10 and f[1].isdigit() and re.fullmatch(r"[0-9.]+", f[6]):
            rows[f[0]] = (float(f[6]), float(f[2]), float(f[7]), float(f[8]))
    return rows


def main(argv: list[str]) -> int:
    if len(argv) < 4:
        print(__doc__)
        return 2
    rounds, steps = int(argv[0]), int(argv[1])
    (la, da), (lb, db) = (x.split("=", 1) for x in argv[2:4])
    scenes = argv[4:]
    for d in (da, db):
        if not (Path(d) / "collide" / "__init__.py").is_file():
            sys.exit(f"contacts_ab.py: {d} holds no copy of the collide package")
    res: dict = {la: {}, lb: {}}
    up = []
    for r in range(rounds):
        order = [(la, da), (lb, db)] if r % 2 == 0 else [(lb, db), (la, da)]
        u0 = _uptime()
        for lab, d in order:
            for scene, row in _run(d, steps, scenes).items():
                res[lab].setdefault(scene, []).append(row)
        up.append(f"# {u0} | {_uptime()}")
    print(f"# {rounds} rounds x {steps} steps, alternating (A={la}: {da}; B={lb}: {db}); each run: "
          f"python tests/bench/contacts.py --steps {steps}" + (" --scenes " + " ".join(scenes) if scenes else ""))
    print(f"{'scene':<22}{la + ' ratio':>30}{lb + ' ratio':>30}  {lb}/{la}  (us {la} -> {lb}; contacts/step)")
    q = []
    for s in sorted(res[la]):
        a, b = np.array(res[la][s]), np.array(res[lb][s])
        q.append(np.median(b[:, 0]) / np.median(a[:, 0]))
        print(f"{s:<22}{' '.join(f'{x:5.2f}' for x in a[:, 0]):>30}{' '.join(f'{x:5.2f}' for x in b[:, 0]):>30}  "
              f"{q[-1]:6.3f}  (us {np.median(a[:, 1]):.1f} -> {np.median(b[:, 1]):.1f}; {a[0, 2]:.1f} {b[0, 2]:.1f})")
    for lab in (la, lb):
        per_run = [np.median([v[i][0] for v in res[lab].values()]) for i in range(rounds)]
        print(f"median ratio over scenes per run, {lab}: " + " ".join(f"{x:.2f}" for x in per_run))
    print(f"{lb}/{la} over scenes: median {np.median(q):.3f}, min {min(q):.3f}, max {max(q):.3f}")
    print("\n".join(up))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
