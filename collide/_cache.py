"""numba's on-disk kernel cache, keyed on every package file a kernel depends on.

numba stamps a cached kernel with its own source file only (numba issue #6845, open since 2021).
Our kernels inline helpers from other files (`_kernels.lanes` runs `_kernels.broadphase`'s tests,
every kernel uses `_kernels._ptr`) and freeze the module constants they read. After an update that
changes only such a file -- a ``git pull`` into the README's editable install, one edit while
developing -- numba would load the old machine code: a silently wrong answer, or a kernel that
disagrees with its twin. Measured with numba 0.68.1: a cached ``g`` calling an inlined ``f`` from
another file kept returning ``f``'s old result after ``f`` changed.

`_PackageLocator` wraps the locator numba would have chosen (same folder, same file names) and adds
to its stamp the content hashes of every file of this package the kernel's file imports,
transitively; numba discards an index whose stamp differs and compiles afresh. It is registered
when `collide` is imported, before any kernel is defined.
"""

from __future__ import annotations

import functools
import hashlib
import os
import re
import warnings

_ROOT = os.path.dirname(os.path.abspath(__file__))
# ``from .x import ...``, ``from ..x.y import (...)``, ``from . import a, b``: the package-relative
# imports (the package imports itself only this way).
_FROM = re.compile(r"^[ \t]*from[ \t]+(\.+)([\w.]*)[ \t]+import[ \t]+(\([^)]*\)|[^\n#]*)", re.M)


def _module_file(package_dir: str, dotted: str) -> str | None:
    path = os.path.join(package_dir, *dotted.split("."))
    for cand in (path + ".py", os.path.join(path, "__init__.py")):
        if os.path.isfile(cand):
            return cand
    return None


@functools.lru_cache(maxsize=None)
def _direct_imports(path: str, mtime_ns: int, size: int) -> tuple[str, ...]:
    # The package files that ``path`` imports by relative imports (keyed on its stat: re-read on change).
    with open(path, encoding="utf-8") as f:
        text = f.read()
    here = os.path.dirname(path)
    out = []
    for dots, module, names in _FROM.findall(text):
        base = here
        for _ in range(len(dots) - 1):
            base = os.path.dirname(base)
        if module:
            found = _module_file(base, module)
            if found is not None:
                out.append(found)
        else:  # from . import a, b as c: each name may be a submodule
            for name in names.strip("()").replace("\n", " ").split(","):
                name = name.split(" as ")[0].strip()
                found = _module_file(base, name) if name else None
                if found is not None:
                    out.append(found)
    return tuple(out)


@functools.lru_cache(maxsize=None)
def _file_hash(path: str, mtime_ns: int, size: int) -> bytes:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).digest()


def dependency_files(path: str) -> list[str]:
    """``path`` and every file of its package it imports, transitively (package-relative imports),
    sorted; only files under ``path``'s top package folder are followed."""
    path = os.path.abspath(path)
    seen = {path}
    todo = [path]
    while todo:
        p = todo.pop()
        st = os.stat(p)
        for q in _direct_imports(p, st.st_mtime_ns, st.st_size):
            q = os.path.abspath(q)
            if q not in seen:
                seen.add(q)
                todo.append(q)
    return sorted(seen)


def source_stamp(path: str, root: str = _ROOT) -> bytes:
    """One hash of the contents of `dependency_files` (paths relative to ``root``)."""
    h = hashlib.sha256()
    for p in dependency_files(path):
        st = os.stat(p)
        h.update(os.path.relpath(p, root).encode())
        h.update(_file_hash(p, st.st_mtime_ns, st.st_size))
    return h.digest()


def _inside(path: str, root: str) -> bool:
    try:
        return os.path.commonpath([os.path.abspath(path), root]) == root
    except ValueError:  # another drive
        return False


def register() -> None:
    """Put `_PackageLocator` (for this copy of the package) first among numba's cache locators."""
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
            return self._inner.get_disambiguator()

        def get_source_stamp(self):
            return (self._inner.get_source_stamp(), source_stamp(self._py_file, root))

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
