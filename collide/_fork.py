"""What a forked child must not inherit: locks (`new_lock`) and numba's GNU OpenMP threads
(`require_parallel`).

The fork of a process with threads copies only the forking thread. A lock another thread of the
parent held at that moment stays held in the child, by a thread that does not exist there, and the
child's first call that takes it waits forever. A lock made by `new_lock` is replaced in a forked
child by a new, free one, where its owner (a module or an object, held weakly) keeps it. The state
the lock guarded is the owner's to make consistent (the broad phase's `_after_fork`); the caches
guarded here change by single dictionary operations under their lock, so a child sees each
operation done or not done.

numba's ``omp`` threading layer on GNU OpenMP (libgomp) cannot run a parallel kernel in a process
forked after the parent started it: libgomp's threads are not in the child (GCC bug 52303), and
numba's launch in such a child prints "Terminating: fork() called from a process already using
GNU OpenMP, this is unsafe." and sends the process SIGTERM (found 2026-12-02: a planner's worker
forked after a `check_batch` was killed at its first one). A forked child of such a parent, and
its own children, have every batch kernel refused instead: `require_parallel` raises a
RuntimeError that says what to do. Where the parent had not started the layer, or runs numba's
``tbb`` or ``workqueue`` layer, the child starts its own and nothing is refused.
"""

from __future__ import annotations

import os
import sys
import threading
import weakref

__all__ = ["new_lock", "require_parallel"]

# id(owner) -> (weak reference to the owner, the names of its attributes holding a lock of
# `new_lock`). Keyed by identity, not by the owner's own hash and equality (a subclass may define
# them); the reference's callback drops the entry before the id can be reused.
_owners: dict = {}
_owners_guard = threading.Lock()  # `_owners` changes under it (renewed in the child first)
_omp_forked = False  # this process was forked from one running numba's GNU OpenMP layer (or its child)


def new_lock(owner: object, name: str) -> threading.Lock:
    """A new lock, for ``owner.<name>``, that a forked child replaces by a free one.

    Parameters
    ----------
    owner : module or object
        What holds the lock (weakly referenced here: an object's lock is forgotten with it).
    name : str
        The attribute of ``owner`` the lock is kept in; the child sets it to a new lock.

    Returns
    -------
    threading.Lock
        The lock, to be stored as ``owner.<name>`` by the caller.
    """
    key = id(owner)
    with _owners_guard:
        entry = _owners.get(key)
        if entry is None or entry[0]() is not owner:
            entry = _owners[key] = (weakref.ref(owner, lambda _, k=key: _owners.pop(k, None)), set())
        entry[1].add(name)
    return threading.Lock()


def require_parallel() -> None:
    """Raise where numba's parallel kernels cannot run in this process (see the module's notes).

    Raises
    ------
    RuntimeError
        This process was forked from one that had started numba's GNU OpenMP threading layer.
    """
    if _omp_forked:
        raise RuntimeError(
            "collide's batch kernels cannot run in this process: it was forked from one that had already "
            "run numba's parallel kernels on GNU OpenMP, which cannot run in a forked process (numba would "
            "terminate it). Start worker processes with multiprocessing's 'spawn' or 'forkserver' method "
            "(multiprocessing.get_context('spawn')), or fork them before the parent's first batch call.")


def _gnu_openmp_started() -> bool:
    # numba's threading layer started in this process, and it is GNU OpenMP. Read from the modules
    # as loaded (nothing imported in a fork handler); any surprise in numba's internals: False.
    try:
        par = sys.modules.get("numba.np.ufunc.parallel")
        omp = sys.modules.get("numba.np.ufunc.omppool")
        return bool(par is not None and par._is_initialized and omp is not None
                    and par._threading_layer == "omp" and omp.openmp_vendor == "GNU")
    except Exception:  # noqa: BLE001 - a numba without these attributes: refuse nothing
        return False


def _after_fork() -> None:
    global _owners_guard, _omp_forked
    _owners_guard = threading.Lock()
    _omp_forked = _omp_forked or _gnu_openmp_started()
    for ref, names in list(_owners.values()):
        owner = ref()
        for name in names if owner is not None else ():
            setattr(owner, name, threading.Lock())


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork)
