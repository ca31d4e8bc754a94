"""Ray casts through a CSG graph's BVH (`raycast`, the kernels in `collide._kernels.ray`) and
a pinhole camera's rays (`pinhole_rays`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._fork import require_parallel
from .._kernels import ray as _ray
from .._validate import as_array, as_count, as_positive
from ._bvh import BVH

__all__ = ["RayHits", "pinhole_rays", "raycast"]

@dataclass(frozen=True)
class RayHits:
    """First hits of a batch of rays.

    Attributes
    ----------
    distance : (R,) float64
        Ray parameter ``t >= 0`` of the first boundary point (in units of ``|direction|``);
        ``inf`` on a miss.
    leaf : (R,) int32
        Unrolled leaf id (see `leaves`, `BVH.leaf_source`) whose surface was hit; -1 on a miss.
    normal : (R, 3) float64
        Unit outward normal of the solid at the hit (facing the ray at an entry); zero on a miss.
    bound_tests, primitive_tests : (R,) int64
        Ray-box tests and exact primitive tests spent on each ray.
    """

    distance: np.ndarray
    leaf: np.ndarray
    normal: np.ndarray
    bound_tests: np.ndarray
    primitive_tests: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """``(R,) bool``: rays that hit."""
        return self.leaf >= 0


def _rays(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    o = as_array(origins, "origins", (None, 3))
    d = as_array(directions, "directions", (None, 3))
    if len(o) != len(d):
        raise ValueError(f"origins and directions: different counts ({len(o)} vs {len(d)})")
    if len(d) and np.any(np.all(d == 0.0, axis=1)):
        raise ValueError(f"directions: zero vector at row {int(np.argmax(np.all(d == 0.0, axis=1)))}")
    return o, d


def _two_prod(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # a * b = p + e exactly (Dekker 1971, Veltkamp's split; no overflow below ~1e290).
    p = a * b
    sa, sb = 134217729.0 * a, 134217729.0 * b  # 2**27 + 1
    ah = sa - (sa - a)
    bh = sb - (sb - b)
    al, bl = a - ah, b - bh
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def _two_sum(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # a + b = s + e exactly (Knuth, TAOCP vol. 2, 4.2.2).
    s = a + b
    v = s - a
    return s, (a - (s - v)) + (b - v)


def _reorigin(bvh: BVH, o: np.ndarray, d: np.ndarray):
    # A ray that starts far from the scene (1e16 away from a unit box) has its entry and exit
    # parameters rounded to one value, and misses. Such a ray's origin is moved along it to just
    # before the root bound, o' = o + t0 d computed in double-double (`_two_prod`, `_two_sum`) so
    # that o' is the point of the given ray to within an ulp of o', and the t0s are added back to
    # the distances. t0 is a float: from 1e100 away one step lands within ~1e85 of the scene, so
    # the step is repeated (each gains ~15 digits). Rays starting within 64 radii of the scene
    # are left bit for bit as they are.
    if bvh.volume == "aabb":
        c = 0.5 * (bvh.node_lo[0] + bvh.node_hi[0])
        rad = 0.5 * float(np.linalg.norm(bvh.node_hi[0] - bvh.node_lo[0]))
    elif bvh.volume == "obb":
        c, rad = bvh.node_center[0], float(np.linalg.norm(bvh.node_hi[0]))
    else:
        c, rad = bvh.node_center[0], float(bvh.node_radius[0])
    if not (np.all(np.isfinite(c)) and np.isfinite(rad)):
        return o, None
    dd = np.einsum("ij,ij->i", d, d)
    total = np.zeros(len(o))
    for _ in range(32):
        # The closest approach to the bound's centre, less its radius, less 8 ulps of itself:
        # rounding t0 (1e17: an ulp is 16, the box's radius 0.9) must not carry the new origin
        # into the bound or past it. A ray is moved while that leaves it 64 radii nearer.
        with np.errstate(over="ignore", invalid="ignore"):
            t0 = np.einsum("ij,ij->i", c - o, d) / dd - 2.0 * rad / np.sqrt(dd)
            t0 = t0 - 8.0 * np.spacing(np.abs(t0))
            far = (t0 > 0) & np.isfinite(t0) & (t0 * np.sqrt(dd) > 64.0 * max(rad, 1e-300))
        if not np.any(far):
            break
        t0 = np.where(far, t0, 0.0)
        with np.errstate(over="ignore", invalid="ignore"):
            p, pe = _two_prod(t0[:, None], d)
            s, se = _two_sum(o, p)
            moved = s + (se + pe)
        far &= np.all(np.isfinite(moved), axis=1)  # the split overflows past ~1e290: left as given
        if not np.any(far):
            break
        o = np.where(far[:, None], moved, o)
        total = total + np.where(far, t0, 0.0)
    return o, (total if np.any(total) else None)


def raycast(bvh: BVH, origins, directions) -> RayHits:
    """First hits of rays ``origins + t * directions``, ``t >= 0``, through a CSG hierarchy.

    The hit is the first point where the ray crosses the boundary of the whole solid (an entry
    for a ray from outside; the exit for a ray that starts inside).

    Parameters
    ----------
    bvh : BVH
        From `build_bvh`.
    origins, directions : (R, 3) array_like of float
        Directions need not be unit (``distance`` is then in units of their length), but must be
        non-zero.

    Returns
    -------
    RayHits

    Notes
    -----
    Rays may start at any distance: one that starts far away is first moved along itself to the
    scene (exactly, to an ulp of the new origin). A scene part smaller than the spacing of float64
    at its own coordinates (a 1000-wide box at 1e20, where that spacing is 16384) is not
    representable and may be missed.
    """
    if not isinstance(bvh, BVH):
        raise ValueError(f"bvh: expected a BVH from build_bvh, got {type(bvh).__name__}")
    o, d = _rays(origins, directions)
    r = len(o)
    # Directions of extreme length (|d|^2 under- or overflows in the kernel: a direction of
    # length 1e-200 gave t = 2.4e200 instead of 4e200) are scaled by a power of two, exactly,
    # and their distances scaled back; ordinary directions pass through bit for bit.
    _, expo = np.frexp(np.abs(d).max(axis=1)) if r else (None, np.zeros(0, int))
    expo = np.where(np.abs(expo) > 100, expo, 0)
    if np.any(expo):
        d = np.ldexp(d, -expo[:, None])
    o, t0 = _reorigin(bvh, o, d) if (bvh.n_nodes and r) else (o, None)
    out_t = np.full(r, np.inf)
    out_leaf = np.full(r, -1, dtype=np.int32)
    out_n = np.zeros((r, 3))
    out_b = np.zeros(r, dtype=np.int64)
    out_p = np.zeros(r, dtype=np.int64)
    if bvh.n_nodes and r:
        require_parallel()  # not in a child forked from a GNU OpenMP parent (`collide._fork`)
        bound = {"aabb": 0, "obb": 1, "sphere": 2}[bvh.volume]
        _ray.raycast_kernel(o, d, bvh.node_kind, bvh.node_first, bvh.node_count, bvh.node_child,
                            bound, bvh.node_lo, bvh.node_hi, bvh.node_rot, bvh.node_center,
                            bvh.node_radius, bvh.node_leaf, bvh.leaf_prim, bvh.leaf_param,
                            bvh.leaf_inv, bvh.leaf_tri_first, bvh.leaf_tri_count, bvh.tri,
                            bvh.span_capacity, bvh.height, bvh.max_children, bvh.max_tri,
                            out_t, out_leaf, out_n, out_b, out_p)
    if t0 is not None:
        out_t = out_t + t0  # inf stays inf: a miss
    if np.any(expo):
        with np.errstate(over="ignore"):
            out_t = np.ldexp(out_t, -expo)  # inf past the float range (a direction of length 1e-320)
        lost = (out_leaf >= 0) & ~np.isfinite(out_t)
        # A hit farther than the largest float along the direction given is a miss, as `RayHits`
        # says inf is (it was leaf 0 at distance inf; review, 2026-11-22).
        out_leaf[lost] = -1
        out_n[lost] = 0.0
    return RayHits(out_t, out_leaf, out_n, out_b, out_p)


def pinhole_rays(eye, target, width: int, height: int, fov_deg: float = 40.0,
                 up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Rays of a pinhole camera, one per pixel, row-major from the top-left pixel.

    Parameters
    ----------
    eye, target : (3,) array_like of float
        Camera position and the point it looks at.
    width, height : int
        Image size in pixels.
    fov_deg : float
        Vertical field of view, in (0, 180) degrees.
    up : (3,) array_like of float
        Approximate up direction (not parallel to ``target - eye``).

    Returns
    -------
    origins : (height * width, 3) float64
    directions : (height * width, 3) float64
        Unit vectors.
    """
    eye = as_array(eye, "eye", (3,))
    fwd = as_array(target, "target", (3,)) - eye
    w = as_count(width, "width", 1)
    h = as_count(height, "height", 1)
    fov = as_positive(fov_deg, "fov_deg")
    if not fov < 180.0:
        raise ValueError(f"fov_deg: a pinhole camera's field of view must be below 180 degrees, got {fov:g}")
    if not np.linalg.norm(fwd) > 0:
        raise ValueError("target: must differ from eye")
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, as_array(up, "up", (3,)))
    if not np.linalg.norm(right) > 1e-12:
        raise ValueError("up: must not be parallel to the viewing direction")
    right /= np.linalg.norm(right)
    true_up = np.cross(right, fwd)
    s = np.tan(np.radians(fov) / 2)
    ys = (1 - 2 * (np.arange(h) + 0.5) / h) * s
    xs = (2 * (np.arange(w) + 0.5) / w - 1) * s * w / h
    d = fwd + xs[None, :, None] * right + ys[:, None, None] * true_up
    d = d.reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1)[:, None]
    return np.repeat(eye[None], len(d), axis=0), d
