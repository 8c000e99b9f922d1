"""The CSV export of the pellet permeability table, and the check that it was not edited.

The upscaling stage writes ``pellet_permeability.csv`` beside the netCDF table for users of
other tools and records the export's sha256 in the table (attribute
``csv_export_sha256``). The macro stage reads the netCDF only, so an edit of the export
would change nothing: the workflow refuses it when it starts (workflow/rules/common.smk),
naming the route to permeabilities of one's own (``macro.table_path``). Light on
purpose (no xarray): building the DAG imports it.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from shared.errors import InputError

__all__ = ["CSV_EXPORT_ATTRIBUTE", "check_csv_export"]

CSV_EXPORT_ATTRIBUTE = "csv_export_sha256"
"""The table's attribute holding the sha256 of the CSV export written beside it."""


def check_csv_export(path: str | Path) -> None:
    """Refuse a CSV export beside the table ``path`` that differs from the one written.

    The macro stage reads the netCDF only, so an edit of ``<table>.csv`` would change
    nothing; the table records its export's sha256 (``csv_export_sha256``). Nothing is
    checked while either file is missing or for a table without the attribute.

    Raises
    ------
    shared.errors.InputError
        Naming the CSV file and the route to other permeabilities (``macro.table_path``).
    """
    path = Path(path)
    export = path.with_suffix(".csv")
    if not (path.is_file() and export.is_file()):
        return
    import netCDF4  # here: the workflow's configuration helpers import this module

    try:
        with netCDF4.Dataset(path) as table:
            recorded = getattr(table, CSV_EXPORT_ATTRIBUTE, None)
    except OSError:
        return  # an unreadable table: the stage that reads it names it
    if recorded is not None and hashlib.sha256(export.read_bytes()).hexdigest() != recorded:
        raise InputError(
            f"{export}: edited since the upscaling stage wrote it (its sha256 differs from the "
            f"one {path.name} records), but the macro stage reads {path} only: delete it to have "
            "it written again, and to run the macro model on "
            "permeabilities of your own, write them to a table of your own and set "
            "macro.table_path (docs/howto-parameters.md, \"Your own permeability table\")"
        )
