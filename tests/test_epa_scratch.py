"""EPA on its caller's scratch (`collide._kernels.epa.epa_on`): the narrow phase's workspace holds
EPA's buffers (`collide._kernels.distance.WS_F_EPA`, ``WS_I_EPA``), so that a penetrating pair
allocates nothing per step; the answers are those of EPA on buffers of its own, and a scratch too
short for the cap lowers it, never writing past its end."""

import os
import subprocess
import sys

import numpy as np
import pytest
from numba import njit

from collide import testing
from collide._kernels import distance as kd
from collide._kernels.epa import CAPPED, CONVERGED, DEGENERATE, epa_on, epa_sizes
from collide._kernels.gjk import OVERLAP, gjk_within
from collide._kernels.support import POINTS
from collide.testing.surfaces import random_rotation
from contact_check import MODELS

_E32 = np.zeros(0, np.int32)


def _shape(pts, rot, pos):
    # a posed cloud with no ball and no adjacency (supports by scan)
    return (POINTS, np.zeros(4), np.ascontiguousarray(pts, dtype=np.float64), _E32, _E32, rot, pos)


@njit(cache=True)
def _within(sa, sb, tol, fws, iws, out):
    # pair_distance_within on the scratch given (the contact kernel's call, cold)
    kd.pair_distance_within(sa, sb, tol, np.inf, np.zeros(3), -1, -1, kd.EPA_CAP, out, fws, iws)


@njit(cache=True)
def _epa_after_gjk(sa, sb, tol, cap, fws, iws, res):
    # GJK's final simplex, then EPA on the scratch given: (GJK's status, EPA's status)
    W = np.zeros((4, 3))
    WA = np.zeros((4, 3))
    WB = np.zeros((4, 3))
    lam = np.zeros(4)
    dirn = np.zeros(4)
    v = np.zeros(3)
    pa = np.zeros(3)
    pb = np.zeros(3)
    hints = np.full(2, -1)
    st, n, lower, scale, it = gjk_within(sa, sb, np.zeros(3), hints, tol, np.inf, 128, W, WA, WB, lam, v, dirn, pa,
                                         pb)
    if st != OVERLAP:
        return st, -1
    est, s, eit = epa_on(sa, sb, W, WA, WB, n, hints, tol, cap, lower, res, fws, iws)
    return st, est


def _pairs(seed, count):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        p = rng.normal(size=(int(rng.integers(4, 40)), 3))
        q = rng.normal(size=(int(rng.integers(4, 40)), 3)) * rng.uniform(0.3, 1.5)
        ra, rb = random_rotation(rng), random_rotation(rng)
        ta, tb = rng.normal(size=3) * 0.2, rng.normal(size=3) * 0.6
        yield p, q, ra, ta, rb, tb


def test_epa_on_the_workspace_answers_as_epa_on_its_own_buffers():
    # The contact kernel's scratch (EPA's included) against pair_distance's (EPA allocating its own):
    # every slot of the answer bit for bit, on penetrating and separated random clouds.
    penetrating = 0
    for p, q, ra, ta, rb, tb in _pairs(0, 300):
        sa, sb = _shape(p, ra, ta), _shape(q, rb, tb)
        tol = 1e-9 * 4.0
        mine = np.empty(kd.OUT_SIZE)
        _within(sa, sb, tol, np.empty(kd.WS_F_EPA), np.empty(kd.WS_I_EPA, np.int64), mine)
        theirs = np.empty(kd.OUT_SIZE)
        kd.pair_distance(sa, sb, tol, np.zeros(3), -1, -1, kd.EPA_CAP, theirs)
        assert np.array_equal(mine, theirs), (mine, theirs)
        penetrating += mine[kd.OUT_PENETRATING] == 1.0
    assert penetrating > 100  # EPA ran on most of them


def test_a_short_scratch_lowers_the_cap_and_never_writes_past_its_end():
    full_f, full_i = epa_sizes.py_func(kd.EPA_CAP)
    mid_f, mid_i = epa_sizes.py_func(12)
    lengths = [(full_f, full_i), (mid_f, mid_i), (mid_f, full_i), (full_f, mid_i), (full_f, 100), (200, full_i)]
    statuses = {CONVERGED: 0, CAPPED: 0, DEGENERATE: 0}
    for p, q, ra, ta, rb, tb in _pairs(1, 60):
        true = testing.polytope_signed_distance(p @ ra.T + ta, q @ rb.T + tb)
        slack = 1e-12 * (np.abs(p).max() + np.abs(q).max() + 2.0)
        sa, sb = _shape(p, ra, ta), _shape(q, rb, tb)
        for nf, ni in lengths:
            fbuf = np.full(nf + 64, 7.0)  # a canary after the scratch given
            ibuf = np.full(ni + 64, 7, np.int64)
            res = np.full(13, np.nan)
            gst, est = _epa_after_gjk(sa, sb, 1e-10, kd.EPA_CAP, fbuf[:nf], ibuf[:ni], res)
            assert np.all(fbuf[nf:] == 7.0) and np.all(ibuf[ni:] == 7), (nf, ni)
            if gst != OVERLAP:
                continue
            statuses[est] += 1
            assert res[0] - slack <= true <= res[1] + slack, (nf, ni, res[:3], true)
            if nf < epa_sizes.py_func(6)[0] or ni < epa_sizes.py_func(6)[1]:
                assert est == DEGENERATE and res[1] == np.inf  # no polytope: GJK's bracket
    assert statuses[CONVERGED] > 0 and statuses[DEGENERATE] > 0


_STEPS = r"""
import sys
import mujoco
from numba.core.runtime import rtsys
import collide.mujoco as cm
model = mujoco.MjModel.from_xml_path(sys.argv[1])
col, data = cm.Collider(model), mujoco.MjData(model)
mujoco.mj_forward(model, data)
col.contacts(data)  # the first call: the tables bound, the kernels loaded
ctrls = cm._random_controls(model, 300, 0, 10)
allocs = penetrating = 0
for step in range(300):
    if step % 10 == 0 and len(ctrls):
        data.ctrl[:] = ctrls[step // 10]
    mujoco.mj_step(model, data)
    before = rtsys.get_allocation_stats().alloc
    c = col.contacts(data)
    allocs += rtsys.get_allocation_stats().alloc - before
    penetrating += int((c.dist < 0).sum())
print(allocs, penetrating)
"""


@pytest.mark.skipif(not (MODELS / "cube_3x3x3" / "scene.xml").is_file(),
                    reason=f"the test models are not present at {MODELS} (../shared/models)")
def test_the_contact_kernel_allocates_nothing_per_step():
    # numba's allocation counters (NUMBA_NRT_STATS=1, read at its start: a process of its own) over 300
    # steps of cube_3x3x3, whose penetrating mesh pairs run EPA cold every step (a kept polytope that
    # no longer answers, a new contact): before EPA ran on the workspace, ~20 allocations a step.
    env = dict(os.environ, NUMBA_NRT_STATS="1")
    run = subprocess.run([sys.executable, "-c", _STEPS, str(MODELS / "cube_3x3x3" / "scene.xml")], env=env,
                         capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-2000:]
    allocs, penetrating = map(int, run.stdout.split())
    assert penetrating > 1000  # real contacts, EPA's
    assert allocs == 0
