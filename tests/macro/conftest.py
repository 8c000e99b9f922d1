"""Fixtures of the macro tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from macro.model import MacroModel
from macro.run import build_model
from shared.upscaling import PermeabilityTable
from tests._macro_cases import small_config, write_table


@pytest.fixture
def table_path(tmp_path: Path) -> Path:
    """A synthetic pellet permeability table (both conditions) written to disk."""
    return write_table(tmp_path / "pellet_permeability.nc")


@pytest.fixture
def model(table_path: Path) -> MacroModel:
    """A new small column (tests._macro_cases.small_config) on the synthetic table, free
    condition; a test module may define its own ``model`` instead."""
    return build_model(small_config(), "small", PermeabilityTable.from_file(table_path, "free"))
