"""`log_rerun` (`collide.mujoco.log_rerun`) and `record_compare` (``compare --rerun``)."""

from __future__ import annotations

from .._validate import as_count
from ._convert import _as_flag
from ._log import RerunLog


def log_rerun(model, path=None, *, spawn: bool = False, recording=None, **options) -> RerunLog:
    """A `RerunLog` of ``model``: call ``.log(data)`` after each step of your loop, then ``.close()``.

    Parameters
    ----------
    model : mujoco.MjModel
    path, spawn, recording, **options
        See `RerunLog`.

    Returns
    -------
    RerunLog

    Examples
    --------
    >>> import mujoco, collide.mujoco as cm                          # doctest: +SKIP
    >>> model = cm.default_scene(); data = mujoco.MjData(model)      # doctest: +SKIP
    >>> with cm.log_rerun(model, "run.rrd") as log:                  # doctest: +SKIP
    ...     for _ in range(300):
    ...         mujoco.mj_step(model, data)
    ...         log.log(data)
    """
    return RerunLog(model, path, spawn=spawn, recording=recording, **options)


def record_compare(model, path=None, *, spawn: bool = False, recording=None, steps: int = 1000, seed: int = 0,
                   name: str = "model", hold: int = 100, contacts: bool = True, **options) -> tuple[dict, list]:
    """`collide.mujoco.compare`, with every step recorded to Rerun.

    The timed run only keeps copies of each step's state (`RerunLog.snapshot`); they are logged
    after it, with our contacts computed on them, so the comparison's times are those of a run
    without a log. Then its per-step series: MuJoCo's broad-phase candidates
    (``stats/pairs/mujoco_candidates``), our broad phase's time and MuJoCo's
    (``stats/time_us/collide_broad``, ``stats/time_us/mujoco_broad``).

    Parameters
    ----------
    model : mujoco.MjModel
    path, spawn, recording, **options
        See `RerunLog`.
    steps, seed, name, hold, contacts
        See `collide.mujoco.compare`. ``contacts=False`` also leaves our contacts out of the
        recording (neither computed nor drawn; ``world/contacts/collide`` and
        ``world/contacts/missed`` absent).

    Returns
    -------
    result : dict
        `collide.mujoco.compare`'s.
    records : list of StepRecord
        What was logged at each step.

    Raises
    ------
    ValueError
        A bad argument (those of `RerunLog` and of `collide.mujoco.compare`), found before the
        file is opened: an existing file is left as it was.

    Notes
    -----
    Every step's state (body and geom poses, MuJoCo's contacts) is kept in memory until the run
    ends: ``96 * (nbody + ngeom)`` bytes a step (a position and a rotation matrix each, float64),
    plus 8 bytes a candidate pair and 64 a MuJoCo contact; for a model of 500 bodies and 1000
    geoms, 144 kB a step, 144 MB for 1000 steps.
    """
    from .. import mujoco as cm

    # compare's arguments, checked before RerunLog opens (and truncates) the file.
    steps = as_count(steps, "steps", 1)
    seed = as_count(seed, "seed", 0)
    hold = as_count(hold, "hold", 1)
    contacts = _as_flag(contacts, "contacts")
    if not isinstance(name, str):
        raise ValueError(f"name: expected a str, got {type(name).__name__}")
    with RerunLog(model, path, spawn=spawn, recording=recording, contacts=contacts, **options) as log:
        result = cm.compare(model, steps=steps, seed=seed, name=name, broadphase=log.broadphase,
                            on_step=log.snapshot, hold=hold, contacts=contacts)
        records = log.flush_snapshots()
        log.log_series("stats/pairs/mujoco_candidates", result["mujoco_candidates_per_step"])
        log.log_series("stats/time_us/collide_broad", result["time_ours_us_per_step"])
        log.log_series("stats/time_us/mujoco_broad", result["time_mujoco_broad_us_per_step"])
    return result, records
