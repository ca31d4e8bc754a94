"""The checked mode (`collide._checked`): run with ``COLLIDE_CHECKED=1`` (CI does, for the
broad-phase and MuJoCo tests), these tests show that a view carved past its buffer and an index
past a view raise IndexError instead of reading a neighbour's memory."""

import numba
import numpy as np
import pytest

import collide
from collide import _checked, shapes
from collide._kernels import layout
from collide._kernels._ptr import check_span

checked_only = pytest.mark.skipif(not _checked.CHECKED, reason="run with COLLIDE_CHECKED=1 (CI runs this file so)")


# Not cached: a test file's kernels are cached by numba's own locator, in the same files in
# both modes, so a kernel compiled in the normal mode would be loaded unchecked in the checked one.
@numba.njit
def _views_of(I, F, W):
    # the last field of each buffer, through the field table (`_kernels.layout`)
    layout.view_i1(I, I, layout.I_SMASK)
    layout.view_f2(I, F, layout.F_GCAP)
    layout.view_f1(I, W, layout.W_COH)
    return I[layout.H_L]


@numba.njit
def _span(end, size):
    check_span(end, size)
    return end


@numba.njit
def _read(a, i):
    return a[i]


def _buffers():
    art = collide.Articulation(body_parent=[0, 0, 1], geom_body=[1, 2],
                               geom_cloud=[shapes.box([0.1, 0.1, 0.1]), shapes.sphere(0.1)])
    bp = collide.BroadPhase(art)
    return bp._I, bp._F, bp._W


def test_the_mode_follows_the_environment_and_has_its_own_cache_files():
    import os
    assert _checked.CHECKED == (os.environ.get("COLLIDE_CHECKED", "").strip() not in ("", "0"))
    assert numba.config.BOUNDSCHECK == (1 if _checked.CHECKED else numba.config.BOUNDSCHECK)
    assert _span(5, 5) == 5  # in range: no error in either mode


@checked_only
def test_views_past_their_buffer_raise():
    I, F, W = _buffers()
    assert _views_of(I, F, W) == 3  # the whole layout fits
    with pytest.raises(IndexError, match="checked mode"):
        _views_of(I, F, W[:10])  # the bounds rows need more
    with pytest.raises(IndexError, match="checked mode"):
        _views_of(I[:-1], F, W)
    with pytest.raises(IndexError, match="checked mode"):
        _span(6, 5)


@checked_only
def test_an_index_past_a_view_raises():
    a = np.arange(4.0)
    assert _read(a, 3) == 3.0
    with pytest.raises(IndexError):
        _read(a, 4)
