"""Side-by-side benchmark against Yade 2023.02a's PartialSatClayEngine (issue 4).

Both codes get the same points: a jittered grid from :func:`shared.dem.points.cube_points`
with the seed, jitter and radius factor of :mod:`benchmarks.dem`, so that the DEM
timings of that module are taken on these very points. The Yade side is
``benchmarks/yade/partialsat_cube.py``, run headless in a subprocess of its own
session (killed as a group on timeout, which also frees the ports 9000 and 21000 it
listens on while it runs); every parameter it uses comes from the settings JSON
written here from :data:`shared.materials.DEFAULT_CLAY` and
:data:`shared.dem.DEFAULT_DEM`.

Compared (ratio = ours / Yade's):

* a coupled iteration with a reused factor: ours is a DEM step (:mod:`benchmarks.dem`:
  ``step_ms`` + ``hydro_forces_ms`` + ``point_suction_ms``) plus the flow part of a
  coupled step (:mod:`benchmarks.flow`: ``coupled_flow_step_s``);
* a remesh: ours is :mod:`benchmarks.flow`'s ``remesh_step_s`` (Delaunay to first
  solve, factorisation included) plus the sector weights of the point forces and the
  transfer of the cell state to the new mesh, timed here;
* the water permeability along x of the homogeneous specimen (porosity phi_0) after
  Yade's equilibration, at the equilibrium saturation S(s_0) and fully saturated,
  both by the wall-flux method (REFERENCE_NOTES section 10), ours on Yade's
  equilibrated point positions with :func:`micro.permeability.permeability_tensor_axes`.

Timings are one run each on a shared machine, never asserted. Run
``python -m benchmarks.yade_compare [N ...]`` to write
``results/benchmarks/yade_compare_<N>.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.dem import bench_dem
from benchmarks.flow import bench_flow
from micro.forces import sector_weights
from micro.permeability import permeability_tensor_axes
from shared.dem import DEFAULT_DEM
from shared.dem.points import cube_points
from shared.fv import transfer_cell_state
from shared.materials import DEFAULT_CLAY
from shared.mesh import build_mesh
from shared.retention import saturation

__all__ = ["bench_yade_compare"]

YADE_SCRIPT = Path(__file__).with_name("yade") / "partialsat_cube.py"
OUT = Path("results/benchmarks")
# The point set of benchmarks.dem.bench_dem (seed 0, jitter 0.2, radius factor 1.02).
SEED = 0
JITTER = 0.2
RADIUS_FACTOR = 1.02
# Appendix .2 prints a truncated friction angle; our Hertz-Mindlin has no sliding
# limit, which a steep friction angle approaches.
FRICTION_ANGLE_DEG = 80.0


def _run_settings(n_points: int) -> dict:
    """Run lengths of the Yade side, scaled so that each size takes minutes.

    Thesis Appendix .2 equilibrates in chunks of 400 iterations until the unbalanced
    force ratio is below 0.05; the budget stops it earlier on large specimens.
    """
    return {
        "equilibration_chunk": 200,
        "max_equilibration_iterations": max(400, int(6e6 / n_points)),
        "unbalanced_force_threshold": 0.05,
        "drop_fraction": 0.1,
        "warmup_iterations": 3,
        "coupled_iterations": max(20, int(3e5 / n_points)),
        "remesh_steps": 3,
    }


def _run_yade(settings_path: Path, timeout: float) -> subprocess.CompletedProcess:
    """Run the Yade script headless, one thread, its whole process group killed on exit.

    Raises
    ------
    subprocess.TimeoutExpired
        If Yade is still running after ``timeout`` seconds (it is killed first).
    """
    command = ["yade", "-x", "-n", "-j1", str(YADE_SCRIPT), str(settings_path)]
    environment = dict(os.environ, OMP_NUM_THREADS="1")
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True, env=environment, cwd=settings_path.parent,
    )
    try:
        output, _ = process.communicate(timeout=timeout)
    finally:
        # Yade may leave helper threads or children holding its ports: end the group.
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        process.wait()
    return subprocess.CompletedProcess(command, process.returncode, output, None)


def _run_yade_side(
    positions: np.ndarray, radii: np.ndarray, folder: Path, timeout: float
) -> tuple[dict, np.ndarray]:
    """Write the inputs, run Yade, return its JSON and its equilibrated positions."""
    points_path = folder / "points.txt"
    np.savetxt(points_path, np.column_stack((positions, radii)))
    settings = {
        "points_path": str(points_path),
        "output_path": str(folder / "yade.json"),
        "positions_out": str(folder / "positions.txt"),
        "clay": dataclasses.asdict(DEFAULT_CLAY),
        "dem": dict(dataclasses.asdict(DEFAULT_DEM), friction_angle_deg=FRICTION_ANGLE_DEG),
        "run": _run_settings(positions.shape[0]),
    }
    settings_path = folder / "settings.json"
    settings_path.write_text(json.dumps(settings, indent=1))
    done = _run_yade(settings_path, timeout)
    (folder / "yade.log").write_text(done.stdout)
    if done.returncode != 0 or not Path(settings["output_path"]).exists():
        tail = "\n".join(done.stdout.splitlines()[-30:])
        raise RuntimeError(f"yade failed (exit {done.returncode}):\n{tail}")
    result = json.loads(Path(settings["output_path"]).read_text())
    return result, np.loadtxt(settings["positions_out"], ndmin=2)


def _our_permeability(positions: np.ndarray) -> dict:
    """Water k_x of the homogeneous frozen specimen at S(s_0) and at S = 1 [m2]."""
    material = DEFAULT_CLAY
    mesh = build_mesh(positions)
    porosity = np.full(mesh.n_cells, material.reference_porosity)
    states = {
        "equilibrium": saturation(
            np.full(mesh.n_cells, material.initial_suction), porosity, material
        ),
        "saturated": np.full(mesh.n_cells, material.saturated_saturation),
    }
    result = {}
    for name, water in states.items():
        k = permeability_tensor_axes(mesh, water, porosity, material.initial_suction, material)
        result[name] = {
            "k_x_m2": k["water"]["x"],
            "k_water_m2": k["water"],
            "saturation": float(water[0]),
        }
    result["n_cells"] = mesh.n_cells
    return result


def _remesh_extras_s(positions: np.ndarray, radii: np.ndarray) -> dict:
    """Remesh costs outside ``bench_flow``: sector weights and the cell-state transfer."""
    material = DEFAULT_CLAY
    old = build_mesh(positions)
    moved = positions + np.random.default_rng(1).uniform(-1e-3, 1e-3, positions.shape) * (
        radii[:, None]
    )
    new = build_mesh(moved)
    porosity = np.full(old.n_cells, material.reference_porosity)
    water = np.full(old.n_cells, 0.5)
    pressure = np.full(old.n_cells, -material.initial_suction)
    # one untimed call each, so that numba compilation is not counted
    sector_weights(new, moved, radii)
    transfer_cell_state(old, new, pressure, water, porosity, material)
    start = time.perf_counter()
    sector_weights(new, moved, radii)
    weights = time.perf_counter() - start
    start = time.perf_counter()
    transfer_cell_state(old, new, pressure, water, porosity, material)
    transfer = time.perf_counter() - start
    return {"sector_weights_s": weights, "transfer_cell_state_s": transfer}


def _our_timings(n_points: int, positions: np.ndarray, radii: np.ndarray) -> dict:
    """Our coupled iteration and remesh costs, composed from the other benchmarks [s]."""
    dem = bench_dem(n_points, seed=SEED)
    flow = bench_flow(n_points)
    extras = _remesh_extras_s(positions, radii)
    dem_step = 1e-3 * (dem["step_ms"] + dem["hydro_forces_ms"] + dem["point_suction_ms"])
    return {
        "coupled_iteration_s": dem_step + flow["coupled_flow_step_s"],
        "coupled_split_s": {
            "dem_step": 1e-3 * dem["step_ms"],
            "hydro_forces": 1e-3 * dem["hydro_forces_ms"],
            "point_suction": 1e-3 * dem["point_suction_ms"],
            "flow_step": flow["coupled_flow_step_s"],
        },
        "remesh_s": flow["remesh_step_s"] + sum(extras.values()),
        "remesh_split_s": dict(bench_flow_remesh_step=flow["remesh_step_s"], **extras),
        "dem": dem,
        "flow": flow,
    }


def bench_yade_compare(n_points: int = 1500, timeout: float = 3600.0) -> dict:
    """Time both codes on the same cube and compare their water permeability along x.

    Parameters
    ----------
    n_points
        Requested number of points (the grid has round(n^(1/3))^3).
    timeout
        Seconds allowed for the Yade run before it is killed.

    Returns
    -------
    dict
        ``{"skipped": "yade not installed"}`` without a ``yade`` executable; else
        ``n_points``, ``yade`` (its JSON: equilibration, permeability, coupled and
        remesh timings), ``ours`` (timings and permeability), and ``ratios``
        (ours / Yade): ``coupled_iteration``, ``remesh``, and ``k_x_equilibrium``,
        ``k_x_saturated``, each against Yade's k_x per the spheres' box, per the
        centres' box, and from its interior gradient.
    """
    if shutil.which("yade") is None:
        return {"skipped": "yade not installed"}
    positions, radii = cube_points(
        n_points, np.random.default_rng(SEED), jitter=JITTER, radius_factor=RADIUS_FACTOR
    )
    with tempfile.TemporaryDirectory(prefix="yade_compare_") as folder:
        yade, equilibrated = _run_yade_side(positions, radii, Path(folder), timeout)
    ours = _our_timings(n_points, positions, radii)
    ours["permeability"] = _our_permeability(equilibrated)
    ratios = {
        "coupled_iteration": ours["coupled_iteration_s"] / yade["coupled"]["per_iteration_s"],
        "remesh": ours["remesh_s"] / yade["remesh"]["remesh_s"],
    }
    for state, theirs in yade["permeability"].items():
        k_ours = ours["permeability"][state]["k_x_m2"]
        ratios[f"k_x_{state}"] = {
            "sphere_box": k_ours / theirs["sphere_box"]["k_x_m2"],
            "centre_box": k_ours / theirs["centre_box"]["k_x_m2"],
            "interior": k_ours / theirs["k_x_interior_m2"],
        }
    return {"n_points": int(positions.shape[0]), "yade": yade, "ours": ours, "ratios": ratios}


def main(argv: list[str] | None = None) -> None:
    """Run each requested size, print its ratios, write ``yade_compare_<N>.json``."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("sizes", nargs="*", type=int, default=[1500, 15000])
    parser.add_argument("--timeout", type=float, default=3600.0, help="Yade run limit [s]")
    arguments = parser.parse_args(argv)
    for size in arguments.sizes:
        result = bench_yade_compare(size, arguments.timeout)
        if "skipped" in result:
            print(json.dumps(result))
            return
        OUT.mkdir(parents=True, exist_ok=True)
        (OUT / f"yade_compare_{size}.json").write_text(json.dumps(result, indent=1))
        print(json.dumps({"n_points": result["n_points"], "ratios": result["ratios"]}))


if __name__ == "__main__":
    main()
