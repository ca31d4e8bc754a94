"""numba's kernel cache follows every package file a kernel imports (`collide._cache`)."""

import ast
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import collide
from collide import _cache

PACKAGE = Path(collide.__file__).parent


def _run(cwd: Path) -> str:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_CACHE")}
    out = subprocess.run([sys.executable, "-c", "import pkgx.b as b; print(b.g(1))"], cwd=cwd, env=env,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_a_cached_kernel_is_recompiled_when_a_file_it_inlines_from_changes(tmp_path):
    # numba alone keeps serving g's old machine code after f changes in another file (numba issue
    # #6845); with the package's locator registered, the edit invalidates g's cache.
    pkg = tmp_path / "pkgx"
    pkg.mkdir()
    shutil.copy(PACKAGE / "_cache.py", pkg / "_cache.py")
    (pkg / "__init__.py").write_text("from . import _cache\n_cache.register()\n")
    (pkg / "a.py").write_text(textwrap.dedent("""
        import numba as nb
        @nb.njit(cache=True, inline="always")
        def f(x):
            return x + 1
    """))
    (pkg / "b.py").write_text(textwrap.dedent("""
        import numba as nb
        from .a import f
        @nb.njit(cache=True)
        def g(x):
            return f(x)
    """))
    assert _run(tmp_path) == "2"
    assert list((pkg / "__pycache__").glob("b.g-*.nbi")), "g was not cached: the test would prove nothing"
    assert _run(tmp_path) == "2"  # from the cache
    (pkg / "a.py").write_text((pkg / "a.py").read_text().replace("x + 1", "x + 2"))
    assert _run(tmp_path) == "3"


def _noticed(tmp_path, name: str, init: str, module: str, call: str, expect: str):
    # A package ``name`` of `_cache.py`'s copy (its __init__ runs ``init`` before register) and a
    # module b (``module``), and a function that runs ``call`` on it in a fresh process (numba's
    # cache under the package) and returns its stderr, its stdout checked to be ``expect``.
    pkg = tmp_path / name
    pkg.mkdir()
    shutil.copy(PACKAGE / "_cache.py", pkg / "_cache.py")
    (pkg / "__init__.py").write_text(f"from . import _cache\n{init}_cache.register()\n")
    (pkg / "b.py").write_text(textwrap.dedent(module))
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_CACHE")}

    def run():
        out = subprocess.run([sys.executable, "-c", f"import {name}.b as b; print({call})"], cwd=tmp_path, env=env,
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        assert out.stdout.strip() == expect
        return out.stderr

    return pkg, run


def test_a_compile_is_announced_on_stderr_once_and_a_cache_load_is_not(tmp_path):
    # The first call compiles for a minute or more with no output of numba's: the package says so first.
    pkg, run = _noticed(tmp_path, "pkgx", "", """
        import numba as nb
        @nb.njit(cache=True)
        def g(x):
            return x + 1
        @nb.njit(cache=True)
        def h(x):
            return g(x) * 2
    """, "b.h(1)", "4")
    notice = _cache.COMPILE_NOTICE.format("pkgx")
    first = run()
    assert first.count(notice) == 1, first  # two kernels compiled, one notice
    assert list((pkg / "__pycache__").glob("b.h-*.nbi")), "h was not cached: the second run would compile"
    assert notice not in run()


def test_a_long_compile_is_announced_again_naming_its_kernel(tmp_path):
    # One process may compile for minutes (check_batch's kernels after the per-step ones): after
    # each STILL_EVERY seconds of compiling since the last line, another names the kernel. Made
    # short here, so that any compile outlasts it; a cache load says nothing.
    _, run = _noticed(tmp_path, "pkgy", "_cache.STILL_EVERY = 0.01\n", """
        import numba as nb
        import numpy as np
        @nb.njit(cache=True)
        def h(x):
            return np.sort(np.cumsum(np.arange(x) * 2.5))[-1]
    """, "b.h(4)", "15.0")
    first = run()
    head, _, _ = _cache.STILL_NOTICE.partition("(")
    lines = [ln for ln in first.splitlines() if ln.startswith(head.format("pkgy"))]
    assert lines, first
    assert all("(pkgy.b.h, " in ln and ln.endswith("once: cached afterwards") for ln in lines), lines
    assert first.count(_cache.COMPILE_NOTICE.format("pkgy")) == 1
    assert run() == ""  # loaded from the cache: not a word


def _module(base: Path, dotted: str) -> Path | None:
    p = base.joinpath(*dotted.split(".")) if dotted else base
    for cand in (p.with_suffix(".py") if dotted else None, p / "__init__.py"):
        if cand is not None and cand.is_file():
            return cand.resolve()
    return None


def _ast_imports(path: Path, root: Path) -> set[Path]:
    # The package files a file imports, resolved by the ast: the module each import names, and each
    # imported name that is a submodule; the package's own __init__ (from . import a) only when a
    # name is not a submodule. Relative imports and imports by the package's name.
    out = set()
    pkg = root.name
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = path.parent
                for _ in range(node.level - 1):
                    base = base.parent
                module, itself = node.module or "", not node.module
            elif node.module == pkg or node.module.startswith(pkg + "."):
                base, module, itself = root.parent, node.module, node.module == pkg
            else:
                continue
            parent = _module(base, module)
            if parent is None:
                continue
            subs = [_module(parent.parent, a.name) if parent.name == "__init__.py" else None for a in node.names]
            out.update(s for s in subs if s is not None)
            if not itself or None in subs:
                out.add(parent)
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name == pkg or a.name.startswith(pkg + "."):
                    found = _module(root.parent, a.name)
                    if found is not None:
                        out.add(found)
    return out


def test_dependency_files_agree_with_the_ast_on_every_package_file():
    files = sorted(PACKAGE.rglob("*.py"))
    assert len(files) > 20
    for path in files:
        st = path.stat()
        direct = {Path(p).resolve() for p in _cache._direct_imports(str(path), st.st_mtime_ns, st.st_size)}
        assert direct == _ast_imports(path, PACKAGE), path
    lanes = {Path(p).relative_to(PACKAGE).as_posix()
             for p in _cache.dependency_files(str(PACKAGE / "_kernels" / "lanes.py"))}
    assert lanes == {"_kernels/lanes.py", "_kernels/lane_tests.py", "_kernels/batch.py", "_kernels/step.py",
                     "_kernels/broadphase.py", "_kernels/coherence.py", "_kernels/walk.py", "_kernels/culling.py",
                     "_kernels/bounds.py", "_kernels/keys.py", "_kernels/layout.py", "_kernels/_ptr.py",
                     "_kernels/_simd.py", "_kernels/_quat.py", "_kernels/_threads.py", "_kernels/_pose.py",
                     "_checked.py"}
    # `from .._kernels import bounds as _k`: a submodule named in the import list
    brute = {Path(p).relative_to(PACKAGE).as_posix()
             for p in _cache.dependency_files(str(PACKAGE / "testing" / "brute.py"))}
    assert "_kernels/bounds.py" in brute


@pytest.mark.parametrize("source", [
    "from .sub import a as _a\n",
    "from . import (h,  # helpers\n    a)\n",
    "from.a import f\n",
    "from .a \\\n    import f\n",
    "from pkgx.a import f\n",
    "import pkgx.a\n",
    "from pkgx import a\n",
])
def test_every_import_form_is_followed(tmp_path, source):
    # Each form, written as Python allows it, makes the target a dependency; the ast agrees.
    pkg = tmp_path / "pkgx"
    (pkg / "sub").mkdir(parents=True)
    for f in ("__init__.py", "a.py", "h.py", "sub/__init__.py", "sub/a.py"):
        (pkg / f).write_text("C = 1\n")
    (pkg / "b.py").write_text(source)
    st = (pkg / "b.py").stat()
    got = {Path(p).resolve() for p in _cache._direct_imports(str(pkg / "b.py"), st.st_mtime_ns, st.st_size,
                                                                str(pkg))}
    assert got == _ast_imports(pkg / "b.py", pkg)
    want = pkg / ("sub/a.py" if "sub" in source else "a.py")
    assert want.resolve() in got, (source, got)


def test_the_narrow_phase_kernel_depends_on_the_modules_it_was_split_into():
    # collide_pairs inlines the plane and polytope routines, the clipping and GJK/EPA from their
    # own files: an edit to any of them must invalidate its cache.
    deps = {Path(p).relative_to(PACKAGE).as_posix()
            for p in _cache.dependency_files(str(PACKAGE / "_kernels" / "manifold.py"))}
    assert deps == {"_kernels/manifold.py", "_kernels/plane.py", "_kernels/polytope.py", "_kernels/faces.py",
                    "_kernels/distance.py", "_kernels/gjk.py", "_kernels/epa.py", "_kernels/support.py",
                    "_kernels/warm.py", "_kernels/point_distance.py", "_kernels/_pose.py",
                    "_kernels/_ptr.py", "_checked.py"}  # _ptr.borrow, and the checked mode it reads


def test_the_stamp_changes_with_a_dependency_only(tmp_path):
    copy = tmp_path / "collide"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    lanes = str(copy / "_kernels" / "lanes.py")
    before = _cache.source_stamp(lanes, str(copy))
    with open(copy / "csg" / "_rays.py", "a") as f:  # not imported by the lane kernel
        f.write("\n# edited\n")
    assert _cache.source_stamp(lanes, str(copy)) == before
    with open(copy / "_kernels" / "broadphase.py", "a") as f:
        f.write("\n# edited\n")
    assert _cache.source_stamp(lanes, str(copy)) != before


def test_the_package_imports_from_a_zip_archive(tmp_path):
    # zipimport deployments: numba's own locator caches those kernels; ours must stand aside (it
    # cannot read files inside the archive: `import collide` raised NotADirectoryError).
    import zipfile

    archive = tmp_path / "collide.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for f in PACKAGE.rglob("*.py"):
            z.write(f, f.relative_to(PACKAGE.parent).as_posix())
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_CACHE")}
    env["PYTHONPATH"] = str(archive)
    env["XDG_CACHE_HOME"] = str(tmp_path / "cache")
    out = subprocess.run([sys.executable, "-c", "import collide; print(collide.__file__)"], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "collide.zip" in out.stdout


def test_saves_of_new_entries_from_many_writers_keep_each_its_own_code(tmp_path):
    # numba names a new entry's data file after the index it read: writers saving other
    # signatures of one function at once could both take "k.1.nbc", and the index would then map
    # one signature to the other's code (collide._cache._lock_saves). Writers with their own file
    # objects, as two processes have, saving at once; then a save waits while the lock is held.
    import fcntl
    import threading

    from numba.core import caching

    def writer(w):
        f = caching.IndexDataCacheFile(cache_path=str(tmp_path), filename_base="k", source_stamp="s")
        for i in range(25):
            f.save(("sig", w, i), ("code", w, i))

    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    try:
        ts = [threading.Thread(target=writer, args=(w,)) for w in range(6)]
        for t in ts:
            t.start()
        for t in ts:
            t.join()
    finally:
        sys.setswitchinterval(old)
    f = caching.IndexDataCacheFile(cache_path=str(tmp_path), filename_base="k", source_stamp="s")
    assert all(f.load(("sig", w, i)) == ("code", w, i) for w in range(6) for i in range(25))

    fd = os.open(tmp_path / _cache.LOCK_NAME, os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    t = threading.Thread(target=f.save, args=(("late",), ("code", "late")))
    t.start()
    t.join(0.5)
    assert t.is_alive() and f.load(("late",)) is None  # waiting for the lock
    os.close(fd)
    t.join(30)
    assert not t.is_alive() and f.load(("late",)) == ("code", "late")
