"""Entry point of the macro stage: one mock-up case -> ``results/macro/<case>.nc`` + figure.

``run(config, case, table_path, CaseOutputs(result, figure))`` reads the pellet
permeability table, hydrates the mock-up (:func:`macro.mock_up.simulate`, the loop of the
library function :func:`macro.mock_up.mock_up`), resuming from and saving to the
snapshot beside the output (:class:`shared.checkpointer.Checkpointer`), and writes the
netCDF file and its figure (:func:`shared.io.write_outputs`), with the ParaView series
when ``macro.vtk_snapshots`` asks for one.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from functools import partial
from pathlib import Path
from typing import Any, NamedTuple

import xarray as xr

from macro.checkpoint import load_snapshot
from macro.laws import MixtureParameters, case_materials
from macro.mock_up import build_model, case_parameters, hydration, mock_up, new_model, simulate
from macro.model import MacroModel
from macro.newton import NewtonError
from macro.settings import MacroSettings
from macro.vtk import SnapshotSeries
from shared.checkpointer import Checkpointer, run_digest
from shared.io import write_outputs
from shared.upscaling import PermeabilityTable, check_suction_coverage

__all__ = ["CaseOutputs", "build_model", "case_parameters", "hydration", "mock_up", "new_model", "run", "simulate"]

LOG = logging.getLogger("claychain.macro")


class CaseOutputs(NamedTuple):
    """The files of :func:`run`: ``results/macro/<case>.nc`` and its PNG (None: no figure)."""

    result: str | Path
    figure: str | Path | None = None


def run(
    config: Mapping[str, Any],
    case: str,
    table_path: str | Path,
    outputs: CaseOutputs,
    *,
    rule: str | None = None,
) -> xr.Dataset:
    """Run one macro case and write its netCDF result (and the figure).

    Parameters
    ----------
    config
        Validated configuration with ``macro`` and ``materials`` (mixture_pellet,
        mixture_powder) sections.
    case
        Name in ``macro.cases``.
    table_path
        ``results/upscaling/pellet_permeability.nc``; its path and sha256 are recorded.
    outputs
        The netCDF result and the PNG figure (None: no figure); the snapshot is
        ``.<case>.snapshot.npz`` beside the netCDF.
    rule
        Snakemake rule name for the provenance.

    Raises
    ------
    shared.io.OutputError
        If the table is missing or malformed (naming the file).
    shared.errors.InputError
        If the table's suctions miss the case's range by more than a decade (naming the
        file); look-ups outside the table within that are clamped, counted and logged.
    ValueError, KeyError
        Naming the configuration key at fault (pellets larger than the container,
        unknown case).
    macro.newton.NewtonError
        Naming a local system without a solution.
    """
    settings, material = case_parameters(config, case)
    table = PermeabilityTable.from_file(table_path, settings.table_condition)
    check_suction_coverage(table, settings.boundary_suction, material.initial_suction, str(table_path),
                           "macro.boundary_suction_pa to materials.mixture_pellet.initial_suction_pa")
    section = {"macro": config["macro"], "case": case,
               "materials": case_materials(config["materials"], config["macro"]["cases"][case])}
    result = Path(outputs.result)
    # the code too (this module and what it imports, as the netCDF's code_sha256), and the
    # table: a snapshot of other code would resume as a mixture of two models
    checkpointer = Checkpointer(result.with_name(f".{result.stem}.snapshot.npz"),
                                run_digest(section, __file__, [table_path]), settings.snapshot_interval, LOG)
    model, rows = _resumed_or_new(checkpointer, case, settings, material, table)
    series = None
    if settings.vtk_snapshots > 0:
        series = SnapshotSeries(result.with_name(f"{result.stem}_vtk"), result.stem, settings.vtk_snapshots,
                                settings.max_time, checkpointer.resumed)
        series.entries = [e for e in series.entries if e[0] <= model.time]
    try:
        ds, reason = simulate(model, rows, checkpointer, series)
    except NewtonError as error:
        kept = f"; the last snapshot ({checkpointer.path}) is kept" if checkpointer.path.is_file() else ""
        raise NewtonError(f"macro case {case} at step {model.steps} (t = {model.time:.6g} s): "
                          f"{error}{kept}") from error
    _warn_clamped(model.table, case)
    ds.attrs.update(stop_reason=reason, runtime_s=checkpointer.wall_time(), resumed=int(checkpointer.resumed))
    write_outputs(ds, result, stage="macro", title=f"claychain macro mock-up {case}", config=section,
                  seed=settings.seed, inputs=[table_path], rule=rule, wildcards={"case": case},
                  references="Caulk (2022) thesis Chap. 4 and Appendix .1",
                  figure=None if outputs.figure is None else (outputs.figure, partial(_case_figure, ds)))
    checkpointer.finish()
    return ds


def _resumed_or_new(checkpointer: Checkpointer, case: str, settings: MacroSettings, material: MixtureParameters,
                    table: PermeabilityTable) -> tuple[MacroModel, dict[str, list[Any]] | None]:
    """The model and records of the checkpointer's snapshot if it holds this case's, else a
    new model (:func:`new_model`) and no records."""
    resumed = load_snapshot(checkpointer, settings, material, table)
    if resumed is not None:
        model, rows = resumed
        LOG.info("case %s: resumed from %s at step %d (t = %.4g s)", case, checkpointer.path,
                 model.steps, model.time)
        return model, rows
    model = new_model(settings, material, table)
    LOG.info("case %s: %d pellets (packing fraction %.3f), %d cells (%d held, %.2g %% void inert)",
             case, model.n_pellets, model.packing.packing_fraction,
             model.n_cells, int(model.held.sum()), 100 * model.neglected_void_fraction())
    return model, None


def _warn_clamped(table: PermeabilityTable, case: str) -> None:
    """One warning line when look-ups fell outside the table's suctions (clamped)."""
    if table.clamped:
        low, high = table.suction_range
        LOG.warning("case %s: %d of %d table look-ups (%.2g %%) fell outside the table's suctions "
                    "[%.3g, %.3g] Pa and were clamped to them (attribute table_clamped_lookups)", case,
                    table.clamped, table.looked_up, 100.0 * table.clamped / table.looked_up, low, high)


def _case_figure(ds: xr.Dataset, path: str | Path) -> Path:
    """The case's figure (:func:`macro.figures.case_figure`), imported when drawn: a run
    without a figure loads no matplotlib."""
    from macro.figures import case_figure

    return case_figure(ds, path)
