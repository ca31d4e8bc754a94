"""The layering rules of DESIGN.md, checked on the source: who may import mujoco, manifold3d, testing."""

import ast
from pathlib import Path

import collide

PACKAGE = Path(collide.__file__).parent


def _imports(path: Path) -> set[str]:
    # Absolute module names imported by a file; relative imports are resolved against the package.
    tree = ast.parse(path.read_text())
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    pkg_parts = list(rel.parts[:-1])  # the package a relative import starts from
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg_parts[: len(pkg_parts) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
                names.add(mod)
                names.update(f"{mod}.{a.name}" for a in node.names)
            else:
                names.add(node.module)
    return names


def _library_files():
    return [p for p in PACKAGE.rglob("*.py") if "testing" not in p.relative_to(PACKAGE).parts]


def _uses(names: set[str], module: str) -> bool:
    return any(n == module or n.startswith(module + ".") for n in names)


def test_only_the_adapter_imports_mujoco():
    # The adapter is the package collide/mujoco/ (every module of it may); the command line too.
    offenders = [str(p.relative_to(PACKAGE)) for p in _library_files()
                 if p.relative_to(PACKAGE).parts[0] != "mujoco" and p.name != "__main__.py"
                 and _uses(_imports(p), "mujoco")]
    assert offenders == []
    assert _uses(_imports(PACKAGE / "mujoco" / "_model.py"), "mujoco")  # the test sees the adapter's imports


def test_only_hull_and_csg_import_manifold3d():
    offenders = [str(p.relative_to(PACKAGE)) for p in _library_files()
                 if p.name != "hull.py" and "csg" not in p.relative_to(PACKAGE).parts
                 and _uses(_imports(p), "manifold3d")]
    assert offenders == []


def test_library_never_imports_testing():
    offenders = [str(p.relative_to(PACKAGE)) for p in _library_files()
                 if _uses(_imports(p), "collide.testing")]
    assert offenders == []


def test_public_surface_is_flat_and_complete():
    for name in collide.__all__:
        assert hasattr(collide, name), name
    assert list(collide.__all__) == sorted(collide.__all__)


def test_every_public_module_declares_all():
    # DESIGN.md: `__all__` in public modules, every name in it defined. Private modules (a leading
    # underscore in any part of the path) and the command line's __main__ are exempt.
    missing, undefined = [], []
    for p in _library_files() + list((PACKAGE / "testing").rglob("*.py")):
        rel = p.relative_to(PACKAGE)
        if any(part.startswith("_") and part != "__init__.py" for part in rel.parts):
            continue
        tree = ast.parse(p.read_text())
        names = None
        for node in tree.body:
            if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
                names = ast.literal_eval(node.value)
        if names is None:
            missing.append(rel.as_posix())
            continue
        module = "collide." + ".".join(rel.with_suffix("").parts)
        module = module.removesuffix(".__init__")
        mod = __import__(module, fromlist=["_"])
        undefined += [f"{module}.{n}" for n in names if not hasattr(mod, n)]
    assert missing == []
    assert undefined == []


# The modules of each split package in import order (as each package's docstring lists them).
_PACKAGE_ORDER = {
    "volumes": ["_axes", "_records", "_obb_families", "_obb_search", "_obb_exact", "_fit_box", "_fit_sphere",
                "_kdop", "_transform", "_overlap"],
    "csg": ["_graph", "_unrolling", "_bvh", "_rays"],
    "shapes": ["_polygons", "_exact", "_tangent", "_plane"],
    "rerun_log": ["_convert", "_stream", "_scene", "_log", "_compare"],
    "mujoco": ["_model", "_kinematics", "_adapter", "_compare", "_report", "_scene"],
    "broadphase": ["_kinematics", "_world_bounds", "_batch"],
}


def test_package_modules_import_downward():
    # At module level a module imports only the siblings before it (a method may import one above
    # it when called: AABB.overlaps, Node.point_cloud); every module of the package is listed.
    for package, order in _PACKAGE_ORDER.items():
        folder = PACKAGE / package
        assert sorted(order) == sorted(p.stem for p in folder.glob("_*.py") if p.stem != "__init__"), package
        for i, name in enumerate(order):
            tree = ast.parse((folder / f"{name}.py").read_text())
            siblings = set()
            for node in tree.body:
                if isinstance(node, ast.ImportFrom) and node.level == 1:
                    siblings.update([node.module] if node.module else [a.name for a in node.names])
            above = siblings - set(order[:i])
            assert not above, f"{package}.{name} imports {sorted(above)} at module level"
