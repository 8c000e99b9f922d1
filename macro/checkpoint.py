"""Snapshots of a macro run: the model's state and the records so far, to resume after a kill.

The model's state is saved generically (:mod:`shared.plain_state`): every attribute of
:class:`macro.model.MacroModel`, dataclass field or not, with the mesh, the exchanges,
the readings and the packing rebuilt as their declared classes, the trial time step of
the implicit scheme and every counter, so that a resumed run continues bit for bit as
the uninterrupted one would (``tests/macro/test_checkpoint.py``). The settings and the
material parameters are not stored but rebuilt from the configuration, and the table
from its file; the table's look-up counters are stored. The file is data only
(:mod:`shared.snapshot`), written and read by the run's
:class:`shared.checkpointer.Checkpointer`: it carries the hash of what decides the run
(the case's configuration, the table's sha256 and the code macro.run imports), and a
snapshot of another configuration or code is ignored (logged); a damaged or
inconsistent one is moved aside and the case starts from the beginning. The run removes
its snapshot when it has written its output.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from macro.laws import MixtureParameters
from macro.model import MacroModel
from macro.settings import MacroSettings
from shared.checkpointer import Checkpointer
from shared.errors import SnapshotError
from shared.plain_state import Decoder, Encoder
from shared.upscaling import PermeabilityTable

__all__ = ["load_snapshot", "save_snapshot"]

_GIVEN = ("settings", "material", "table")
"""Attributes of the model rebuilt from the configuration and the table file, not stored."""


def save_snapshot(checkpointer: Checkpointer, model: MacroModel, rows: dict[str, list[Any]]) -> None:
    """Write the model and the records so far to the checkpointer's file, atomically, with
    the wall time so far (:meth:`shared.checkpointer.Checkpointer.save`).

    Raises
    ------
    TypeError
        Naming an attribute of the model whose type a snapshot cannot hold.
    """
    encoder = Encoder(given=_GIVEN)
    meta = {"model": encoder.attributes(model, "model"), "rows": encoder.encode(rows, None, "rows")}
    checkpointer.save(meta, encoder.arrays)


def load_snapshot(checkpointer: Checkpointer, settings: MacroSettings, material: MixtureParameters,
                  table: PermeabilityTable) -> tuple[MacroModel, dict[str, list[Any]]] | None:
    """The saved model and records; None if there is no usable snapshot.

    Parameters
    ----------
    checkpointer
        The run's: its file, and the hash of the case's configuration, table and code.
    settings, material, table
        The case's, from its configuration and table file (the digest guarantees they
        are those of the saved run); the table's counters are set to the saved ones.

    Returns
    -------
    tuple or None
        None when the file is absent, of another configuration, table or code (logged), or
        fails its checks (moved aside, logged), such as records that differ in shape from
        one to another (profiles on other bins cannot make one result).
    """

    def restore(meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> tuple[MacroModel, dict[str, list[Any]]]:
        decoder = Decoder(arrays, {"settings": settings, "material": material, "table": table})
        model = decoder.build(MacroModel, meta["model"], "model")
        rows = decoder.decode(meta["rows"], None, "rows")
        uneven = sorted(k for k, values in rows.items() if len({np.shape(v) for v in values}) > 1)
        if uneven:
            raise SnapshotError(f"records of {', '.join(uneven)} differ in shape")
        return model, rows

    return checkpointer.resume(restore)
