"""Fixtures of the macro tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests._macro_cases import write_table


@pytest.fixture
def table_path(tmp_path: Path) -> Path:
    """A synthetic pellet permeability table (both conditions) written to disk."""
    return write_table(tmp_path / "pellet_permeability.nc")
