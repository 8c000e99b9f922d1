"""Entry point of the micro stage: hydrate one pellet case through its suction checkpoints.

A case is a specimen (CT-informed or homogeneous porosity), a crack model switch and a
confinement. After each checkpoint the whole state goes to a checkpoint file beside the
output, so that a killed run resumes at its last checkpoint; the file is removed when
the case finishes. The result is ``results/micro/<case>.nc`` (docs/design.md §2) and a figure;
with ``micro.vtk_snapshots``, also ParaView snapshots in ``results/micro/<case>_vtk/``
(:mod:`micro.vtk`).
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
from micro.hydration import (
    BalanceProgress,
    DivergenceError,
    FlowSystem,
    HydrationSettings,
    advance_to_balance,
)
from micro.pellet import (
    POROSITY_BINS,
    CheckpointMeasurement,
    SpecimenSpec,
    initial_state,
    measure_checkpoint,
    settle,
)
from micro.permeability import principal_permeability
from shared.config import ConfigError
from shared.dem.parameters import DEMParameters, dem_parameters
from shared.io import read_dataset, write_dataset
from shared.materials import ClayParameters, clay_parameters
from shared.mesh import mesh_from_tetrahedra
from shared.progress import ConvergenceProgress, PhaseClock, Progress
from shared.provenance import config_sha256, module_sha256

__all__ = [
    "phase_wall_times",
    "run",
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

_SCALARS = {
    "saturation": ("1", "pore-volume weighted water saturation"),
    "eps_v": ("1", "volumetric strain of the specimen from its state at 132 MPa"),
    "porosity_mean": ("1", "volume-weighted mean porosity"),
    "crack_count": ("1", "number of open bonds on mesh edges (cracks)"),
    "crack_count_imbibed": ("1", "number of water-filled cracks"),
    "crack_count_gas": ("1", "number of gas-filled cracks"),
    "crack_area": ("m2", "total crack area"),
    "crack_area_imbibed": ("m2", "area of water-filled cracks"),
    "crack_area_gas": ("m2", "area of gas-filled cracks"),
    "crack_volume": ("m3", "total crack volume"),
    "time": ("s", "simulated hydration time"),
    "n_remesh": ("1", "number of Delaunay remeshes so far"),
    "flow_steps": ("1", "flow steps taken to reach the checkpoint"),
    "dem_steps": ("1", "DEM relaxation steps taken to reach the checkpoint"),
    "unbalanced_force": ("1", "unbalanced-force ratio at the end of the checkpoint"),
    "suction_misfit": ("1", "largest relative departure of a cell's suction from the boundary's"),
    "balanced": ("1", "1 if hydraulic and mechanical balance were reached, else 0"),
}
_COUNTS = ("crack_count", "crack_count_imbibed", "crack_count_gas", "n_remesh", "flow_steps",
           "dem_steps", "balanced")
"""The scalars that count something, stored as integers."""


def case_settings(config: Mapping[str, Any], case: str) -> tuple[SpecimenSpec, HydrationSettings, bool]:
    """Specimen, numerical settings and porosity source (True: CT grid) of a case.

    Raises
    ------
    ConfigError
        If the case is unknown.
    """
    micro = config["micro"]
    if case not in micro["cases"]:
        raise ConfigError(f"config key 'micro.cases.{case}': no such case")
    entry = micro["cases"][case]
    spec = SpecimenSpec(
        edge_length=entry.get("specimen_size_m", micro["specimen_size_m"]),
        n_points=entry.get("n_points", micro["n_points"]), layout=micro["layout"],
        jitter=micro["jitter"], confinement=entry["confinement_pa"], seed=micro["seed"],
        offset=tuple(entry["offset_m"]),
    )
    settings = hydration_settings(micro["numerics"], entry["crack_coupling"])
    return spec, settings, entry["porosity"] == "ct"


def hydration_settings(numerics: Mapping[str, Any], cracks: bool) -> HydrationSettings:
    """The staggered scheme's settings from a validated ``micro.numerics`` section."""
    return HydrationSettings(
        initial_time_step=numerics["initial_time_step_s"],
        time_step_growth=numerics["time_step_growth"],
        max_flow_steps=numerics["max_flow_steps"],
        hydraulic_tolerance=numerics["hydraulic_tolerance"],
        unbalanced_force_tolerance=numerics["unbalanced_force_tolerance"],
        max_relaxation_steps=numerics["max_relaxation_steps"],
        final_relaxations=numerics["final_relaxations"],
        check_interval=numerics["check_interval"],
        ramp_steps=numerics["ramp_steps"],
        damping=numerics["relaxation_damping"],
        max_step_fraction=numerics["max_step_fraction"],
        porosity_bounds=tuple(numerics["porosity_bounds"]),
        cracks=cracks,
        solver=numerics["solver"],
        amg_unknowns=numerics["amg_unknowns"],
    )


def case_material(config: Mapping[str, Any], case: str) -> dict[str, Any]:
    """``materials.pellet`` with this case's own values (``micro.cases.<case>.materials``)."""
    return {**config["materials"]["pellet"], **config["micro"]["cases"][case]["materials"]}


def case_parameters(config: Mapping[str, Any], case: str) -> tuple[ClayParameters, DEMParameters]:
    """Clay and DEM parameters of a case, from its material and ``micro.numerics``."""
    material = case_material(config, case)
    return clay_parameters(material), dem_parameters(material, config["micro"]["numerics"])


def _dataset(records: list[dict[str, Any]], checkpoints: np.ndarray) -> xr.Dataset:
    suction = checkpoints[: len(records)]
    data: dict[str, Any] = {}
    for name, (units, long_name) in _SCALARS.items():
        dtype = np.int64 if name in _COUNTS else float
        data[name] = ("suction", np.array([r[name] for r in records], dtype=dtype),
                      {"units": units, "long_name": long_name})
    data["permeability"] = (
        ("suction", "phase", "axis"), np.stack([r["permeability"] for r in records]),
        {"units": "m2", "long_name": "intrinsic x relative permeability, measured by a steady "
                                     "solve with a linear boundary pressure"},
    )
    data.update(_tensor_variables(records))
    for suffix, label in (("", "all"), ("_imbibed", "water-filled"), ("_gas", "gas-filled")):
        data[f"crack_fabric{suffix}"] = (
            ("suction", "i", "j"), np.stack([r[f"crack_fabric{suffix}"] for r in records]),
            {"units": "m2", "long_name": f"crack fabric tensor (1/N) sum a_c n n of {label} cracks"},
        )
    data["porosity_hist"] = (
        ("suction", "bin"), np.stack([r["porosity_hist"] for r in records]),
        {"units": "1", "long_name": "volume fraction of cells per porosity bin"},
    )
    centres = 0.5 * (POROSITY_BINS[1:] + POROSITY_BINS[:-1])
    coords = {
        # suction indexes the checkpoints (ds.sel(suction=1e6)); the checkpoint's number
        # is a coordinate along it (the ParaView series' time step, micro/vtk.py)
        "suction": ("suction", suction, {"units": "Pa", "long_name": "boundary suction"}),
        "checkpoint": ("suction", np.arange(len(records)), {"units": "1", "long_name": "checkpoint index"}),
        "phase": ("phase", np.array(["water", "gas"]), {"long_name": "fluid phase"}),
        "axis": ("axis", np.array(["x", "y", "z"]), {"long_name": "direction (z: compaction axis)"}),
        "i": ("i", np.arange(3), {"units": "1", "long_name": "tensor row (x, y, z)"}),
        "j": ("j", np.arange(3), {"units": "1", "long_name": "tensor column (x, y, z)"}),
        "bin": ("bin", centres, {"units": "1", "long_name": "porosity bin centre"}),
        "principal": ("principal", np.arange(3),
                      {"units": "1", "long_name": "principal axis, by ascending principal value"}),
    }
    return xr.Dataset(data, coords=coords)


def _tensor_variables(records: list[dict[str, Any]]) -> dict[str, Any]:
    """The permeability tensors of the records and their principal values and directions.

    A record without a tensor (from a checkpoint file of an older version) gives NaN.
    """
    missing = np.full((2, 3, 3), np.nan)
    if any("permeability_tensor" not in r for r in records):
        log.warning("records without a permeability tensor (resumed from an older checkpoint "
                    "file): stored as NaN")
    tensor = np.stack([np.asarray(r.get("permeability_tensor", missing), dtype=float)
                       for r in records])
    derived = principal_permeability(tensor)
    how = ("linear pressure on all six walls along x, y and z in turn (one factorisation per "
           "phase), Darcy velocity averaged over the inner 80 % of the box")
    return {
        "permeability_tensor": (
            ("suction", "phase", "i", "j"), tensor,
            {"units": "m2", "long_name": "permeability tensor K_ij = -mu <v_i> / (grad p)_j, "
                                         f"{how}"},
        ),
        "permeability_tensor_symmetric": (
            ("suction", "phase", "i", "j"), derived.symmetric,
            {"units": "m2", "long_name": "symmetric part (K + K^T)/2 of the permeability tensor"},
        ),
        "permeability_principal": (
            ("suction", "phase", "principal"), derived.values,
            {"units": "m2", "long_name": "principal permeabilities: eigenvalues of the symmetric "
                                         "part, ascending"},
        ),
        "permeability_principal_direction": (
            ("suction", "phase", "i", "principal"), derived.directions,
            {"units": "1", "long_name": "principal directions: unit eigenvectors (components "
                                        "i = x, y, z) of the symmetric part, largest component "
                                        "positive"},
        ),
        "permeability_asymmetry": (
            ("suction", "phase"), derived.asymmetry,
            {"units": "1", "long_name": "relative asymmetry ||K - K^T||_F / ||K||_F of the "
                                        "permeability tensor"},
        ),
    }


def phase_wall_times(attrs: Mapping[str, Any]) -> dict[str, float]:
    """The wall time per phase [s] that :func:`run` writes as ``wall_time_<phase>_s``
    attributes, by phase name (empty for an output written before phases were timed)."""
    return {key[len("wall_time_"):-len("_s")]: float(value) for key, value in attrs.items()
            if key.startswith("wall_time_") and key.endswith("_s") and key != "wall_time_s"}


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
        The written results. Besides ``wall_time_s`` and ``peak_memory_mb``, the
        attributes ``wall_time_<phase>_s`` split the wall time [s] into settling,
        flow, swelling, relaxation, geometry, remesh, cracks, measurement and output
        (what remains is set-up and the figure).

    Raises
    ------
    DivergenceError
        If the coupled solution diverges; the last good checkpoint stays on disk.
    """
    started = time.monotonic()
    spec, settings, heterogeneous = case_settings(config, case)
    # the studies aggregate finished cases: they are not part of a case's configuration
    section = {"micro": {k: v for k, v in config["micro"].items() if k != "studies"}, "case": case,
               "material": case_material(config, case)}
    checkpoints = np.asarray(config["micro"]["checkpoints_suction_pa"], dtype=float)
    output = Path(output)
    state_file = output.with_suffix(".checkpoint.npz")
    # the code too (this module and what it imports): a checkpoint of other code is not resumed
    digest = config_sha256({**section, "code": module_sha256(__file__)})
    grid = read_dataset(porosity_input, ["porosity"])["porosity"]
    material, parameters = case_parameters(config, case)
    resumed = load_checkpoint(state_file, digest, material)
    # optional ParaView snapshots, a side product beside the netCDF (not a rule output)
    vtk_dir = None
    if config["micro"].get("vtk_snapshots", False):
        vtk_dir = output.with_name(f"{output.stem}_vtk")
    if resumed is None:
        if vtk_dir is not None:
            vtk.clear_snapshots(vtk_dir, output.stem)
        source = grid if heterogeneous else None
        mean = None if heterogeneous else _specimen_mean(spec, grid, material, parameters)
        clock = PhaseClock()
        with clock.phase("settling"):
            state = initial_state(spec, source, mean, material, parameters)
            system, settled = settle(state, FlowSystem.for_mesh(state.mesh, settings=settings),
                                     spec, source, mean, settings, material, parameters)
        log.info("%s: settled at the initial suction in %d DEM steps (unbalanced force %.3g)",
                 case, settled["dem_steps"], settled["unbalanced_force"])
        records: list[dict[str, Any]] = []
        reference_volume = float(state.mesh.volumes.sum())
        earlier = 0.0
        balance = None
    else:
        state, system, records, reference_volume, balance = resumed
        # the wall time of the runs before, up to their last checkpoint file
        earlier, phase_seconds = checkpoint_wall_time(state_file)
        clock = PhaseClock(phase_seconds)
        log.info("%s: resuming after checkpoint %d of %d%s", case, len(records), checkpoints.size,
                 "" if balance is None else f", {balance.flow_steps} flow steps into the next")
    progress = Progress(checkpoints.size, f"micro {case}", log, interval=0.0, trend=True,
                        done_before=len(records))
    interval = float(config["micro"]["snapshot_interval_s"])
    last_save = time.monotonic()
    balancing: ConvergenceProgress | None = None

    pending: CheckpointMeasurement | None = None

    def record_pending() -> None:
        """Wait for the last checkpoint's measurement and add its record."""
        nonlocal pending
        if pending is None:
            return
        with clock.phase("measurement"):
            record = pending.result()
        pending = None
        log.info("%s: s = %.3g Pa, S = %.3f, eps_v = %.4f, cracks %d, k_w,x = %.3g m2, "
                 "k_g,x = %.3g m2, balanced %d", case, checkpoints[len(records)],
                 record["saturation"], record["eps_v"], record["crack_count"],
                 record["permeability"][0, 0], record["permeability"][1, 0],
                 record["balanced"])
        records.append(record)

    def save(system: FlowSystem, balance: BalanceProgress | None) -> None:
        """Save the state with every record so far (waits for a pending measurement)."""
        nonlocal last_save
        record_pending()
        with clock.phase("output"):
            save_checkpoint(state_file, digest, state, system, records, reference_volume,
                            wall_time=earlier + time.monotonic() - started, balance=balance,
                            phase_seconds=clock.seconds)
        last_save = time.monotonic()

    def due(intervals: float) -> bool:
        """Whether ``intervals`` times ``interval`` have passed since the last save."""
        return time.monotonic() - last_save >= intervals * interval

    def snapshot(system: FlowSystem, balance: BalanceProgress) -> None:
        """Log the balance's progress (once a minute); save the state between two flow
        steps when ``interval`` has passed. A save waits for the worker: while it
        measures, the save is put off until it is done, for one more interval at most."""
        if balancing is not None:
            balancing.update(balance.flow_steps, balance.misfit)
        if due(1.0) and (pending is None or pending.done() or due(2.0)):
            save(system, balance)

    # one BLAS thread: numba's kernels own the job's threads, and an idle OpenBLAS thread
    # spins after every call (pyamg's norms), taking the core the worker solves on
    with measurement_executor(state.mesh.n_cells) as executor, threadpool_limits(
            1, user_api="blas"):
        for index in range(len(records), checkpoints.size):
            suction = float(checkpoints[index])
            # flow steps and the largest relative suction misfit, down to the tolerance
            balancing = ConvergenceProgress(
                settings.hydraulic_tolerance,
                f"{case}: balance at {suction:.3g} Pa (checkpoint {index + 1}/{checkpoints.size}), "
                "suction misfit", log)
            try:
                system, diagnostics = advance_to_balance(state, system, suction, settings,
                                                         material, parameters, start=balance,
                                                         snapshot=snapshot, clock=clock)
                balance = None
            except DivergenceError as err:
                raise DivergenceError(
                    f"case {case}, checkpoint {index} ({suction:.4g} Pa): {err}; "
                    f"the last good checkpoint is kept in {state_file}"
                ) from err
            # each checkpoint is measured on a mesh rebuilt from the moved points (not the
            # per-step update_mesh, which rounds differently); the checkpoint file keeps it.
            # The worker solves the permeabilities while the next checkpoint hydrates,
            # unless the worker still measures the one before (it lags) or a save is
            # overdue: both processes then share this one's solves, and a checkpoint
            # measured so is saved.
            background = index + 1 < checkpoints.size and not due(2.0) and (
                pending is None or pending.done())
            with clock.phase("measurement"):
                state.mesh = mesh_from_tetrahedra(state.dem.positions, state.mesh.tetrahedra,
                                                  state.mesh.neighbours, reorient=False)
                measurement = measure_checkpoint(state, suction, reference_volume, material,
                                                 settings.cracks, executor=executor,
                                                 background=background)
            measurement.record.update(diagnostics)
            record_pending()
            pending = measurement
            if not measurement.in_background:
                save(system, None)
            if vtk_dir is not None:
                with clock.phase("output"):
                    vtk.write_checkpoint_snapshot(vtk_dir, output.stem, index, state,
                                                  checkpoints)
            progress.update(index + 1)
        record_pending()
    ds = _dataset(records, checkpoints)
    ds.attrs.update(n_points=state.dem.n_points, n_cells=state.mesh.n_cells,
                    confinement=spec.confinement, crack_model=int(settings.cracks),
                    porosity_source="ct" if heterogeneous else "homogeneous",
                    wall_time_s=earlier + time.monotonic() - started,
                    peak_memory_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
                    **{f"wall_time_{name}_s": seconds for name, seconds in clock.seconds.items()})
    write_dataset(ds, output, stage="micro", title=f"micro pellet hydration, case {case}",
                  config=section, seed=spec.seed, inputs=[porosity_input], rule=rule,
                  references="Caulk (2022), PhD thesis, Univ. Grenoble Alpes, Chap. 3")
    figures.case_figure(ds, case, figure_output)
    state_file.unlink(missing_ok=True)
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
