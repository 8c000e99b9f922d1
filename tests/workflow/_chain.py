"""A copy of the workflow in a temporary folder and Snakemake run on it, as a user runs it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Callable
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
    # this checkout first, the caller's path after it, each folder once (Snakemake scans
    # every folder of the path for its plugins)
    folders = [str(ROOT), *os.environ.get("PYTHONPATH", "").split(os.pathsep)]
    path = os.pathsep.join(dict.fromkeys(f for f in folders if f))
    result = subprocess.run(
        [sys.executable, "-m", "snakemake", "--cores", "2", *args],
        cwd=folder, capture_output=True, text=True, timeout=timeout,
        env={**os.environ, "PYTHONPATH": path},
    )
    assert (result.returncode == 0) == ok, result.stderr[-3000:]
    return result


def edited_copy(run: Path, copy: Path, edit: Callable[[dict], None] | None = None) -> Path:
    """A copy of a (finished) workflow folder at ``copy`` with ``edit`` applied to its
    config/config.yaml: results and ``.snakemake`` metadata included, modification times
    kept and symlinks copied as links, so Snakemake sees the run as it was."""
    shutil.copytree(run, copy, symlinks=True)
    if edit is not None:
        path = copy / "config" / "config.yaml"
        config = yaml.safe_load(path.read_text())
        edit(config)
        path.write_text(yaml.safe_dump(config))
    return copy


def listed(result: subprocess.CompletedProcess) -> set[str]:
    """The outputs that a ``--list-changes`` run lists."""
    return {line.strip() for line in result.stdout.splitlines() if line.startswith("results/")}
