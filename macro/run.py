"""Entry point of the macro stage: one mock-up case -> ``results/macro/<case>.nc`` + figure.

``run(config, case, table_path, CaseOutputs(result, figure))`` packs the pellets, builds the
mixture on the Delaunay mesh of their centres, hydrates it from both ends and records the
wall readings (docs/design.md §2). It stops near equilibrium (:mod:`macro.stopping`: the
saturations and the wall pressures have levelled off relative to their current levels)
or at the ``max_time_s`` / ``max_steps`` guards, whichever comes first; the reason is
recorded.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping
from functools import partial
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import xarray as xr

from macro.checkpoint import load_snapshot, save_snapshot
from macro.laws import MixtureParameters, case_materials, mixture_parameters
from macro.model import MacroModel
from macro.newton import NewtonError
from macro.packing import pack_cylinder
from macro.records import INVARIANTS, MEASUREMENT_ROWS, PASSAGE_PRESSURE, Records
from macro.settings import MacroSettings, macro_settings
from macro.stopping import DAY, MONITORED, RunProgress
from macro.vtk import SnapshotSeries
from shared.checkpointer import Checkpointer, run_digest
from shared.errors import ConfigError
from shared.io import write_outputs
from shared.upscaling import PermeabilityTable, check_suction_coverage

__all__ = ["CaseOutputs", "build_model", "case_parameters", "hydration", "mock_up", "new_model", "run", "simulate"]

LOG = logging.getLogger("claychain.macro")
FloatArray = npt.NDArray[np.float64]
PACKING_TOLERANCE = 0.05
"""Largest overlap left by the packing, as a fraction of the pellet radius."""
THIN_ABOVE = 4000
"""Records kept in memory before every other one is dropped (see ``simulate``)."""


class CaseOutputs(NamedTuple):
    """The files of :func:`run`: ``results/macro/<case>.nc`` and its PNG (None: no figure)."""

    result: str | Path
    figure: str | Path | None = None


def case_parameters(config: Mapping[str, Any], case: str) -> tuple[MacroSettings, MixtureParameters]:
    """The settings and material parameters of a case from the validated ``macro`` and
    ``materials`` sections."""
    settings = macro_settings(config["macro"], case)
    material = mixture_parameters(case_materials(config["materials"], config["macro"]["cases"][case]),
                                  settings.powder)
    return settings, material


def build_model(config: Mapping[str, Any], case: str, table: PermeabilityTable) -> MacroModel:
    """The initial model of a case from the validated ``macro`` and ``materials`` sections."""
    return new_model(*case_parameters(config, case), table)


def new_model(settings: MacroSettings, material: MixtureParameters, table: PermeabilityTable) -> MacroModel:
    """The initial model: the pellets packed in the container, the powder between them.

    Raises
    ------
    shared.errors.ConfigError
        If the packing leaves pellets overlapping by more than ``PACKING_TOLERANCE``.
    """
    packing = pack_cylinder(settings.height, settings.radius, settings.pellet_radius,
                            settings.packing_fraction, np.random.default_rng(settings.seed),
                            settings.packing_sweeps, settings.pellet_radius_spread)
    if packing.largest_overlap > PACKING_TOLERANCE * settings.pellet_radius:
        raise ConfigError(
            f"macro.mixture: a pellet packing fraction of {settings.packing_fraction:.3g}: the packing left pellets overlapping "
            f"each other or the container by {packing.largest_overlap / settings.pellet_radius:.2g} of a "
            f"radius within {settings.packing_sweeps} minimiser iterations (macro.numerics.packing_iterations); "
            "lower the packing fraction or raise the iterations")
    model = MacroModel.create(settings, material, table, packing)
    model.packing = packing
    return model


def mock_up(table: PermeabilityTable, settings: MacroSettings, material: MixtureParameters) -> xr.Dataset:
    """The mock-up hydrated from both ends until near equilibrium or a guard, in memory:
    no file is read or written (no snapshot, no ParaView series).

    Parameters
    ----------
    table
        The pellet permeability table (:meth:`shared.upscaling.PermeabilityTable.from_file`
        or built from the upscaling stage's Dataset).
    settings, material
        The case's settings and mixture parameters (:func:`case_parameters`).

    Returns
    -------
    xarray.Dataset
        The records and readings :func:`run` writes, with the ``stop_reason``.
    """
    ds, reason = simulate(new_model(settings, material, table))
    ds.attrs["stop_reason"] = reason
    return ds


def hydration(model: MacroModel, records: Records, thin_above: int) -> Iterator[int]:
    """The coupled steps as a generator: each step is taken, recorded (thinned past
    ``thin_above`` records) and measured when due, then yields the quantity that sets the
    stop distance (-1 while it is unknown); the caller decides when to stop, snapshot or
    write. It ends at ``max_steps``."""
    s = model.settings
    while model.steps < s.max_steps:
        dt = model.step(max_dt=s.max_time - model.time)
        records.record(model, dt)
        _, held_by = records.stop_distance(model)
        records.thin(thin_above)
        if records.measure_due(model):
            records.measure(model)
        yield held_by


def simulate(
    model: MacroModel,
    rows: dict[str, list[Any]] | None = None,
    checkpointer: Checkpointer | None = None,
    series: SnapshotSeries | None = None,
) -> tuple[xr.Dataset, str]:
    """Hydrate until near equilibrium or a guard; returns the records and the stop reason.

    ``model`` is :func:`build_model`'s (it carries its ``packing``), new or resumed;
    ``rows`` are the records of a resumed run (None: a new run, :class:`macro.records.
    Records`); ``checkpointer`` saves the model and the records after a whole step when
    its interval of wall time has passed (None: never); ``series`` writes the ParaView
    snapshots when due and at the end. The stop distance (:func:`macro.stopping.stop_distance`) is evaluated
    after every step and recorded. The column's permeability
    (:func:`macro.column_permeability.column_permeability`) is measured at the start,
    when the run first passes each of ``column_permeability_times_s`` and at the end.
    """
    s: MacroSettings = model.settings
    records = Records(model, rows)
    rows = records.rows
    if records.new:
        records.record(model, 0.0)
        records.stop_distance(model)
        records.measure(model)
    progress = RunProgress(f"macro ({model.n_pellets} pellets, {model.n_cells} cells)", LOG,
                           s.max_time, s.max_steps, s.stop_after, model.time, model.steps)
    held_by = -1
    reason = "max_steps"
    if checkpointer is not None:
        checkpointer.restart_cadence()
    for held_by in hydration(model, records, THIN_ABOVE):
        if series is not None and series.due(model):
            series.write(model)
        progress.update(model.time, model.steps, rows["saturation"][-1], rows["time"], rows["stop_distance"],
                        held_by)
        if model.time >= s.max_time * (1.0 - 1e-12):
            reason = "max_time"
            break
        if model.time >= s.stop_after and rows["stop_distance"][-1] <= 1.0:
            reason = "near_equilibrium"
            break
        if checkpointer is not None and checkpointer.due():
            save_snapshot(checkpointer, model, rows)
    progress.update(model.time, model.steps, rows["saturation"][-1], rows["time"], rows["stop_distance"],
                    held_by, force=True)
    if series is not None:
        series.write(model)
    if rows["permeability_time"][-1] != model.time:
        records.measure(model)
    LOG.info("stopped (%s) at t = %.4g d after %d steps, stop distance %.3g%s", reason, model.time / DAY,
             model.steps, rows["stop_distance"][-1], f" ({MONITORED[held_by]})" if held_by >= 0 else "")
    return _dataset(model, rows, records.edges), reason


def _keep(steps: npt.NDArray[np.int64], wanted: int) -> npt.NDArray[np.int64]:
    """Indices of at most ``wanted`` records nearest to equally spaced step numbers, the
    first and last included (the records in memory are thinned unevenly)."""
    targets = np.linspace(steps[0], steps[-1], min(steps.size, wanted))
    nearest = np.clip(np.searchsorted(steps, targets), 1, steps.size - 1)
    nearest -= (targets - steps[nearest - 1]) < (steps[nearest] - targets)
    return np.unique(nearest)


def _dataset(model: MacroModel, rows: Mapping[str, list[Any]], edges: FloatArray) -> xr.Dataset:
    s = model.settings
    keep = _keep(np.asarray(rows["step"]), s.records)
    pick = {k: np.asarray(v)[keep] for k, v in rows.items() if k not in MEASUREMENT_ROWS}
    z = 0.5 * (edges[:-1] + edges[1:]) + 0.5 * s.height
    packing = model.packing
    coords = {
        "time": ("time", pick["time"], {"units": "s", "long_name": "simulated time"}),
        "sensor": ("sensor", list(s.sensors.names), {"units": "1", "long_name": "radial pressure sensor (macro.sensors)"}),
        "sensor_height": ("sensor", s.sensors.heights, {"units": "m", "long_name": "height of the sensor's centre above the lower plate"}),
        "sensor_band_width": ("sensor", s.sensors.widths, {"units": "m", "long_name": "height of the wall band the sensor reads"}),
        "band": ("band", np.arange(len(s.bands.names)), {"units": "1", "long_name": "equal height band of the curved wall, from the bottom"}),
        "band_height": ("band", s.bands.heights, {"units": "m", "long_name": "height of the band's middle above the lower plate"}),
        "material": ("material", ["pellet", "powder"], {"units": "1", "long_name": "material"}),
        "z": ("z", z, {"units": "m", "long_name": "height above the lower plate"}),
        "pellet": ("pellet", np.arange(model.n_pellets), {"units": "1", "long_name": "pellet index"}),
        "xyz": ("xyz", ["x", "y", "z"], {"units": "1", "long_name": "axis"}),
        "plate": ("plate", ["upper", "lower"], {"units": "1", "long_name": "plate of the container"}),
        "permeability_time": ("permeability_time", np.asarray(rows["permeability_time"]),
                              {"units": "s", "long_name": "simulated time of a column permeability measurement"}),
    }
    data = {
        "sensor_pressure": (("time", "sensor"), pick["sensors"], {"units": "Pa", "long_name": "radial pressure read by each sensor: radial force in its band over 2 pi R w"}),
        "band_pressure": (("time", "band"), pick["bands"], {"units": "Pa", "long_name": "radial pressure on the curved wall per equal height band (Appendix .1 getPressure), force over 2 pi R dz"}),
        "axial_pressure_upper": (("time",), pick["axial_upper"], {"units": "Pa", "long_name": "axial pressure on the upper plate"}),
        "axial_pressure_lower": (("time",), pick["axial_lower"], {"units": "Pa", "long_name": "axial pressure on the lower plate"}),
        "mean_suction": (("time", "material"), pick["suction"], {"units": "Pa", "long_name": "volume-weighted mean suction"}),
        "mean_saturation": (("time", "material"), pick["saturation"], {"units": "1", "long_name": "pore-volume-weighted mean water saturation"}),
        "swelling_profile": (("time", "z"), pick["swelling"], {"units": "1", "long_name": "mean volumetric swelling strain V/V0 - 1 of pellets and powder along the axis"}),
        "suction_profile": (("time", "z"), pick["suction_profile"], {"units": "Pa", "long_name": "mean suction along the axis"}),
        "pellet_suction": (("time", "pellet"), pick["pellet_suction"], {"units": "Pa", "long_name": "suction of each pellet (field snapshots)"}),
        "stop_distance": (("time",), pick["stop_distance"], {"units": "1", "long_name": "largest relative rate of the monitored quantities over its tolerance (1 = stop; NaN: too few records in the window)"}),
        "unbalanced_force": (("time",), pick["unbalanced"], {"units": "1", "long_name": "mean resultant over mean contact force"}),
        "time_step": (("time",), pick["dt"], {"units": "s", "long_name": "time step that ended at this record"}),
        "balanced": (("time",), (pick["unbalanced"] < s.dem_balance_tolerance).astype(np.int8),
                     {"units": "1", "long_name": "1 if the reading is from a balanced state (unbalanced force ratio below numerics.dem_balance_tolerance)"}),
        **{name: (("time",), pick[name], {"units": units, "long_name": long})
           for name, (units, long) in INVARIANTS.items()},
        "pellet_position": (("pellet", "xyz"), packing.positions, {"units": "m", "long_name": "initial pellet centre (origin at the container's centre)"}),
        "column_permeability": (("permeability_time",), np.asarray(rows["column_permeability"]), {"units": "m2", "long_name": "permeability of the whole column along its axis (steady flow between the plates, Appendix .1 emulatePermeability)"}),
        "sensor_passage_time": (("sensor",), rows["passage"][0][:-2], {"units": "s", "long_name": f"first time the sensor read {PASSAGE_PRESSURE:g} Pa (every step; NaN: never)"}),
        "axial_passage_time": (("plate",), rows["passage"][0][-2:], {"units": "s", "long_name": f"first time the plate read {PASSAGE_PRESSURE:g} Pa (every step; NaN: never)"}),
        "pellet_radius_final": (("pellet",), model.radii, {"units": "m", "long_name": "pellet radius at the end"}),
    }
    table = model.table
    attrs = {
        "n_pellets": model.n_pellets,
        "n_cells": model.n_cells,
        "packing_fraction": packing.packing_fraction,
        "packing_largest_overlap_m": packing.largest_overlap,
        "table_condition": s.table_condition,
        "table_lookups": table.looked_up,
        "table_clamped_lookups": table.clamped,
        **model.counters.attributes(),
        "steps": model.steps,
        "inert_void_fraction": model.neglected_void_fraction(),
        "boundary_inflow_kg": model.boundary_inflow,
        "dry_density_target_kg_m3": s.dry_density,
        "dry_density_initial_kg_m3": float(pick["dry_density"][0]),
        "dry_density_final_kg_m3": float(pick["dry_density"][-1]),
        "pellet_powder_dry_mass_ratio": model.dry_mass_ratio(),
        "powder_initial_porosity": model.powder_porosity,
        "balanced_fraction": float(np.mean(pick["unbalanced"] < s.dem_balance_tolerance)),
        "powder_heterogeneity": str(s.powder["heterogeneity"]),
        "powder_swelling_pressure": int(s.powder_pressure),
        "powder_pressure_on_walls": int(s.powder_on_walls),
        "sensor_area_convention": ("force / (2 pi R dz)" if s.sensors.area_share == 1.0
                                   else "force / (pi R dz), the thesis's getPressure"),
        "stop_monitored": ", ".join(MONITORED),
    }
    return xr.Dataset(data, coords=coords, attrs=attrs)


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
             case, model.n_pellets, model.packing.packing_fraction,  # type: ignore[union-attr]
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
