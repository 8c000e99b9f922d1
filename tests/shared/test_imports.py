"""shared.imports: the modules a script imports, read from the sources on a tree built
for the test (absolute, relative, nested and lazy imports; standard and third-party
modules and names that are not modules are not followed); the one list of packages,
PACKAGES, against the tree and pyproject.toml; the names that the benchmarks and the
workflow scripts import from the packages exist."""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path

from shared.imports import PACKAGES, imported_sources


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def test_the_import_graph_of_a_small_tree(tmp_path: Path) -> None:
    root = tmp_path / "tree"
    _write(root / "pkg" / "__init__.py", "")
    _write(root / "pkg" / "sub" / "__init__.py", "from .inner import helper\n")
    _write(root / "pkg" / "sub" / "inner.py", "import json\n\ndef helper():\n    from ..lazy import x\n")
    _write(root / "pkg" / "lazy.py", "x = 1\n")
    _write(root / "pkg" / "unused.py", "x = 2\n")
    _write(root / "pkg" / "direct.py", "from pkg.sub.inner import helper as h\nimport numpy\n")
    script = root / "scripts" / "run.py"
    _write(script, '"""import pkg.unused is prose here."""\nimport os\nfrom pkg import direct\nimport _local\n')
    _write(root / "scripts" / "_local.py", "from pkg.sub import helper\n")
    found = imported_sources(script, root, packages=("pkg",))
    assert found == {
        "_local": (root / "scripts" / "_local.py").resolve(),
        "pkg": (root / "pkg" / "__init__.py").resolve(),
        "pkg.direct": (root / "pkg" / "direct.py").resolve(),
        "pkg.lazy": (root / "pkg" / "lazy.py").resolve(),
        "pkg.sub": (root / "pkg" / "sub" / "__init__.py").resolve(),
        "pkg.sub.inner": (root / "pkg" / "sub" / "inner.py").resolve(),
    }
    assert list(found) == sorted(found)
    assert "pkg" not in sys.modules  # read, not imported


ROOT = Path(__file__).resolve().parents[2]
# a package at the root that no rule runs, so that no code hash covers it: the
# performance harness (benchmarks/README.md)
NOT_PIPELINE = {"benchmarks"}


def test_the_packages_are_the_root_folders_that_are_packages() -> None:
    """A new package at the root that PACKAGES misses would fall outside every code hash."""
    found = {d.name for d in ROOT.iterdir() if (d / "__init__.py").is_file()}
    assert found - NOT_PIPELINE == set(PACKAGES) and len(PACKAGES) == len(set(PACKAGES))


def test_pyprojects_package_lists_are_the_packages() -> None:
    """pyproject.toml cannot import PACKAGES: its lists are checked against it here."""
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    linter = pyproject["tool"]["importlinter"]
    assert linter["root_packages"] == list(PACKAGES)
    contracts = {c["name"]: c for c in linter["contracts"]}
    stages = [p for p in PACKAGES if p != "shared"]
    assert contracts["stages are independent of each other"]["modules"] == stages
    layers = contracts["shared sits below every stage"]["layers"]
    assert [sorted(layer.replace(" ", "").split("|")) for layer in layers] == [sorted(stages), ["shared"]]
    installed = pyproject["tool"]["setuptools"]["packages"]["find"]["include"]
    assert set(PACKAGES) <= {pattern.rstrip("*") for pattern in installed}
    assert set(PACKAGES) <= set(pyproject["tool"]["ruff"]["lint"]["isort"]["known-first-party"])


def _project_imports(path: Path) -> list[tuple[str, str, int]]:
    """(module, name, line) of every ``from <package> import name`` in ``path``, at any
    depth (function-level imports included)."""
    import ast

    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                and node.module.split(".")[0] in PACKAGES:
            found += [(node.module, alias.name, node.lineno) for alias in node.names]
    return found


def test_the_benchmarks_and_scripts_import_names_that_exist() -> None:
    """The benchmarks run outside the suite, and a function-level import of a name that
    moved only fails when that benchmark is next run (macro_ogs imported
    PASSAGE_PRESSURE from macro.run after it moved to macro.records)."""
    import importlib

    root = Path(__file__).resolve().parents[2]
    files = sorted([*(root / "benchmarks").glob("*.py"), *(root / "workflow" / "scripts").glob("*.py")])
    missing = []
    for path in files:
        for module, name, line in _project_imports(path):
            imported = importlib.import_module(module)
            if not hasattr(imported, name):
                try:
                    importlib.import_module(f"{module}.{name}")
                except ModuleNotFoundError:
                    missing.append(f"{path.relative_to(root)}:{line}: {module}.{name}")
    assert len(files) > 20
    assert not missing, missing
