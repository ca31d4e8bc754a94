"""Input checks shared by every module: clear ``ValueError`` s, never a crash deeper down.

Every public entry point funnels user arrays through these helpers, so a NaN pose or a wrongly
shaped array is reported with the argument's name before scipy, manifold3d or numba sees it. One
exception, for speed: `collide.mujoco.BroadPhase.pairs_batch` hands a float64 C-contiguous qpos to
its kernel unchecked and checks it here only when the kernel refuses a pose (every non-finite
qpos entry makes one; tested), so the error still names the entry.
"""

from __future__ import annotations

import numpy as np


def _reject_complex(value, name: str) -> None:
    # numpy casts complex to float with only a warning, dropping the imaginary part silently.
    try:
        is_complex = np.iscomplexobj(value)
    except (TypeError, ValueError):
        return  # not an array at all: the conversion that follows names the problem
    if is_complex:
        raise ValueError(f"{name}: complex values are not coordinates (got dtype {np.asarray(value).dtype})")


def as_array(value, name: str, shape: tuple, dtype=np.float64) -> np.ndarray:
    """Convert ``value`` to a C-contiguous array of ``dtype`` and check its shape and finiteness.

    Parameters
    ----------
    value : array_like
        The user's input.
    name : str
        Argument name used in error messages.
    shape : tuple of (int or None)
        Expected shape; ``None`` entries match any length.
    dtype : numpy dtype
        Target dtype (float64 by default).

    Returns
    -------
    array : ndarray
        A new or existing C-contiguous array of ``dtype``.
    """
    _reject_complex(value, name)
    try:
        # Not ascontiguousarray(value): it turns a scalar into shape (1,), which would then pass
        # for a one-element array (a 0-d array is contiguous already).
        arr = np.asarray(value, dtype=dtype)
        if not arr.flags.c_contiguous:
            arr = np.ascontiguousarray(arr)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: cannot be read as a {np.dtype(dtype).name} array ({exc})") from None
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name}: expected shape {want}, got {arr.shape}")
    if arr.dtype.kind == "f" and arr.size and not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"{name}: non-finite value (NaN or inf) at index {tuple(int(i) for i in bad)}")
    return arr


def as_points(value, name: str = "points") -> np.ndarray:
    """Return ``value`` as finite ``(n, 3) float64`` points; an empty input gives ``(0, 3)``."""
    _reject_complex(value, name)
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: cannot be read as a float64 array ({exc})") from None
    if arr.size == 0:
        # An empty list (any nesting of empty lists) is the empty cloud; an empty array of
        # another shape ((3, 0), (0, 4)) is a shape error, as a full one would be.
        if arr.ndim == 2 and arr.shape[1] != 3 or arr.ndim > 2:
            raise ValueError(f"{name}: expected shape (n, 3), got {arr.shape}")
        return np.zeros((0, 3))
    return as_array(arr, name, (None, 3))


def _as_finite(value, name: str) -> float:
    # A finite real number (not a string, not a bool: radius=True meant nothing; not a complex,
    # whose imaginary part float() would drop; not an array, which float() reads if it has one element).
    if isinstance(value, (str, bytes, bool, np.bool_, complex, np.complexfloating)) or (
            isinstance(value, np.ndarray) and value.ndim):
        raise ValueError(f"{name}: expected a number, got {value!r}")
    try:
        r = float(value)
    except OverflowError:  # an int beyond float's range (10**400)
        raise ValueError(f"{name}: must be finite, got {value!r}") from None
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(r):
        raise ValueError(f"{name}: must be finite, got {r}")
    return r


def as_radius(value, name: str = "radius") -> float:
    """Return ``value`` as a finite float ``>= 0``."""
    r = _as_finite(value, name)
    if r < 0.0:
        raise ValueError(f"{name}: must be >= 0, got {r}")
    return r


def as_positive(value, name: str) -> float:
    """Return ``value`` as a finite float ``> 0``."""
    r = _as_finite(value, name)
    if r <= 0.0:
        raise ValueError(f"{name}: must be > 0, got {r}")
    return r


def as_count(value, name: str, minimum: int, maximum: int | None = None) -> int:
    """Return ``value`` as an int ``>= minimum`` (and ``<= maximum`` when given)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name}: expected an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name}: must be >= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise ValueError(f"{name}: must be <= {maximum}, got {value}")
    return int(value)


def as_affine(matrix, translation=None, name: str = "matrix") -> tuple[np.ndarray, np.ndarray]:
    """Split an affine map into its linear part and translation.

    Parameters
    ----------
    matrix : (4, 4) or (3, 3) array_like
        A homogeneous affine matrix (last row ``[0, 0, 0, 1]``), or the linear part when
        ``translation`` is given (or omitted, meaning zero).
    translation : (3,) array_like, optional
        Translation applied after the linear part.

    Returns
    -------
    linear : (3, 3) float64
    translation : (3,) float64
    """
    if isinstance(matrix, tuple):
        if len(matrix) != 2 or translation is not None:
            raise ValueError(f"{name}: a tuple must be (rotation (3, 3), translation (3,))")
        matrix, translation = matrix
    _reject_complex(matrix, name)
    try:
        m = np.asarray(matrix, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: cannot be read as a float64 array ({exc})") from None
    if m.shape == (4, 4):
        if translation is not None:
            raise ValueError(f"{name}: give either a (4, 4) matrix or a (3, 3) linear part with a translation")
        m = as_array(m, name, (4, 4))
        if not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]):
            raise ValueError(f"{name}: last row of a (4, 4) affine matrix must be [0, 0, 0, 1], got {m[3]}")
        return m[:3, :3].copy(), m[:3, 3].copy()
    linear = as_array(m, name, (3, 3))
    t = np.zeros(3) if translation is None else as_array(translation, "translation", (3,))
    return linear, t
