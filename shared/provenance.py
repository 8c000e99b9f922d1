"""Provenance: hashes of code, configuration and input files, and the code version."""

from __future__ import annotations

import hashlib
import json
import subprocess
from collections.abc import Iterable, Mapping
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

__all__ = [
    "code_sha256",
    "code_version",
    "config_sha256",
    "file_sha256",
    "folder_sha256",
    "inputs_record",
    "module_sha256",
    "script_sha256",
]

_REPO_ROOT = Path(__file__).resolve().parent.parent


def file_sha256(path: str | Path, chunk_bytes: int = 1 << 20) -> str:
    """Return the hex sha256 of a file's bytes, read in chunks."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(chunk_bytes), b""):
            digest.update(block)
    return digest.hexdigest()


def folder_sha256(path: str | Path) -> tuple[str, int]:
    """Return one sha256 over a folder's files (names relative to it, then bytes, in name
    order; hidden files skipped) and the number of files: a slice folder's input hash."""
    folder = Path(path)
    files = sorted(
        f for f in folder.rglob("*")
        if f.is_file() and not any(part.startswith(".") for part in f.relative_to(folder).parts)
    )
    digest = hashlib.sha256()
    for file in files:
        digest.update(str(file.relative_to(folder)).encode())
        digest.update(bytes.fromhex(file_sha256(file)))
    return digest.hexdigest(), len(files)


def config_sha256(section: Mapping[str, Any] | None) -> str:
    """Return the sha256 of a configuration mapping in canonical JSON form.

    Keys are sorted so that two configurations that differ only in key order hash alike.
    """
    text = json.dumps(section if section is not None else {}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def code_sha256(*patterns: str) -> str:
    """Return one sha256 over the project's Python sources matching glob patterns.

    Snakemake's code trigger only sees a rule's own script, not the modules it imports;
    rules pass this hash as a parameter so that an edit of the code they use reruns them.

    Parameters
    ----------
    *patterns
        Globs relative to the repository root: ``"imaging/*.py"``, ``"shared/io.py"``; a
        bare folder name (``"micro"``) means every ``.py`` file below it.
    """
    digest = hashlib.sha256()
    sources: set[Path] = set()
    for pattern in patterns:
        folder = _REPO_ROOT / pattern
        matches = sorted(folder.rglob("*.py")) if folder.is_dir() else sorted(_REPO_ROOT.glob(pattern))
        if not matches:
            raise ValueError(f"no project source matches {pattern!r}")
        sources.update(matches)
    for source in sorted(sources):
        digest.update(str(source.relative_to(_REPO_ROOT)).encode())
        digest.update(source.read_bytes())
    return digest.hexdigest()


@lru_cache(maxsize=1)
def code_version() -> str:
    """Return ``git describe`` of the checkout, else the installed package version."""
    try:
        out = subprocess.run(
            ["git", "describe", "--always", "--dirty", "--tags"],
            cwd=_REPO_ROOT,
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        )
        return out.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        try:
            return metadata.version("claychain")
        except metadata.PackageNotFoundError:
            return "unknown"


def inputs_record(paths: Iterable[str | Path]) -> str:
    """Return a JSON list of ``{"path", "sha256"}`` records for existing input files, and
    ``{"path", "sha256", "files"}`` for input folders (:func:`folder_sha256`)."""
    records: list[dict[str, Any]] = []
    for path in map(Path, paths):
        if path.is_file():
            records.append({"path": str(path), "sha256": file_sha256(path)})
        elif path.is_dir():
            digest, count = folder_sha256(path)
            records.append({"path": str(path), "sha256": digest, "files": count})
    return json.dumps(records)


def script_sha256(
    script: str | Path,
    root: str | Path = _REPO_ROOT,
    *,
    lookups: dict[tuple[str, tuple[Path, ...]], Path | None] | None = None,
) -> str:
    """Return one sha256 over the sources of our modules that a script imports.

    The modules are those of :func:`shared.imports.imported_sources` (the import graph
    read from the sources, transitively); the hash covers each module's name and bytes, so
    it does not depend on where the tree lies. A rule passes it as a parameter: an edit of
    the code its script runs reruns it, an edit of other code does not.

    Parameters
    ----------
    script
        The rule's script.
    root
        The folder that holds the packages (the repository root by default).
    lookups
        Passed to :func:`~shared.imports.imported_sources`: where module names were found,
        shared by the calls of one Snakemake invocation.

    Returns
    -------
    str
        The hex digest.
    """
    from shared.imports import imported_sources

    digest = hashlib.sha256()
    for module, source in imported_sources(script, root, lookups=lookups).items():
        digest.update(module.encode())
        digest.update(b"\0")
        digest.update(source.read_bytes())
    return digest.hexdigest()


def _package_root(path: Path) -> Path | None:
    """The folder that holds the outermost package around a source file; None when the
    file's folder is not a package."""
    folder = path.parent
    if not (folder / "__init__.py").is_file():
        return None
    while (folder.parent / "__init__.py").is_file():
        folder = folder.parent
    return folder.parent


def module_sha256(path: str | Path) -> str:
    """Return one sha256 over a module's own source and the sources of our modules it imports.

    The hash of the code that runs when ``path`` is the entry point: :func:`script_sha256`
    (the imports, transitively) plus the module's own name and bytes. The packages are
    read from the tree that holds the module, so a copy of the tree hashes its own
    sources. A file outside our packages (a Snakemake script, run from a copy that
    carries the job's preamble) counts by its imports only.

    Parameters
    ----------
    path
        The entry module's source file.

    Returns
    -------
    str
        The hex digest.
    """
    from shared.imports import PACKAGES

    path = Path(path).resolve()
    root = _package_root(path)
    if root is None or path.relative_to(root).parts[0] not in PACKAGES:
        return script_sha256(path)
    module = ".".join(path.relative_to(root).with_suffix("").parts).removesuffix(".__init__")
    digest = hashlib.sha256(script_sha256(path, root).encode())
    digest.update(module.encode())
    digest.update(b"\0")
    digest.update(path.read_bytes())
    return digest.hexdigest()
