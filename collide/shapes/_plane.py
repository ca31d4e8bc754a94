"""The plane: a halfspace is unbounded, so `plane` returns a `Plane`, not a cloud."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._validate import as_array

__all__ = ["Plane", "plane"]


@dataclass(frozen=True, eq=False)
class Plane:
    """The solid halfspace ``{x : normal . x <= offset}`` in the geom frame.

    **Unbounded, so not a PointCloud**: no finite cloud, box or sphere contains it, and passing
    it where a cloud is expected raises ``ValueError``. The broad phase handles planes itself
    (a plane against a bounded volume is one support-function test). MuJoCo's plane geom is
    ``normal = (0, 0, 1)``, ``offset = 0``: the solid below its xy plane.

    Attributes
    ----------
    normal : (3,) float64
        Unit outward normal (read-only).
    offset : float
        Signed distance of the boundary plane from the origin along ``normal``.
    """

    normal: np.ndarray
    offset: float

    def __post_init__(self):
        n = as_array(self.normal, "normal", (3,))
        try:
            object.__setattr__(self, "offset", float(self.offset))
        except (TypeError, ValueError):
            raise ValueError(f"offset: expected a number, got {type(self.offset).__name__}") from None
        given = float(self.offset)
        if not math.isfinite(given):
            raise ValueError(f"offset: must be finite, got {given}")
        big = float(np.abs(n).max())
        if big > 0.0 and not 1e-150 < big < 1e150:
            # Divide by the largest component first: |n| overflowed for (1e308, 1e308, 0) and
            # the normal silently became zero.
            n, d0 = n / big, float(self.offset) / big
            object.__setattr__(self, "offset", d0)
        length = float(np.linalg.norm(n))
        if not length > 0.0:
            raise ValueError("normal: must be non-zero")
        d = float(self.offset)
        if not math.isfinite(d):
            # finite as given: the normal's length, far below 1, scaled it past the float range
            raise ValueError(f"normal: too short for its offset (largest component {big:.3g}, offset "
                             f"{given:.3g}: the same halfspace needs offset / |normal|, beyond the float "
                             "range); scale both")
        if abs(length - 1.0) > 1e-12:
            n, d = n / length, d / length
        n = np.array(n, dtype=np.float64)
        n.setflags(write=False)
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "offset", d)

    def __eq__(self, other) -> bool:
        # Written out: the generated __eq__ would compare the normal arrays elementwise.
        if not isinstance(other, Plane):
            return NotImplemented
        return bool(np.array_equal(self.normal, other.normal)) and self.offset == other.offset

    def __hash__(self) -> int:
        return hash((tuple(self.normal.tolist()), self.offset))

    def _unbounded(self, what: str):
        raise ValueError(f"{what}: a Plane is an unbounded halfspace and has no bounding {what}; "
                         "the broad phase handles planes itself (see shapes.plane)")

    def aabb(self):
        """Always raises ``ValueError``: a halfspace has no bounding box."""
        self._unbounded("aabb")

    def obb(self, method: str = "optimal"):
        """Always raises ``ValueError``: a halfspace has no bounding box."""
        self._unbounded("obb")

    def sphere(self, method: str = "exact"):
        """Always raises ``ValueError``: a halfspace has no bounding sphere."""
        self._unbounded("sphere")

    def signed_distance(self, points) -> np.ndarray:
        """``(n,) float64``: ``normal . x - offset`` for ``points`` ``(n, 3)`` (<= 0 inside)."""
        p = as_array(points, "points", (None, 3))
        return p @ self.normal - self.offset


def plane(normal=(0.0, 0.0, 1.0), offset: float = 0.0) -> Plane:
    """The halfspace ``{x : normal . x <= offset}``: a `Plane`, **not** a `PointCloud`.

    A plane is unbounded, so it has no bounding cloud; the broad phase handles planes itself.

    Parameters
    ----------
    normal : (3,) array_like of float, default (0, 0, 1)
        Non-zero; a non-unit normal is normalised together with ``offset`` (same halfspace).
    offset : float, default 0.0

    Returns
    -------
    Plane
    """
    try:
        d = float(offset)
    except (TypeError, ValueError):
        raise ValueError(f"offset: expected a number, got {offset!r}") from None
    return Plane(normal, d)
