"""shared.lazy: a package's lazily exported name is imported from its submodule on first
access only, is the submodule's object, and is then kept in the package; the lazy
packages export every name their submodules declare public (their ``__all__``)."""

from __future__ import annotations

import importlib
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

from shared.lazy import type_checking_exports


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


def test_the_type_checking_block_is_read_as_the_lazy_map(tmp_path: Path) -> None:
    init = tmp_path / "__init__.py"
    init.write_text("from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n"
                    "    from .heavy import A, b\n    from pkg.light import C\n")
    assert type_checking_exports(init, "pkg") == {"A": "heavy", "b": "heavy", "C": "light"}
    init.write_text("import typing\n\nif typing.TYPE_CHECKING:\n    from .heavy import A as B\n")
    with pytest.raises(ValueError, match="'A' is aliased"):
        type_checking_exports(init, "pkg")
    init.write_text("from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n    from other.heavy import A\n")
    with pytest.raises(ValueError, match="only 'from pkg.<submodule> import"):
        type_checking_exports(init, "pkg")


# the lazy packages, and their public submodules that they do not re-export (stage
# modules that would import xarray and matplotlib: docstring of imaging/packing)
LAZY_PACKAGES = {"shared.dem": set(), "imaging.packing": {"config", "dataset", "run", "figures"}}


@pytest.mark.parametrize("name", sorted(LAZY_PACKAGES))
def test_a_lazy_package_exports_its_submodules_public_names(name: str) -> None:
    """Every name of ``__all__`` is its submodule's object, and every public submodule
    not set apart exports its whole ``__all__`` here (``dem_parameters``, once missing
    from shared.dem's TYPE_CHECKING block, would fail)."""
    package = importlib.import_module(name)
    exports = type_checking_exports(package.__file__, name)
    assert package.__all__ == sorted(exports) and len(exports) > 5
    for export, module in exports.items():
        assert getattr(package, export) is getattr(importlib.import_module(f"{name}.{module}"), export)
    public = {m.name for m in pkgutil.iter_modules(package.__path__) if not m.name.startswith("_")}
    assert set(exports.values()) == public - LAZY_PACKAGES[name]
    for module in public - LAZY_PACKAGES[name]:
        declared = importlib.import_module(f"{name}.{module}").__all__
        assert set(declared) <= set(package.__all__), f"{name}.{module}"


@pytest.mark.parametrize(("light", "heavy"), [("shared.dem.parameters", "shared.dem.contacts"),
                                              ("imaging.packing.config", "imaging.packing.deposition")])
def test_a_light_submodule_does_not_import_numba(light: str, heavy: str) -> None:
    """What the laziness is for: the workflow's key lists and checks import these."""
    code = f"import sys, {light}; print('numba' in sys.modules, {heavy!r} in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                            cwd=Path(__file__).resolve().parents[2])
    assert result.stdout.split() == ["False", "False"]
