"""The type check: mypy (pinned in pyproject.toml's test extra, configured under
[tool.mypy]) finds no error in the packages, and the few ``# type: ignore`` comments left
each name the error they silence and say why.

mypy keeps its cache in the repository's .mypy_cache (git-ignored), so that a second run
re-checks the changed modules only: a cold run took 16 to 20 CPU seconds (22 to 42 s on the
shared 2-core machine, 2026-12-02), a warm one under 1.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from shared.imports import PACKAGES

ROOT = Path(__file__).resolve().parents[2]
MAX_IGNORES = 30
# "# type: ignore[code, ...]  # why", the reason on the same line
_IGNORE = re.compile(r"#\s*type:\s*ignore(?P<codes>\[[a-z-]+(?:,\s*[a-z-]+)*\])?(?P<rest>.*)$")


def _ignores() -> list[tuple[str, int, str]]:
    """Every ``# type: ignore`` comment of the packages and the workflow's scripts."""
    found = []
    for folder in (*PACKAGES, "workflow"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            for number, line in enumerate(path.read_text().splitlines(), 1):
                if "type: ignore" in line:
                    found.append((path.relative_to(ROOT).as_posix(), number, line))
    return found


def test_mypy_finds_no_error() -> None:
    try:
        import mypy  # noqa: F401
    except ImportError:
        pytest.fail(f"mypy is not installed in {sys.executable}: reinstall the test extra "
                    "(pip install -e '.[test]')")
    run = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, f"mypy found errors:\n{run.stdout}{run.stderr}"
    assert "Success: no issues found" in run.stdout


def test_mypy_checks_the_packages() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]
    assert config["packages"] == list(PACKAGES)
    # a stale ignore fails the check, and none is without its error code
    assert config["warn_unused_ignores"] is True
    assert "ignore-without-code" in config["enable_error_code"]


def test_the_ignores_are_few_and_each_says_why() -> None:
    ignores = _ignores()
    assert len(ignores) <= MAX_IGNORES, "\n".join(f"{p}:{n}" for p, n, _ in ignores)
    unexplained = []
    for path, number, line in ignores:
        match = _IGNORE.search(line)
        if match is None or not match["codes"] or not re.match(r"\s+#\s*\S", match["rest"]):
            unexplained.append(f"{path}:{number}: {line.strip()}")
    assert not unexplained, "each ignore needs [code] and '  # reason':\n" + "\n".join(unexplained)


def test_the_ignore_pattern_tells_a_reason_from_none() -> None:
    def explained(line: str) -> bool:
        match = _IGNORE.search(line)
        return bool(match and match["codes"] and re.match(r"\s+#\s*\S", match["rest"]))

    assert explained("x = f()  # type: ignore[attr-defined]  # numba's stubs lack it")
    assert explained("class A(B):  # type: ignore[misc, valid-type]  # chosen at import")
    assert not explained("x = f()  # type: ignore[attr-defined]")
    assert not explained("x = f()  # type: ignore  # no code")
    assert not explained("x = f()  # type: ignore[attr-defined]  #")
