"""Timing of the partially saturated flow machinery: remesh step versus reuse step.

A jittered grid of about ``n_points`` points fills a 7 mm cube (the thesis's specimen).
Phases timed (wall clock, one run each after a warm-up of the numba kernels on a tiny
mesh): Delaunay, geometry, geometry update of moved points with the same
connectivity, pattern, conductance, assembly, analysis + factorisation
(first solve on a new pattern), a refactorisation on the same pattern, a solve that
reuses the factor unchanged, and a full transient step (conductance, assembly, drift
check, solve with the stale factor corrected by CG, saturation update) after the state
drifted slightly. Run ``python -m benchmarks.flow`` to write
``results/benchmarks/flow.json``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from shared.fv import assemble_matrix, facet_conductance, flow_pattern, transient_step
from shared.materials import DEFAULT_CLAY
from shared.mesh import WALLS, boundary_cell_mask, delaunay_tetrahedra, mesh_from_tetrahedra
from shared.retention import saturation, saturation_derivative
from shared.solver import CholeskySolver

__all__ = ["bench_flow", "jittered_cube"]

EDGE = 7e-3


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


def _clock(start: float) -> float:
    return time.perf_counter() - start


def bench_flow(n_points: int = 15000, *, relative_drift: float = 2e-3) -> dict:
    """Time the flow phases at about ``n_points`` points in a 7 mm cube.

    Parameters
    ----------
    n_points
        Approximate number of DEM points.
    relative_drift
        Relative random change of the cell pressures before the reuse step [1]; it
        sets the coefficient drift, hence the CG iterations of the reuse step.

    Returns
    -------
    dict
        Sizes (points, cells, facets, unknowns, factor non-zeros), phase times [s],
        ``remesh_step`` (Delaunay + geometry + pattern + conductance + assembly +
        analysis + factorisation + solve), ``reuse_step`` (one transient step with a
        reused factor), their ratio, ``coupled_flow_step`` (geometry update of moved
        points with fixed connectivity + reuse step: the flow part of one coupled DEM
        step), the drift and factor applications of the reuse step.
    """
    material = DEFAULT_CLAY
    _warm_up()
    times: dict[str, float] = {}
    points = jittered_cube(n_points)
    start = time.perf_counter()
    triangulation = delaunay_tetrahedra(points)
    times["delaunay"] = _clock(start)
    start = time.perf_counter()
    mesh = mesh_from_tetrahedra(*triangulation)
    times["geometry"] = _clock(start)
    moved = mesh.points * (1.0 + 1e-6)
    start = time.perf_counter()
    mesh_from_tetrahedra(moved, mesh.tetrahedra, mesh.neighbours, reorient=False)
    times["geometry_update"] = _clock(start)

    rng = np.random.default_rng(1)
    porosity = rng.uniform(0.2, 0.3, mesh.n_cells)
    pressure = -rng.uniform(40e6, 60e6, mesh.n_cells)
    water = saturation(-pressure, porosity, material)
    imposed = np.full(mesh.n_cells, -1e6)

    start = time.perf_counter()
    pattern = flow_pattern(mesh, boundary_cell_mask(mesh, list(WALLS)))
    times["pattern"] = _clock(start)
    start = time.perf_counter()
    conductance = facet_conductance(mesh, water, porosity, "water", material)
    times["conductance"] = _clock(start)
    # Time step making storage comparable with conduction: a conservative conditioning.
    capacity = porosity * mesh.volumes * saturation_derivative(-pressure, porosity, material)
    time_step = float(capacity.sum() / (2.0 * conductance.sum()))
    storage = capacity / time_step
    start = time.perf_counter()
    matrix = assemble_matrix(mesh, pattern, conductance, storage)
    times["assembly"] = _clock(start)
    rhs = rng.standard_normal(pattern.n_free)

    solver = CholeskySolver()
    start = time.perf_counter()
    solver.solve(matrix, rhs)
    times["analysis_factorization_solve"] = _clock(start)
    start = time.perf_counter()
    solver.solve(matrix, rhs, force_refactor=True)
    times["factorization_solve"] = _clock(start)
    start = time.perf_counter()
    solver.solve(matrix, rhs)
    times["solve_reused_factor"] = _clock(start)

    drifted_pressure = pressure * (1.0 + relative_drift * rng.standard_normal(mesh.n_cells))
    applications = solver.stats.factor_applications
    factorizations = solver.stats.factorizations
    start = time.perf_counter()
    transient_step(
        mesh, pattern, solver, drifted_pressure, water, porosity,
        facet_conductance(mesh, water, porosity, "water", material),
        imposed, time_step, material,
    )
    times["reuse_step"] = _clock(start)

    remesh = (
        times["delaunay"] + times["geometry"] + times["pattern"] + times["conductance"]
        + times["assembly"] + times["analysis_factorization_solve"]
    )
    return {
        "n_points": int(points.shape[0]),
        "n_cells": mesh.n_cells,
        "n_facets": mesh.n_facets,
        "n_unknowns": pattern.n_free,
        "times_s": times,
        "analysis_s": times["analysis_factorization_solve"] - times["factorization_solve"],
        "remesh_step_s": remesh,
        "reuse_step_s": times["reuse_step"],
        "coupled_flow_step_s": times["geometry_update"] + times["reuse_step"],
        "remesh_over_reuse": remesh / times["reuse_step"],
        "relative_pressure_drift": relative_drift,
        "reuse_drift": solver.last_drift,
        "reuse_refactored": solver.stats.factorizations > factorizations,
        "reuse_factor_applications": solver.stats.factor_applications - applications,
        "reuse_backward_error": solver.last_residual,
    }


def _warm_up() -> None:
    """Compile or load the numba kernels on a tiny mesh so they are not timed."""
    mesh = mesh_from_tetrahedra(*delaunay_tetrahedra(jittered_cube(64)))
    porosity = np.full(mesh.n_cells, 0.25)
    water = np.full(mesh.n_cells, 0.5)
    pressure = np.full(mesh.n_cells, -1e6)
    pattern = flow_pattern(mesh, boundary_cell_mask(mesh, list(WALLS)))
    transient_step(
        mesh, pattern, CholeskySolver(), pressure, water, porosity,
        facet_conductance(mesh, water, porosity), pressure, 1.0,
    )


def main() -> None:
    """Run at 1.5k and 15k points, two drifts, and write ``results/benchmarks/flow.json``."""
    results = [
        bench_flow(n, relative_drift=drift) for n in (1500, 15000) for drift in (2e-3, 1e-5)
    ]
    path = Path("results/benchmarks/flow.json")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=2, default=float))
    print(json.dumps(results, indent=2, default=float))


if __name__ == "__main__":
    main()
