"""Benchmark cases of the sequential deposition (Ferrage et al. 2015).

- :func:`bench_deposition`: Table II series 2 (monodisperse disks of aspect ratio 0.1,
  2500 disks), its cost per particle against the bed;
- :func:`bench_deposition_cost`: the cost per particle against the particles already in
  the bed; ``deposition_cost.{json,png}``;
- :func:`bench_deposition_axis_ratio`: Fig. 7 analogue, porosity vs l_a / l_b at
  reduced N; ``deposition_axis_ratio.{json,png}``;
- :func:`bench_deposition_freedom`: Fig. 4 / 6a analogue, porosity vs S_part over a grid
  of deposition freedom at reduced N; ``deposition_freedom.{json,png}``.

Reduced-N sweeps keep the Table II bed height (w = 7.5 d sqrt(N / 2500)); porosity and
S_part are those of the linear zone, without the voxel image. The cases in full:
docs/performance.md, "benchmarks.deposition".
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)
import numpy as np  # noqa: E402
import numpy.typing as npt  # noqa: E402

from imaging.packing import (  # noqa: E402
    DepositionParameters,
    Packing,
    Population,
    deposit,
    sample_semi_axes,
)
from imaging.packing.analysis import (  # noqa: E402
    legendre_order,
    linear_zone,
    porosity_profile,
    profile_edges,
    zone_porosity,
)
from shared.figures import save_figure  # noqa: E402

DIAMETER = 1.0e-6
OUT = Path("results/benchmarks")

#: Table II of the paper: (theta_max [deg], theta_ini random in (0, theta_max),
#: A_slide [d], A_swiv = A_rot [deg]).
SERIES: dict[int, tuple[float, bool, float, float]] = {
    1: (90.0, True, 1.0 / 7.0, 10.0),
    2: (90.0, True, 5.0, 80.0),
    3: (0.0, False, 5.0, 80.0),
}

#: l_a / l_b of the Fig. 7 sweep.
AXIS_RATIOS = (1.0, 1.25, 1.5, 2.0, 3.0)
#: Seeds per series of the Fig. 7 sweep: series 1 (low freedom) varies most between seeds.
AXIS_RATIO_SEEDS = {1: 2, 2: 1, 3: 1}

#: Deposition freedom grid of the Fig. 4a sweep (theta_ini random in (0, 90 deg)):
#: A_swiv [deg] x A_slide [d], from the paper's smallest (5 deg, d / 60) to Table II
#: series 2 (80 deg, 5 d).
SWIVELS = (5.0, 10.0, 40.0, 80.0)
SLIDES = (1.0 / 60.0, 1.0 / 7.0, 5.0)
#: Fig. 4b points: (theta_max [deg], random, A_slide [d], A_swiv [deg]), low and high
#: freedom with a fixed entry angle.
ENTRY_CASES = (
    (90.0, False, 1.0 / 7.0, 10.0),
    (45.0, False, 1.0 / 7.0, 10.0),
    (0.0, False, 1.0 / 7.0, 10.0),
)


def _parameters(attempts_per_cycle: int = 800) -> DepositionParameters:
    return DepositionParameters(
        box_width=7.5 * DIAMETER, contact_distance=5e-4 * DIAMETER, theta_max=np.pi / 2,
        theta_random=True, slide_amplitude=5 * DIAMETER, swivel_amplitude=np.radians(80),
        rotation_amplitude=np.radians(80), attempts_per_cycle=attempts_per_cycle,
        log_interval=60.0)


def _warm_up() -> None:
    """Compile (or load) the kernels outside the timed runs."""
    population = Population(basal_surface_median=np.pi / 4 * DIAMETER**2, aspect_ratio_median=0.1,
                            axis_ratio_median=1.5)
    warm = np.random.default_rng(1)
    deposit(sample_semi_axes(population, 3, warm), _parameters(10), warm)


def bench_deposition(n_particles: int = 500) -> dict:
    """Deposit ``n_particles`` Table II disks; report particles/s and the cost per particle
    over successive tenths of the bed.

    Returns
    -------
    dict
        ``particles_per_second``, ``total_s``, ``cost_per_particle_s`` (mean wall time per
        particle in each tenth of the deposition order), ``cost_growth`` (last tenth over
        second tenth; the first tenth lands on the floor, which is cheaper),
        ``projected_table2_s`` (2500 particles at the measured late cost), bed height and
        order parameter.
    """
    result, _ = _series2_run(n_particles)
    return result


def _series2_run(n_particles: int) -> tuple[dict, Packing]:
    population = Population(basal_surface_median=np.pi / 4 * DIAMETER**2, aspect_ratio_median=0.1)
    _warm_up()
    rng = np.random.default_rng(0)
    semi_axes = sample_semi_axes(population, n_particles, rng)
    start = time.perf_counter()
    packing = deposit(semi_axes, _parameters(), rng)
    total = time.perf_counter() - start
    tenths = np.array_split(packing.wall_time, 10)
    cost = [float(np.mean(t)) for t in tenths if t.size]
    return {
        "n_particles": n_particles,
        "total_s": total,
        "particles_per_second": n_particles / total,
        "cost_per_particle_s": cost,
        "cost_growth": cost[-1] / cost[1] if len(cost) > 2 else float("nan"),
        "projected_table2_s": 2500 * cost[-1],
        "accepted_moves_mean": float(packing.accepted_moves.mean()),
        "bed_height_diameters": float(packing.centers[:, 2].max() / DIAMETER),
        "S_part": legendre_order(packing.normals),
    }, packing


# --- cost per particle as the bed grows ----------------------------------------------------

#: Where earlier packing files (with their ``settle_time``) are looked for.
STORED_PACKINGS = (Path("results/packing"), OUT / "deposition_validation")


def cost_curve(wall_time: npt.ArrayLike, n_bins: int = 20) -> dict[str, list[float]]:
    """Mean, median and 90th percentile of the settling time per particle over ``n_bins``
    equal blocks of the deposition order.

    Parameters
    ----------
    wall_time : array_like, shape (n,)
        Settling wall time of each particle, in order of deposition [s].
    n_bins : int

    Returns
    -------
    dict
        ``in_bed`` (particles already in the bed at the middle of each block), ``mean_s``,
        ``median_s``, ``p90_s`` [s], ``growth`` (mean of the last block over the mean of
        the blocks 2-3, the first landing on the floor) and ``late_growth`` (last block
        over the middle one: the cost rises while the bed surface roughens, then should
        stay flat).
    """
    wall = np.asarray(wall_time, dtype=np.float64)
    blocks = np.array_split(np.arange(wall.size), min(n_bins, wall.size))
    mean = [float(wall[b].mean()) for b in blocks]
    early = float(np.mean(mean[1:3])) if len(mean) > 3 else mean[0]
    return {
        "in_bed": [float(b.mean()) for b in blocks],
        "mean_s": mean,
        "median_s": [float(np.median(wall[b])) for b in blocks],
        "p90_s": [float(np.quantile(wall[b], 0.9)) for b in blocks],
        "growth": mean[-1] / early,
        "late_growth": mean[-1] / mean[len(mean) // 2],
    }


def _stored_curves() -> dict[str, dict[str, Any]]:
    """Cost curves of the full-scale packing files found in :data:`STORED_PACKINGS`."""
    import xarray as xr

    curves = {}
    for directory in STORED_PACKINGS:
        for path in sorted(directory.glob("*.nc")):
            if path.stem.endswith(("_s0.2", "_s0.1")):
                continue
            with xr.open_dataset(path) as ds:
                if "settle_time" not in ds:
                    continue
                wall = ds["settle_time"].values
            curves[path.stem] = {"file": str(path), "n_particles": int(wall.size),
                                 "total_s": float(wall.sum()), **cost_curve(wall)}
    return curves


def bench_deposition_cost(n_particles: int = 2500) -> dict:
    """Cost per particle against the particles already in the bed: Table II series 2 run
    here (``n_particles`` disks), plus every stored full-scale packing file's settling times.
    Writes ``results/benchmarks/deposition_cost.{json,png}``.

    Returns
    -------
    dict
        ``series2`` (:func:`bench_deposition`'s result with its :func:`cost_curve`) and
        ``stored`` (name -> cost curve of a stored file).
    """
    result, packing = _series2_run(n_particles)
    result.update(cost_curve(packing.wall_time))
    out = {"series2": result, "stored": _stored_curves()}
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "deposition_cost.json").write_text(json.dumps(out, indent=2))
    cost_figure(out, OUT / "deposition_cost.png")
    return out


def cost_figure(result: Mapping[str, Any], path: Path) -> Path:
    """Cost per particle [ms] against particles in the bed; one panel for series 2 (mean,
    median, 90th percentile), one for every stored run's mean normalised by its own
    overall mean."""
    fig, (left, right) = plt.subplots(1, 2, figsize=(10.0, 4.0))
    s2 = result["series2"]
    for key, style in (("mean_s", "o-"), ("median_s", "s--"), ("p90_s", "^:")):
        left.plot(s2["in_bed"], 1e3 * np.asarray(s2[key]), style, ms=3,
                  label=key.removesuffix("_s"))
    left.set_ylim(bottom=0.0)
    left.set_xlabel("particles already in the bed")
    left.set_ylabel("settling time per particle [ms]")
    left.set_title(f"Table II series 2, N = {s2['n_particles']} "
                   f"({s2['particles_per_second']:.1f} particles/s)", fontsize=9)
    left.legend(fontsize=8)
    for name, curve in result["stored"].items():
        mean = np.asarray(curve["mean_s"])
        overall = curve["total_s"] / curve["n_particles"]
        right.plot(curve["in_bed"], mean / overall, "o-", ms=3,
                   label=f"{name} (N = {curve['n_particles']}, {1e3 * overall:.0f} ms)")
    right.axhline(1.0, color="0.6", lw=0.8)
    right.set_ylim(0.0, 2.0)
    right.set_xlabel("particles already in the bed")
    right.set_ylabel("cost per particle / run mean")
    right.set_title("stored packing files (settle_time)", fontsize=9)
    right.legend(fontsize=6)
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)


# --- reduced-N sweeps of the paper's Figs. 4, 6a and 7 -------------------------------------


def reduced_box(n_particles: int) -> float:
    """Box width [m] holding ``n_particles`` at the Table II particles per floor area."""
    return 7.5 * DIAMETER * math.sqrt(n_particles / 2500.0)


def sweep_run(n_particles: int, theta_max_deg: float, theta_random: bool, slide_d: float,
              swivel_deg: float, axis_ratio: float = 1.0, seed: int = 0,
              scan_points: int = 0, **options: Any) -> dict[str, Any]:
    """Deposit monodisperse R = 0.1 disks of equivalent diameter d = 1 um and measure the
    linear zone.

    Parameters
    ----------
    n_particles : int
    theta_max_deg : float
        theta_max [deg].
    theta_random : bool
        theta_ini uniform in (0, theta_max), else theta_ini = theta_max.
    slide_d : float
        A_slide in units of d.
    swivel_deg : float
        A_swiv = A_rot [deg].
    axis_ratio : float
        l_a / l_b.
    seed : int
    scan_points : int
        n_sp of the paper's contact scan; 0: exact contacts.
    **options
        Other fields of :class:`DepositionParameters` (readings of the moves, cycles).

    Returns
    -------
    dict
        The settings, ``box_width_m``, ``porosity``, ``S_part`` (linear zone),
        ``z_min_d``, ``z_max_d`` (in d), ``n_zone`` and ``deposition_s``.
    """
    population = Population(basal_surface_median=np.pi / 4 * DIAMETER**2, aspect_ratio_median=0.1,
                            axis_ratio_median=axis_ratio)
    rng = np.random.default_rng([seed, 3])
    semi_axes = sample_semi_axes(population, n_particles, rng)
    width = reduced_box(n_particles)
    params = DepositionParameters(
        box_width=width, contact_distance=5e-4 * DIAMETER, theta_max=math.radians(theta_max_deg),
        theta_random=theta_random, slide_amplitude=slide_d * DIAMETER,
        swivel_amplitude=math.radians(swivel_deg), rotation_amplitude=math.radians(swivel_deg),
        log_interval=600.0, scan_points=scan_points, **options)
    start = time.perf_counter()
    bed = deposit(semi_axes, params, rng)
    elapsed = time.perf_counter() - start
    z = bed.centers[:, 2]
    edges = profile_edges(float(z.max()), 0.5 * DIAMETER)
    low, high = linear_zone(edges, porosity_profile(z, bed.volumes, width, edges))
    zone = (z > low) & (z <= high)
    return {
        "n_particles": n_particles, "box_width_m": width, "axis_ratio": axis_ratio,
        "theta_max_deg": theta_max_deg, "theta_random": theta_random, "slide_d": slide_d,
        "swivel_deg": swivel_deg, "seed": seed, "scan_points": scan_points,
        "porosity": zone_porosity(z, bed.volumes, width, low, high),
        "S_part": legendre_order(bed.normals[zone]),
        "z_min_d": low / DIAMETER, "z_max_d": high / DIAMETER, "n_zone": int(zone.sum()),
        "deposition_s": elapsed,
    }


def bench_deposition_axis_ratio(n_particles: int = 400,
                                seeds: int | Mapping[int, int] | None = None,
                                scan_points: int = 0) -> dict:
    """Fig. 7 analogue: porosity vs l_a / l_b in :data:`AXIS_RATIOS` for the three Table II
    series, ``n_particles`` per run in a box of 7.5 d sqrt(N / 2500), ``seeds`` runs per
    point (an int for every series, or per series; default :data:`AXIS_RATIO_SEEDS`), exact
    contacts or (``scan_points`` > 0) the paper's scan.
    Writes ``results/benchmarks/deposition_axis_ratio[_scan].{json,png}``.

    Returns
    -------
    dict
        ``rows`` (:func:`sweep_run` results, with ``series``), ``n_particles``,
        ``box_width_m``, ``total_s``.
    """
    _warm_up()
    start = time.perf_counter()
    rows = []
    if seeds is None:
        seeds = AXIS_RATIO_SEEDS
    if isinstance(seeds, int):
        seeds = dict.fromkeys(SERIES, seeds)
    for series, (theta, random, slide, swivel) in SERIES.items():
        for ratio in AXIS_RATIOS:
            for seed in range(seeds[series]):
                row = sweep_run(n_particles, theta, random, slide, swivel, ratio, seed, scan_points)
                rows.append({"series": series, **row})
    out = {"n_particles": n_particles, "box_width_m": reduced_box(n_particles), "rows": rows,
           "total_s": time.perf_counter() - start}
    OUT.mkdir(parents=True, exist_ok=True)
    stem = "deposition_axis_ratio" + ("_scan" if scan_points else "")
    (OUT / f"{stem}.json").write_text(json.dumps(out, indent=2))
    axis_ratio_figure(out, OUT / f"{stem}.png")
    return out


def bench_deposition_axis_ratio_scan(n_particles: int = 400) -> dict:
    """:func:`bench_deposition_axis_ratio` with the paper's contact scan, n_sp = 150."""
    return bench_deposition_axis_ratio(n_particles, scan_points=150)


#: Parts of the algorithm varied one at a time by :func:`bench_deposition_sensitivity`:
#: (label, scan_points, DepositionParameters fields).
SENSITIVITY_VARIANTS: tuple[tuple[str, int, dict[str, Any]], ...] = (
    ("exact contacts (reference)", 0, {}),
    ("scan, n_sp = 150", 150, {}),
    ("scan, n_sp = 500", 500, {}),
    ("two-contact swivel about a horizontal axis", 0, {"contact_line_swivel": False}),
    ("slides in random directions", 0, {"steepest_slide": False}),
    ("swivels about random horizontal axes", 0, {"steepest_swivel": False}),
    ("one cycle of 800 attempts", 0, {"n_cycles": 1}),
    ("3 cycles of 200 attempts", 0, {"attempts_per_cycle": 200}),
)


def bench_deposition_sensitivity(n_particles: int = 400) -> dict:
    """Which part of the algorithm moves porosity and S_part most: the Table II series 1
    and 2 (low and high freedom) with each of :data:`SENSITIVITY_VARIANTS`, ``n_particles``
    monodisperse R = 0.1 disks, one seed. Writes ``results/benchmarks/deposition_sensitivity.json``
    and a markdown table ``deposition_sensitivity.md``.

    Returns
    -------
    dict
        ``rows`` (:func:`sweep_run` results with ``series`` and ``variant``),
        ``n_particles``, ``total_s``.
    """
    _warm_up()
    start = time.perf_counter()
    rows = []
    for series in (1, 2):
        for label, scan_points, options in SENSITIVITY_VARIANTS:
            row = sweep_run(n_particles, *SERIES[series], scan_points=scan_points, **options)
            rows.append({"series": series, "variant": label, **row})
    out = {"n_particles": n_particles, "rows": rows, "total_s": time.perf_counter() - start}
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "deposition_sensitivity.json").write_text(json.dumps(out, indent=2))
    (OUT / "deposition_sensitivity.md").write_text(sensitivity_markdown(out))
    return out


def sensitivity_markdown(result: Mapping[str, Any]) -> str:
    """The sensitivity table: porosity and S_part per variant, change from the reference."""
    lines = [f"# Deposition: sensitivity to the parts of the algorithm (N = {result['n_particles']}, "
             "one seed)", "",
             "| variant | series 1 porosity | S_part | series 2 porosity | S_part |",
             "|---|---|---|---|---|"]
    rows = result["rows"]
    reference = {r["series"]: r for r in rows if r["variant"] == SENSITIVITY_VARIANTS[0][0]}
    for label, _, _ in SENSITIVITY_VARIANTS:
        cells = []
        for series in (1, 2):
            row = next(r for r in rows if r["series"] == series and r["variant"] == label)
            base = reference[series]
            cells.append(f"{row['porosity']:.3f} ({row['porosity'] - base['porosity']:+.3f}) | "
                         f"{row['S_part']:.2f} ({row['S_part'] - base['S_part']:+.2f})")
        lines.append(f"| {label} | {cells[0]} | {cells[1]} |")
    return "\n".join(lines) + "\n"


def axis_ratio_figure(result: Mapping[str, Any], path: Path) -> Path:
    """Porosity vs l_a / l_b per series (mean over seeds, each seed as a dot)."""
    fig, ax = plt.subplots(figsize=(5.5, 4.0))
    rows = result["rows"]
    for series in SERIES:
        mine = [r for r in rows if r["series"] == series]
        ratios = sorted({r["axis_ratio"] for r in mine})
        mean = [np.mean([r["porosity"] for r in mine if r["axis_ratio"] == e]) for e in ratios]
        ax.plot(ratios, mean, "o-", color=f"C{series - 1}", label=f"series {series}")
        ax.plot([r["axis_ratio"] for r in mine], [r["porosity"] for r in mine], ".",
                color=f"C{series - 1}", alpha=0.5)
    ax.axvline(1.5, color="0.7", ls=":", lw=1)
    ax.set_xlabel("$\\ell_a / \\ell_b$")
    ax.set_ylabel("porosity $\\epsilon$ of the linear zone")
    ax.set_title(f"Fig. 7 analogue: R = 0.1, N = {result['n_particles']}, "
                 f"w = {result['box_width_m'] / DIAMETER:.2f} d", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)


def freedom_cases() -> list[tuple[float, bool, float, float]]:
    """(theta_max [deg], random, A_slide [d], A_swiv [deg]) of the freedom sweep: the
    A_swiv x A_slide grid with theta_ini random in (0, 90 deg), then :data:`ENTRY_CASES`."""
    grid = [(90.0, True, slide, swivel) for swivel in SWIVELS for slide in SLIDES]
    return grid + list(ENTRY_CASES)


def bench_deposition_freedom(n_particles: int = 400,
                             cases: Iterable[tuple[float, bool, float, float]] | None = None,
                             scan_points: int = 0) -> dict:
    """Fig. 4 / 6a analogue: porosity and S_part over a grid of deposition freedom
    (:func:`freedom_cases`) at ``n_particles`` monodisperse R = 0.1 disks, exact contacts
    or (``scan_points`` > 0) the paper's scan. Writes
    ``results/benchmarks/deposition_freedom[_scan].{json,png}``.

    Returns
    -------
    dict
        ``rows`` (:func:`sweep_run` results), ``n_particles``, ``box_width_m``, ``total_s``.
    """
    _warm_up()
    start = time.perf_counter()
    rows = [sweep_run(n_particles, *case, scan_points=scan_points) for case in (cases or freedom_cases())]
    out = {"n_particles": n_particles, "box_width_m": reduced_box(n_particles), "rows": rows,
           "total_s": time.perf_counter() - start}
    OUT.mkdir(parents=True, exist_ok=True)
    stem = "deposition_freedom" + ("_scan" if scan_points else "")
    (OUT / f"{stem}.json").write_text(json.dumps(out, indent=2))
    freedom_figure(out, OUT / f"{stem}.png")
    return out


def bench_deposition_freedom_scan(n_particles: int = 400) -> dict:
    """:func:`bench_deposition_freedom` with the paper's contact scan, n_sp = 150 (Table III)."""
    return bench_deposition_freedom(n_particles, scan_points=150)


def _freedom_label(row: Mapping[str, Any]) -> str:
    slide = row["slide_d"]
    slide_text = f"d/{1.0 / slide:.0f}" if slide < 1.0 else f"{slide:g}d"
    entry = "" if row["theta_random"] else f", th={row['theta_max_deg']:g}"
    return f"{row['swivel_deg']:g}deg,{slide_text}{entry}"


def freedom_figure(result: Mapping[str, Any], path: Path) -> Path:
    """Left: porosity vs A_slide per A_swiv (Fig. 4a); right: porosity vs S_part of every
    run (Fig. 6a)."""
    fig, (left, right) = plt.subplots(1, 2, figsize=(11.0, 4.2))
    rows = result["rows"]
    grid = [r for r in rows if r["theta_random"] and r["theta_max_deg"] == 90.0]
    for k, swivel in enumerate(sorted({r["swivel_deg"] for r in grid})):
        mine = sorted((r for r in grid if r["swivel_deg"] == swivel), key=lambda r: r["slide_d"])
        left.semilogx([r["slide_d"] for r in mine], [r["porosity"] for r in mine], "o-",
                      color=f"C{k}", label=f"A_swiv = {swivel:g} deg")
    left.set_xlabel("$A_{slide}$ [d]")
    left.set_ylabel("porosity $\\epsilon$")
    left.set_title("Fig. 4a analogue, theta_ini in (0, 90 deg)", fontsize=9)
    left.legend(fontsize=7)
    for row in rows:
        marker = "o" if row["theta_random"] else "s"
        right.plot(row["S_part"], row["porosity"], marker, color="C0" if marker == "o" else "C3")
        right.annotate(_freedom_label(row), (row["S_part"], row["porosity"]),
                       textcoords="offset points", xytext=(3, 2), fontsize=5)
    right.plot([], [], "o", color="C0", label="theta_ini random in (0, 90 deg)")
    right.plot([], [], "s", color="C3", label="theta_ini fixed")
    right.axhspan(0.46, 0.84, color="0.92", zorder=-1, label="paper, R = 0.1 range")
    right.set_xlabel("$S_{part}$ (linear zone)")
    right.set_ylabel("porosity $\\epsilon$")
    right.set_title(f"Fig. 6a analogue: N = {result['n_particles']}, "
                    f"w = {result['box_width_m'] / DIAMETER:.2f} d", fontsize=9)
    right.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)
