"""Entry point of the micro stage: hydrate one pellet case through its suction checkpoints.

A case is a specimen (CT-informed or homogeneous porosity), a crack model switch and a
confinement. Three layers:

* :func:`hydrate`, the library function: a porosity grid and validated settings
  (:class:`micro.config.MicroSettings`, from :func:`micro_settings`) in, the case's
  Dataset out, with no file (callable from a notebook);
* :func:`checkpoints_reached`, the run loop as a generator: it hydrates a
  :class:`Hydration` to each checkpoint in turn and yields a :class:`Checkpoint`, so that
  the caller decides what to write;
* :func:`run`, the stage's entry point: it reads the grid, resumes from the restart file
  beside the output (:class:`Checkpointer`: a killed run resumes at its last save), saves
  after each checkpoint and between flow steps, and writes ``results/micro/<case>.nc``
  (docs/design.md §2) and a figure; with ``micro.vtk_snapshots``, also ParaView
  snapshots in ``results/micro/<case>_vtk/`` (:mod:`micro.vtk`). The restart file is
  removed when the case finishes.
"""

from __future__ import annotations

import dataclasses
import logging
import multiprocessing
import os
import resource
import signal
import threading
import time
from collections.abc import Iterator, Mapping
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import AbstractContextManager, contextmanager, nullcontext
from dataclasses import dataclass, field
from functools import partial
from logging.handlers import QueueHandler, QueueListener
from multiprocessing.queues import Queue
from pathlib import Path
from typing import Any

import numba
import numpy as np
import xarray as xr
from threadpoolctl import threadpool_limits

from micro import figures, vtk
from micro.checkpoint import checkpoint_wall_time, load_checkpoint, save_checkpoint
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
from micro.results import records_dataset
from micro.settings import (
    case_material,
    case_parameters,
    case_settings,
    hydration_settings,
    micro_settings,
)
from shared.dem.parameters import DEMParameters
from shared.io import read_dataset, write_dataset
from shared.materials import ClayParameters
from shared.mesh import mesh_from_tetrahedra
from shared.progress import ConvergenceProgress, PhaseClock, Progress
from shared.provenance import config_sha256, module_sha256

__all__ = [
    "Checkpoint",
    "Checkpointer",
    "Hydration",
    "checkpoints_reached",
    "hydrate",
    "micro_settings",
    "settled",
    "phase_wall_times",
    "run",
    # the settings' builders (micro.settings): tests and benchmarks read them here
    "case_settings",
    "hydration_settings",
    "case_material",
    "case_parameters",
]

MEASUREMENT_PROCESS_CELLS = 100_000
"""Cells from which a worker process makes the permeability solves (:func:`measurement_executor`)."""
WORKER_NICENESS = 10
"""Niceness the measurement worker adds to its own (the hydration goes first)."""
WORKER_PARENT_POLL_S = 1.0
"""Interval [s] at which the measurement worker checks that the run's process lives."""

log = logging.getLogger("micro")


def phase_wall_times(attrs: Mapping[str, Any]) -> dict[str, float]:
    """The wall time per phase [s] that :func:`run` writes as ``wall_time_<phase>_s``
    attributes, by phase name (empty for an output written before phases were timed)."""
    return {key[len("wall_time_"):-len("_s")]: float(value) for key, value in attrs.items()
            if key.startswith("wall_time_") and key.endswith("_s") and key != "wall_time_s"}


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


@dataclass
class Checkpointer:
    """A case's restart file: resume from it, and save to it between flow steps every
    ``interval`` [s] (:meth:`flow_step`) and whenever the caller asks (:meth:`save`).

    Attributes
    ----------
    path
        The restart file, ``<output>.checkpoint.npz``.
    digest
        Hash of the case's configuration and code: a file of another digest is not resumed.
    interval
        Wall time between two saves between flow steps [s] (``micro.snapshot_interval_s``).
    started
        ``time.monotonic()`` at the run's start.
    earlier
        Wall time of the killed runs before, up to their last save [s].
    clock
        The wall time per phase, the earlier runs' included.
    last_save
        ``time.monotonic()`` at the last save (or since the cadence started).
    """

    path: Path
    digest: str
    interval: float
    started: float
    earlier: float = 0.0
    clock: PhaseClock = field(default_factory=PhaseClock)
    last_save: float = field(default_factory=time.monotonic)

    def resume(self, settings: MicroSettings) -> Hydration | None:
        """The hydration saved in the file, or None (no file, or one of other settings
        or code); resuming carries the earlier runs' wall time over."""
        resumed = load_checkpoint(self.path, self.digest, settings.material)
        if resumed is None:
            return None
        self.earlier, phase_seconds = checkpoint_wall_time(self.path)
        self.clock = PhaseClock(phase_seconds)
        return Hydration(settings, *resumed)

    def wall_time(self) -> float:
        """The case's wall time so far [s], the earlier runs' included."""
        return self.earlier + time.monotonic() - self.started

    def due(self, intervals: float) -> bool:
        """Whether ``intervals`` times ``interval`` have passed since the last save."""
        return time.monotonic() - self.last_save >= intervals * self.interval

    def save(self, hydration: Hydration, system: FlowSystem, balance: BalanceProgress | None) -> None:
        """Save the state with every record so far (waits for a pending measurement)."""
        hydration.record_pending(self.clock)
        with self.clock.phase("output"):
            save_checkpoint(self.path, self.digest, hydration.state, system, hydration.records,
                            hydration.reference_volume, wall_time=self.wall_time(),
                            balance=balance, phase_seconds=self.clock.seconds)
        self.last_save = time.monotonic()

    def flow_step(self, hydration: Hydration, system: FlowSystem, balance: BalanceProgress) -> None:
        """Save the state between two flow steps when ``interval`` has passed. A save
        waits for the worker: while it measures, the save is put off until it is done,
        for one more interval at most."""
        pending = hydration.pending
        if self.due(1.0) and (pending is None or pending.done() or self.due(2.0)):
            self.save(hydration, system, balance)


def checkpoints_reached(
    hydration: Hydration, clock: PhaseClock, executor: Executor | None = None,
    checkpointer: Checkpointer | None = None,
) -> Iterator[Checkpoint]:
    """Hydrate to each checkpoint not yet recorded, in turn, yielding each one reached.

    Each checkpoint is measured on a mesh rebuilt from the moved points (not the
    per-step update_mesh, which rounds differently; a restart file keeps it). With
    ``executor`` (:func:`measurement_executor`), the worker solves the permeabilities
    while the next checkpoint hydrates, unless it still measures the one before (it
    lags) or a save is overdue: both processes then share this one's solves. The last
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
        Saves between flow steps at its cadence (:meth:`Checkpointer.flow_step`); None
        saves nothing.

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
        yield Checkpoint(index, measurement.in_background)
    hydration.record_pending(clock)


def _flow_step(hydration: Hydration, balancing: ConvergenceProgress,
               checkpointer: Checkpointer | None, system: FlowSystem,
               balance: BalanceProgress) -> None:
    """After each flow step: log the balance's progress (once a minute) and let the
    checkpointer save the state."""
    balancing.update(balance.flow_steps, balance.misfit)
    if checkpointer is not None:
        checkpointer.flow_step(hydration, system, balance)


@contextmanager
def measuring(n_cells: int) -> Iterator[Executor | None]:
    """The measurement worker of a mesh of ``n_cells`` cells (:func:`measurement_executor`),
    with one BLAS thread in this process: numba's kernels own the job's threads, and an
    idle OpenBLAS thread spins after every call (pyamg's norms), taking the core the
    worker solves on."""
    with measurement_executor(n_cells) as executor, threadpool_limits(1, user_api="blas"):
        yield executor


def hydrate(porosity_grid: xr.Dataset, settings: MicroSettings) -> xr.Dataset:
    """Hydrate one case through its suction checkpoints; no file is read or written.

    Parameters
    ----------
    porosity_grid
        The imaging stage's grid (``results/porosity/<sample>.nc``): its ``porosity``
        variable [1] on (z, y, x) node coordinates [m].
    settings
        The case's settings (:func:`micro_settings`).

    Returns
    -------
    xarray.Dataset
        One record per checkpoint along ``suction`` [Pa] (:mod:`micro.results`): what
        :func:`run` writes, less the provenance and wall-time attributes.

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


def run(
    config: Mapping[str, Any],
    case: str,
    porosity_input: str | Path,
    output: str | Path,
    figure_output: str | Path,
    rule: str | None = None,
) -> xr.Dataset:
    """Hydrate one case through the configured suction checkpoints and write its results.

    Parameters
    ----------
    config
        Validated configuration: its ``micro`` section (with at least this case) and
        ``materials.pellet``.
    case
        Case name (a key of ``micro.cases``).
    porosity_input
        ``results/porosity/<sample>.nc`` of the CT sample.
    output, figure_output
        ``results/micro/<case>.nc`` and its PNG.
    rule
        Snakemake rule name, for provenance.

    Returns
    -------
    xarray.Dataset
        The written results (:func:`hydrate`'s). Besides ``wall_time_s`` and
        ``peak_memory_mb``, the attributes ``wall_time_<phase>_s`` split the wall time
        [s] into settling, flow, swelling, relaxation, geometry, remesh, cracks,
        measurement and output (what remains is set-up and the figure).

    Raises
    ------
    DivergenceError
        If the coupled solution diverges; the last good checkpoint stays on disk.
    """
    started = time.monotonic()
    settings = micro_settings(config, case)
    # the studies aggregate finished cases: they are not part of a case's configuration
    section = {"micro": {k: v for k, v in config["micro"].items() if k != "studies"}, "case": case,
               "material": case_material(config, case)}
    output = Path(output)
    # the code too (this module and what it imports): a checkpoint of other code is not resumed
    checkpointer = Checkpointer(output.with_suffix(".checkpoint.npz"),
                                config_sha256({**section, "code": module_sha256(__file__)}),
                                float(config["micro"]["snapshot_interval_s"]), started)
    grid = read_dataset(porosity_input, ["porosity"])
    hydration = checkpointer.resume(settings)
    # optional ParaView snapshots, a side product beside the netCDF (not a rule output)
    vtk_dir = output.with_name(f"{output.stem}_vtk") if config["micro"].get("vtk_snapshots") else None
    if hydration is None:
        if vtk_dir is not None:
            vtk.clear_snapshots(vtk_dir, output.stem)
        hydration = settled(grid["porosity"], settings, checkpointer.clock)
    else:
        log.info("%s: resuming after checkpoint %d of %d%s", case, len(hydration.records),
                 len(settings.checkpoints), "" if hydration.balance is None
                 else f", {hydration.balance.flow_steps} flow steps into the next")
    progress = Progress(len(settings.checkpoints), f"micro {case}", log, interval=0.0,
                        trend=True, done_before=len(hydration.records))
    checkpointer.last_save = time.monotonic()  # the cadence counts from here, settled
    clock = checkpointer.clock
    with measuring(hydration.state.mesh.n_cells) as executor:
        for reached in checkpoints_reached(hydration, clock, executor, checkpointer):
            # a checkpoint measured here (not by the worker) is saved at once
            if not reached.in_background:
                checkpointer.save(hydration, hydration.system, None)
            if vtk_dir is not None:
                with clock.phase("output"):
                    vtk.write_checkpoint_snapshot(vtk_dir, output.stem, reached.index,
                                                  hydration.state, settings.checkpoints)
            progress.update(reached.index + 1)
    ds = hydration.dataset()
    ds.attrs.update(wall_time_s=checkpointer.wall_time(),
                    peak_memory_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
                    **{f"wall_time_{name}_s": seconds for name, seconds in clock.seconds.items()})
    write_dataset(ds, output, stage="micro", title=f"micro pellet hydration, case {case}",
                  config=section, seed=settings.specimen.seed, inputs=[porosity_input], rule=rule,
                  references="Caulk (2022), PhD thesis, Univ. Grenoble Alpes, Chap. 3")
    figures.case_figure(ds, case, figure_output)
    checkpointer.path.unlink(missing_ok=True)
    return ds


def measurement_executor(n_cells: int) -> AbstractContextManager[Executor | None]:
    """A worker process for the checkpoints' permeability solves, or None.

    It makes the eight solves of a checkpoint while this process hydrates towards the
    next (a save of the state waits for them), and half of those of the last checkpoint,
    of a checkpoint reached while it still measures the one before or with a save
    overdue. One process beside this one when the job has two threads or more (numba's,
    as the Snakemake job sets them) and the mesh has ``MEASUREMENT_PROCESS_CELLS`` cells
    or more (below, the mesh's transfer and the process's start cost more than they
    save).
    A process, not a thread: pyamg's cycles and CHOLMOD hold the GIL. The worker is
    spawned (forking a process whose OpenMP threads run is unsafe) and runs numba and
    BLAS on one thread at a lower priority; its log records go to this process's
    handlers (the case's log). A script that runs the micro stage must guard its main
    code with ``if __name__ == "__main__":``, since the spawned worker imports it.
    """
    if numba.get_num_threads() < 2 or n_cells < MEASUREMENT_PROCESS_CELLS:
        return nullcontext(None)
    log.info("measurements: the permeability solves in a worker process, in the "
             "background while the run hydrates")
    return _worker_pool()


@contextmanager
def _worker_pool() -> Iterator[Executor]:
    """The spawned measurement worker, its log records relayed to this process's."""
    context = multiprocessing.get_context("spawn")
    records = context.Queue()
    root = logging.getLogger()
    relay = QueueListener(records, *root.handlers, respect_handler_level=True)
    relay.start()
    try:
        with ProcessPoolExecutor(1, mp_context=context, initializer=_measurement_worker,
                                 initargs=(records, root.level)) as executor:
            yield executor
    finally:
        relay.stop()


def _measurement_worker(records: Queue, level: int) -> None:
    """The worker runs numba and BLAS on one thread and yields the cores to the
    hydration, the run's critical path, whenever its threads want both (niceness
    ``WORKER_NICENESS``). Its log records go to ``records`` at the run's ``level``. It
    exits when the run's process dies: a killed run leaves no orphan that keeps solving
    and holding a copy of the mesh (gigabytes at 300k points). It ignores Ctrl-C: the
    run's process stops when the task under way returns, and reports the interrupt in one
    line (a worker ended by it would end the run with a broken pool's traceback)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    root = logging.getLogger()
    root.handlers[:] = [QueueHandler(records)]
    root.setLevel(level)
    numba.set_num_threads(1)
    threadpool_limits(1, user_api="blas")
    os.nice(WORKER_NICENESS)
    threading.Thread(target=_exit_with_parent, args=(os.getppid(),), daemon=True).start()


def _exit_with_parent(parent: int) -> None:
    """Exit this process once ``parent`` is no longer its parent (it died)."""
    while os.getppid() == parent:
        time.sleep(WORKER_PARENT_POLL_S)
    os._exit(1)


def _specimen_mean(spec: SpecimenSpec, grid: xr.DataArray, material: ClayParameters,
                   parameters: DEMParameters) -> float:
    """Mean CT porosity over the specimen's cells, so that cases differ only in heterogeneity."""
    probe = initial_state(dataclasses.replace(spec, n_points=min(spec.n_points, 512)), grid,
                          None, material, parameters)
    return float((probe.porosity * probe.mesh.volumes).sum() / probe.mesh.volumes.sum())
