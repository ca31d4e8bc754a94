"""The machine a benchmark ran on, for the header of its committed output (one home for it)."""

from __future__ import annotations

import platform
from pathlib import Path


def cpu() -> str:
    """The CPU's model name (``/proc/cpuinfo``; the platform's processor string elsewhere)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown cpu"
