"""The launcher script (claychain): its help and its refusal of an unknown command."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _claychain(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", str(ROOT / "claychain"), *args], capture_output=True,
                          text=True, timeout=60)


@pytest.mark.parametrize("flag", ["--help", "-h", "help"])
def test_the_launcher_help_lists_commands_presets_and_examples(flag):
    result = _claychain(flag)
    assert result.returncode == 0, result.stderr
    for word in ("run", "test", "setup", "--set", "Examples:"):
        assert word in result.stdout
    for preset in sorted((ROOT / "config/paper").glob("*.yaml")):
        first = next(line for line in preset.read_text().splitlines() if line.startswith("#"))
        assert f"config/paper/{preset.name}" in result.stdout
        assert first.lstrip("# ").strip() in result.stdout


def test_an_unknown_command_prints_the_usage_on_stderr_and_exits_2():
    result = _claychain("bogus")
    assert result.returncode == 2
    assert result.stdout == ""
    assert "unknown command 'bogus'" in result.stderr and "usage:" in result.stderr
