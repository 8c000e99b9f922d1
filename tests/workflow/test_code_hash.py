"""Rule code hashes follow the modules each rule's script really imports (shared.imports)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import xarray as xr

import shared.io
from shared.imports import PACKAGES, imported_sources
from shared.io import read_dataset, write_dataset
from shared.provenance import module_sha256, script_sha256

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = sorted(p.name for p in (ROOT / "workflow/scripts").glob("*.py") if p.name[0] != "_")
CT_SCRIPTS = ["imaging_phantom.py", "imaging_porosity.py", "imaging_rev.py"]
MICRO_SCRIPTS = ["micro_case.py", "micro_compare.py", "micro_convergence.py", "micro_scale.py"]


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    """A copy of the packages and scripts, to edit."""
    for name in (*PACKAGES, "workflow/scripts"):
        shutil.copytree(ROOT / name, tmp_path / name,
                        ignore=shutil.ignore_patterns("__pycache__"))
    return tmp_path


def _hashes(tree: Path) -> dict[str, str]:
    return {s: script_sha256(tree / "workflow/scripts" / s, tree) for s in SCRIPTS}


def _touch(path: Path) -> None:
    path.write_text(path.read_text() + "\n# edited\n")


def test_the_hash_does_not_depend_on_where_the_tree_lies(tree):
    assert _hashes(tree) == {s: script_sha256(ROOT / "workflow/scripts" / s) for s in SCRIPTS}


def test_the_macro_case_follows_the_shared_laws_it_imports():
    modules = imported_sources(ROOT / "workflow/scripts/macro_case.py", ROOT)
    assert {"macro.laws", "shared.retention", "shared.swelling", "shared.permeability",
            "_logging"} <= set(modules)
    assert "macro.ensemble" not in modules and not any(m.startswith("micro") for m in modules)


def test_the_upscaling_table_follows_its_table_code_and_not_the_micro_model():
    modules = imported_sources(ROOT / "workflow/scripts/upscaling_table.py", ROOT)
    assert {"micro.upscaling.run", "micro.upscaling.table", "shared.upscaling"} <= set(modules)
    assert "micro.run" not in modules


@pytest.mark.parametrize("module", ["macro.run", "micro.upscaling.run", "imaging.ct.run",
                                    "imaging.packing.run"])
def test_the_static_walk_covers_what_python_imports(module, tmp_path):
    """Every module of ours that importing the entry point loads is in the hash."""
    script = tmp_path / "script.py"
    script.write_text(f"import {module}\n")
    code = (f"import sys, {module}\n"
            f"print(' '.join(m for m in sys.modules if m.split('.')[0] in {PACKAGES!r}))")
    loaded = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                            text=True, check=True, timeout=300).stdout.split()
    assert set(loaded) <= set(imported_sources(script, ROOT))


def test_editing_shared_retention_reruns_the_macro_case(tree):
    before = _hashes(tree)
    _touch(tree / "shared/retention.py")
    after = _hashes(tree)
    assert before["macro_case.py"] != after["macro_case.py"]
    assert before["macro_ensemble.py"] == after["macro_ensemble.py"]
    assert all(before[s] == after[s] for s in CT_SCRIPTS)


def test_editing_the_packing_reruns_no_ct_rule(tree):
    before = _hashes(tree)
    for path in (tree / "imaging/packing").glob("*.py"):
        _touch(path)
    after = _hashes(tree)
    assert all(before[s] == after[s] for s in CT_SCRIPTS)
    assert before["packing_deposit.py"] != after["packing_deposit.py"]


def test_editing_macro_reruns_no_micro_rule(tree):
    before = _hashes(tree)
    for path in (tree / "macro").rglob("*.py"):
        _touch(path)
    after = _hashes(tree)
    assert all(before[s] == after[s] for s in MICRO_SCRIPTS + ["upscaling_table.py"])
    assert before["macro_case.py"] != after["macro_case.py"]


def test_relative_and_lazy_imports_are_followed(tmp_path):
    package = tmp_path / "shared"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "sub/__init__.py").write_text("from . import leaf\n")
    (package / "sub/leaf.py").write_text("from ..other import name\n")
    (package / "other.py").write_text("def f():\n    import shared.late\n")
    (package / "late.py").write_text("")
    (package / "unused.py").write_text("")
    script = tmp_path / "script.py"
    script.write_text("import numpy\nfrom shared import sub\n")
    assert set(imported_sources(script, tmp_path)) == {
        "shared", "shared.sub", "shared.sub.leaf", "shared.other", "shared.late"}


def _written_code_hash(tree: Path, entry: str) -> str:
    """The ``code_sha256`` attribute of a file written as the tree's ``entry`` module would."""
    shared.io._entry_sha256.cache_clear()  # once per process otherwise: the code of the first write
    ds = xr.Dataset({"x": ("n", [1.0], {"units": "1", "long_name": "x"})})
    path = write_dataset(ds, tree / "out.nc", stage="macro", title="t", code=tree / entry)
    return read_dataset(path).attrs["code_sha256"]


def test_the_file_code_hash_follows_what_the_writing_module_imports(tree):
    before = _written_code_hash(tree, "macro/run.py")
    _touch(tree / "imaging/ct/run.py")  # another stage's run module
    _touch(tree / "micro/hydration.py")
    assert _written_code_hash(tree, "macro/run.py") == before
    _touch(tree / "shared/retention.py")  # imported through macro.laws
    edited = _written_code_hash(tree, "macro/run.py")
    assert edited != before
    _touch(tree / "macro/run.py")  # the writing module itself
    assert _written_code_hash(tree, "macro/run.py") != edited


def test_the_file_code_hash_defaults_to_the_calling_module(tmp_path):
    ds = xr.Dataset({"x": ("n", [1.0], {"units": "1", "long_name": "x"})})
    path = write_dataset(ds, tmp_path / "out.nc", stage="macro", title="t")
    assert read_dataset(path).attrs["code_sha256"] == module_sha256(__file__)
