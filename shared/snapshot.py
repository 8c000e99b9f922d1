"""Restart files that hold data, never code: arrays and plain metadata, checked before use.

A snapshot is numpy's ``.npz`` (a zip of ``.npy`` members), read with
``allow_pickle=False``, so opening one can run no code whatever it holds. Its first
member, ``header``, is JSON: the format name, the digest of what decides the run (the
caller's hash of its configuration and code) and the sha256 of the content; ``meta`` is
the JSON of the plain metadata, and the other members are the arrays. Reading checks, in
this order, the format, the digest (a snapshot of another configuration or code is
ignored, logged, and overwritten by the run's next one), the checksum and then the
caller's own rebuilding of its state. A file that fails any check but the digest is moved
aside (``<name>.rejected``, ``<name>.rejected-2``, ...) with one log line saying why, and
the run starts over instead of meeting the same bad file at every rerun. Files are
written to a temporary name and renamed (:func:`shared.io.atomic_write`).
"""

from __future__ import annotations

import hashlib
import json
import logging
import zipfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from shared.errors import SnapshotError
from shared.io import atomic_write

__all__ = ["FORMAT", "content_sha256", "read_meta", "read_snapshot", "set_aside", "write_snapshot"]

FORMAT = "claychain-snapshot/1"
"""The format name in every header; a file without it is not one of ours (or older)."""

T = TypeVar("T")


def content_sha256(meta: str, arrays: Mapping[str, np.ndarray]) -> str:
    """sha256 of the metadata's JSON text and of every array's name, dtype, shape and bytes.

    Parameters
    ----------
    meta
        The JSON text of the metadata.
    arrays
        The arrays by member name (taken in sorted order).
    """
    digest = hashlib.sha256(meta.encode())
    for name in sorted(arrays):
        array = np.asarray(arrays[name])
        digest.update(f"\0{name}\0{array.dtype.str}\0{array.shape}\0".encode())
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


def write_snapshot(path: Path, digest: str, meta: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
    """Write a snapshot atomically: the header (format, ``digest``, checksum) first.

    Parameters
    ----------
    path
        The ``.npz`` file.
    digest
        The hash of what decides the run; :func:`read_snapshot` ignores a file of another.
    meta
        Plain metadata (JSON: numbers, strings, lists, str-keyed dicts, None).
    arrays
        Arrays by member name (not ``header`` or ``meta``; no object dtype).
    """
    text = json.dumps(meta)
    header = {"format": FORMAT, "digest": digest, "sha256": content_sha256(text, arrays)}
    members: dict[str, Any] = {"header": np.array(json.dumps(header)), "meta": np.array(text), **arrays}
    atomic_write(path, lambda tmp: np.savez(tmp, **members))


def _read(path: Path, digest: str) -> tuple[dict[str, Any], dict[str, np.ndarray]] | None:
    """The metadata and arrays of a snapshot that passes its checks; None for another digest.

    Raises
    ------
    SnapshotError
        Saying why the file is not a usable snapshot.
    """
    try:
        with open(path, "rb") as handle, np.load(handle, allow_pickle=False) as data:
            if "header" not in data.files:
                raise SnapshotError("not a claychain snapshot (no header: another program or an older version)")
            header = json.loads(str(data["header"]))
            if not isinstance(header, dict) or header.get("format") != FORMAT:
                raise SnapshotError(f"not a {FORMAT} file")
            if header.get("digest") != digest:
                return None
            text = str(data["meta"])
            arrays = {name: data[name] for name in data.files if name not in ("header", "meta")}
    except (OSError, EOFError, ValueError, KeyError, zipfile.BadZipFile) as error:
        if isinstance(error, SnapshotError):
            raise
        raise SnapshotError(f"unreadable ({type(error).__name__}: {' '.join(str(error).split())})") from error
    if content_sha256(text, arrays) != header.get("sha256"):
        raise SnapshotError("its content does not match its checksum (damaged)")
    return json.loads(text), arrays


def read_meta(path: Path) -> dict[str, Any]:
    """The plain metadata of a snapshot, read as data without its checks (for a report on
    a file that :func:`read_snapshot` has accepted, or in a test)."""
    with open(path, "rb") as handle, np.load(handle, allow_pickle=False) as data:
        meta: dict[str, Any] = json.loads(str(data["meta"]))
    return meta


def set_aside(path: Path, reason: str, log: logging.Logger) -> Path:
    """Rename a bad restart file to the first free ``<name>.rejected[-n]`` and log why.

    Returns
    -------
    Path
        The file's new name.
    """
    target = path.with_name(f"{path.name}.rejected")
    count = 1
    while target.exists():
        count += 1
        target = path.with_name(f"{path.name}.rejected-{count}")
    path.rename(target)
    log.warning("%s: %s; moved to %s, the run starts from the beginning", path, reason, target.name)
    return target


def read_snapshot(path: Path, digest: str, restore: Callable[[dict[str, Any], dict[str, np.ndarray]], T],
                  log: logging.Logger) -> T | None:
    """What ``restore(meta, arrays)`` rebuilds from a snapshot that passes its checks.

    Parameters
    ----------
    path
        The ``.npz`` file (absent: None).
    digest
        The run's hash; a file of another is ignored (logged) and left to be overwritten.
    restore
        Rebuilds the caller's state; raises :class:`shared.errors.SnapshotError` (or a
        ``KeyError``, ``TypeError``, ``ValueError``, ``AttributeError``) for content it
        cannot use.
    log
        Where the one line of a file ignored or set aside goes.

    Returns
    -------
    object or None
        None when there is no usable snapshot: the run starts from the beginning.
    """
    if not path.is_file():
        return None
    try:
        content = _read(path, digest)
        if content is None:
            log.info("%s: snapshot of another configuration or code: the run starts from the beginning", path)
            return None
        try:
            return restore(*content)
        except (KeyError, TypeError, ValueError, AttributeError) as error:
            if isinstance(error, SnapshotError):
                raise
            raise SnapshotError(f"its content does not fit the code ({type(error).__name__}: {error})") from error
    except SnapshotError as error:
        set_aside(path, str(error), log)
        return None
