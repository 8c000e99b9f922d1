"""Where a whole micro run spends its time, and how it scales with the number of points.

- ``micro_profile --size N``: the heterogeneous case at N DEM points under cProfile,
  cumulative wall time of the phases (DEM relaxation, flow steps and their solves,
  remeshes, permeability measurements, settling, output) and the solvers' counters;
- ``micro_scaling``: wall time, peak memory and wall time per phase of the convergence
  preset's cases, with a power law fitted per phase and a log-log figure;
- ``measurement_workers --size N``: one checkpoint's eight permeability solves alone,
  with a second thread and in the worker process, bit for bit alike;
- ``micro_ramp --size N``: load ramps of 50 to 400 DEM steps against the spread of
  equally valid runs.

Run as ``python -m benchmarks run CASE``. Timings are measured, never asserted. The
cases in full: docs/performance.md, "benchmarks.micro_profile".
"""

from __future__ import annotations

import copy
import cProfile
import json
import pstats
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from benchmarks.flow import _exponent, _save_cost_figure
from benchmarks.parameters import CONFIG
from micro.run import phase_wall_times

__all__ = ["bench_measurement_workers", "bench_micro_profile", "bench_micro_ramp",
           "bench_micro_relaxation", "bench_micro_scaling"]

# The convergence study's cases from which the N^1.1 target is fitted.
SCALING_FROM_POINTS = 15_000
# The phases of a run's curve; the rest of its wall time is "other".
MAIN_PHASES = ("relaxation", "flow", "measurement", "remesh")
RECORDED_CASES = "benchmarks/reference/micro_cases.json"

PHASES = {
    "checkpoint_balance": ("micro/hydration.py", "advance_to_balance"),
    "dem_relaxation": ("micro/hydration.py", "relax"),
    "flow_step": ("micro/hydration.py", "_flow_step"),
    "linear_solve": ("shared/solver/spd.py", "solve"),
    "factorisation": ("shared/solver/spd.py", "_buy"),
    "remesh": ("micro/hydration.py", "triangulate"),
    "geometry_update": ("micro/hydration.py", "update_geometry"),
    "cracks": ("micro/hydration.py", "update_cracks"),
    "permeability_measurement": ("micro/pellet.py", "measure_checkpoint"),
    "initial_settling": ("micro/pellet.py", "settle"),
    "netcdf_output": ("shared/io.py", "write_dataset"),
    "checkpoint_files": ("micro/checkpoint.py", "save_checkpoint"),
}


def _counting_solves(work: dict[str, dict[str, int]]):  # type: ignore[no-untyped-def]
    """:meth:`shared.solver.SPDSolver.solve` that adds each call's work to ``work``, keyed
    by ``flow`` (tolerance 1e-8) or ``measurement`` (1e-13)."""
    import dataclasses

    from shared.solver import SPDSolver

    solve = SPDSolver.solve

    def counted(self, lower, rhs, **options):  # type: ignore[no-untyped-def]
        before = dataclasses.replace(self.stats)
        try:
            return solve(self, lower, rhs, **options)
        finally:
            kind = "flow" if self.residual_tolerance > 1e-10 else "measurement"
            totals = work.setdefault(kind, {})
            for name, value in dataclasses.asdict(self.stats).items():
                totals[name] = totals.get(name, 0) + value - getattr(before, name)

    return counted


def bench_micro_profile(points: int = 8000, grid: str = "results/porosity/pellet.nc") -> dict:
    """Cumulative wall time per phase of one heterogeneous micro run at ``points`` points,
    and the solvers' work (solves, factorisations or hierarchy setups, CG iterations,
    fallbacks to the factor) of its flow steps and of its measurements."""
    import logging

    from micro.run import CaseOutputs, run
    from shared.solver import SPDSolver

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    config = copy.deepcopy(CONFIG)
    config["micro"]["n_points"] = points
    config["micro"]["vtk_snapshots"] = False
    case = "heterogeneous"
    profiler = cProfile.Profile()
    work: dict[str, dict[str, int]] = {}
    solve = SPDSolver.solve
    SPDSolver.solve = _counting_solves(work)  # type: ignore[method-assign]
    try:
        with tempfile.TemporaryDirectory() as folder:
            start = time.perf_counter()
            profiler.enable()
            ds = run(config, case, grid, CaseOutputs(Path(folder) / "case.nc", Path(folder) / "case.png"))
            profiler.disable()
            wall = time.perf_counter() - start
    finally:
        SPDSolver.solve = solve  # type: ignore[method-assign]
    stats = pstats.Stats(profiler).stats  # type: ignore[attr-defined]
    phases = {}
    for phase, (module, name) in PHASES.items():
        phases[phase] = sum(row[3] for (path, _, function), row in stats.items()
                            if function == name and path.endswith(module))
    return {
        "n_points": points,
        "remeshes": int(ds["n_remesh"].values[-1]),
        "wall_s": wall,
        "cumulative_s": phases,
        "fraction_of_wall": {k: v / wall for k, v in phases.items()},
        "solver_work": work,
    }


def bench_micro_relaxation(points: int = 1000, grid: str = "results/porosity/pellet.nc") -> dict:
    """DEM relaxations of one heterogeneous micro run at ``points`` points: how many, how
    many steps each (percentiles) and how many end at the load ramp's floor
    (``micro.numerics.ramp_steps``: balance is only checked once the ramp is done)."""
    import logging

    import numpy as np

    import micro.hydration as hydration
    from micro.run import CaseOutputs, run

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    config = copy.deepcopy(CONFIG)
    config["micro"]["n_points"] = points
    config["micro"]["vtk_snapshots"] = False
    ramp = config["micro"]["numerics"]["ramp_steps"]
    calls: list[tuple[int, float]] = []
    relax = hydration.relax

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        start = time.perf_counter()
        steps, unbalanced = relax(*args, **kwargs)
        calls.append((steps, time.perf_counter() - start))
        return steps, unbalanced

    hydration.relax = counted
    try:
        with tempfile.TemporaryDirectory() as folder:
            start = time.perf_counter()
            ds = run(config, "heterogeneous", grid, CaseOutputs(Path(folder) / "c.nc", Path(folder) / "c.png"))
            wall = time.perf_counter() - start
    finally:
        hydration.relax = relax
    steps = np.array([c[0] for c in calls])
    return {"n_points": points, "wall_s": wall, "relaxations": len(calls),
            "relaxation_s": float(sum(c[1] for c in calls)), "dem_steps": int(steps.sum()),
            "steps_percentiles_10_50_90_99": np.percentile(steps, [10, 50, 90, 99]).tolist(),
            "ended_at_ramp": int((steps <= ramp).sum()), "ramp_steps": ramp,
            "final_eps_v": float(ds["eps_v"].values[-1])}


# The ramp lengths of ``micro_ramp`` and the runs whose spread makes its envelope.
RAMPS = (50, 100, 200, 400)
ENVELOPE_RUNS = {"solver amg": {"solver": "amg"}, "check interval 11": {"check_interval": 11}}
ENVELOPE_RAMP = 200
PROTOCOLS = {"default": None, "four checkpoints": [132.0e6, 40.0e6, 10.0e6, 1.0e6]}


def _case_run(points: int, numerics: dict, grid: str,
              checkpoints: list[float] | None = None) -> dict:
    """One heterogeneous run with these ``micro.numerics`` changes: wall time, phases,
    DEM steps and the checkpoints' eps_v, saturation and water permeability (geometric
    mean of the axes)."""
    from micro.run import CaseOutputs, run

    config = copy.deepcopy(CONFIG)
    config["micro"]["n_points"] = points
    config["micro"]["vtk_snapshots"] = False
    config["micro"]["numerics"].update(numerics)
    if checkpoints is not None:
        config["micro"]["checkpoints_suction_pa"] = checkpoints
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        ds = run(config, "heterogeneous", grid, CaseOutputs(Path(folder) / "c.nc", Path(folder) / "c.png"))
        wall = time.perf_counter() - start
    water = ds["permeability"].sel(phase="water").values
    return {"numerics": numerics, "wall_s": wall, "phases_s": phase_wall_times(ds.attrs),
            "dem_steps": int(ds["dem_steps"].values.sum()),
            "eps_v": ds["eps_v"].values.tolist(), "saturation": ds["saturation"].values.tolist(),
            "permeability_water": np.exp(np.log(water).mean(axis=-1)).tolist()}


def bench_micro_ramp(points: int = 8000, grid: str = "results/porosity/pellet.nc") -> dict:
    """Checkpoints and cost of the heterogeneous case for several load ramps, and the
    envelope of equally valid runs (see the module docstring), for each protocol: per
    run the largest departure of eps_v and saturation, and of log10 k_w, from the
    200-step run."""
    import logging

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    result: dict = {"n_points": points, "protocols": {}}
    for protocol, checkpoints in PROTOCOLS.items():
        runs = {f"ramp {ramp}": _case_run(points, {"ramp_steps": ramp}, grid, checkpoints)
                for ramp in RAMPS}
        for label, change in ENVELOPE_RUNS.items():
            runs[label] = _case_run(points, {"ramp_steps": ENVELOPE_RAMP, **change}, grid,
                                    checkpoints)
        reference = runs[f"ramp {ENVELOPE_RAMP}"]
        for entry in runs.values():
            entry["departure"] = {
                name: float(np.max(np.abs(np.subtract(entry[name], reference[name]))))
                for name in ("eps_v", "saturation")}
            entry["departure"]["log10_permeability_water"] = float(np.max(np.abs(
                np.log10(entry["permeability_water"])
                - np.log10(reference["permeability_water"]))))
        envelope = {name: max(runs[label]["departure"][name] for label in ENVELOPE_RUNS)
                    for name in reference["departure"]}
        result["protocols"][protocol] = {"runs": runs, "envelope": envelope}
    return result


def _scaling_record(case: str, n_points: int, wall: float, peak_mb: float,
                    phases: dict[str, float], **extra: object) -> dict:
    """One case of the curve: the main phases and the rest of the wall time (``other``)."""
    main = {name: float(phases.get(name, 0.0)) for name in MAIN_PHASES}
    return {"case": case, "n_points": n_points, "wall_s": wall, "peak_memory_mb": peak_mb,
            "phases_s": {**main, "other": wall - sum(main.values())}, **extra}


def bench_micro_scaling(folder: str = "results/micro", recorded: str = RECORDED_CASES) -> dict:
    """Wall time per phase and peak memory of the convergence preset's cases versus N,
    with the exponent fitted per phase from 15k points up: the finished cases in
    ``folder``, and those of ``recorded`` (earlier sessions' runs) that it lacks."""
    records = []
    for path in Path(folder).glob("points_*.nc"):
        with xr.open_dataset(path) as ds:
            attrs = dict(ds.attrs)
        records.append(_scaling_record(
            path.stem, int(attrs["n_points"]), float(attrs["wall_time_s"]),
            float(attrs["peak_memory_mb"]), phase_wall_times(attrs),
            n_cells=int(attrs["n_cells"]), source=str(path)))
    measured = {r["n_points"] for r in records}
    for entry in json.loads(Path(recorded).read_text())["cases"]:
        if entry["n_points"] not in measured:
            records.append(_scaling_record(
                entry["case"], entry["n_points"], entry["wall_s"], entry["peak_memory_mb"],
                entry["phases_s"], source=f"{recorded} ({entry['commit']}, {entry['date']})"))
    records.sort(key=lambda r: r["n_points"])
    fitted = [r for r in records if r["n_points"] >= SCALING_FROM_POINTS]
    exponents: dict[str, float] = {}
    if len(fitted) >= 2:
        exponents["wall"] = _exponent([r["n_points"] for r in fitted],
                                      [r["wall_s"] for r in fitted])
        for name in (*MAIN_PHASES, "other"):
            rows = [r for r in fitted if r["phases_s"][name] > 0.0]
            if len(rows) >= 2:
                exponents[name] = _exponent([r["n_points"] for r in rows],
                                            [r["phases_s"][name] for r in rows])
    if records:
        _plot_micro_scaling(records, exponents, Path("results/benchmarks/micro_scaling.png"))
    return {"records": records, "exponents_from_15k": exponents,
            "fitted_points": [r["n_points"] for r in fitted]}


def _plot_micro_scaling(records: list[dict], exponents: dict[str, float], path: Path) -> None:
    """Log-log figure of a whole run's wall time and its phases versus N, with N^1.1."""
    figure = Figure(figsize=(7.0, 5.0))
    axes = figure.add_subplot()
    points = np.array([r["n_points"] for r in records], dtype=float)
    walls = np.array([r["wall_s"] for r in records])

    def label(name: str) -> str:
        return f"{name} (N^{exponents[name]:.2f})" if name in exponents else name

    axes.loglog(points, walls, "ko-", label=label("wall"))
    for name in sorted({k for r in records for k in r["phases_s"]}):
        rows = [r for r in records if r["phases_s"].get(name, 0.0) > 0.0]
        axes.loglog([r["n_points"] for r in rows], [r["phases_s"][name] for r in rows], "s--",
                    label=label(name))
    anchor = points >= SCALING_FROM_POINTS
    if np.any(anchor):
        first = int(np.argmax(anchor))
        axes.loglog(points[first:], walls[first] * (points[first:] / points[first]) ** 1.1, "k:",
                    label="N^1.1 (target)")
    _save_cost_figure(figure, axes, "wall time [s]",
                      "Whole heterogeneous micro runs (default protocol), 2 cores", path)


def bench_measurement_workers(points: int = 150_000) -> dict:
    """One checkpoint's eight permeability solves (three axes and the tensor, water and
    gas) alone, with a second thread, and with a worker process: a jittered cube of
    ``points`` points, random saturation and porosity, 2 % of the facets 1e4 times more
    conductive (cracks). The three must agree bit for bit; the wall times are measured,
    never asserted. The worker process is started before the clock (a run starts it
    once)."""
    from concurrent.futures import ThreadPoolExecutor
    from contextlib import nullcontext

    import numba

    from benchmarks.parameters import CLAY
    from micro.permeability import FrozenState, checkpoint_permeabilities
    from micro.pool import measurement_executor
    from shared.dem import cube_points
    from shared.fv import facet_conductance
    from shared.mesh import build_mesh

    rng = np.random.default_rng(0)
    mesh = build_mesh(cube_points(points, rng, jitter=0.2)[0])
    saturation = rng.uniform(0.4, 0.95, mesh.n_cells)
    porosity = rng.uniform(0.25, 0.4, mesh.n_cells)
    cracks = np.where(rng.random(mesh.n_facets) < 0.02, 1e4, 1.0)
    phases = {phase: facet_conductance(mesh, saturation, porosity, phase, CLAY) * cracks
              for phase in ("water", "gas")}
    arguments = (mesh, saturation, porosity, 5e7, CLAY)
    record: dict = {"n_points": points, "n_cells": mesh.n_cells,
                    "numba_threads": numba.get_num_threads()}
    results = {}
    executors = {"alone": nullcontext(None), "thread": ThreadPoolExecutor(1),
                 "process": measurement_executor(mesh.n_cells)}
    for name, context in executors.items():
        with context as executor:
            if executor is not None:
                executor.submit(int).result()  # started before the clock
            start = time.perf_counter()
            axes, tensor = checkpoint_permeabilities(FrozenState(*arguments, phases), executor=executor)
            record[f"wall_{name}_s"] = time.perf_counter() - start
        results[name] = (axes, tensor)
    for name in ("thread", "process"):
        record[f"speed_up_{name}"] = record["wall_alone_s"] / record[f"wall_{name}_s"]
    record["identical"] = all(results[name][0] == results["alone"][0]
                              and np.array_equal(results[name][1], results["alone"][1])
                              for name in ("thread", "process"))
    return record
