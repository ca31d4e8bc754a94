"""collide.distance's input handling: every accepted form of a pose gives the same answer through
one compiled signature, every bad input a ValueError naming it, and the call works after one.

The public call hands (rotation, translation) ndarrays that are float64, C-contiguous, aligned and
writable to its kernel as they are, converts anything else first, and has the kernel check the
poses (finite, rigid, in range, shaped (3, 3) and (3,)); a shape's hull data is cached by identity
(`collide.signed_distance._described`). These tests exercise each of those paths.
"""

import math
import pickle
from unittest.mock import MagicMock

import numpy as np
import pytest

import collide
from collide import Cylinder, Distance, PointCloud, testing
from collide import signed_distance as sd
from collide._kernels import distance as kd
from collide.testing.surfaces import random_rotation


def _fields(r):
    return (r.distance, r.lower, r.upper, *r.point_a, *r.point_b, *r.normal, r.iterations, *r.hints)


def _hull(rng, n):
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0.4, 1.0, 3)


def _forms(rot, pos):
    # The same pose in every accepted form but the canonical one.
    ro_r, ro_p = rot.copy(), pos.copy()
    ro_r.flags.writeable = ro_p.flags.writeable = False
    big = np.zeros((6, 6))
    big[::2, ::2] = rot
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rot, pos
    return {
        "read-only": (ro_r, ro_p),
        "Fortran order": (np.asfortranarray(rot), pos),
        "transposed view": (np.ascontiguousarray(rot.T).T, pos),
        "strided view": (big[::2, ::2], big[0, ::2] * 0 + pos),
        "lists": (rot.tolist(), pos.tolist()),
        "tuples": (tuple(map(tuple, rot)), tuple(pos)),
        "(4, 4) matrix": m,
        "(4, 4) list": m.tolist(),
        "matrix subclass": (np.asmatrix(rot), pos),
        "big-endian": (rot.astype(">f8"), pos.astype(">f8")),
        "unaligned": (_unaligned(rot), _unaligned(pos)),
        # numba refuses a masked array beside another odd argument with NumbaTypeError, which is no
        # TypeError (helper-66's review of 38d0449)
        "masked arrays": (np.ma.array(rot), np.ma.array(pos)),
        "masked and a list": (np.ma.array(rot), pos.tolist()),
        "read-only and masked": (ro_r, np.ma.array(pos)),
    }


def _unaligned(a):
    buf = np.zeros(a.size * 8 + 1, np.uint8)
    out = buf[1:].view(np.float64).reshape(a.shape)
    out[...] = a
    assert not out.flags.aligned
    return out


@pytest.mark.filterwarnings("ignore:the matrix subclass")
def test_every_pose_form_gives_the_canonical_answer_through_one_signature():
    rng = np.random.default_rng(0)
    a, b = PointCloud(_hull(rng, 300)), PointCloud(_hull(rng, 60), 0.05)
    checked = 0
    for k in range(6):
        ra, rb = random_rotation(rng), random_rotation(rng)
        ta, tb = rng.normal(size=3) * 0.3, rng.normal(size=3) * 0.3 + [1.2 * (k % 3), 0.0, 0.0]
        want = collide.distance(a, b, (ra, ta), (rb, tb))
        swapped = collide.distance(b, a, (rb, tb), (ra, ta))
        true = testing.polytope_signed_distance(a.points @ ra.T + ta, b.points @ rb.T + tb, a.radius, b.radius)
        assert want.lower - 1e-12 <= true <= want.upper + 1e-12
        assert swapped.lower - 1e-12 <= true <= swapped.upper + 1e-12
        for name, pose in _forms(rb, tb).items():
            assert _fields(collide.distance(a, b, (ra, ta), pose)) == _fields(want), name
            assert _fields(collide.distance(b, a, pose, (ra, ta))) == _fields(swapped), name  # as pose_a
            checked += 1
        # float32 poses: the answer for the rounded pose (float32 rotations pass as rigid).
        r32, t32 = rb.astype(np.float32), tb.astype(np.float32)
        got = collide.distance(a, b, (ra, ta), (r32, t32))
        assert _fields(got) == _fields(collide.distance(a, b, (ra, ta), (r32.astype(float), t32.astype(float))))
        # integer arrays (an identity and a translation)
        got = collide.distance(a, b, None, (np.eye(3, dtype=int), np.array([3, 0, 0])))
        assert got.distance == collide.distance(a, b, None, (np.eye(3), np.array([3.0, 0, 0]))).distance
    assert checked == 6 * len(_forms(np.eye(3), np.zeros(3)))
    # numba compiles its kernel once per argument types (layouts, flags, dtypes): none of these
    # inputs may have made a second compile (a minute of CI each).
    assert len(kd.query.signatures) == 1, kd.query.signatures


def test_the_inputs_are_not_modified_and_the_result_owns_its_arrays():
    rng = np.random.default_rng(1)
    a = PointCloud(_hull(rng, 50))
    rot, pos = random_rotation(rng), np.array([2.0, 0.1, 0.0])
    keep = rot.copy(), pos.copy()
    r = collide.distance(a, a, None, (rot, pos))
    assert np.array_equal(rot, keep[0]) and np.array_equal(pos, keep[1])
    pos[0] = 5.0  # the caller reuses its arrays: the result does not change
    assert r.point_b[0] < 2.5 and r.distance < 2.0
    r2 = collide.distance(a, a, None, (rot, pos), warm=r)
    assert r.distance < r2.distance  # the warm start read r, did not write it


# ------------------------------------------------------------------------------ bad input

BAD_POSES = [
    ("NaN rotation", (np.full((3, 3), np.nan), np.zeros(3)), "non-finite"),
    ("inf translation", (np.eye(3), np.array([0.0, np.inf, 0.0])), "non-finite"),
    ("NaN in a list", ([[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0.0, float("nan"), 0.0]), "translation.*non-finite"),
    ("NaN, read-only", "readonly-nan", "non-finite"),
    ("scaled", (2.0 * np.eye(3), np.zeros(3)), "orthonormal"),
    ("sheared", (np.array([[1.0, 0.1, 0], [0, 1, 0], [0, 0, 1]]), np.zeros(3)), "orthonormal"),
    ("reflection", (np.diag([1.0, -1.0, 1.0]), np.zeros(3)), "orthonormal"),
    ("Fortran, scaled", (np.asfortranarray(np.diag([1.0, 1.0, 1.1])), np.zeros(3)), "orthonormal"),
    ("far", (np.eye(3), np.array([0.0, 0.0, 1e200])), "beyond"),
    ("rotation (3, 4)", (np.zeros((3, 4)), np.zeros(3)), r"rotation: expected shape \(3, 3\)"),
    ("rotation (2, 2)", (np.eye(2), np.zeros(3)), r"rotation: expected shape \(3, 3\)"),
    ("rotation (9,)", (np.eye(3).ravel(), np.zeros(3)), r"rotation: expected shape \(3, 3\)"),
    ("translation (4,)", (np.eye(3), np.zeros(4)), r"translation: expected shape \(3\)"),
    ("translation (3, 1)", (np.eye(3), np.zeros((3, 1))), r"translation: expected shape \(3\)"),
    ("translation (0,)", (np.eye(3), np.zeros(0)), r"translation: expected shape \(3\)"),
    ("three items", (np.eye(3), np.zeros(3), 1.0), "tuple"),
    ("(4, 4) with a bad last row", np.ones((4, 4)), "last row"),
    ("(4, 4) NaN", np.full((4, 4), np.nan), "non-finite"),
    ("complex", (np.eye(3) * 1j, np.zeros(3)), "complex"),
    ("strings", (np.eye(3), ["a", "b", "c"]), "translation"),
    ("a number", 3.0, "shape"),
    ("a mock", (np.eye(3), MagicMock()), "translation"),  # numba's typing of it raised KeyError (helper-66)
]


def _bad(pose):
    if isinstance(pose, str) and pose == "readonly-nan":
        r = np.eye(3)
        r[1, 1] = np.nan
        r.flags.writeable = False
        return (r, np.zeros(3))
    return pose


@pytest.mark.parametrize("name,pose,what", BAD_POSES, ids=[b[0] for b in BAD_POSES])
def test_a_bad_pose_is_named_and_the_call_works_after_it(name, pose, what):
    rng = np.random.default_rng(2)
    a, b = PointCloud(_hull(rng, 200)), Cylinder(0.3, 0.5)
    good = (random_rotation(rng), np.array([1.5, 0.2, 0.0]))
    before = _fields(collide.distance(a, b, None, good))
    with pytest.raises(ValueError, match="pose_b.*" + what):
        collide.distance(a, b, None, _bad(pose))
    with pytest.raises(ValueError, match="pose_a.*" + what):
        collide.distance(b, a, _bad(pose), good)
    assert _fields(collide.distance(a, b, None, good)) == before  # the same answer after the error


def test_bad_shapes_and_options_are_named_and_the_call_works_after_them():
    a = PointCloud([[0.0, 0.0, 0.0]], 0.5)
    pose = (np.eye(3), np.array([2.0, 0.0, 0.0]))
    want = collide.distance(a, a, None, pose).distance
    cases = [
        (lambda: collide.distance(PointCloud.empty(), a), "shape a: the cloud is empty"),
        (lambda: collide.distance(a, PointCloud.empty()), "shape b: the cloud is empty"),
        (lambda: collide.distance(a, "box"), "shape b: expected a PointCloud"),
        (lambda: collide.distance(None, a), "shape a: expected a PointCloud"),
        (lambda: collide.distance(a, PointCloud([[1e200, 0.0, 0.0]])), "shape b: .*beyond"),
        (lambda: collide.distance(a, PointCloud([[0.0, 0.0, 0.0]], -1.0)), "radius: must be >= 0"),
        (lambda: collide.distance(a, a, tolerance=float("nan")), "tolerance"),
        (lambda: collide.distance(a, a, tolerance=0.0), "tolerance"),
        (lambda: collide.distance(a, a, tolerance=0.7), r"tolerance: must be in \(0, 0.01\]"),
        (lambda: collide.distance(a, a, tolerance=np.float64(1e300)), "tolerance"),
        (lambda: collide.distance(a, a, max_iterations=3), "max_iterations"),
        (lambda: collide.distance(a, a, max_iterations=10.0), "max_iterations"),
        (lambda: collide.distance(a, a, warm=[1.0, 0.0]), "warm"),
        (lambda: collide.distance(a, a, warm=[np.inf, 0.0, 0.0]), "warm"),
        (lambda: collide.distance(a, a, warm="up"), "warm"),
    ]
    for call, what in cases:
        with pytest.raises(ValueError, match=what):
            call()
        assert collide.distance(a, a, None, pose).distance == want


# --------------------------------------------------------------------------- the result object

def test_distance_is_an_immutable_value_that_pickles_and_warm_starts():
    rng = np.random.default_rng(3)
    a, b = PointCloud(_hull(rng, 400)), PointCloud(_hull(rng, 300))
    pose = (random_rotation(rng), np.array([2.1, 0.3, 0.1]))
    r = collide.distance(a, b, None, pose)
    assert type(r.distance) is float and type(r.lower) is float and type(r.upper) is float
    assert type(r.iterations) is int and all(type(h) is int for h in r.hints)
    assert r.gap == r.upper - r.lower and r.lower <= r.distance <= r.upper
    assert r.point_a.shape == r.point_b.shape == r.normal.shape == (3,)
    assert "distance=" in repr(r) and "normal=" in repr(r)
    with pytest.raises(AttributeError):
        r.distance = 0.0
    with pytest.raises(AttributeError):
        r.extra = 1
    back = pickle.loads(pickle.dumps(r))
    assert _fields(back) == _fields(r)
    # A warm start from the result, its unpickled copy, or a hand-built one: the same answer.
    pose2 = (pose[0], pose[1] + [0.01, 0.0, 0.0])
    cold = collide.distance(a, b, None, pose2)
    for w in (r, back, Distance(r.distance, r.point_a, r.point_b, r.normal, r.lower, r.upper, r.iterations, r.hints)):
        warm = collide.distance(a, b, None, pose2, warm=w)
        assert abs(warm.distance - cold.distance) <= 1e-12 and warm.iterations <= cold.iterations
    # A hand-built result with a non-finite normal or out-of-range hints: a cold start, not a crash.
    for normal, hints in ((np.array([np.nan, 0.0, 0.0]), (0, 0)), (r.normal, (10**9, -5)), (np.zeros(3), (3, 4)),
                          (r.normal, (1e300, -1e300)), (r.normal, (np.nan, np.inf))):
        w = Distance(0.0, np.zeros(3), np.zeros(3), normal, 0.0, 0.0, 0, hints)
        assert abs(collide.distance(a, b, None, pose2, warm=w).distance - cold.distance) <= 1e-12


def test_a_read_only_warm_result_is_copied_not_compiled_for():
    # pickle protocol 5 with out-of-band buffers received as bytes (as ray and dask deliver arrays)
    # gives a Distance over a read-only buffer: the call copies it into the kernel's one form.
    a = PointCloud([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], 0.1)
    pose = (np.eye(3), np.array([3.0, 0.2, 0.0]))
    r = collide.distance(a, a, None, pose)
    bufs = []
    w = pickle.loads(pickle.dumps(r, protocol=5, buffer_callback=bufs.append), buffers=[bytes(b.raw()) for b in bufs])
    assert not w._out.flags.writeable
    assert _fields(collide.distance(a, a, None, pose, warm=w)) == _fields(collide.distance(a, a, None, pose, warm=r))
    assert len(kd.query.signatures) == 1, kd.query.signatures


def test_a_warm_result_of_another_dtype_or_shape_is_converted():
    # A crafted Distance over a float32, big-endian or (16, 1) buffer: converted, not a numba error.
    a = PointCloud([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], 0.1)
    pose = (np.eye(3), np.array([3.0, 0.2, 0.0]))
    r = collide.distance(a, a, None, pose)
    for buf in (r._out.astype(np.float32), r._out.astype(">f8"), r._out.reshape(-1, 1).copy()):
        got = collide.distance(a, a, None, pose, warm=sd._from_out(buf))
        assert abs(got.distance - r.distance) <= 1e-12
    assert len(kd.query.signatures) == 1, kd.query.signatures


def test_the_shape_cache_survives_eviction_and_fresh_shapes():
    # More distinct shapes than the cache holds, each against the closed form of two spheres.
    rng = np.random.default_rng(4)
    first = None
    for k in range(sd._CACHE_SIZE + 50):
        c, r = rng.normal(size=3), rng.uniform(0.1, 0.5)
        s = PointCloud([c], r)
        if first is None:
            first = (s, c, r)
        d = collide.distance(s, PointCloud([[0.0, 0.0, 0.0]], 0.25))
        assert d.distance == pytest.approx(math.hypot(*c) - r - 0.25, abs=1e-12)
    assert len(sd._shapes) <= sd._CACHE_SIZE
    s, c, r = first  # evicted by now, and computed again
    assert collide.distance(s, PointCloud([[0.0, 0.0, 0.0]], 0.25)).distance == pytest.approx(
        math.hypot(*c) - r - 0.25, abs=1e-12)


_FIRST_CALLS = r"""
import sys, threading
import numpy as np
import collide
from collide._kernels import distance as kd
a = collide.PointCloud([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], 0.1)
rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
poses = [(rot.astype(np.float32), np.array([2.5, 0.25, 0.0], np.float32)), (rot, np.array([2.5, 0.25, 0.0]))]
got = [None, None]
barrier = threading.Barrier(2)
def first(i):
    barrier.wait()
    got[i] = collide.distance(a, a, None, poses[i]).distance
ts = [threading.Thread(target=first, args=(i,)) for i in range(2)]
[t.start() for t in ts]
[t.join() for t in ts]
sigs = kd.query.signatures
after = collide.distance(a, a, None, (rot.T.copy().T, [2.5, 0.25, 0.0])).distance
print(repr(got[0]), repr(got[1]), repr(after), len(sigs))
"""


def test_the_first_calls_load_one_signature_whatever_their_form():
    # The kernel's dispatcher compiles nothing but its one signature (`signed_distance._load_query`):
    # in a fresh process, two threads' first calls at once, one of them with float32 arrays (which
    # numba would otherwise compile a second kernel for, a minute), then a transposed view and a
    # list: one signature, and the answers of the canonical form.
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    run = subprocess.run([sys.executable, "-c", _FIRST_CALLS], capture_output=True, text=True, cwd=root, timeout=900)
    assert run.returncode == 0, run.stderr[-2000:]
    first32, first64, after, nsig = run.stdout.split()
    assert int(nsig) == 1
    assert float(first64) == float(after) and abs(float(first32) - float(first64)) < 1e-6
    assert 0.0 < float(first64) < 2.0  # the pair is apart (a real query, not a refused one)
