"""Snapshots of a macro run: the whole model and the records so far, to resume after a kill.

The model is a plain dataclass of numpy arrays, the mesh, the packing and the table's
look-up counters; it is pickled whole (with the trial time step of the implicit scheme
and every counter), so that a resumed run continues bit for bit as the uninterrupted
one would (``tests/macro/test_checkpoint.py``). A snapshot carries the hash of what
decides the run (the case's configuration, the table's sha256 and the sources of macro/
and shared/): a snapshot written under another configuration or code is ignored (logged).
Files are written to a temporary name and renamed; the run removes its snapshot when it
has written its output.
"""

from __future__ import annotations

import logging
import pickle
from pathlib import Path
from typing import Any

import numpy as np

from macro.model import MacroModel
from shared.io import OutputError, atomic_write

__all__ = ["load_snapshot", "save_snapshot"]

LOG = logging.getLogger("claychain.macro")


def save_snapshot(path: Path, digest: str, model: MacroModel, rows: dict[str, list[Any]],
                  wall_time: float) -> None:
    """Write the model, the records and the wall time so far [s], atomically."""
    payload = {"digest": digest, "model": model, "rows": rows, "wall_time": float(wall_time)}

    def write(tmp: str) -> None:
        with open(tmp, "wb") as handle:
            pickle.dump(payload, handle, protocol=pickle.HIGHEST_PROTOCOL)

    atomic_write(path, write)


def load_snapshot(path: Path, digest: str) -> tuple[MacroModel, dict[str, list[Any]], float] | None:
    """The saved model, records and wall time, or None if absent or of another
    configuration, table or code.

    Raises
    ------
    shared.io.OutputError
        Naming the file when it exists but cannot be read (truncated, not a snapshot) or
        when its records differ in shape from one to another (profiles on other bins
        cannot make one result): delete it to start the case afresh.
    """
    if not path.is_file():
        return None
    try:
        with open(path, "rb") as handle:
            payload = pickle.load(handle)
        digest_saved = payload["digest"]
    except (OSError, EOFError, pickle.UnpicklingError, KeyError, TypeError, AttributeError) as error:
        raise OutputError(f"{path}: unreadable macro snapshot ({type(error).__name__}); "
                          "delete it to start the case afresh") from error
    if digest_saved != digest:
        LOG.info("%s: snapshot of another configuration, table or code: the case starts afresh", path)
        return None
    rows = payload["rows"]
    uneven = sorted(k for k, values in rows.items() if len({np.shape(v) for v in values}) > 1)
    if uneven:
        raise OutputError(f"{path}: macro snapshot whose records of {', '.join(uneven)} differ in "
                          "shape; delete it to start the case afresh")
    return payload["model"], rows, float(payload["wall_time"])
