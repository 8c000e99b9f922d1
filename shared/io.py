"""netCDF input and output with CF attributes, provenance and atomic writes.

Every file of the chain goes through :func:`write_dataset`: it checks that each variable
carries ``units`` and ``long_name``, turns attributes netCDF cannot store (bools, dicts,
lists, None) into numbers and JSON strings, adds the provenance attributes of
docs/design.md §2, compresses, and writes to a temporary name in the target folder
before renaming, so an interrupted run never leaves a readable but wrong file.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterable, Mapping
from datetime import UTC, datetime
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from shared.errors import OutputError
from shared.imports import PACKAGES
from shared.provenance import code_sha256, code_version, config_sha256, inputs_record, module_sha256

__all__ = ["OutputError", "read_dataset", "write_dataset", "write_outputs", "netcdf_safe_attrs",
           "atomic_write", "write_failure"]


@cache
def _entry_sha256(entry: str) -> str:
    """The ``code_sha256`` attribute of the files a module writes: the hash of that module
    and of what it imports (:func:`shared.provenance.module_sha256`), once per process, so
    it is the code at the first write. Without a source file (code run from a string) every
    package counts."""
    if not Path(entry).is_file():
        return code_sha256(*PACKAGES)
    return module_sha256(entry)


def netcdf_safe_attrs(attrs: Mapping[str, Any]) -> dict[str, Any]:
    """Return attributes that netCDF can store: strings, numbers and 1-D numeric arrays.

    Bools become 0/1, mappings and lists of non-numbers become JSON strings, None is
    dropped (xarray issues #1681, #3743).
    """
    safe: dict[str, Any] = {}
    for key, value in attrs.items():
        if value is None:
            continue
        if isinstance(value, (bool, np.bool_)):
            safe[key] = int(value)
        elif isinstance(value, (str, int, float, np.integer, np.floating)):
            safe[key] = value
        elif isinstance(value, Mapping):
            safe[key] = json.dumps(value, sort_keys=True, default=str)
        elif isinstance(value, (list, tuple, np.ndarray)):
            array = np.asarray(value)
            if array.ndim == 1 and array.dtype.kind in "iuf" and array.size > 0:
                safe[key] = array
            else:
                safe[key] = json.dumps(np.asarray(value).tolist(), default=str)
        else:
            safe[key] = str(value)
    return safe


def _check_contract(ds: xr.Dataset) -> None:
    for name, var in ds.variables.items():
        if name in ds.dims and var.dtype.kind not in "iuf":
            continue
        missing = [a for a in ("units", "long_name") if a not in var.attrs]
        if missing:
            raise OutputError(f"variable {name!r} lacks attribute(s) {missing}")
    anonymous = [d for d in ds.dims if str(d).startswith("dim_")]
    if anonymous:
        raise OutputError(f"anonymous dimension(s) {anonymous}: name every dimension")


def write_dataset(
    ds: xr.Dataset,
    path: str | Path,
    *,
    stage: str,
    title: str,
    config: Mapping[str, Any] | None = None,
    seed: int | None = None,
    inputs: Iterable[str | Path] = (),
    rule: str | None = None,
    wildcards: Mapping[str, str] | None = None,
    references: str | None = None,
    comment: str | None = None,
    code: str | Path | None = None,
) -> Path:
    """Write a dataset to netCDF atomically, with CF and provenance attributes.

    Numeric variables are compressed (zlib 4, shuffle), in the HDF5 chunks of their
    ``encoding["chunksizes"]`` when set (e.g. one per slice for a volume written slab by
    slab from dask: whole chunks, no read-modify-write).

    Parameters
    ----------
    ds
        Dataset whose variables all carry ``units`` and ``long_name``.
    path
        Target ``.nc`` path; its folder is created.
    stage
        Pipeline stage (``imaging``, ``packing``, ``micro``, ...).
    title
        CF ``title``.
    config
        The stage's configuration section; its sha256 is recorded.
    seed
        Random seed of the run (``-1`` is recorded when the run uses none).
    inputs
        Input files; their paths and sha256 are recorded.
    rule, wildcards
        Snakemake rule name and wildcards, when called from a rule.
    references, comment
        CF ``references`` and ``comment``.
    code
        The module whose source and imports make the ``code_sha256`` attribute; by default
        the caller's (a stage's run module).

    Returns
    -------
    Path
        The written path.

    Raises
    ------
    OutputError
        If a variable lacks ``units`` or ``long_name`` or a dimension is anonymous.
    """
    _check_contract(ds)
    now = datetime.now(UTC).replace(microsecond=0).isoformat()
    version = code_version()
    entry = str(Path(code if code is not None else sys._getframe(1).f_code.co_filename).resolve())
    out = ds.copy()
    out.attrs = netcdf_safe_attrs(
        {
            **ds.attrs,
            "Conventions": "CF-1.11",
            "title": title,
            "institution": "claychain",
            "source": f"claychain {stage} {version}",
            "history": f"{now} claychain {stage}" + (f" rule {rule}" if rule else ""),
            "references": references,
            "comment": comment,
            "stage": stage,
            "created": now,
            "code_version": version,
            "code_sha256": _entry_sha256(entry),
            "config_sha256": config_sha256(config),
            "config_json": json.dumps(config if config is not None else {}, default=str),
            "seed": -1 if seed is None else int(seed),
            "inputs": inputs_record(inputs),
            "snakemake_rule": rule,
            "wildcards_json": json.dumps(dict(wildcards or {}), sort_keys=True),
        }
    )
    for name in out.variables:
        out[name].attrs = netcdf_safe_attrs(out[name].attrs)
    encoding = {
        name: {"zlib": True, "complevel": 4, "shuffle": True,
               **{k: v for k, v in var.encoding.items() if k == "chunksizes"}}
        for name, var in out.data_vars.items()
        if var.dtype.kind in "iuf" and var.ndim > 0
    }
    return atomic_write(path, lambda tmp: out.to_netcdf(tmp, engine="netcdf4", encoding=encoding))


def write_outputs(
    ds: xr.Dataset,
    path: str | Path,
    *,
    files: Mapping[str | Path, bytes | Callable[[str], object]] | None = None,
    figure: tuple[str | Path, Callable[[str | Path], object]] | None = None,
    **provenance: Any,
) -> Path:
    """Write a stage's outputs: its netCDF file, its other files, then its figure.

    The one writer of the stages' ``run()`` functions: the netCDF file through
    :func:`write_dataset`, each other file (a CSV export, a restart file) through
    :func:`atomic_write`, and the figure last, so that a failure leaves no file half
    written and a figure never describes a file that was not written.

    Parameters
    ----------
    ds
        The dataset (:func:`write_dataset`'s contract).
    path
        Target ``.nc`` path.
    files
        Other files: per path, its bytes, or a function writing the file at the
        temporary path it is given.
    figure
        ``(png_path, draw)``: ``draw(png_path)`` writes the figure (through
        :func:`shared.figures.save_figure`, atomic too).
    **provenance
        The keyword arguments of :func:`write_dataset` (``stage`` and ``title``
        required); ``code`` defaults to the caller's module, as there.

    Returns
    -------
    Path
        The netCDF path.
    """
    provenance.setdefault("code", sys._getframe(1).f_code.co_filename)
    written = write_dataset(ds, path, **provenance)
    for target, content in (files or {}).items():
        write = content if callable(content) else _bytes_writer(content)
        atomic_write(target, write)
    if figure is not None:
        target, draw = figure
        draw(target)
    return written


def _bytes_writer(content: bytes) -> Callable[[str], object]:
    """A writer of ``content`` to the path it is given (:func:`atomic_write`)."""
    return lambda tmp: Path(tmp).write_bytes(content)


def _umask() -> int:
    """The process's file-creation mask (read by setting and restoring it)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write(path: str | Path, write: Callable[[str], object]) -> Path:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then rename it to ``path``.

    The folder is created if missing. On any error the temporary file is removed and
    ``path`` keeps its old content, so an interrupted run never leaves a readable but
    wrong file. The temporary name keeps ``path``'s suffix (writers that choose the
    format by it, or append one, write the file named), and the file gets the
    permissions of a newly created one under the process's umask, not the owner-only
    mode of a temporary file, so that a group shares the results.

    Raises
    ------
    OutputError
        Naming ``path`` (:func:`write_failure`), for an ``OSError`` or ``RuntimeError``
        of the writing: permissions, a full or read-only file system, the netCDF
        library's errors (e.g. "NetCDF: HDF error" on a full disk, which names no file).
    """
    path = Path(path)
    tmp_name = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, tmp_name = tempfile.mkstemp(
            prefix=f".{path.name}.", suffix=f".tmp{path.suffix}", dir=path.parent
        )
        os.close(handle)
        write(tmp_name)
        os.chmod(tmp_name, 0o666 & ~_umask())
        os.replace(tmp_name, path)
    except BaseException as error:
        if tmp_name is not None:
            Path(tmp_name).unlink(missing_ok=True)
        if isinstance(error, OSError | RuntimeError):
            raise OutputError(write_failure(path, error)) from error
        raise
    return path


def write_failure(path: str | Path, error: BaseException) -> str:
    """The one line for a file that cannot be written: its name, the cause and the free
    space where it goes."""
    text = getattr(error, "strerror", None) or " ".join(str(error).split()) or type(error).__name__
    folder = os.path.dirname(os.path.abspath(path))
    while folder and not os.path.isdir(folder):
        folder = os.path.dirname(folder)
    try:
        free = f"{shutil.disk_usage(folder).free / 1e6:.3g} MB free there"
    except OSError:
        free = "free space unknown"
    return f"cannot write {path}: {text} ({free}; is the results folder read-only or full?)"


def read_dataset(path: str | Path, required: Iterable[str] = ()) -> xr.Dataset:
    """Load a netCDF file fully into memory and check that it holds the named variables.

    Raises
    ------
    OutputError
        If the file is missing, unreadable, or lacks a required variable.
    """
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{path}: is a folder, expected a netCDF file")
    if not path.is_file():
        raise OutputError(f"{path}: no such file")
    try:
        ds = xr.load_dataset(path, engine="netcdf4")
    except (OSError, ValueError) as err:
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise OutputError(f"{path}: not a readable netCDF file ({reason})") from err
    missing = [name for name in required if name not in ds.variables]
    if missing:
        raise OutputError(f"{path}: missing variable(s) {missing}")
    return ds
