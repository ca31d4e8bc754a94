"""numba's kernel cache follows every package file a kernel imports (`collide._cache`)."""

import ast
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

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


def _ast_imports(path: Path) -> set[Path]:
    # The package files a file imports with relative imports, resolved by the ast.
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = path.parent
            for _ in range(node.level - 1):
                base = base.parent
            names = [node.module] if node.module else [a.name for a in node.names]
            for name in names:
                p = base.joinpath(*name.split("."))
                for cand in (p.with_suffix(".py"), p / "__init__.py"):
                    if cand.is_file():
                        out.add(cand.resolve())
    return out


def test_dependency_files_agree_with_the_ast_on_every_package_file():
    files = sorted(PACKAGE.rglob("*.py"))
    assert len(files) > 20
    for path in files:
        st = path.stat()
        direct = {Path(p).resolve() for p in _cache._direct_imports(str(path), st.st_mtime_ns, st.st_size)}
        assert direct == _ast_imports(path), path
    lanes = {Path(p).relative_to(PACKAGE).as_posix()
             for p in _cache.dependency_files(str(PACKAGE / "_kernels" / "lanes.py"))}
    assert lanes == {"_kernels/lanes.py", "_kernels/broadphase.py", "_kernels/_ptr.py", "_kernels/_simd.py"}


def test_the_stamp_changes_with_a_dependency_only(tmp_path):
    copy = tmp_path / "collide"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    lanes = str(copy / "_kernels" / "lanes.py")
    before = _cache.source_stamp(lanes, str(copy))
    with open(copy / "csg.py", "a") as f:  # not imported by the lane kernel
        f.write("\n# edited\n")
    assert _cache.source_stamp(lanes, str(copy)) == before
    with open(copy / "_kernels" / "broadphase.py", "a") as f:
        f.write("\n# edited\n")
    assert _cache.source_stamp(lanes, str(copy)) != before
