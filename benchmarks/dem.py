"""Timing of the DEM phases on a 7 mm cube: contact detection, forces, integration.

Run ``python -m benchmarks.dem [n_points ...] [--output results/benchmarks/dem.json]``;
prints one JSON record per size (median wall times in ms). Timings are measured, never
asserted.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from benchmarks.parameters import DEM
from micro.forces import hydromechanical_forces, point_suction, sector_weights
from shared.dem import (
    contact_forces,
    cube_points,
    detect_contacts,
    integrate,
    new_state,
    stable_time_step,
    step,
    wall_forces,
    walls_around,
)
from shared.mesh import build_mesh

__all__ = ["bench_dem"]


def _timings_ms(
    name: str,
    function: Callable[[], object],
    repeats: int,
    setup: Callable[[], object] | None = None,
) -> dict:
    """Median and fastest of ``repeats`` calls after a warm-up call [ms].

    The fastest call estimates the cost on an idle machine; the median includes the
    contention of a shared one. ``setup``, if given, runs untimed before every call.
    """
    prepare = setup if setup is not None else (lambda: None)
    prepare()
    function()
    times = []
    for _ in range(repeats):
        prepare()
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return {
        f"{name}_ms": 1e3 * float(np.median(times)),
        f"{name}_min_ms": 1e3 * float(np.min(times)),
    }


def bench_dem(
    n_points: int = 15000, repeats: int = 20, seed: int = 0, hydro: bool = True
) -> dict:
    """Median wall time of each DEM phase at ``n_points`` points of a 7 mm cube.

    Parameters
    ----------
    n_points
        Requested number of points (jittered grid, so round(n^(1/3))^3 of them).
    repeats
        Timed repetitions per phase (after one warm-up call that compiles).
    seed
        Seed of the point jitter.
    hydro
        Also time the per-step point coupling of the flow model on a Delaunay mesh of
        the points: ``hydro_forces_ms`` (Eqs. 3.28-3.32 as :mod:`micro.hydration` calls
        it, sector weights computed in the force kernel), ``point_suction_ms``, and for
        comparison ``hydro_forces_cached_weights_ms`` (weights passed in) and
        ``sector_weights_ms`` (computing them separately).

    Returns
    -------
    dict
        ``n_points``, ``n_contacts``, ``stable_time_step_s``, and median milliseconds
        (``*_min_ms``: fastest call) of ``contacts_ms`` (full cell list detection),
        ``forces_ms`` (Hertz-Mindlin), ``walls_ms`` (six servo walls),
        ``integration_ms`` (leapfrog), ``step_ms`` (a whole :func:`shared.dem.step` at
        the coupled time step, Verlet list reused; ``step_rebuilds`` counts the calls
        that rebuilt it) and ``dem_step_with_detection_ms`` (forces + walls +
        integration + a full detection, the worst case).
    """
    rng = np.random.default_rng(seed)
    positions, radii = cube_points(n_points, rng, jitter=0.2, radius_factor=1.02)
    state = new_state(positions, radii, DEM)
    walls = walls_around(state.positions, state.radii, 1e6)
    # the coupled run's time step (Appendix .2): points creep, the Verlet list holds
    time_step = DEM.time_step
    forces = np.zeros((state.n_points, 3))
    torques = np.zeros((state.n_points, 3))
    factor = DEM.interaction_radius_factor
    skin = state.contacts.skin

    def detect() -> object:
        return detect_contacts(state.positions, state.radii, factor, skin)

    def hertz() -> object:
        forces[:] = 0.0
        torques[:] = 0.0
        return contact_forces(state, time_step, DEM, forces, torques)

    def wall() -> object:
        return wall_forces(state, walls, forces, DEM)

    def advance() -> None:
        integrate(state, forces, torques, time_step, DEM.damping)

    rebuilds: list[bool] = []

    def whole() -> object:
        report = step(state, time_step, DEM, walls=walls)
        rebuilds.append(report.contacts_rebuilt)
        return report

    record: dict = {
        "n_points": state.n_points,
        "n_contacts": int(state.contacts.pairs.shape[0]),
        "stable_time_step_s": stable_time_step(state, DEM, walls=walls),
    }
    for name, function in (
        ("contacts", detect),
        ("forces", hertz),
        ("walls", wall),
        ("integration", advance),
        ("step", whole),
    ):
        record.update(_timings_ms(name, function, repeats))
    record["step_rebuilds"] = int(np.sum(rebuilds))
    record["dem_step_with_detection_ms"] = (
        record["contacts_ms"] + record["forces_ms"] + record["walls_ms"]
        + record["integration_ms"]
    )
    if hydro:
        record.update(_bench_hydro(state.positions.copy(), state.radii, repeats))
    return record


def _bench_hydro(positions: np.ndarray, radii: np.ndarray, repeats: int) -> dict:
    mesh = build_mesh(positions)
    rng = np.random.default_rng(1)
    pressure = -rng.uniform(1e6, 1e8, mesh.n_cells)
    saturation = rng.uniform(0.3, 1.0, mesh.n_cells)
    weights = sector_weights(mesh, positions, radii)

    def hydro_forces() -> object:
        return hydromechanical_forces(mesh, positions, radii, pressure, saturation)

    def hydro_forces_cached() -> object:
        return hydromechanical_forces(
            mesh, positions, radii, pressure, saturation, weights=weights
        )

    def suction() -> object:
        return point_suction(mesh.tetrahedra, mesh.volumes, -pressure, positions.shape[0])

    def weighting() -> object:
        return sector_weights(mesh, positions, radii)

    record: dict = {"n_cells": mesh.n_cells}
    for name, function in (
        ("hydro_forces", hydro_forces),
        ("hydro_forces_cached_weights", hydro_forces_cached),
        ("point_suction", suction),
        ("sector_weights", weighting),
    ):
        record.update(_timings_ms(name, function, repeats))
    return record


def main(argv: list[str] | None = None) -> None:
    """Print one JSON record per size; with ``--output``, also write them as a list."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("sizes", nargs="*", type=int, default=[1500, 15000, 50000])
    parser.add_argument("--output", type=Path, help="JSON file for the records")
    parser.add_argument("--no-hydro", action="store_true", help="skip mesh coupling timings")
    arguments = parser.parse_args(argv)
    records = []
    for size in arguments.sizes:
        records.append(bench_dem(size, hydro=not arguments.no_hydro))
        print(json.dumps(records[-1]))
    if arguments.output is not None:
        arguments.output.parent.mkdir(parents=True, exist_ok=True)
        arguments.output.write_text(json.dumps(records, indent=1))


if __name__ == "__main__":
    main()
