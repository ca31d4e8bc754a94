"""numba's on-disk kernel cache, keyed on every package file a kernel depends on.

numba stamps a cached kernel with its own source file only (a documented limitation: "cache
invalidation fails to recognize changes in symbols defined in a different file", numba's JIT
guide; feature request numba/numba#1833, work in numba/numba#8396).
Our kernels inline helpers from other files (`_kernels.lanes` runs `_kernels.broadphase`'s tests,
every kernel uses `_kernels._ptr`) and freeze the module constants they read. After an update that
changes only such a file -- a ``git pull`` into the README's editable install, one edit while
developing -- numba would load the old machine code: a silently wrong answer, or a kernel that
disagrees with its twin. Measured with numba 0.68.1: a cached ``g`` calling an inlined ``f`` from
another file kept returning ``f``'s old result after ``f`` changed.

`_PackageLocator` wraps the locator numba would have chosen (same folder, same file names) and adds
to its stamp the content hashes of every file of this package the kernel's file imports,
transitively; numba discards an index whose stamp differs and compiles afresh. It is registered
when `collide` is imported, before any kernel is defined. (``NUMBA_CACHE_LOCATOR_CLASSES``, where
set, replaces numba's list of locators, this one included: numba's own stamps then.)

A cache miss means a compile, with no output of numba's: a minute or more for the per-step
kernels, several for the batch checker's. `register` also listens to numba's ``numba:compile``
event (numba.core.event, broadcast only when a kernel is compiled, not when it is loaded from the
cache) and says so on stderr when a kernel of this package first starts compiling, then again,
naming the kernel, after each `STILL_EVERY` seconds of compiling since its last line.
"""

from __future__ import annotations

import functools
import hashlib
import os
import re
import sys
import threading
import time
import warnings

_ROOT = os.path.dirname(os.path.abspath(__file__))


def _module_file(base: str, dotted: str) -> str | None:
    # The file of module ``dotted`` ("" for the package itself) under the folder ``base``.
    path = os.path.join(base, *dotted.split(".")) if dotted else base
    for cand in (path + ".py", os.path.join(path, "__init__.py")):
        if os.path.isfile(cand):
            return cand
    return None


@functools.lru_cache(maxsize=None)
def _patterns(pkg: str):
    # ``from .x import a``, ``from..x.y import (a, b)``, ``from . import a``, ``from pkg.x import a``;
    # ``import pkg.x as y``. Comments are dropped and backslash continuations joined first.
    from_ = re.compile(r"^[ \t]*from[ \t]*(\.+|" + re.escape(pkg) + r"(?=[\s.]))([\w.]*)[ \t]*import\b[ \t]*"
                       r"(\([^)]*\)|[^\n]*)", re.M)
    import_ = re.compile(r"^[ \t]*import[ \t]+([^\n]*)", re.M)
    return from_, import_


@functools.lru_cache(maxsize=None)
def _direct_imports(path: str, mtime_ns: int, size: int, root: str = _ROOT) -> tuple[str, ...]:
    """The files of the package at ``root`` that the file ``path`` imports, relatively or by the
    package's name: each module named, and each imported name that is a submodule (``from .sub
    import a`` imports ``sub/a.py`` when it exists; the package's ``__init__`` only when a name
    is not a submodule). Keyed on the file's stat, so a changed file is read again."""
    with open(path, encoding="utf-8", errors="replace") as f:
        text = f.read()
    text = re.sub(r"#[^\n]*", "", text).replace("\\\n", " ")
    pkg = os.path.basename(root)
    from_, import_ = _patterns(pkg)
    here = os.path.dirname(path)
    out = []
    for lead, module, names in from_.findall(text):
        if lead.startswith("."):
            base = here
            for _ in range(len(lead) - 1):
                base = os.path.dirname(base)
            itself = not module  # from . import a: the package itself
        else:  # pkg.x.y: from the folder holding the package
            base, module, itself = os.path.dirname(root), pkg + module, not module
        parent = _module_file(base, module)
        if parent is None:
            continue
        folder = os.path.dirname(parent) if parent.endswith("__init__.py") else None
        all_submodules = True
        for name in names.strip("()").replace("\n", " ").split(","):
            name = name.split(" as ")[0].strip()
            sub = _module_file(folder, name) if (folder and name and name != "*") else None
            if sub is not None:
                out.append(sub)
            elif name:
                all_submodules = False
        if not itself or not all_submodules:
            out.append(parent)
    for names in import_.findall(text):
        for name in names.split(","):
            name = name.split(" as ")[0].strip()
            if name == pkg or name.startswith(pkg + "."):
                found = _module_file(os.path.dirname(root), name)
                if found is not None:
                    out.append(found)
    return tuple(out)


@functools.lru_cache(maxsize=None)
def _file_hash(path: str, mtime_ns: int, size: int) -> bytes:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).digest()


def dependency_files(path: str, root: str = _ROOT) -> list[str]:
    """``path`` and every file of the package at ``root`` it imports, transitively (see
    `_direct_imports`), sorted."""
    path = os.path.abspath(path)
    seen = {path}
    todo = [path]
    while todo:
        p = todo.pop()
        st = os.stat(p)
        for q in _direct_imports(p, st.st_mtime_ns, st.st_size, root):
            q = os.path.abspath(q)
            if q not in seen:
                seen.add(q)
                todo.append(q)
    return sorted(seen)


def source_stamp(path: str, root: str = _ROOT) -> bytes:
    """One hash of the contents of `dependency_files` (paths relative to ``root``)."""
    h = hashlib.sha256()
    for p in dependency_files(path, root):
        st = os.stat(p)
        h.update(os.path.relpath(p, root).encode())
        h.update(_file_hash(p, st.st_mtime_ns, st.st_size))
    return h.digest()


def _inside(path: str, root: str) -> bool:
    # A source file of this package on disk (not in a zip archive, not a frozen application's:
    # numba's own locators handle those, and their files cannot be read here).
    if getattr(sys, "frozen", False) or not os.path.isfile(path):
        return False
    path, root = os.path.normcase(os.path.abspath(path)), os.path.normcase(root)
    try:
        return os.path.commonpath([path, root]) == root
    except ValueError:  # another drive
        return False


COMPILE_NOTICE = ("compiling {}'s kernels, once: a minute or more (the batch checker's several minutes); "
                  "cached afterwards")
# Said again after each STILL_EVERY seconds spent compiling the package's kernels since the last
# notice, naming the kernel (`_announce_compiles`): one process may compile for minutes, a kernel
# at a time, and each call that compiles would otherwise be silent after the first notice.
STILL_EVERY = 60.0
STILL_NOTICE = "still compiling {}'s kernels ({}, {:.0f} min of compiling so far), once: cached afterwards"


def _announce_compiles(root: str) -> None:
    # On stderr, when a kernel of the package at ``root`` starts compiling (a cache miss): the first
    # run is otherwise a silent minute; then again (`STILL_NOTICE`, from a timer thread) after each
    # `STILL_EVERY` seconds spent in the package's compiles since the last line, so that no compile
    # is silent for longer. Loading from the cache broadcasts nothing. Compiles are timed from the
    # outermost compile of a package kernel to its end (its callees, numba's own functions
    # included, compile inside it); numba compiles one function at a time (its compiler lock).
    try:
        from numba.core import event
    except ImportError:  # pragma: no cover (every numba this package supports has it)
        return
    pkg = os.path.basename(root)

    def ours(ev) -> str | None:
        # The compiled function's qualified name when it is a kernel of this package, else None.
        disp = (ev.data or {}).get("dispatcher")
        func = getattr(disp, "py_func", None)
        module = getattr(func, "__module__", "") or ""
        if module == pkg or module.startswith(pkg + "."):
            return f"{module}.{getattr(func, '__qualname__', '?')}"
        return None

    class _Notice(event.Listener):
        _collide_root = root
        said = False

        def __init__(self):
            super().__init__()
            self.lock = threading.Lock()
            self.outer = None  # the running outermost package compile's event data (None: none running)
            self.name = None  # that outermost kernel
            self.t0 = 0.0  # when it (or the last notice during it) began
            self.spent = 0.0  # seconds compiling since the last notice
            self.total = 0.0  # seconds compiling, all told
            self.timer = None
            if hasattr(os, "register_at_fork"):  # one listener a process: registered once
                os.register_at_fork(after_in_child=self._forked)

        def _forked(self):
            # A forked child: the timer thread and any thread compiling are the parent's, and may
            # have held the lock (`collide._fork`); the child's next compile starts afresh.
            self.lock = threading.Lock()
            self.outer = self.timer = None

        def on_start(self, ev):
            with self.lock:
                if self.outer is not None:
                    return
                name = ours(ev)
                if name is None:
                    return
                first, self.said = not self.said, True
                self.outer, self.name, self.t0 = ev.data, name, time.perf_counter()
                self._arm(max(STILL_EVERY - self.spent, 0.0))
            if first:  # printed outside the lock: whatever the write runs may compile
                print(COMPILE_NOTICE.format(pkg), file=sys.stderr, flush=True)

        def on_end(self, ev):
            with self.lock:
                if self.outer is None or ev.data is not self.outer:  # start and end share one data dict
                    return
                now = time.perf_counter()
                self.spent += now - self.t0
                self.total += now - self.t0
                self.outer = None
                if self.timer is not None:
                    self.timer.cancel()
                    self.timer = None

        def _arm(self, delay):
            timer = threading.Timer(delay, self._still)
            timer.daemon = True  # never keeps the process alive
            try:
                timer.start()
            except RuntimeError:  # no thread to be had (Python >= 3.12 at exit, a thread limit): no line
                timer = None
            self.timer = timer

        def _still(self):
            with self.lock:
                if self.outer is None or threading.current_thread() is not self.timer:
                    return  # that compile ended (or another timer replaced this one)
                now = time.perf_counter()
                self.total += now - self.t0
                line = STILL_NOTICE.format(pkg, self.name, self.total / 60.0)
                self.t0, self.spent = now, 0.0
                self._arm(STILL_EVERY)
            print(line, file=sys.stderr, flush=True)

    listeners = getattr(event, "_registered", {}).get("numba:compile", [])  # one listener per copy
    if not any(getattr(lst, "_collide_root", None) == root for lst in listeners):
        event.register("numba:compile", _Notice())


def register(suffix: str = "") -> None:
    """Put `_PackageLocator` (for this copy of the package) first among numba's cache locators;
    ``suffix`` is appended to its cache files' names (a compilation mode kept apart). Also says
    on stderr when a kernel of the package first starts compiling (`COMPILE_NOTICE`), and after each
    `STILL_EVERY` seconds of compiling since (`STILL_NOTICE`)."""
    _announce_compiles(_ROOT)
    try:
        from numba.core import caching

        impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # the older name: _CacheImpl
        base = caching._CacheLocator
        impl._locator_classes  # noqa: B018 (present in every numba this package supports)
    except (ImportError, AttributeError):  # pragma: no cover (a numba without these internals)
        warnings.warn("collide: this numba's cache cannot be keyed on the files a kernel imports; after "
                      "updating collide, delete its __pycache__ folders", RuntimeWarning, stacklevel=2)
        return
    root = _ROOT

    class _PackageLocator(base):
        # Delegates everything but the stamp to the locator numba would have used.
        _collide_root = root

        def __init__(self, inner, py_file):
            self._inner = inner
            self._py_file = py_file

        def ensure_cache_path(self):
            self._inner.ensure_cache_path()

        def get_cache_path(self):
            return self._inner.get_cache_path()

        def get_disambiguator(self):
            # e.g. the checked mode's kernels (`collide._checked`) in cache files of their own
            return self._inner.get_disambiguator() + suffix

        def get_source_stamp(self):
            try:
                ours = source_stamp(self._py_file, root)
            except OSError:  # a file gone meanwhile: a stamp that matches no index, so a recompile
                ours = None
            return (self._inner.get_source_stamp(), ours)

        @classmethod
        def from_function(cls, py_func, py_file):
            if not _inside(py_file, root):
                return None
            for other in impl._locator_classes:
                if getattr(other, "_collide_root", None) is not None:  # ours, or another copy's
                    continue
                inner = other.from_function(py_func, py_file)
                if inner is not None:
                    return cls(inner, py_file)
            return None

    classes = impl._locator_classes
    if not any(getattr(c, "_collide_root", None) == root for c in classes):
        classes.insert(0, _PackageLocator)
    _lock_saves(caching)


# One lock file per cache folder, beside numba's index files.
LOCK_NAME = "collide-cache.lock"


def _lock_saves(caching) -> None:
    """Make numba's saving of a cache entry one process's at a time in each cache folder.

    numba's ``IndexDataCacheFile.save`` reads a function's index, picks for a new entry the first
    data-file name the index does not list (``<name>.1.nbc``, ...), then writes the index and the
    data file. Two processes saving new entries (other signatures) of one function at once can
    pick the same name: the index one of them leaves then maps its signature to the other's
    machine code, which numba loads without checking. The test run's warm-up process
    (``tests/_warmup.py``) compiles beside the tests, and users run several processes on one
    checkout, so the read-modify-write runs under an exclusive ``flock`` of the folder's
    `LOCK_NAME`; loading is unchanged (it reads whole files, written to a temporary file and
    renamed). Where the lock cannot be taken (no ``fcntl``, a read-only folder) numba saves as
    before.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover (Windows)
        return
    cls = getattr(caching, "IndexDataCacheFile", None)
    save = getattr(cls, "save", None)
    if save is None or getattr(save, "_collide_locked", False):
        return

    def locked_save(self, key, data):
        try:
            fd = os.open(os.path.join(self._cache_path, LOCK_NAME), os.O_RDWR | os.O_CREAT, 0o644)
        except (OSError, AttributeError):
            return save(self, key, data)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            return save(self, key, data)
        finally:
            os.close(fd)  # releases the lock

    locked_save._collide_locked = True
    locked_save.__wrapped__ = save
    cls.save = locked_save
