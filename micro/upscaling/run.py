"""Entry point of the upscaling stage: micro results -> ``results/upscaling/pellet_permeability``.

Reads the micro results, computes the table (:func:`micro.upscaling.table.upscale`, no
file I/O) and writes, through :func:`shared.io.write_outputs`, the netCDF table (the only
thing macro reads from micro, docs/design.md §2), its CSV export (condition, suction,
phase, axis, k) for users of other tools, whose sha256 the table records (a hand edit of
the export is refused, :func:`shared.table_export.check_csv_export`), and a figure. The
table is checked before anything is written, and every file is replaced atomically, so
a refused source leaves no partial table.
"""

from __future__ import annotations

import csv
import hashlib
import io
import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import xarray as xr

from micro.upscaling.figures import table_figure
from micro.upscaling.table import SOURCE_VARIABLES, UpscalingSettings, table_rows, upscale
from shared.config import ConfigError
from shared.io import OutputError, read_dataset, write_outputs
from shared.table_export import CSV_EXPORT_ATTRIBUTE

__all__ = ["TableOutputs", "run"]

log = logging.getLogger("micro.upscaling")


def _csv_export(table: xr.Dataset) -> str:
    """The table's CSV export: one row (condition, suction, phase, axis, k) per value."""
    stream = io.StringIO(newline="")
    writer = csv.writer(stream)
    writer.writerow(["condition", "suction_pa", "phase", "axis", "k_m2"])
    for condition, suction, phase, axis, k in table_rows(table):
        writer.writerow([condition, f"{suction:.10g}", phase, axis, f"{k:.10g}"])
    return stream.getvalue()


class TableOutputs(NamedTuple):
    """The files of :func:`run`: ``results/upscaling/pellet_permeability.nc``, its CSV
    export and its PNG."""

    table: str | Path
    csv: str | Path
    figure: str | Path


def run(
    upscaling: Mapping[str, Any],
    inputs: Mapping[str, Sequence[str | Path]],
    outputs: TableOutputs,
    *,
    rule: str | None = None,
) -> xr.Dataset:
    """Build, check and write the pellet permeability table.

    Parameters
    ----------
    upscaling
        Validated ``upscaling`` section (``conditions``, ``suction_range_pa``).
    inputs
        Per condition, the micro result files of its case or ensemble.
    outputs
        ``pellet_permeability.nc``, ``.csv`` and ``.png``.
    rule
        Snakemake rule name, for provenance.

    Raises
    ------
    ConfigError
        Naming the source file, if a source cannot enter the table.
    """
    sources: dict[str, list[tuple[str, xr.Dataset]]] = {}
    for condition, paths in inputs.items():
        members = []
        for path in paths:
            try:
                members.append((str(path), read_dataset(path, SOURCE_VARIABLES)))
            except OutputError as err:
                raise ConfigError(f"upscaling source of condition {condition!r}: {err}") from err
        sources[condition] = members
    table = upscale(sources, UpscalingSettings.from_config(upscaling))
    files = [str(p) for paths in inputs.values() for p in paths]
    export = _csv_export(table).encode()
    # the export's hash in the table: a hand edit of the export is refused, not ignored
    table.attrs[CSV_EXPORT_ATTRIBUTE] = hashlib.sha256(export).hexdigest()
    write_outputs(table, outputs.table, stage="upscaling", title="pellet permeability table",
                  config=dict(upscaling), inputs=files, rule=rule,
                  references="Caulk (2022), PhD thesis, Sec. 3.5.3 and 4.6",
                  files={outputs.csv: export},
                  figure=(outputs.figure, lambda path: table_figure(table, path)))
    for condition in table["condition"].values:
        k = table["k"].sel(condition=condition, phase="water")
        log.info("%s: water k %.3g-%.3g m2 over %.3g-%.3g Pa from %d result(s)", condition,
                 float(k.min()), float(k.max()), float(table["suction"][0]),
                 float(table["suction"][-1]), int(table["n_realizations"].sel(condition=condition)))
    return table
