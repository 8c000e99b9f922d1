"""shared.lazy: a package's lazily exported name is imported from its submodule on first
access only, is the submodule's object, and is then kept in the package."""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import pytest


def test_a_lazy_name_is_imported_on_first_access(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    package = tmp_path / "lazy_probe_pkg"
    package.mkdir()
    (package / "__init__.py").write_text(
        "from shared.lazy import lazy_getattr\n\n"
        "__getattr__ = lazy_getattr(__name__, {'VALUE': 'heavy'}, globals())\n")
    (package / "heavy.py").write_text("VALUE = object()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in ("lazy_probe_pkg", "lazy_probe_pkg.heavy"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    probe = importlib.import_module("lazy_probe_pkg")
    assert "lazy_probe_pkg.heavy" not in sys.modules and "VALUE" not in vars(probe)
    value = probe.VALUE
    heavy = sys.modules["lazy_probe_pkg.heavy"]
    assert value is heavy.VALUE and vars(probe)["VALUE"] is value
    with pytest.raises(AttributeError, match="module 'lazy_probe_pkg' has no attribute 'missing'"):
        probe.missing  # noqa: B018


def test_shared_dems_exports_are_their_submodules_objects() -> None:
    import shared.dem as dem

    exports = dem._EXPORTS
    assert exports
    for name, module in exports.items():
        assert getattr(dem, name) is getattr(importlib.import_module(f"shared.dem.{module}"), name)


def test_a_light_submodule_does_not_import_numba() -> None:
    """What the laziness is for: the workflow's key lists import shared.dem.parameters."""
    code = "import sys, shared.dem.parameters; print('numba' in sys.modules, 'shared.dem.contacts' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                            cwd=Path(__file__).resolve().parents[2])
    assert result.stdout.split() == ["False", "False"]
