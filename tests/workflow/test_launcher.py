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
    blocks = result.stdout.split("Presets")[1].split("Examples:")[0].split("\n  config/paper/")
    described = {block.split("\n", 1)[0].strip(): " ".join(block.split("\n", 1)[1].split())
                 for block in blocks[1:]}
    for preset in sorted((ROOT / "config/paper").glob("*.yaml")):
        first = next(line for line in preset.read_text().splitlines() if line.startswith("#"))
        text = described[preset.name]
        # the description starts as the file's comment does and ends with its sentence
        assert text.startswith(" ".join(first.lstrip("# ").split()[:6])), (preset.name, text)
        assert text.endswith((".", ")")) and "Use:" not in text, (preset.name, text)


def test_an_unknown_command_prints_the_usage_on_stderr_and_exits_2():
    result = _claychain("bogus")
    assert result.returncode == 2
    assert result.stdout == ""
    assert "unknown command 'bogus'" in result.stderr and "usage:" in result.stderr
