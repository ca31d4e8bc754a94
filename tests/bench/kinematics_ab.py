"""Time of `collide.mujoco.kinematics_batch` per configuration on every model, for one package copy.

    python tests/bench/kinematics_ab.py DIR > out_X.json

``DIR`` holds a copy of the ``collide`` package (``git archive <rev> collide | tar -x -C DIR``), put
first on ``sys.path``. Prints ``{scene: us per configuration}`` (best of 7 calls of 2,000 random
configurations near ``qpos0``) as JSON. For an A/B, run two copies by turns (A B A B ...) and compare
the medians of each scene's three best runs: a developer's tool; the output is not committed, the
comparison is (tests/bench/check_batch.txt).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

sys.path.insert(0, sys.argv[1])

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from collide.mujoco._kinematics import kinematics_batch  # noqa: E402

MODELS = Path(__file__).resolve().parents[2] / ".." / "shared" / "models"


def main() -> None:
    res = {}
    for d in sorted(p for p in MODELS.iterdir() if (p / "scene.xml").is_file()):
        m = mujoco.MjModel.from_xml_path(str(d / "scene.xml"))
        rng = np.random.default_rng(0)
        q = np.tile(m.qpos0, (2000, 1)) + 0.1 * rng.standard_normal((2000, m.nq))
        kinematics_batch(m, q[:4])  # compile / warm up
        best = np.inf
        for _ in range(7):
            t = time.perf_counter()
            kinematics_batch(m, q)
            best = min(best, time.perf_counter() - t)
        res[d.name] = best / len(q) * 1e6
    print(json.dumps(res))


if __name__ == "__main__":
    main()
