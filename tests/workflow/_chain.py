"""A copy of the workflow in a temporary folder and Snakemake run on it, as a user runs it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]


def workdir(tmp: Path, config: dict | None) -> Path:
    """The Snakefile and workflow/ in ``tmp`` with ``config`` as config/config.yaml (None:
    the repository's config folder, presets included)."""
    shutil.copy(ROOT / "Snakefile", tmp / "Snakefile")
    shutil.copytree(ROOT / "workflow", tmp / "workflow")
    if config is None:
        shutil.copytree(ROOT / "config", tmp / "config")
    else:
        (tmp / "config").mkdir()
        (tmp / "config" / "config.yaml").write_text(yaml.safe_dump(config))
    return tmp


def snakemake(folder: Path, *args: str, ok: bool = True, timeout: float = 900) -> subprocess.CompletedProcess:
    """``snakemake --cores 2 *args`` in ``folder`` on this checkout's packages; asserts that
    it succeeds (``ok``) or fails."""
    path = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    result = subprocess.run(
        [sys.executable, "-m", "snakemake", "--cores", "2", *args],
        cwd=folder, capture_output=True, text=True, timeout=timeout,
        env={**os.environ, "PYTHONPATH": path},
    )
    assert (result.returncode == 0) == ok, result.stderr[-3000:]
    return result
