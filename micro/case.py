"""One micro case hydrated through its suction checkpoints, with no file: the library function.

* :func:`hydrate`: a porosity grid and validated settings (:class:`micro.config.
  MicroSettings`, from :func:`micro.settings.micro_settings`) in, the case's Dataset out
  (callable from a notebook);
* :func:`checkpoints_reached`, the loop as a generator: it hydrates a :class:`Hydration`
  to each checkpoint in turn and yields a :class:`Checkpoint`; with a
  :class:`shared.checkpointer.Checkpointer`, it saves the state between flow steps at
  the checkpointer's cadence and at each checkpoint measured here, so that a killed run
  resumes (:func:`resumed_or_settled`) at its last save, bit for bit.

:func:`micro.run.run` reads the grid and writes the Dataset around them.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Iterator
from concurrent.futures import Executor
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
import xarray as xr

from micro.checkpoint import load_checkpoint, save_checkpoint
from micro.config import MicroSettings
from micro.hydration import (
    BalanceProgress,
    DivergenceError,
    FlowSystem,
    PelletState,
    advance_to_balance,
)
from micro.pellet import (
    CheckpointMeasurement,
    SpecimenSpec,
    initial_state,
    measure_checkpoint,
    settle,
)
from micro.pool import measuring
from micro.results import records_dataset
from shared.checkpointer import Checkpointer
from shared.dem.parameters import DEMParameters
from shared.materials import ClayParameters
from shared.mesh import mesh_from_tetrahedra
from shared.progress import ConvergenceProgress, PhaseClock

__all__ = ["Checkpoint", "Hydration", "checkpoints_reached", "hydrate", "resumed_or_settled", "settled"]

log = logging.getLogger("micro")


@dataclass
class Hydration:
    """A case's hydration under way, which :func:`checkpoints_reached` advances.

    Attributes
    ----------
    settings
        The case's settings.
    state, system
        The coupled state and its flow system.
    records
        The records of the checkpoints done (:mod:`micro.results`).
    reference_volume
        Volume of the settled specimen [m3], the reference of ``eps_v``.
    balance
        The balance under way towards the next checkpoint (a run resumed between two
        flow steps), else None.
    pending
        The last checkpoint's measurement, whose permeabilities a worker process may
        still be solving (its record is not in ``records`` yet).
    """

    settings: MicroSettings
    state: PelletState
    system: FlowSystem
    records: list[dict[str, Any]]
    reference_volume: float
    balance: BalanceProgress | None = None
    pending: CheckpointMeasurement | None = None

    def record_pending(self, clock: PhaseClock) -> None:
        """Wait for the pending measurement and add its record."""
        if self.pending is None:
            return
        with clock.phase("measurement"):
            record = self.pending.result()
        self.pending = None
        log.info("%s: s = %.3g Pa, S = %.3f, eps_v = %.4f, cracks %d, k_w,x = %.3g m2, "
                 "k_g,x = %.3g m2, balanced %d", self.settings.name,
                 self.settings.checkpoints[len(self.records)], record["saturation"],
                 record["eps_v"], record["crack_count"], record["permeability"][0, 0],
                 record["permeability"][1, 0], record["balanced"])
        self.records.append(record)

    def dataset(self) -> xr.Dataset:
        """The records so far as the case's Dataset, with the specimen's attributes."""
        settings = self.settings
        ds = records_dataset(self.records, np.asarray(settings.checkpoints, dtype=float))
        ds.attrs.update(n_points=self.state.dem.n_points, n_cells=self.state.mesh.n_cells,
                        confinement=settings.specimen.confinement,
                        crack_model=int(settings.hydration.cracks),
                        porosity_source="ct" if settings.heterogeneous else "homogeneous")
        return ds


def settled(porosity: xr.DataArray, settings: MicroSettings, clock: PhaseClock) -> Hydration:
    """A case's hydration at its start: the specimen built on the porosity grid [1] and
    settled at the initial suction (timed as ``settling`` on ``clock``)."""
    spec, material, parameters = settings.specimen, settings.material, settings.parameters
    source = porosity if settings.heterogeneous else None
    mean = None if settings.heterogeneous else _specimen_mean(spec, porosity, material, parameters)
    with clock.phase("settling"):
        state = initial_state(spec, source, mean, material, parameters)
        system, diagnostics = settle(
            state, FlowSystem.for_mesh(state.mesh, settings=settings.hydration), spec, source,
            mean, settings.hydration, material, parameters)
    log.info("%s: settled at the initial suction in %d DEM steps (unbalanced force %.3g)",
             settings.name, diagnostics["dem_steps"], diagnostics["unbalanced_force"])
    return Hydration(settings, state, system, [], float(state.mesh.volumes.sum()))


def resumed_or_settled(porosity: xr.DataArray, settings: MicroSettings,
                       checkpointer: Checkpointer) -> Hydration:
    """A case's hydration from the checkpointer's file if it holds this case's, else
    :func:`settled` (timed on the checkpointer's clock)."""
    resumed = load_checkpoint(checkpointer, settings.material)
    if resumed is None:
        return settled(porosity, settings, checkpointer.clock)
    hydration = Hydration(settings, *resumed)
    log.info("%s: resuming after checkpoint %d of %d%s", settings.name, len(hydration.records),
             len(settings.checkpoints), "" if hydration.balance is None
             else f", {hydration.balance.flow_steps} flow steps into the next")
    return hydration


@dataclass(frozen=True)
class Checkpoint:
    """A checkpoint reached by :func:`checkpoints_reached`.

    Attributes
    ----------
    index
        Its number, from 0.
    in_background
        Whether a worker process still solves its permeabilities (its record then joins
        the records with the next checkpoint, or at the end).
    """

    index: int
    in_background: bool


def checkpoints_reached(
    hydration: Hydration, clock: PhaseClock, executor: Executor | None = None,
    checkpointer: Checkpointer | None = None,
) -> Iterator[Checkpoint]:
    """Hydrate to each checkpoint not yet recorded, in turn, yielding each one reached.

    Each checkpoint is measured on a mesh rebuilt from the moved points (not the
    per-step update_mesh, which rounds differently; a restart file keeps it). With
    ``executor`` (:func:`micro.pool.measurement_executor`), the worker solves the
    permeabilities while the next checkpoint hydrates, unless it still measures the one
    before (it lags) or a save is overdue: both processes then share this one's solves. The last
    record joins ``hydration.records`` when the generator ends.

    Parameters
    ----------
    hydration
        The case's hydration, advanced in place.
    clock
        Times the phases (settling, flow, ..., measurement).
    executor
        The measurement worker, or None (this process measures).
    checkpointer
        Saves the state between flow steps at its cadence (:func:`_flow_step`) and at
        each checkpoint measured here, before it is yielded; None saves nothing.

    Raises
    ------
    DivergenceError
        If the coupled solution diverges; the message names the case and checkpoint.
    """
    settings = hydration.settings
    count = len(settings.checkpoints)
    for index in range(len(hydration.records), count):
        suction = float(settings.checkpoints[index])
        # flow steps and the largest relative suction misfit, down to the tolerance
        balancing = ConvergenceProgress(
            settings.hydration.hydraulic_tolerance,
            f"{settings.name}: balance at {suction:.3g} Pa (checkpoint {index + 1}/{count}), "
            "suction misfit", log)
        try:
            hydration.system, diagnostics = advance_to_balance(
                hydration.state, hydration.system, suction, settings.hydration,
                settings.material, settings.parameters, start=hydration.balance,
                snapshot=partial(_flow_step, hydration, balancing, checkpointer), clock=clock)
            hydration.balance = None
        except DivergenceError as err:
            kept = "" if checkpointer is None else (
                f"; the last good checkpoint is kept in {checkpointer.path}")
            raise DivergenceError(
                f"case {settings.name}, checkpoint {index} ({suction:.4g} Pa): {err}{kept}"
            ) from err
        overdue = checkpointer is not None and checkpointer.due(2.0)
        background = index + 1 < count and not overdue and (
            hydration.pending is None or hydration.pending.done())
        state = hydration.state
        with clock.phase("measurement"):
            state.mesh = mesh_from_tetrahedra(state.dem.positions, state.mesh.tetrahedra,
                                              state.mesh.neighbours, reorient=False)
            measurement = measure_checkpoint(state, suction, hydration.reference_volume,
                                             settings.material, settings.hydration.cracks,
                                             executor=executor, background=background)
        measurement.record.update(diagnostics)
        hydration.record_pending(clock)
        hydration.pending = measurement
        # a checkpoint measured here (not by the worker) is saved at once
        if checkpointer is not None and not measurement.in_background:
            _save(checkpointer, hydration, hydration.system, None)
        yield Checkpoint(index, measurement.in_background)
    hydration.record_pending(clock)


def _save(checkpointer: Checkpointer, hydration: Hydration, system: FlowSystem,
          balance: BalanceProgress | None) -> None:
    """Save the state with every record so far (waits for a pending measurement)."""
    clock = checkpointer.clock
    hydration.record_pending(clock)
    with clock.phase("output"):
        save_checkpoint(checkpointer, hydration.state, system, hydration.records,
                        hydration.reference_volume, balance=balance)


def _flow_step(hydration: Hydration, balancing: ConvergenceProgress,
               checkpointer: Checkpointer | None, system: FlowSystem,
               balance: BalanceProgress) -> None:
    """After each flow step: log the balance's progress (once a minute) and save the
    state when the checkpointer's interval has passed. A save waits for the worker:
    while it measures, the save is put off until it is done, for one more interval at
    most."""
    balancing.update(balance.flow_steps, balance.misfit)
    if checkpointer is None:
        return
    pending = hydration.pending
    if checkpointer.due(1.0) and (pending is None or pending.done() or checkpointer.due(2.0)):
        _save(checkpointer, hydration, system, balance)


def hydrate(porosity_grid: xr.Dataset, settings: MicroSettings) -> xr.Dataset:
    """Hydrate one case through its suction checkpoints; no file is read or written.

    Parameters
    ----------
    porosity_grid
        The imaging stage's grid (``results/porosity/<sample>.nc``): its ``porosity``
        variable [1] on (z, y, x) node coordinates [m].
    settings
        The case's settings (:func:`micro.settings.micro_settings`).

    Returns
    -------
    xarray.Dataset
        One record per checkpoint along ``suction`` [Pa] (:mod:`micro.results`): what
        :func:`micro.run.run` writes, less the provenance and wall-time attributes.

    Raises
    ------
    DivergenceError
        If the coupled solution diverges.
    """
    clock = PhaseClock()
    hydration = settled(porosity_grid["porosity"], settings, clock)
    with measuring(hydration.state.mesh.n_cells) as executor:
        for _ in checkpoints_reached(hydration, clock, executor):
            pass
    return hydration.dataset()


def _specimen_mean(spec: SpecimenSpec, grid: xr.DataArray, material: ClayParameters,
                   parameters: DEMParameters) -> float:
    """Mean CT porosity over the specimen's cells, so that cases differ only in heterogeneity."""
    probe = initial_state(dataclasses.replace(spec, n_points=min(spec.n_points, 512)), grid,
                          None, material, parameters)
    return float((probe.porosity * probe.mesh.volumes).sum() / probe.mesh.volumes.sum())
