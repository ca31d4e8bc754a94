"""The checked mode: ``COLLIDE_CHECKED=1`` in the environment before ``import collide``.

The per-step kernels view their flat buffers through raw addresses and offsets (`_kernels._ptr`):
a wrong offset reads a neighbouring buffer silently, and an index past a view reads whatever
lies there (issue 48: a segmentation fault that 644 passing tests never exercised). In the
checked mode

- every index into every array in a `collide` kernel is bounds-checked (numba's ``boundscheck``,
  ``IndexError`` on a miss), the pointer-built views included, and
- every set of views carved out of one buffer (`_kernels._ptr.check_span`) is checked to end
  inside that buffer.

The kernels run several times slower and the batch kernels on one thread (numba runs a parallel
loop that may raise serially); the answers are the same. Checked kernels are cached apart
from the normal ones (their cache files carry ``checked`` in their name), so switching modes
compiles each mode once. CI runs the broad-phase and MuJoCo tests once in this mode.
"""

from __future__ import annotations

import os

CHECKED: bool = os.environ.get("COLLIDE_CHECKED", "").strip() not in ("", "0")


def enable_boundscheck() -> None:
    """In the checked mode, numba's bounds checking on for the kernels compiled from now on (a
    process-wide numba setting; set before any `collide` kernel compiles)."""
    if not CHECKED:
        return
    import numba

    os.environ["NUMBA_BOUNDSCHECK"] = "1"  # a numba config reload keeps it
    numba.config.BOUNDSCHECK = 1
