"""Timing of the partially saturated flow machinery: remesh, reuse and coupled steps.

A jittered grid of about ``n_points`` points fills a 7 mm cube (the thesis's specimen).
Every phase is called once to compile or warm it, then timed ``repeats`` times; the
records give the median (``*_ms``) and the fastest call (``*_min_ms``) in milliseconds.
Timings are measured, never asserted. Cases: :func:`bench_flow` (every phase of a
remesh, a solve and a transient step), :func:`bench_flow_scaling` (its cost against N),
:func:`bench_solver_crossover` (factor against multigrid: where ``method="auto"``
should switch) and :func:`bench_coupled_step` (coupled steps as :mod:`micro.hydration`
runs them). The phases in full: docs/performance.md, "benchmarks.flow".

Run ``python -m benchmarks.flow [--quick]`` to write ``results/benchmarks/flow.json``,
``flow_scaling.json``, ``flow_scaling.png``, ``flow_coupled.json`` and
``solver_crossover.json``/``.png``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from benchmarks.dem import _timings_ms
from benchmarks.parameters import CLAY, DEM, SETTINGS
from micro.hydration import FlowSystem, PelletState, swell, triangulate, update_geometry
from shared.delaunay import delaunay_tetrahedra, same_cells
from shared.dem import cube_points, new_state, step
from shared.fv import (
    FlowPattern,
    assemble_matrix,
    facet_conductance,
    flow_pattern,
    transient_step,
)
from shared.mesh import (
    WALLS,
    Mesh,
    boundary_cell_mask,
    build_mesh,
    mesh_from_tetrahedra,
    update_mesh,
)
from shared.retention import saturation, saturation_derivative
from shared.solver import SPDSolver

__all__ = [
    "bench_flow", "bench_flow_scaling", "bench_solver_crossover", "bench_coupled_step",
    "jittered_cube",
]

EDGE = 7e-3
SCALING_SIZES = (1500, 5000, 15000, 50000)
CROSSOVER_SIZES = (1500, 5000, 15000, 37500, 75000, 150000)
# Point motion before a repaired remesh [fraction of the grid spacing]: it leaves 5 % of
# the cells non-Delaunay, within the 4-9 % that a run's remeshes redo.
REMESH_MOTION = 0.01


def jittered_cube(
    n_points: int, edge: float = EDGE, jitter: float = 0.25, seed: int = 0
) -> np.ndarray:
    """Points of a jittered cubic grid with about ``n_points`` points in a cube [m].

    Parameters
    ----------
    n_points
        Target number of points (rounded to a cube number).
    edge
        Cube edge [m].
    jitter
        Uniform jitter amplitude as a fraction of the grid spacing [1].
    seed
        Seed of the random generator.
    """
    per_side = max(2, round(n_points ** (1.0 / 3.0)))
    spacing = edge / per_side
    axis = (np.arange(per_side) + 0.5) * spacing
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    rng = np.random.default_rng(seed)
    return grid + rng.uniform(-jitter, jitter, grid.shape) * spacing


def _unsaturated_state(
    n_cells: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Porosity [1], pressure [Pa] and saturation [1] of a clay at 40-60 MPa suction."""
    porosity = rng.uniform(0.2, 0.3, n_cells)
    pressure = -rng.uniform(40e6, 60e6, n_cells)
    return porosity, pressure, saturation(-pressure, porosity, CLAY)


def bench_flow(
    n_points: int = 15000,
    *,
    relative_drift: float = 2e-3,
    repeats: int = 5,
    ordering_method: str | None = None,
) -> dict:
    """Time the flow phases at about ``n_points`` points in a 7 mm cube.

    Parameters
    ----------
    n_points
        Approximate number of DEM points.
    relative_drift
        Relative random change of the cell pressures before the reuse step [1]; it
        sets the coefficient drift, hence the CG iterations of the reuse step.
    repeats
        Timed calls per phase (after one untimed call).
    ordering_method
        Passed to :class:`shared.solver.SPDSolver`: None (the pattern's nested
        dissection) or a CHOLMOD ordering such as ``"metis"`` for comparison.

    Returns
    -------
    dict
        Sizes (points, cells, facets, unknowns), the machine's load average before the
        timings (other jobs share the cores); median and fastest time of each phase
        [ms] (``factorisation_solve_blas2``: the refactorisation with two OpenBLAS
        threads, :class:`shared.solver.SPDSolver` ``factor_blas_threads=2``);
        ``remesh_step_ms`` (Delaunay repair + geometry + pattern + conductance +
        assembly + analysis + factorisation + solve; ``repair_kept_fraction``: the
        share of the cells that the motion left Delaunay), ``reuse_step_ms`` (one transient
        step with a reused factor), their ratio, ``coupled_flow_step_ms`` (geometry
        update + reuse step: the flow part of one coupled step), each also as
        ``*_min_ms`` and as medians in seconds (``*_s``); the drift and factor
        applications, CG iterations and backward error of one reuse step (from the
        factor of the undrifted matrix, ``residual_tolerance`` of the solver).
    """
    material = CLAY
    rng = np.random.default_rng(1)
    points = jittered_cube(n_points)
    triangulation = delaunay_tetrahedra(points)
    mesh = mesh_from_tetrahedra(*triangulation)
    spacing = EDGE / round(points.shape[0] ** (1.0 / 3.0))
    remeshed = points + np.random.default_rng(2).uniform(
        -REMESH_MOTION, REMESH_MOTION, points.shape) * spacing
    moved = mesh.points * (1.0 + 1e-6)
    porosity, pressure, water = _unsaturated_state(mesh.n_cells, rng)
    imposed = np.full(mesh.n_cells, -1e6)
    dirichlet = boundary_cell_mask(mesh, list(WALLS))
    pattern = flow_pattern(mesh, dirichlet)
    conductance = facet_conductance(mesh, water, porosity, "water", material)
    # Time step making storage comparable with conduction: a conservative conditioning.
    capacity = porosity * mesh.volumes * saturation_derivative(-pressure, porosity, material)
    time_step = float(capacity.sum() / (2.0 * conductance.sum()))
    matrix = assemble_matrix(mesh, pattern, conductance, capacity / time_step)
    rhs = rng.standard_normal(pattern.n_free)
    solver = SPDSolver(ordering_method=ordering_method)
    threaded = SPDSolver(ordering_method=ordering_method, factor_blas_threads=2)
    drifted = pressure * (1.0 + relative_drift * rng.standard_normal(mesh.n_cells))
    stale = SPDSolver(ordering_method=ordering_method)

    def reuse_step() -> object:
        return transient_step(
            mesh, pattern, stale, drifted, water, porosity,
            facet_conductance(mesh, water, porosity, "water", material),
            imposed, time_step, material,
        )

    def fresh_stale_factor() -> None:
        # Every timed reuse step starts from the factor of the undrifted matrix.
        stale.solve(matrix, rhs, force_refactor=True, ordered=True)

    phases = {
        "delaunay": lambda: delaunay_tetrahedra(points),
        "delaunay_repair": lambda: triangulate(remeshed, mesh),
        "geometry": lambda: mesh_from_tetrahedra(*triangulation),
        "geometry_update": lambda: update_mesh(mesh, moved),
        "pattern": lambda: flow_pattern(mesh, dirichlet),
        "conductance": lambda: facet_conductance(mesh, water, porosity, "water", material),
        "assembly": lambda: assemble_matrix(mesh, pattern, conductance, capacity / time_step),
        "analysis_factorisation_solve": lambda: SPDSolver(
            ordering_method=ordering_method
        ).solve(matrix, rhs, ordered=True),
        "factorisation_solve": lambda: solver.solve(
            matrix, rhs, force_refactor=True, ordered=True
        ),
        "factorisation_solve_blas2": lambda: threaded.solve(
            matrix, rhs, force_refactor=True, ordered=True
        ),
        "solve_reused_factor": lambda: solver.solve(matrix, rhs, ordered=True),
    }
    record: dict = {
        "n_points": int(points.shape[0]),
        "n_cells": mesh.n_cells,
        "n_facets": mesh.n_facets,
        "n_unknowns": pattern.n_free,
        "ordering_method": ordering_method or "nested dissection (flow_pattern)",
        "relative_pressure_drift": relative_drift,
        "load_average_1min": os.getloadavg()[0],
        "remesh_motion": REMESH_MOTION,
        "repair_kept_fraction": np.count_nonzero(same_cells(
            mesh.tetrahedra, triangulate(remeshed, mesh)[0], points.shape[0]) >= 0) / mesh.n_cells,
    }
    for name, function in phases.items():
        record.update(_timings_ms(name, function, repeats))
    record.update(_timings_ms("reuse_step", reuse_step, repeats, setup=fresh_stale_factor))
    fresh_stale_factor()
    before = dataclasses.replace(stale.stats)
    reuse_step()
    drifted_matrix = assemble_matrix(
        mesh, pattern, conductance,
        porosity * mesh.volumes * saturation_derivative(-drifted, porosity, material) / time_step,
    )
    record["reuse_drift"] = stale.drift(drifted_matrix)
    record["reuse_refactored"] = stale.stats.factorisations > before.factorisations
    record["reuse_factor_applications"] = (
        stale.stats.factor_applications - before.factor_applications
    )
    record["reuse_iterations"] = stale.stats.iterations - before.iterations
    record["reuse_backward_error"] = stale.last_residual
    record["residual_tolerance"] = stale.residual_tolerance
    remesh_phases = (
        "delaunay_repair", "geometry", "pattern", "conductance", "assembly",
        "analysis_factorisation_solve",
    )
    for suffix in ("ms", "min_ms"):
        record[f"remesh_step_{suffix}"] = sum(record[f"{p}_{suffix}"] for p in remesh_phases)
        record[f"coupled_flow_step_{suffix}"] = (
            record[f"geometry_update_{suffix}"] + record[f"reuse_step_{suffix}"]
        )
    record["remesh_over_reuse"] = record["remesh_step_ms"] / record["reuse_step_ms"]
    # Median step times in seconds, the keys benchmarks.yade_compare reads.
    for name in ("remesh_step", "reuse_step", "coupled_flow_step"):
        record[f"{name}_s"] = 1e-3 * record[f"{name}_ms"]
    return record


def _exponent(sizes: list[int], costs: list[float]) -> float:
    """Least-squares slope of log(cost) versus log(N) [1]."""
    return float(np.polyfit(np.log(sizes), np.log(costs), 1)[0])


def bench_flow_scaling(
    sizes: tuple[int, ...] = SCALING_SIZES,
    *,
    repeats: int = 3,
    figure: Path | None = Path("results/benchmarks/flow_scaling.png"),
) -> dict:
    """Cost of the flow phases versus the number of points, with fitted exponents.

    Parameters
    ----------
    sizes
        Approximate numbers of points.
    repeats
        Timed calls per phase and size.
    figure
        Where to write the log-log figure of the curve (None: no figure).

    Returns
    -------
    dict
        ``records`` (one :func:`bench_flow` record per size), ``exponents`` (fitted
        slope of log(median cost) versus log(N) for every phase and step) and
        ``n_log_n_exponent``, the slope N log N itself has over the same range (the
        target: a step's exponent no larger than it).
    """
    records = [bench_flow(n, repeats=repeats) for n in sizes]
    points = [r["n_points"] for r in records]
    names = [key[:-3] for key in records[0] if key.endswith("_ms") and not key.endswith("min_ms")]
    exponents = {name: _exponent(points, [r[f"{name}_ms"] for r in records]) for name in names}
    reference = _exponent(points, [n * np.log(n) for n in points])
    result = {"records": records, "exponents": exponents, "n_log_n_exponent": reference}
    if figure is not None:
        _plot_scaling(records, exponents, figure)
    return result


def _plot_scaling(records: list[dict], exponents: dict[str, float], path: Path) -> None:
    """Log-log figure of the step and phase costs versus N with an N log N guide."""
    points = np.array([r["n_points"] for r in records], dtype=float)
    figure = Figure(figsize=(7.0, 5.0))
    axes = figure.add_subplot()
    steps = ("remesh_step", "coupled_flow_step", "reuse_step")
    phases = ("delaunay", "analysis_factorisation_solve", "geometry_update", "pattern")
    for name in steps + phases:
        style = "o-" if name in steps else "s--"
        axes.loglog(
            points, [r[f"{name}_ms"] for r in records], style,
            label=f"{name} (N^{exponents[name]:.2f})",
        )
    guide = points * np.log(points)
    anchor = records[0]["coupled_flow_step_ms"]
    axes.loglog(points, anchor * guide / guide[0], "k:", label="N log N")
    _save_cost_figure(figure, axes, "median wall time [ms]",
                      "Flow machinery, 7 mm cube, jittered grid", path)


def _save_cost_figure(figure: Figure, axes: Axes, ylabel: str, title: str, path: Path) -> None:
    """Label, grid and legend a log-log cost-versus-N axes, and write its figure."""
    axes.set_xlabel("points N")
    axes.set_ylabel(ylabel)
    axes.set_title(title)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=7)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.tight_layout()
    figure.savefig(path, dpi=120)


def _transient_system(
    n_points: int, rng: np.random.Generator, crack_fraction: float = 0.0
) -> tuple[Mesh, FlowPattern, np.ndarray, np.ndarray, np.ndarray]:
    """Mesh, pattern, conductances, storage and pressure of a transient flow system as
    :func:`bench_flow` builds it; ``crack_fraction`` of the facets conduct
    1e9-1e10 times the clay (open water-filled cracks)."""
    mesh = build_mesh(jittered_cube(n_points))
    porosity, pressure, water = _unsaturated_state(mesh.n_cells, rng)
    pattern = flow_pattern(mesh, boundary_cell_mask(mesh, list(WALLS)))
    conductance = facet_conductance(mesh, water, porosity, "water", CLAY)
    capacity = porosity * mesh.volumes * saturation_derivative(-pressure, porosity, CLAY)
    storage = capacity * 2.0 * conductance.sum() / capacity.sum()
    cracked = rng.random(mesh.n_facets) < crack_fraction
    conductance = np.where(cracked, conductance * 10.0 ** rng.uniform(9, 10, mesh.n_facets),
                           conductance)
    return mesh, pattern, conductance, storage, pressure


def bench_solver_crossover(
    sizes: tuple[int, ...] = CROSSOVER_SIZES,
    *,
    crack_fraction: float = 0.03,
    repeats: int = 3,
    figure: Path | None = Path("results/benchmarks/solver_crossover.png"),
) -> dict:
    """Cost of one solve with each preconditioner of :class:`shared.solver.SPDSolver`.

    For each size and for a clay without and with cracks (``crack_fraction`` of the
    facets 1e9-1e10 times more conductive), on the system of one transient step
    (:func:`bench_flow`'s conditioning) at the micro run's tolerance (1e-8, judged on
    the whole pressure): a fresh solve (analysis + factorisation + substitution, or
    multigrid setup + V-cycle CG) and a solve reusing the preconditioner on the matrix
    of a pressure drifted by 2e-3 (the factor then needs a few CG iterations, the
    hierarchy about as many as fresh). The micro run's profile decides how the two
    combine: at 8k points its flow solves buy a preconditioner 208 times in 214 solves
    (110 patterns: remeshes and checkpoints), so the fresh solve is the one that
    counts. Medians in seconds; iterations of one solve.
    """
    records = []
    for n_points in sizes:
        for fraction in (0.0, crack_fraction):
            rng = np.random.default_rng(2)
            mesh, pattern, conductance, storage, pressure = _transient_system(
                n_points, rng, fraction)
            matrix = assemble_matrix(mesh, pattern, conductance, storage)
            drifted = assemble_matrix(mesh, pattern, conductance * (
                1.0 + 2e-3 * rng.standard_normal(mesh.n_facets)), storage)
            offset = pressure[pattern.free_cells]
            rhs = 1e-3 * rng.standard_normal(pattern.n_free) * np.abs(matrix.diagonal()) \
                * np.abs(offset).max()
            record: dict = {"n_points": int(mesh.points.shape[0]), "n_unknowns": pattern.n_free,
                            "crack_fraction": fraction,
                            "load_average_1min": os.getloadavg()[0]}
            for method in ("direct", "amg"):
                solver = SPDSolver(method=method)

                def fresh(solver: SPDSolver = solver, matrix=matrix, rhs=rhs, offset=offset) -> None:
                    solver.reset()
                    solver.solve(matrix, rhs, ordered=True, offset=offset)

                def reused(solver: SPDSolver = solver, drifted=drifted, rhs=rhs, offset=offset) -> None:
                    solver.solve(drifted, rhs, ordered=True, offset=offset)

                def refresh(solver: SPDSolver = solver, matrix=matrix, rhs=rhs, offset=offset) -> None:
                    solver.solve(matrix, rhs, ordered=True, offset=offset,
                                 force_refactor=True)

                record.update(_timings_ms(f"{method}_fresh", fresh, repeats))
                record.update(_timings_ms(f"{method}_reused", reused, repeats, setup=refresh))
                for name, call in (("fresh", fresh), ("reused", reused)):
                    if name == "reused":
                        refresh()
                    before = solver.stats.iterations
                    call()
                    record[f"{method}_{name}_iterations"] = solver.stats.iterations - before
            for key in [k for k in record if k.endswith("_ms")]:
                record[key[:-3] + "_s"] = 1e-3 * record.pop(key)
            records.append(record)
    cracked = [r for r in records if r["crack_fraction"] > 0]
    clean = [r for r in records if r["crack_fraction"] == 0]
    points = [r["n_points"] for r in clean]
    exponents = {
        f"{method}_{name}{suffix}": _exponent(points, [r[f"{method}_{name}_s"] for r in rows])
        for method in ("direct", "amg") for name in ("fresh", "reused")
        for suffix, rows in (("", clean), ("_cracked", cracked))
    }
    result = {"records": records, "exponents": exponents}
    if figure is not None:
        _plot_crossover(records, figure)
    return result


def _plot_crossover(records: list[dict], path: Path) -> None:
    """Log-log figure of the fresh and reused solve of each preconditioner versus N."""
    figure = Figure(figsize=(7.0, 5.0))
    axes = figure.add_subplot()
    for cracked, style in ((False, "-"), (True, "--")):
        rows = [r for r in records if (r["crack_fraction"] > 0) == cracked]
        points = [r["n_points"] for r in rows]
        for method, marker in (("direct", "o"), ("amg", "s")):
            for name, colour in (("fresh", "C0" if method == "direct" else "C1"),
                                 ("reused", "C2" if method == "direct" else "C3")):
                axes.loglog(points, [r[f"{method}_{name}_s"] for r in rows],
                            marker + style, color=colour,
                            label=f"{method} {name}" + (", cracks" if cracked else ""))
    _save_cost_figure(figure, axes, "median wall time of one solve [s]",
                      "SPDSolver: CHOLMOD factor vs Ruge-Stueben multigrid (7 mm cube)", path)


def bench_coupled_step(
    n_points: int = 15000, repeats: int = 8, seed: int = 0, radius_factor: float = 1.02,
    residual_tolerance: float | None = None,
) -> dict:
    """Time coupled steps as :func:`micro.hydration.advance_to_balance` runs them.

    The phases run in the order of the hydration loop, on a jittered point cube at
    50 MPa suction with a 40 MPa boundary: a flow step (conductance +
    :func:`shared.fv.transient_step` with the solver :class:`micro.hydration.FlowSystem`
    builds; the state advances from step to step, so the factor goes stale as in a run
    and the solver's rent-or-buy rule decides when to refactor), the swelling radii
    and hydro-mechanical forces (:func:`micro.hydration.swell`), one DEM step
    (:func:`shared.dem.step`, Verlet list reused) and the geometry update of the moved
    points (:func:`micro.hydration.update_geometry`). A step in which a cell inverted
    (a remesh) is not counted.

    With the default ``radius_factor`` the points start overlapping and unrelaxed, so
    they accelerate from step to step; near-cospherical cell pairs and slivers then
    change their conductances by orders of magnitude per step, and the stale factor
    needs more CG iterations each step. With ``radius_factor`` 0.8 no two points of
    the jittered grid touch: the points start at rest and barely move, as near
    mechanical balance, and only the hydration front changes the matrix.

    Parameters
    ----------
    n_points
        Requested number of points (rounded to a cube number).
    repeats
        Coupled steps after one untimed step (remeshed steps are not timed).
    seed
        Seed of the point jitter and the porosity.
    radius_factor
        Interaction radius over half the grid spacing [1] (:func:`shared.dem.cube_points`).
    residual_tolerance
        Solver tolerance; None keeps hydration's (:class:`shared.solver.SPDSolver`'s
        default). ``inf`` accepts the stale factor's single substitution as it is, never
        refactoring: Yade's reuse (a stale system solved silently, docs/yade.md §8.2),
        timed for a like-for-like comparison of the implementations, not a mode of ours.

    Returns
    -------
    dict
        Sizes, the radius factor, the load average after the steps, the timed and
        remeshed step counts;
        per timed step the factor applications, CG iterations and factorisations, and
        the largest saturation error the solve left in a free cell (|S_new - S - dS/dp
        dp|, the flux-form update's departure from the retention-consistent one)
        beside the largest saturation change of the step;
        median and fastest time per phase [ms]; ``coupled_step_ms`` / ``_min_ms`` (the
        sum as hydration runs it, median and fastest over all timed steps),
        ``coupled_step_mean_ms`` (the mean: the amortised cost, refactorisations
        included) and ``coupled_step_reused_ms`` / ``_min_ms`` (median and fastest
        over the steps that reused the factor, None if none did).
    """
    material = CLAY
    rng = np.random.default_rng(seed)
    positions, radii = cube_points(n_points, rng, jitter=0.2, radius_factor=radius_factor)
    dem = new_state(positions, radii, DEM)
    mesh = build_mesh(dem.positions)
    porosity = rng.uniform(0.2, 0.3, mesh.n_cells)
    # Uniform 50 MPa suction wetted from a 40 MPa boundary: a smooth hydration front.
    pressure = np.full(mesh.n_cells, -50e6)
    state = PelletState(
        dem=dem, mesh=mesh, pressure=pressure,
        saturation=saturation(-pressure, porosity, material),
        solid_volume=(1.0 - porosity) * mesh.volumes, porosity=porosity,
    )
    def flow_system(mesh: Mesh) -> FlowSystem:
        system = FlowSystem.for_mesh(mesh)
        if residual_tolerance is not None:
            system.solver.residual_tolerance = residual_tolerance
        return system

    system = flow_system(mesh)
    time_step = DEM.time_step
    flow_time_step = SETTINGS.initial_time_step
    loads = np.zeros_like(dem.positions)
    bounds, damping = SETTINGS.porosity_bounds, SETTINGS.damping

    accuracy: dict[str, list[float]] = {"error": [], "change": []}

    def flow_step() -> None:
        conductance = facet_conductance(state.mesh, state.saturation, state.porosity, "water",
                                        material)
        imposed = np.full(state.mesh.n_cells, -40e6)
        result = transient_step(
            state.mesh, system.pattern, system.solver, state.pressure, state.saturation,
            state.porosity, conductance, imposed, flow_time_step, material,
        )
        # the flux-form update departs from S + dS/dp dp by dt r / (n V): the solve's error
        free = system.pattern.free_cells
        derivative = saturation_derivative(-state.pressure[free], state.porosity[free], material)
        change = result.saturation[free] - state.saturation[free]
        consistent = derivative * (result.pressure[free] - state.pressure[free])
        accuracy["error"].append(float(np.abs(change - consistent).max()))
        accuracy["change"].append(float(np.abs(change).max()))
        state.pressure, state.saturation = result.pressure, result.saturation

    phases = {
        "flow_step": flow_step,
        "hydro_forces": lambda: swell(state, material),
        "dem_step": lambda: step(dem, time_step, DEM, loads, None, damping),
        "geometry_update": lambda: update_geometry(state, bounds, material),
    }
    times: dict[str, list[float]] = {name: [] for name in phases}
    work: dict[str, list] = {"applications": [], "iterations": [], "factorisations": [],
                             "saturation_error": [], "saturation_change": []}
    remeshes = 0
    for count in range(repeats + 1):
        before = dataclasses.replace(system.solver.stats)
        elapsed = {}
        for name, function in phases.items():
            start = time.perf_counter()
            function()
            elapsed[name] = 1e3 * (time.perf_counter() - start)
        if state.n_remesh > remeshes:
            # A cell inverted and update_geometry remeshed: rebuild the flow system as
            # hydration does, and leave this step out of the statistics.
            remeshes = state.n_remesh
            system = flow_system(state.mesh)
            continue
        if count > 0:  # the first step compiles or warms the kernels
            for name, value in elapsed.items():
                times[name].append(value)
            for name in ("error", "change"):
                work[f"saturation_{name}"].append(accuracy[name][-1])
            stats = system.solver.stats
            work["applications"].append(stats.factor_applications - before.factor_applications)
            work["iterations"].append(stats.iterations - before.iterations)
            work["factorisations"].append(stats.factorisations - before.factorisations)
    totals = np.sum([times[name] for name in phases], axis=0)
    reused = totals[np.array(work["factorisations"]) == 0]
    record: dict = {
        "n_points": dem.n_points,
        "n_cells": mesh.n_cells,
        "n_unknowns": system.pattern.n_free,
        "radius_factor": radius_factor,
        "residual_tolerance": float(system.solver.residual_tolerance),
        "refactor_iterations": system.solver.refactor_iterations,
        "load_average_1min": os.getloadavg()[0],
        "timed_steps": len(totals),
        "remeshed_steps": remeshes,
        "factor_applications_per_step": work["applications"],
        "iterations_per_step": work["iterations"],
        "factorisations_per_step": work["factorisations"],
        "saturation_error_per_step": work["saturation_error"],
        "saturation_change_per_step": work["saturation_change"],
        "coupled_step_per_step_ms": totals.tolist(),
    }
    for name, values in times.items():
        record[f"{name}_ms"] = float(np.median(values))
        record[f"{name}_min_ms"] = float(np.min(values))
    record["coupled_step_ms"] = float(np.median(totals))
    record["coupled_step_min_ms"] = float(np.min(totals))
    record["coupled_step_mean_ms"] = float(np.mean(totals))
    record["coupled_step_reused_ms"] = float(np.median(reused)) if reused.size else None
    record["coupled_step_reused_min_ms"] = float(np.min(reused)) if reused.size else None
    return record


def main(argv: list[str] | None = None) -> None:
    """Write flow.json (1.5k and 15k, two drifts; 15k with METIS), flow_scaling.json/.png,
    flow_coupled.json (1.5k and 15k, overlapping and settled points; 15k settled with
    Yade's unchecked single substitution)."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="sizes up to 15k, 2 repeats")
    parser.add_argument("--output", type=Path, default=Path("results/benchmarks"))
    arguments = parser.parse_args(argv)
    repeats = 2 if arguments.quick else 3
    sizes = SCALING_SIZES[:-1] if arguments.quick else SCALING_SIZES
    output = arguments.output
    output.mkdir(parents=True, exist_ok=True)
    results = {
        "flow": [
            bench_flow(n, relative_drift=drift, repeats=repeats)
            for n in (1500, 15000) for drift in (2e-3, 1e-5)
        ] + [bench_flow(15000, repeats=repeats, ordering_method="metis")],
        "flow_scaling": bench_flow_scaling(
            sizes, repeats=repeats, figure=output / "flow_scaling.png"
        ),
        "flow_coupled": [
            bench_coupled_step(n, radius_factor=factor)
            for n in (1500, 15000) for factor in (1.02, 0.8)
        ] + [bench_coupled_step(15000, radius_factor=0.8, residual_tolerance=np.inf)],
    }
    for name, result in results.items():
        (output / f"{name}.json").write_text(json.dumps(result, indent=1, default=float))
    print(json.dumps(results["flow_scaling"]["exponents"], indent=1))


if __name__ == "__main__":
    main()
