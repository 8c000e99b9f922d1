"""The macro model as a library function: one mock-up case in memory, no file.

:func:`mock_up` packs the pellets, builds the mixture on the Delaunay mesh of their
centres, hydrates it from both ends and records the wall readings (docs/design.md §2)
until it stops near equilibrium (:mod:`macro.stopping`: the saturations and the wall
pressures have levelled off relative to their current levels) or at the ``max_time_s``
/ ``max_steps`` guards, whichever comes first; the reason is recorded. Its loop is the
generator :func:`hydration`, one yield per step, iterated by :func:`simulate`, which
decides when to stop and, given a :class:`shared.checkpointer.Checkpointer`, when to
save a snapshot (:func:`macro.run.run` passes one; :func:`mock_up` none).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np
import xarray as xr

from macro.checkpoint import save_snapshot
from macro.laws import MixtureParameters, case_materials, mixture_parameters
from macro.model import MacroModel
from macro.packing import pack_cylinder
from macro.records import Records, records_dataset
from macro.settings import MacroSettings, macro_settings
from macro.stopping import DAY, MONITORED, RunProgress
from macro.vtk import SnapshotSeries
from shared.checkpointer import Checkpointer
from shared.errors import ConfigError
from shared.upscaling import PermeabilityTable

__all__ = ["build_model", "case_parameters", "hydration", "mock_up", "new_model", "simulate"]

LOG = logging.getLogger("claychain.macro")
PACKING_TOLERANCE = 0.05
"""Largest overlap left by the packing, as a fraction of the pellet radius."""
THIN_ABOVE = 4000
"""Records kept in memory before every other one is dropped (see ``simulate``)."""


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
    """The initial model: the pellets packed in the container, the powder between them,
    balanced (:meth:`macro.model.MacroModel.balance`).

    Raises
    ------
    shared.errors.ConfigError
        If the packing leaves pellets overlapping by more than ``PACKING_TOLERANCE``.
    """
    packing = pack_cylinder(settings.height, settings.radius, settings.pellet_radius,
                            settings.packing_fraction, np.random.default_rng(settings.seed),
                            settings.packing_sweeps, settings.pellet_radius_spread)
    if packing.largest_overlap > PACKING_TOLERANCE * settings.pellet_radius:
        overlap = packing.largest_overlap / settings.pellet_radius
        raise ConfigError(
            f"macro.mixture: a pellet packing fraction of {settings.packing_fraction:.3g}: the packing left "
            f"pellets overlapping each other or the container by {overlap:.2g} of a radius within "
            f"{settings.packing_sweeps} minimiser iterations (macro.numerics.packing_iterations); "
            "lower the packing fraction or raise the iterations")
    model = MacroModel.create(settings, material, table, packing)
    model.packing = packing
    model.balance()
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
        The records and readings :func:`macro.run.run` writes, with the ``stop_reason``.
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
    records.start(model)
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
    return records_dataset(model, rows, records.edges), reason
