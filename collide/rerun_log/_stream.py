"""The recording stream: ``rerun`` imported when a log is made, series sent as columns, the exit hook.

A log keeps its per-step series (and the poses of replayed states) in dicts and sends them as
columns every few steps (`_send`); a log dropped or left open at interpreter exit sends what it
kept then (`_watch`).
"""

from __future__ import annotations

import atexit
import weakref

import numpy as np


def _rerun():
    try:
        import rerun
    except ImportError:
        raise ImportError("rerun-sdk is not installed: pip install 'collide[viz]' (or pip install rerun-sdk)") from None
    return rerun


def _send(rr, rec, series: dict, poses: dict) -> None:
    # The kept series and replayed mesh poses, sent as columns and cleared in place: also the
    # finalizer of a log never closed (`RerunLog.__init__`), so it holds these dicts, not the log.
    for entity, (steps, values) in series.items():
        if steps:
            rec.send_columns(entity, indexes=[rr.TimeColumn("step", sequence=np.asarray(steps, dtype=np.int64))],
                             columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)))
    series.clear()
    for entity, (steps, translation, mat) in poses.items():
        if steps:
            rec.send_columns(entity, indexes=[rr.TimeColumn("step", sequence=steps)],
                             columns=rr.Transform3D.columns(translation=translation, mat3x3=mat))
    poses.clear()


def _send_at_exit(rr, rec, series: dict, poses: dict) -> None:
    # A log dropped or left open at interpreter exit: its last series are sent, not lost (they go
    # every `series_every` steps).
    try:
        _send(rr, rec, series, poses)
        rec.flush()
    except Exception:  # noqa: BLE001 - at exit, with the sink perhaps gone: nothing to tell
        pass


_OPEN: set = set()  # the finalizers of the logs not closed yet
_hooked = False


def _at_exit() -> None:
    for f in list(_OPEN):
        f()  # a finalizer already run (its log collected) does nothing


def _watch(log, *args) -> weakref.finalize:
    # weakref.finalize's own exit hook runs after Rerun's shutdown whenever some module made a
    # finalizer before rerun was imported (it is registered once, with the first one), and the
    # file is closed by then (tried: the series were lost). So ours is an atexit hook of its own,
    # registered after rerun's (atexit runs last in, first out): the series reach the file.
    global _OPEN, _hooked
    if not _hooked:
        atexit.register(_at_exit)
        _hooked = True
    f = weakref.finalize(log, _send_at_exit, *args)
    f.atexit = False
    _OPEN = {g for g in _OPEN if g.alive}
    _OPEN.add(f)
    return f
