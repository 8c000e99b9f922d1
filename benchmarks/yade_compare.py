"""Side-by-side benchmark against Yade 2023.02a's PartialSatClayEngine.

Both codes get the same points: a jittered grid from :func:`shared.dem.points.cube_points`
with the seed, jitter and radius factor of :mod:`benchmarks.dem`. The Yade side is
``benchmarks/yade/partialsat_cube.py``, run headless in a subprocess of its own session
(killed as a group when it ends or times out); its parameters come from the settings
JSON written here from the default configuration (:mod:`benchmarks.parameters`).
Compared (ratio = ours / Yade's): a coupled iteration with a reused factor, a remesh,
the water permeability along x of the homogeneous specimen (wall flux, docs/yade.md
§10) and the permeability curve k_x(S) at :data:`CURVE_SUCTIONS_PA`. What each side
times and reads: docs/performance.md, "benchmarks.yade_compare".
Timings (medians and fastest of repeated calls, with the load average) are never
asserted. Run ``python -m benchmarks.yade_compare [N ...]`` to write
``results/benchmarks/yade_compare_<N>.json`` and ``yade_compare_<N>.png``.
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
import threading
import time
from collections import deque
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from scipy.spatial import Delaunay

from benchmarks.dem import bench_dem
from benchmarks.flow import bench_flow
from benchmarks.parameters import CLAY, DEM
from micro.permeability import FrozenState, axis_permeabilities, measure_permeability
from shared.dem.points import cube_points
from shared.fv import facet_conductance, transfer_cell_state
from shared.mesh import Mesh, build_mesh
from shared.retention import saturation

__all__ = ["bench_yade_compare", "plot_curve", "yade_gradient_factor"]

YADE_SCRIPT = Path(__file__).with_name("yade") / "partialsat_cube.py"
OUT = Path("results/benchmarks")
# The point set of benchmarks.dem.bench_dem (seed 0, jitter 0.2, radius factor 1.02).
SEED = 0
JITTER = 0.2
RADIUS_FACTOR = 1.02
# Appendix .2 prints a truncated friction angle; our Hertz-Mindlin has no sliding
# limit, which a steep friction angle approaches.
FRICTION_ANGLE_DEG = 80.0
FLOW_REPEATS = 3
# Suctions of the permeability curve [Pa]: the initial suction of Table 3.1 down to
# near saturation; 0 stands for full saturation.
CURVE_SUCTIONS_PA = (132e6, 60e6, 20e6, 5e6, 1e6, 0.3e6, 0.1e6, 0.0)
# Yade's default conductance clamp (FlowEngine minKdivKmean, maxKdivKmean).
CLAMP = (1e-4, 1e2)
# Pressure drop of the permeability measurements, as a fraction of the suction.
DROP_FRACTION = 0.1
# Yade's warning for a boundary cell whose volume minus its solid parts is negative.
NEGATIVE_VOLUME = "negative volume for an ordinary pore"


def _run_settings(n_points: int) -> dict:
    """Run lengths of the Yade side, scaled so that each size takes minutes.

    Thesis Appendix .2 equilibrates in chunks of 400 iterations until the unbalanced
    force ratio is below 0.05; chunks of 200 stop closer to the threshold, and the
    budget (about 6e6 point-iterations, a few minutes at any size) stops large
    specimens before it.
    """
    return {
        "equilibration_chunk": 200,
        "max_equilibration_iterations": max(400, int(6e6 / n_points)),
        "unbalanced_force_threshold": 0.05,
        "drop_fraction": DROP_FRACTION,
        "warmup_iterations": 3,
        "coupled_iterations": max(20, int(3e5 / n_points)),
        "remesh_steps": 4,
    }


def _kill_group(pid: int) -> None:
    """End a process group (Yade and any helper holding its ports), if still there."""
    try:
        os.killpg(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def _run_yade(settings_path: Path, timeout: float) -> tuple[int, int, str]:
    """Run the Yade script headless on one thread, in a session of its own.

    The engine prints a warning line per degenerate boundary cell and step, millions
    of lines on large specimens: they are counted while reading, not stored. The
    whole process group is killed on exit or timeout, so nothing keeps its ports.

    Returns
    -------
    tuple
        Exit status, number of ``NEGATIVE_VOLUME`` warnings, and the last 30 other
        output lines.

    Raises
    ------
    subprocess.TimeoutExpired
        If Yade was still running after ``timeout`` seconds (it is killed then).
    """
    command = ["yade", "-x", "-n", "-j1", str(YADE_SCRIPT), str(settings_path)]
    environment = dict(os.environ, OMP_NUM_THREADS="1")
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True, env=environment, cwd=settings_path.parent,
    )
    killer = threading.Timer(timeout, _kill_group, (process.pid,))
    killer.start()
    start = time.perf_counter()
    warnings = 0
    tail: deque[str] = deque(maxlen=30)
    try:
        assert process.stdout is not None
        for line in process.stdout:
            if NEGATIVE_VOLUME in line:
                warnings += 1
            else:
                tail.append(line)
        status = process.wait()
    finally:
        killer.cancel()
        _kill_group(process.pid)
        process.wait()
    if time.perf_counter() - start >= timeout:
        raise subprocess.TimeoutExpired(command, timeout, "".join(tail))
    return status, warnings, "".join(tail)


def _curve_points() -> list[dict[str, float]]:
    """Suction and van Genuchten saturation S(s, phi_0) of each curve point."""
    material = CLAY
    suctions = np.array(CURVE_SUCTIONS_PA)
    values = saturation(suctions, material.reference_porosity, material)
    return [
        {"suction_pa": float(s), "saturation": float(w)} for s, w in zip(suctions, values, strict=False)
    ]


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
        "clay": dataclasses.asdict(CLAY),
        "dem": dict(dataclasses.asdict(DEM), friction_angle_deg=FRICTION_ANGLE_DEG),
        "run": _run_settings(positions.shape[0]),
        "curve": _curve_points(),
    }
    settings_path = folder / "settings.json"
    settings_path.write_text(json.dumps(settings, indent=1))
    status, warnings, tail = _run_yade(settings_path, timeout)
    if status != 0 or not Path(settings["output_path"]).exists():
        raise RuntimeError(f"yade failed (exit {status}):\n{tail}")
    result = json.loads(Path(settings["output_path"]).read_text())
    result["negative_volume_warnings"] = warnings
    return result, np.loadtxt(settings["positions_out"], ndmin=2)


def _our_permeability(positions: np.ndarray) -> dict:
    """Water k_x of the homogeneous frozen specimen at S(s_0) and at S = 1 [m2]."""
    material = CLAY
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
        k = axis_permeabilities(FrozenState(mesh, water, porosity, material.initial_suction, material))
        result[name] = {
            "k_x_m2": k["water"]["x"],
            "k_water_m2": k["water"],
            "saturation": float(water[0]),
        }
    result["n_cells"] = mesh.n_cells
    result["curve"] = _our_curve(mesh, porosity)
    return result


def _our_curve(mesh: Mesh, porosity: np.ndarray) -> list[dict[str, float]]:
    """Water k_x at each curve point, as computed and with Yade's clamp emulated [m2].

    The wall pressures follow the Yade side (:func:`_curve_points`): -s -+ dP/2 with
    dP = 10 % of s, and for full saturation the drop of s_0 (a steady solve does not
    depend on the mean pressure).
    """
    material = CLAY
    rows = []
    for point in _curve_points():
        suction = point["suction_pa"]
        water = np.full(mesh.n_cells, point["saturation"])
        conductance = facet_conductance(mesh, water, porosity, "water", material)
        mean = float(conductance.mean())
        clamped = np.clip(conductance, CLAMP[0] * mean, CLAMP[1] * mean)
        drop = DROP_FRACTION * (suction if suction > 0.0 else material.initial_suction)
        values = {
            name: measure_permeability(
                mesh, g, material.water_viscosity, 0,
                mean_pressure=-suction if suction > 0.0 else drop, pressure_drop=drop,
            )
            for name, g in (("k_x_m2", conductance), ("k_x_clamped_m2", clamped))
        }
        rows.append(dict(point, **values, clamped_fraction=float(np.mean(clamped != conductance))))
    return rows


def yade_gradient_factor(
    positions: np.ndarray, fraction: float = 0.4, samples: int = 5
) -> dict[str, float]:
    """Bias of the Yade script's interior pressure gradient on these points [1].

    ``interior_gradient`` of the Yade script samples ``getPorePressure`` on a
    ``samples`` x ``samples`` grid of the inner half of two planes at x = centre -+
    ``fraction`` L / 2 of the centres' box. That call returns the pressure of the
    cell containing the point, which sits at the cell's dual point, not at the
    point; with equal radii Yade's regular triangulation is the Delaunay one, so
    for a linear field p = p_0 + g x the script measures g f with
    f = (mean dual x on the upper plane - mean on the lower) / (fraction L), and its
    interior permeability is the flux-based one divided by f.

    Returns
    -------
    dict
        ``factor`` f and the mean offsets of the sampled duals from each plane
        ``offset_lower_m``, ``offset_upper_m`` [m].
    """
    triangulation = Delaunay(positions)
    low, high = positions.min(axis=0), positions.max(axis=0)
    centre, size = 0.5 * (low + high), high - low
    offsets = (np.arange(samples) / (samples - 1) - 0.5) * 0.5
    means = []
    for side in (-0.5, 0.5):
        x = centre[0] + side * fraction * size[0]
        points = np.array([
            (x, centre[1] + u * size[1], centre[2] + w * size[2])
            for u in offsets for w in offsets
        ])
        corners = positions[triangulation.simplices[triangulation.find_simplex(points)]]
        edges = corners[:, 1:] - corners[:, :1]
        duals = corners[:, 0] + np.linalg.solve(
            edges, 0.5 * (edges**2).sum(axis=-1)[..., None]
        )[..., 0]
        means.append((float(duals[:, 0].mean()), x))
    (lower, x_lower), (upper, x_upper) = means
    return {
        "factor": float((upper - lower) / (fraction * size[0])),
        "offset_lower_m": lower - x_lower,
        "offset_upper_m": upper - x_upper,
    }


def _remesh_extras_s(positions: np.ndarray, radii: np.ndarray) -> dict:
    """Remesh cost outside ``bench_flow``: the cell-state transfer."""
    material = CLAY
    old = build_mesh(positions)
    moved = positions + np.random.default_rng(1).uniform(-1e-3, 1e-3, positions.shape) * (
        radii[:, None]
    )
    new = build_mesh(moved)
    porosity = np.full(old.n_cells, material.reference_porosity)
    water = np.full(old.n_cells, 0.5)
    pressure = np.full(old.n_cells, -material.initial_suction)
    # one untimed call, so that numba compilation is not counted
    transfer_cell_state(old, new, pressure, water, porosity, material)
    start = time.perf_counter()
    transfer_cell_state(old, new, pressure, water, porosity, material)
    return {"transfer_cell_state_s": time.perf_counter() - start}


def _our_timings(n_points: int, positions: np.ndarray, radii: np.ndarray) -> dict:
    """Our coupled iteration and remesh costs, composed from the other benchmarks [s].

    The flow step is timed at two pressure drifts since the last factorisation:
    ``balanced`` (1e-5, the hydraulic balance at which Yade is timed) and ``drifting``
    (2e-3, a step during hydration, where our solver corrects the stale factor by CG
    while Yade keeps solving its stale matrix). :func:`benchmarks.flow.bench_flow`
    times each phase once, so it runs ``FLOW_REPEATS`` times; medians are used, and
    the fastest runs (with the fastest DEM calls) for the idle-machine estimate.
    """
    dem = bench_dem(n_points, seed=SEED)
    flows = {
        name: [bench_flow(n_points, relative_drift=drift) for _ in range(FLOW_REPEATS)]
        for name, drift in (("balanced", 1e-5), ("drifting", 2e-3))
    }

    def flow_time(name: str, key: str, statistic=np.median) -> float:
        return float(statistic([run[key] for run in flows[name]]))

    extras = _remesh_extras_s(positions, radii)
    dem_split = {
        "dem_step": 1e-3 * dem["step_ms"],
        "hydro_forces": 1e-3 * dem["hydro_forces_ms"],
        "point_suction": 1e-3 * dem["point_suction_ms"],
    }
    dem_step = sum(dem_split.values())
    dem_step_min = 1e-3 * sum(
        dem[f"{phase}_min_ms"] for phase in ("step", "hydro_forces", "point_suction")
    )
    flow_step = flow_time("balanced", "coupled_flow_step_s")
    remesh = flow_time("balanced", "remesh_step_s")
    return {
        "coupled_iteration_s": dem_step + flow_step,
        "coupled_iteration_min_s": dem_step_min
        + flow_time("balanced", "coupled_flow_step_s", np.min),
        "coupled_iteration_drifting_s": dem_step + flow_time("drifting", "coupled_flow_step_s"),
        "coupled_split_s": dict(dem_split, flow_step=flow_step),
        "remesh_s": remesh + sum(extras.values()),
        "remesh_split_s": dict(bench_flow_remesh_step=remesh, **extras),
        "dem": dem,
        "flow": flows,
    }


def bench_yade_compare(
    n_points: int = 1500, timeout: float = 3600.0, figure: bool = True
) -> dict:
    """Time both codes on the same cube and compare their water permeability along x.

    Parameters
    ----------
    n_points
        Requested number of points (the grid has round(n^(1/3))^3).
    timeout
        Seconds allowed for the Yade run before it is killed.
    figure
        Write the permeability curves to ``results/benchmarks/yade_compare_<N>.png``
        (N as requested).

    Returns
    -------
    dict
        ``{"skipped": "yade not installed"}`` without a ``yade`` executable; else
        ``n_points``, ``load_average_1min`` (at start and end), ``yade`` (its JSON:
        equilibration, permeability, coupled and remesh timings), ``ours`` (timings
        and permeability), and ``ratios``
        (ours / Yade): ``coupled_iteration`` (medians; ``coupled_iteration_min``,
        fastest runs; ``coupled_iteration_drifting``, our median away from hydraulic
        balance), ``remesh``, and ``k_x_equilibrium``,
        ``k_x_saturated``, each against Yade's k_x per the spheres' box, per the
        centres' box, and from its interior gradient; ``curve``: one row per point of
        :data:`CURVE_SUCTIONS_PA` (see :func:`_curve_table`).
    """
    if shutil.which("yade") is None:
        return {"skipped": "yade not installed"}
    load_start = os.getloadavg()[0]
    positions, radii = cube_points(
        n_points, np.random.default_rng(SEED), jitter=JITTER, radius_factor=RADIUS_FACTOR
    )
    with tempfile.TemporaryDirectory(prefix="yade_compare_") as folder:
        yade, equilibrated = _run_yade_side(positions, radii, Path(folder), timeout)
    ours = _our_timings(n_points, positions, radii)
    ours["permeability"] = _our_permeability(equilibrated)
    gradient = yade_gradient_factor(equilibrated)
    ours["permeability"]["yade_gradient_factor"] = gradient
    ratios = {
        "coupled_iteration": ours["coupled_iteration_s"] / yade["coupled"]["per_iteration_s"],
        "coupled_iteration_min": ours["coupled_iteration_min_s"]
        / yade["coupled"]["per_iteration_min_s"],
        "coupled_iteration_drifting": ours["coupled_iteration_drifting_s"]
        / yade["coupled"]["per_iteration_s"],
        "remesh": ours["remesh_s"] / yade["remesh"]["remesh_s"],
    }
    for state, theirs in yade["permeability"].items():
        k_ours = ours["permeability"][state]["k_x_m2"]
        ratios[f"k_x_{state}"] = {
            "sphere_box": k_ours / theirs["sphere_box"]["k_x_m2"],
            "centre_box": k_ours / theirs["centre_box"]["k_x_m2"],
            "interior": k_ours / theirs["k_x_interior_m2"],
        }
    result = {
        "n_points": int(positions.shape[0]),
        # Wall-clock ratios on a shared machine: the load says how much to trust them.
        "load_average_1min": {"start": load_start, "end": os.getloadavg()[0]},
        "yade": yade,
        "ours": ours,
        "ratios": ratios,
        "curve": _curve_table(
            yade["permeability_curve"], ours["permeability"]["curve"], gradient["factor"]
        ),
    }
    if figure:
        plot_curve(result, OUT / f"yade_compare_{n_points}.png")
    return result


def _curve_table(
    theirs: list[dict], ours: list[dict], gradient_factor: float
) -> list[dict[str, float]]:
    """One row per curve point: suction, S, k of both codes and their ratios.

    Yade's wall flux Q crosses the whole meshed cross-section, whose flow
    boundaries sit on the spheres' box (``boundaryUseMaxMin``), and its interior
    gradient is read at cell duals (:func:`yade_gradient_factor`); so
    ``k_yade_m2`` = Q mu / (A_spheres g f) is the script's interior value times f
    A_centres / A_spheres: its bulk permeability, free of the wall cells'
    resistance. Also given: ``k_yade_interior_m2`` (the script's value, per
    centres' box, uncorrected), ``k_yade_centre_box_m2`` and ``k_yade_sphere_box_m2``
    (Q over the wall pressure drop, wall cells included), ``k_ours_clamped_m2``
    (ours with Yade's default clamp). Ratios are ours / the Yade value named.
    """
    rows = []
    for yade, mine in zip(theirs, ours, strict=True):
        area_ratio = yade["centre_box"]["area_m2"] / yade["sphere_box"]["area_m2"]
        k_yade = yade["k_x_interior_m2"] * gradient_factor * area_ratio
        k_ours = mine["k_x_m2"]
        rows.append({
            "suction_pa": mine["suction_pa"],
            "saturation": mine["saturation"],
            "k_yade_m2": k_yade,
            "k_yade_interior_m2": yade["k_x_interior_m2"],
            "k_yade_centre_box_m2": yade["centre_box"]["k_x_m2"],
            "k_yade_sphere_box_m2": yade["sphere_box"]["k_x_m2"],
            "k_ours_m2": k_ours,
            "k_ours_clamped_m2": mine["k_x_clamped_m2"],
            "ratio": k_ours / k_yade,
            "ratio_interior": k_ours / yade["k_x_interior_m2"],
            "ratio_centre_box": k_ours / yade["centre_box"]["k_x_m2"],
            "ratio_sphere_box": k_ours / yade["sphere_box"]["k_x_m2"],
            "ratio_clamped": mine["k_x_clamped_m2"] / k_yade,
        })
    return rows


def plot_curve(result: dict, path: Path) -> None:
    """Figure of k_x against S for both codes (log k), k_0 Se^n, and their ratios."""
    rows = result["curve"]
    water = np.array([r["saturation"] for r in rows])
    figure = Figure(figsize=(6.5, 6.4))
    axes, lower = figure.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": (3, 1)})
    series = (
        ("k_yade_m2", "o-", "Yade, bulk (interior gradient, corrected)"),
        ("k_yade_interior_m2", "^-.", "Yade, interior gradient as sampled"),
        ("k_yade_centre_box_m2", "v:", "Yade, wall drop (centres' box)"),
        ("k_ours_m2", "s--", "ours, wall flux"),
        ("k_ours_clamped_m2", "x", "ours, Yade's clamp emulated"),
    )
    for key, style, label in series:
        axes.semilogy(water, [r[key] for r in rows], style, label=label)
    material = CLAY
    grid = np.linspace(water.min(), water.max(), 100)
    effective = (grid - material.residual_saturation) / (
        material.saturated_saturation - material.residual_saturation
    )
    axes.semilogy(
        grid,
        material.intrinsic_permeability_reference
        * effective ** material.relative_permeability_exponent,
        "k:", lw=0.8, label="k_0 Se^n (input)",
    )
    for row in rows:
        text = "sat." if row["suction_pa"] == 0 else f"{row['suction_pa'] / 1e6:g} MPa"
        axes.annotate(text, (row["saturation"], row["k_yade_m2"]), fontsize=6,
                      textcoords="offset points", xytext=(3, -9))
    for key, style, label in (
        ("ratio", "o-", "ours / Yade bulk"),
        ("ratio_interior", "^-.", "ours / Yade interior as sampled"),
        ("ratio_centre_box", "v:", "ours / Yade wall drop (centres' box)"),
    ):
        lower.plot(water, [r[key] for r in rows], style, label=label)
    lower.set_xlabel("water saturation S [1]")
    lower.set_ylabel("k ratio [1]")
    lower.grid(True, alpha=0.3)
    lower.legend(fontsize=7)
    axes.set_ylabel("water permeability k_x [m2]")
    axes.set_title(
        f"Homogeneous cube, {result['n_points']} points, phi_0 = "
        f"{material.reference_porosity:g}, frozen Yade-equilibrated positions",
        fontsize=9,
    )
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=7)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.tight_layout()
    figure.savefig(path, dpi=120)


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
        for row in result["curve"]:
            print(
                f"s = {row['suction_pa']:9.3g} Pa  S = {row['saturation']:.4f}  "
                f"k_yade = {row['k_yade_m2']:.4g}  k_ours = {row['k_ours_m2']:.4g}  "
                f"ratio = {row['ratio']:.4f}  (interior {row['ratio_interior']:.4f}, "
                f"centre box {row['ratio_centre_box']:.4f}, "
                f"clamped {row['ratio_clamped']:.4f})"
            )


if __name__ == "__main__":
    main()
