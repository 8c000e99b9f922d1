"""Paper-target validation table of the sequential deposition (Ferrage et al. 2015).

Runs the six presets of ``config/paper/packing_*.yaml`` (Table II series 1-3, and the three
vermiculite size fractions of Table III) through :func:`imaging.packing.run.run`, and
compares what the packing file holds with the paper: Table IV for the fractions, the
porosity ranges of Sec. III for the Table II series. Writes, in ``results/benchmarks/``,
``deposition_validation.json`` (one row per preset and scale, accumulated over calls),
``deposition_validation.md`` (the table, ours vs paper, pass/fail, with the sweeps of
:mod:`benchmarks.deposition` and the truncation table), ``deposition_validation.png``
(a Fig. 6a analogue) and the packing files; :func:`write_report` rewrites the report
from the JSON files. Scaled-down runs (``scale`` < 1) keep the bed height and the voxel
edge in a narrower box: they check that the chain runs, the full-scale rows validate.
The outputs and the scaling in full: docs/performance.md,
"benchmarks.deposition_validation".
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)
import numpy as np  # noqa: E402
import yaml  # noqa: E402

from imaging.packing import _settle_kernels  # noqa: E402
from imaging.packing._bed import BedIndex  # noqa: E402
from imaging.packing.analysis import surface_areas  # noqa: E402
from imaging.packing.config import check_packings, parameters_of, population_of  # noqa: E402
from imaging.packing.deposition import _entry_pose  # noqa: E402
from imaging.packing.population import sample_semi_axes, volumes  # noqa: E402
from imaging.packing.run import PackingOutputs, run  # noqa: E402
from shared.config import DEFAULT_CONFIG_PATH, validate_config  # noqa: E402
from shared.figures import save_figure  # noqa: E402

PRESET_DIR = Path("config/paper")
OUT = Path("results/benchmarks")
STEM = "deposition_validation"

#: Presets in the order of the table: Table II series, then the size fractions.
PRESETS = (
    "table2_series1", "table2_series2", "table2_series3",
    "fraction_0p1-0p2um", "fraction_1-2um", "fraction_10-20um",
)

#: Quantities of the table: (key in the row, label, unit, key in the packing dataset,
#: factor from the dataset's unit to the table's unit).
QUANTITIES = (
    ("porosity", "porosity", "1", "porosity", 1.0),
    ("S_part", "S_part", "1", "S_part", 1.0),
    ("S_vol", "S_vol", "1", "S_vol", 1.0),
    ("eta", "eta", "1", "eta", 1.0),
    ("beta", "beta", "deg", "beta", 1.0),
    ("A_B", "A_B", "m2/g", "A_B", 1.0),
    ("A_L", "A_L", "m2/g", "A_L", 1.0),
    ("A_T", "A_T", "m2/g", "A_T", 1.0),
    ("A_Bcont", "A_Bcont", "m2/g", "A_Bcont", 1.0),
    ("f_o", "f_o", "1", "overlap_fraction", 1.0),
    ("z_min", "z_min", "um", "z_min", 1.0e6),
    ("z_max", "z_max", "um", "z_max", 1.0e6),
    ("w_eps", "w_eps (centred)", "um", "w_rev_porosity_centred", 1.0e6),
    ("w_sp", "w_s-p (centred)", "um", "w_rev_interface_centred", 1.0e6),
    ("w_eps_random", "w_eps (random windows)", "um", "w_rev_porosity", 1.0e6),
    ("w_sp_random", "w_s-p (random windows)", "um", "w_rev_interface", 1.0e6),
    ("R_p", "R_p", "1", "R_p", 1.0),
    ("R_s", "R_s", "1", "R_s", 1.0),
)

#: Table IV of the paper (calculated values; w_eps, w_s-p in um, areas in m2/g, beta in deg).
TABLE_IV: dict[str, dict[str, float]] = {
    "fraction_0p1-0p2um": dict(
        porosity=0.63, S_part=0.63, S_vol=0.60, eta=0.007, beta=0.12, A_L=18.3, A_B=76.2,
        A_T=94.5, A_Bcont=5.3, f_o=6.9e-5, z_min=0.15, z_max=1.35, w_eps=0.39, w_sp=0.66,
        R_p=0.494, R_s=0.481),
    "fraction_1-2um": dict(
        porosity=0.64, S_part=0.36, S_vol=0.34, eta=0.008, beta=0.32, A_L=2.6, A_B=10.3,
        A_T=12.9, A_Bcont=0.66, f_o=2.3e-5, z_min=1.0, z_max=7.0, w_eps=4.2, w_sp=4.8,
        R_p=0.689, R_s=0.691),
    "fraction_10-20um": dict(
        porosity=0.70, S_part=0.10, S_vol=0.11, eta=0.011, beta=1.19, A_L=0.07, A_B=0.32,
        A_T=0.39, A_Bcont=0.014, f_o=2.0e-6, z_min=7.0, z_max=207.0, w_eps=87.0, w_sp=112.0,
        R_p=0.880, R_s=0.916),
}

#: What the paper's text gives for the Table II series (disks, R = 0.1); it prints no
#: per-series values at R = 0.1 (only Figs. 4-6), so the ranges are the citable bounds.
#: Sec. III A: "the obtained eps values range between 0.84 and 0.51" over the amplitude
#: tests with theta_ini random in (0, pi/2) (Fig. 4a), i.e. series 1 and 2 settings;
#: Sec. III D: "porosity values range between 0.46 and 0.84" over all R = 0.1 tests,
#: the low end from theta_ini = 0 with high freedom, i.e. series 3; low freedom lies at
#: the high end, high freedom at the low end (Sec. III A, Fig. 4a). Sec. III D also gives
#: the mean eta (~0.003) and beta (0.47 deg) over all R = 0.1 packings.
TABLE_II_TEXT: dict[str, dict[str, Any]] = {
    "table2_series1": {"porosity_range": (0.51, 0.84), "source": "Sec. III A, Fig. 4a"},
    "table2_series2": {"porosity_range": (0.51, 0.84), "source": "Sec. III A, Fig. 4a"},
    "table2_series3": {"porosity_range": (0.46, 0.84), "source": "Sec. III D"},
}
TABLE_II_MEANS = {"eta": 0.003, "beta": 0.47}

#: Pass criteria of issue 3: porosity and S_part of the fractions against Table IV
#: (absolute tolerances: 0.02 is the paper's stated uncertainty on eps, Sec. III A; 0.05 on
#: S_part is our reading, the issue naming no number), eta < 0.02 and beta < 1.5 deg for
#: every run, A_L, A_B, A_T within 15 % of Table IV. Table II series pass on porosity when
#: inside the paper's range.
ABS_TOLERANCE = {"porosity": 0.02, "S_part": 0.05}
REL_TOLERANCE = {"A_L": 0.15, "A_B": 0.15, "A_T": 0.15}
UPPER_BOUND = {"eta": 0.02, "beta": 1.5}


def _as_fraction(scale: float) -> float:
    """The scale factor as a fraction: the harness passes ``--size`` as an int, read as a
    percentage when above 1 (``--size 20`` is scale 0.2)."""
    scale = float(scale)
    if scale > 1.0:
        scale /= 100.0
    if not 0.0 < scale <= 1.0:
        raise ValueError(f"scale: must be in (0, 1] (or a percentage in (1, 100]), got {scale!r}")
    return scale


def preset_section(name: str, scale: float = 1.0) -> dict[str, Any]:
    """The packing section of a paper preset, scaled down for a quick check.

    Parameters
    ----------
    name : str
        Preset name, ``config/paper/packing_<name>.yaml``.
    scale : float
        Fraction of the particles in (0, 1]; the box width scales by ``sqrt(scale)``
        (constant particles per floor area) as does the voxel resolution (constant voxel
        edge); polydisperse size laws are truncated at a diameter w / 2 (or the preset's
        lower cut), and the linear zone is detected rather than taken from the preset.

    Returns
    -------
    dict
        The section as a preset file gives it (:func:`packing_section` fills in the
        schema's defaults).
    """
    text = (PRESET_DIR / f"packing_{name}.yaml").read_text()
    (section,) = yaml.safe_load(text)["packings"].values()
    if scale == 1.0:
        return section
    root = math.sqrt(scale)
    # A narrower box with a more truncated size law fills a bed of another height: the
    # preset's linear zone no longer applies, detect it.
    section.pop("z_min_m", None)
    section.pop("z_max_m", None)
    section["n_particles"] = max(1, round(section["n_particles"] * scale))
    section["box_width_m"] = section["box_width_m"] * root
    if "voxel_resolution" in section:
        section["voxel_resolution"] = max(16, round(section["voxel_resolution"] * root))
    if section.get("basal_surface_sigma", 0.0) > 0.0:
        # The narrower box no longer holds the tail of the size law; truncate it at a
        # diameter w / 2 unless the preset already cuts lower.
        bound = math.pi * (section["box_width_m"] / 4.0) ** 2
        preset = section.get("basal_surface_max_m2")
        section["basal_surface_max_m2"] = bound if preset is None else min(bound, preset)
    return section


def packing_section(section: Mapping[str, Any], name: str = "preset") -> dict[str, Any]:
    """A packing entry as the workflow hands it to :func:`~imaging.packing.run.run`:
    validated against the configuration schema (defaults filled in) and checked across
    keys, in place of the packings of the default configuration."""
    config = yaml.safe_load(DEFAULT_CONFIG_PATH.read_text())
    config["packings"] = {name: dict(section)}
    validate_config(config)
    check_packings(config)
    return config["packings"][name]


def _paper(name: str) -> dict[str, Any]:
    """The paper's values of a preset: Table IV, or the Sec. III text for Table II."""
    if name in TABLE_IV:
        return {"source": "Table IV", **TABLE_IV[name]}
    return {**TABLE_II_TEXT[name], **TABLE_II_MEANS}


def _checks(ours: Mapping[str, float], paper: Mapping[str, Any]) -> dict[str, bool]:
    """Pass/fail of one run against the criteria of issue 3 (see the module constants)."""
    checks = {key: bool(ours[key] < bound) for key, bound in UPPER_BOUND.items()}
    if "porosity_range" in paper:
        low, high = paper["porosity_range"]
        checks["porosity"] = bool(low <= ours["porosity"] <= high)
        return checks
    for key, tolerance in ABS_TOLERANCE.items():
        checks[key] = bool(abs(ours[key] - paper[key]) <= tolerance)
    for key, tolerance in REL_TOLERANCE.items():
        checks[key] = bool(abs(ours[key] / paper[key] - 1.0) <= tolerance)
    return checks


def validate_preset(name: str, scale: float, directory: Path, mode: str = "exact",
                    seed: int | None = None) -> dict[str, Any]:
    """Run one preset and compare it with the paper.

    Parameters
    ----------
    name : str
        Preset name (see :data:`PRESETS`).
    scale : float
        Fraction of the particles in (0, 1] (see :func:`preset_section`).
    directory : Path
        Where the packing file and its figure are written.
    mode : str
        Contact mode, ``exact`` or ``scan`` (the preset's ``scan_points``).
    seed : int, optional
        Random seed in place of the preset's (run-to-run spread).

    Returns
    -------
    dict
        ``preset``, ``scale``, ``mode``, ``seed``, ``n_particles``, ``box_width_m``, ``ours`` (the quantities
        of :data:`QUANTITIES` in the table's units, plus ``S``), ``paper``, ``rel_diff``
        (ours / paper - 1 where the paper gives a value), ``checks``, ``passed``,
        ``wall_time_s`` (deposition, analyses and writing), ``deposition_s`` (summed
        settling time) and ``particles_per_second`` (over the deposition only).
    """
    section = preset_section(name, scale)
    section["contact_mode"] = mode
    suffix = "" if mode == "exact" else f"_{mode}"
    if seed is not None and seed != section.get("seed", 1):
        section["seed"] = seed
        suffix += f"_seed{seed}"
    section = packing_section(section, name)
    start = time.perf_counter()
    stem = f"{name}_s{scale:g}{suffix}"
    ds = run(section, stem, PackingOutputs(directory / f"{stem}.nc", directory / f"{stem}.png"))
    wall = time.perf_counter() - start
    ours = {key: float(ds[var]) * factor if var in ds else float("nan")
            for key, _, _, var, factor in QUANTITIES}
    ours["S"] = float(ds["S"])
    paper = _paper(name)
    checks = _checks(ours, paper)
    deposition = float(ds["settle_time"].sum())
    n_particles = int(ds.sizes["particle"])
    return {
        "preset": name,
        "scale": scale,
        "mode": mode,
        "seed": int(section["seed"]),
        "n_particles": n_particles,
        "box_width_m": float(section["box_width_m"]),
        "ours": ours,
        "paper": paper,
        "rel_diff": {key: ours[key] / paper[key] - 1.0 for key in ours
                     if isinstance(paper.get(key), float)},
        "checks": checks,
        "passed": all(checks.values()),
        "wall_time_s": wall,
        "deposition_s": deposition,
        "particles_per_second": n_particles / deposition,
    }


#: Truncations of a fraction's basal surface law compared by :func:`truncation_table`:
#: (label, largest equivalent diameter as a fraction of w or None, basal surface sigma or
#: None for the preset's). The 1-2 um preset uses w / 4; sigma 1.35 is twice Table I's
#: diameter sigma (0.675), the value consistent with it since S ~ d^2.
TRUNCATIONS = (
    ("none", None, None),
    ("d <= w", 1.0, None),
    ("d <= w / 2", 0.5, None),
    ("d <= w / 3", 1.0 / 3.0, None),
    ("d <= w / 4", 0.25, None),
    ("sigma_S = 1.35, none", None, 1.35),
    ("sigma_S = 1.35, d <= w / 2", 0.5, 1.35),
)


def expected_areas(section: Mapping[str, Any]) -> tuple[float, float]:
    """A_B and A_L [m2/g] of an untruncated population in the limit of many particles.

    With independent log-normal laws of S (median m, sigma s), R (median r, sigma s_R) and
    e = l_a / l_b, the equivalent diameter d = 2 sqrt(S / pi) is log-normal of median
    d_m = 2 sqrt(m / pi) and sigma s / 2, and h = R d. Eqs. 8-9 tend to
    A_B = 2 E[d^2] / (rho E[R] E[d^3]) = 2 exp(-5 s^2 / 8) / (rho r exp(s_R^2 / 2) d_m) and
    A_L = 4 E[g] E[d^2] / (rho E[d^3]) = 4 E[g] exp(-5 s^2 / 8) / (rho d_m), with
    g = sqrt((e + 1 / e) / 2) from the perimeter pi sqrt(2 (l_a^2 + l_b^2)) = pi d g; E[g]
    is taken by quadrature over the axis-ratio law truncated below 1.
    """
    sigma = float(section["basal_surface_sigma"])
    d_m = 2.0 * math.sqrt(section["basal_surface_median_m2"] / math.pi)
    rho_g = 1000.0 * section["density_kg_m3"]
    r_mean = section["aspect_ratio_median"] * math.exp(section["aspect_ratio_sigma"] ** 2
                                                        / 2.0)
    e_median = section["axis_ratio_median"]
    e_sigma = section["axis_ratio_sigma"]
    if e_sigma > 0.0:
        # ln e = ln(median) + e_sigma x, x standard normal restricted to e >= 1
        x = np.linspace(-math.log(e_median) / e_sigma, 10.0, 20001)
        e = e_median * np.exp(e_sigma * x)
        weight = np.exp(-0.5 * x**2)
        g_mean = float(np.trapezoid(np.sqrt((e + 1.0 / e) / 2.0) * weight, x)
                       / np.trapezoid(weight, x))
    else:
        g_mean = math.sqrt((e_median + 1.0 / e_median) / 2.0)
    spread = math.exp(-5.0 * sigma**2 / 8.0)
    return 2.0 * spread / (rho_g * r_mean * d_m), 4.0 * g_mean * spread / (rho_g * d_m)


def truncation_table(name: str, seeds: int = 5) -> list[dict[str, Any]]:
    """Surface areas of a fraction's particle law under several truncations (no packing:
    Eqs. 8-10 over the sampled particles, which the linear zone subsamples at random).

    Parameters
    ----------
    name : str
        A fraction preset.
    seeds : int
        Independent samples of the preset's particle count per truncation.

    Returns
    -------
    list of dict
        ``truncation``, ``basal_surface_sigma``, ``largest_d_um`` (None when untruncated),
        ``cut_share`` (share of the law above the bound), ``height_um`` (height of the bed
        these particles fill at Table IV's porosity [um]), mean and standard deviation over
        the seeds of ``A_B``, ``A_L``, ``A_T`` [m2/g], and the closed form of
        :func:`expected_areas` for the untruncated rows.
    """
    base = preset_section(name)
    width = base["box_width_m"]
    rows = []
    for label, fraction, sigma in TRUNCATIONS:
        section = {**base, "basal_surface_max_m2": None}
        if sigma is not None:
            section["basal_surface_sigma"] = sigma
        largest = None if fraction is None else fraction * width
        if largest is not None:
            section["basal_surface_max_m2"] = math.pi * largest**2 / 4.0
        section = packing_section(section, name)
        population = population_of(section)
        samples = [sample_semi_axes(population, section["n_particles"],
                                    np.random.default_rng([seed, 7])) for seed in range(seeds)]
        areas = np.array([surface_areas(semi_axes) for semi_axes in samples])
        # bed height these particles fill at the paper's porosity: compare with z_max
        height = np.mean([volumes(semi_axes).sum() for semi_axes in samples]) / (
            width**2 * (1.0 - TABLE_IV[name]["porosity"]))
        s = section["basal_surface_sigma"]
        cut = 0.0 if largest is None else 0.5 * math.erfc(
            math.log(math.pi * largest**2 / 4.0 / section["basal_surface_median_m2"])
            / (s * math.sqrt(2.0)))
        row = {"truncation": label, "basal_surface_sigma": s,
               "largest_d_um": None if largest is None else largest * 1e6, "cut_share": cut,
               "height_um": float(height) * 1e6}
        for k, key in enumerate(("A_B", "A_L", "A_T")):
            row[key] = float(areas[:, k].mean())
            row[f"{key}_std"] = float(areas[:, k].std())
        if largest is None:
            a_b, a_l = expected_areas(section)
            row.update(A_B_expected=a_b, A_L_expected=a_l, A_T_expected=a_b + a_l)
        rows.append(row)
    return rows


def truncation_markdown(name: str, rows: Iterable[Mapping[str, Any]]) -> str:
    """Markdown of :func:`truncation_table` with the paper's Table IV areas."""
    paper = TABLE_IV[name]
    lines = [f"## Surface areas of {name} vs truncation of the basal surface law", "",
             "Eqs. 8-10 over sampled particle sets of the preset's size (mean +- std over "
             "seeds); 'expected' is the closed form for the untruncated law "
             "(`expected_areas`). The box holds no particle wider than w. Bed height: what "
             "the particles fill at Table IV's porosity, against its z_max = "
             f"{paper['z_max']:g} um.",
             "", "| truncation | sigma_S | largest d [um] | share cut | bed height [um] | A_B | "
             "A_L | A_T | A_T expected |", "|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        largest = "-" if row["largest_d_um"] is None else f"{row['largest_d_um']:.3g}"
        expected = _cell(row.get("A_T_expected"))
        lines.append(
            f"| {row['truncation']} | {row['basal_surface_sigma']:.3g} | {largest} | "
            f"{row['cut_share']:.2%} | {row['height_um']:.3g} | "
            + " | ".join(f"{row[k]:.3g} +- {row[k + '_std']:.2g}" for k in ("A_B", "A_L", "A_T"))
            + f" | {expected} |")
    lines.append(f"| paper, Table IV | | | | | {paper['A_B']} | {paper['A_L']} | "
                 f"{paper['A_T']} | |")
    lines.append("")
    return "\n".join(lines)


#: Paragraph of the report on how exact the contacts are (numbers from
#: tests/imaging/packing/test_deposition.py::test_every_particle_rests_on_a_support).
CONTACT_ACCURACY = (
    "**Contact accuracy.** Contacts and overlaps are computed exactly on the disk shape "
    "(GJK distance and conservative advancement on the support function), instead of the "
    "paper's multiscale scan with n_sp scan points (Sec. II B). A fall stops at a vertical "
    "gap of d_cont / 2 (GJK bounds converged to 0.2 of that gap), so no particle enters "
    "another: the voxel overlap fraction f_o is 0 in every run, against the paper's "
    "2e-6 to 6.9e-5 (Table IV), and the independent dense point sampling of the tests finds "
    "no point of a particle inside another. Contacts are exact to d_cont: in the test beds "
    "(40 elliptic disks; 60 polydisperse disks), every particle's Euclidean distance to the "
    "floor or to an earlier particle, by GJK, is at most 0.52 and 0.54 d_cont (test bound "
    "0.6 d_cont), median 0.50 d_cont, so every particle rests on a support; the paper's "
    "scan approaches a contact only to within d_cont along z. Rows with scan contacts use "
    "that scan (Sec. II B as written, imaging/packing/_scan_kernels.py) with the preset's "
    "n_sp: falls found to within d_cont where the refinement reaches the lowest point, "
    "small overlaps where the grid misses it (f_o > 0, as the paper's).")


def _cell(value: float | None) -> str:
    """A table cell: three significant digits, or n/a for a missing value."""
    return "n/a" if value is None or not np.isfinite(value) else f"{value:.3g}"


def markdown_table(rows: Iterable[Mapping[str, Any]]) -> str:
    """The markdown table of the runs: one block per run, ours vs paper per quantity.

    Parameters
    ----------
    rows : iterable of dict
        Rows of :func:`validate_preset`.

    Returns
    -------
    str
    """
    lines = ["# Sequential deposition vs Ferrage et al. (2015)", "",
             "Criteria (issue 3): porosity |diff| <= 0.02 and S_part |diff| <= 0.05 vs Table IV "
             "(fractions); porosity inside the Sec. III range (Table II series); eta < 0.02, "
             "beta < 1.5 deg (all runs); A_L, A_B, A_T within 15 % of Table IV (fractions). "
             "Scale < 1: N x scale, w x sqrt(scale) (a quick check, not a validation).", "",
             CONTACT_ACCURACY, "",
             "| preset | scale | contacts | seed | N | porosity (paper) | S_part (paper) | eta | "
             "beta [deg] | A_T [m2/g] (paper) | f_o | wall [s] | particles/s | result |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        ours, paper = row["ours"], row["paper"]
        porosity = ("{:.2f}-{:.2f}".format(*paper["porosity_range"])
                    if "porosity_range" in paper else _cell(paper["porosity"]))
        lines.append(
            f"| {row['preset']} | {row['scale']:g} | {row.get('mode', 'exact')} | {_seed(row)} | "
            f"{row['n_particles']} | "
            f"{_cell(ours['porosity'])} ({porosity}) | "
            f"{_cell(ours['S_part'])} ({_cell(paper.get('S_part'))}) | {_cell(ours['eta'])} | "
            f"{_cell(ours['beta'])} | {_cell(ours['A_T'])} ({_cell(paper.get('A_T'))}) | "
            f"{_cell(ours['f_o'])} | {row['wall_time_s']:.0f} | {row['particles_per_second']:.1f} | "
            f"{'PASS' if row['passed'] else 'FAIL'} |")
    lines.append("")
    for row in rows:
        paper, checks = row["paper"], row["checks"]
        lines += [f"## {row['preset']} ({row.get('mode', 'exact')} contacts, scale {row['scale']:g}, "
                  f"seed {_seed(row)}, N = {row['n_particles']}, "
                  f"w = {row['box_width_m'] * 1e6:.3g} um): "
                  f"{'PASS' if row['passed'] else 'FAIL'}", "",
                  f"paper source: {paper['source']}; wall time {row['wall_time_s']:.0f} s "
                  f"(deposition {row['deposition_s']:.0f} s, "
                  f"{row['particles_per_second']:.2f} particles/s)", "",
                  "| quantity | unit | ours | paper | rel. diff | check |",
                  "|---|---|---|---|---|---|"]
        for key, label, unit, _, _ in QUANTITIES:
            target = paper.get(key)
            if key == "porosity" and "porosity_range" in paper:
                target_text = "{:.2f}-{:.2f}".format(*paper["porosity_range"])
            else:
                target_text = _cell(target)
            diff = row["rel_diff"].get(key, float("nan"))
            check = "" if key not in checks else ("pass" if checks[key] else "FAIL")
            lines.append(f"| {label} | {unit} | {_cell(row['ours'][key])} | {target_text} | "
                         f"{f'{diff:+.1%}' if np.isfinite(diff) else ''} | {check} |")
        lines.append("")
    return "\n".join(lines)


def spread_markdown(rows: Iterable[Mapping[str, Any]]) -> str:
    """Run-to-run spread: porosity and S_part of every preset, scale and contact mode run
    with more than one seed, their mean and range, and the mean's difference from the
    paper (Table IV; the Sec. III range's nearest bound for the Table II series)."""
    groups: dict[tuple[str, float, str], list[Mapping[str, Any]]] = {}
    for row in rows:
        groups.setdefault(_row_key(row)[:3], []).append(row)
    lines = ["## Run-to-run spread (same preset, other seeds)", "",
             "| preset | scale | contacts | seeds | porosity: values, range | "
             "mean - paper | S_part: values, range | mean - paper |",
             "|---|---|---|---|---|---|---|---|"]
    for (preset, scale, mode), group in groups.items():
        if len(group) < 2:
            continue
        cells = []
        for key in ("porosity", "S_part"):
            values = np.array([row["ours"][key] for row in group])
            paper = group[0]["paper"]
            if key == "porosity" and "porosity_range" in paper:
                low, high = paper["porosity_range"]
                gap = values.mean() - np.clip(values.mean(), low, high)
            else:
                gap = values.mean() - paper[key] if isinstance(paper.get(key), float) else np.nan
            cells += [", ".join(_cell(v) for v in values) + f"; {np.ptp(values):.3f}",
                      f"{gap:+.3f}" if np.isfinite(gap) else "n/a"]
        lines.append(f"| {preset} | {scale:g} | {mode} | "
                     f"{', '.join(str(_seed(row)) for row in group)} | " + " | ".join(cells) + " |")
    if len(lines) == 4:
        return ""
    return "\n".join(lines + [""])


def _sweep(name: str) -> dict[str, Any] | None:
    """The JSON of a sweep of :mod:`benchmarks.deposition` (``deposition_<name>.json`` in
    ``results/benchmarks/``), or None if it has not been run."""
    path = OUT / f"deposition_{name}.json"
    return json.loads(path.read_text()) if path.exists() else None


def sweeps_markdown() -> str:
    """Report sections of the reduced-N sweeps and the cost curve of
    :mod:`benchmarks.deposition`, for those that have been run."""
    lines = []
    freedom = _sweep("freedom")
    if freedom is not None:
        lines += [f"## Deposition freedom sweep (Figs. 4, 6a): N = {freedom['n_particles']}, "
                  f"w = {freedom['box_width_m'] * 1e6:.3g} um (R = 0.1 disks, d = 1 um)", "",
                  "`python -m benchmarks run deposition_freedom --size 400`; linear-zone "
                  "values, one seed per case (the paper's uncertainty on porosity is 0.02; "
                  "at this N expect about as much from the seed).", "",
                  "| A_swiv [deg] | A_slide [d] | theta_ini [deg] | porosity | S_part |",
                  "|---|---|---|---|---|"]
        for row in freedom["rows"]:
            entry = (f"(0, {row['theta_max_deg']:g})" if row["theta_random"]
                     else f"{row['theta_max_deg']:g}")
            lines.append(f"| {row['swivel_deg']:g} | {row['slide_d']:.3g} | {entry} | "
                         f"{row['porosity']:.3f} | {row['S_part']:.3f} |")
        loosest = max(freedom["rows"], key=lambda r: r["porosity"])
        densest = min(freedom["rows"], key=lambda r: r["porosity"])
        lines += ["", f"Porosity spans {densest['porosity']:.3f} to {loosest['porosity']:.3f} "
                  f"(highest at A_swiv = {loosest['swivel_deg']:g} deg, A_slide = "
                  f"{loosest['slide_d']:.3g} d, theta_ini "
                  f"{'random' if loosest['theta_random'] else 'fixed'} "
                  f"{loosest['theta_max_deg']:g} deg). Paper (Sec. III A, Fig. 4a): 0.51 to "
                  "0.84 over its amplitude grid, above 0.7 only for the three smallest "
                  "amplitude pairs (down to 5 deg, d / 60), whose beds hold large pores "
                  "(Fig. 3c); porosity falls with S_part along one master curve (Fig. 6a)."]
        lines.append("")
    axis = _sweep("axis_ratio")
    if axis is not None:
        ratios = sorted({row["axis_ratio"] for row in axis["rows"]})
        lines += [f"## Porosity vs l_a / l_b (Fig. 7): N = {axis['n_particles']}, "
                  f"w = {axis['box_width_m'] * 1e6:.3g} um (R = 0.1, d = 1 um)", "",
                  "`python -m benchmarks run deposition_axis_ratio --size 400`; linear-zone "
                  "porosity per Table II series (mean over seeds; "
                  f"{axis.get('note', 'one seed per point')}). Paper (Sec. IV A): no effect "
                  "of l_a / l_b below 1.5, porosity rising significantly above.", "",
                  "| series | " + " | ".join(f"{e:g}" for e in ratios) + " |",
                  "|---|" + "---|" * len(ratios)]
        for series in sorted({row["series"] for row in axis["rows"]}):
            cells = [np.mean([r["porosity"] for r in axis["rows"]
                              if r["series"] == series and r["axis_ratio"] == e]) for e in ratios]
            lines.append(f"| {series} | " + " | ".join(f"{c:.3f}" for c in cells) + " |")
        lines.append("")
    cost = _sweep("cost")
    if cost is not None:
        s2 = cost["series2"]
        lines += ["## Cost per particle as the bed grows", "",
                  "`python -m benchmarks run deposition_cost --size 2500`: mean settling time "
                  "per particle over 20 blocks of the deposition order; growth = last block "
                  "over blocks 2-3 (the first lands on the floor), late growth = last block "
                  "over the middle one. Wall times on 2 cores shared with other jobs.", "",
                  "| run | N | particles/s | block 1 [ms] | block 2 [ms] | middle block [ms] "
                  "| last block [ms] | growth | late growth |",
                  "|---|---|---|---|---|---|---|---|---|"]
        curves = {"Table II series 2 (this run)": s2}
        curves.update({f"{name} (stored settle_time)": curve
                       for name, curve in cost["stored"].items()})
        for name, curve in curves.items():
            ms = 1e3 * np.asarray(curve["mean_s"])
            lines.append(f"| {name} | {curve['n_particles']} | "
                         f"{curve['n_particles'] / curve['total_s']:.1f} | {ms[0]:.0f} | "
                         f"{ms[1]:.0f} | {ms[ms.size // 2]:.0f} | {ms[-1]:.0f} | "
                         f"{curve['growth']:.2f} | {curve['late_growth']:.2f} |")
        lines.append("")
    return "\n".join(lines)


def porosity_order_figure(rows: Iterable[Mapping[str, Any]], path: Path,
                          sweep: Mapping[str, Any] | None = None) -> Path:
    """Fig. 6a analogue: porosity vs S_part of every run, with the paper's points.

    Parameters
    ----------
    rows : iterable of dict
        Rows of :func:`validate_preset`.
    path : Path
        PNG file.
    sweep : dict, optional
        The deposition freedom sweep (``benchmarks.deposition.bench_deposition_freedom``),
        drawn as the reduced-N points of the master curve.

    Returns
    -------
    Path
    """
    fig, ax = plt.subplots(figsize=(6.0, 4.5))
    # The paper's R = 0.1 disk porosities (Sec. III D) span this band; its master curve
    # is printed only as a figure.
    ax.axhspan(0.46, 0.84, color="0.9", label="paper, porosity range of R = 0.1 disks")
    for name, values in TABLE_IV.items():
        ax.plot(values["S_part"], values["porosity"], "ks", mfc="none")
        ax.annotate(name.removeprefix("fraction_"), (values["S_part"], values["porosity"]),
                    textcoords="offset points", xytext=(4, -10), fontsize=7)
    ax.plot([], [], "ks", mfc="none", label="paper, Table IV fractions")
    for row in rows:
        full = row["scale"] == 1.0
        ax.plot(row["ours"]["S_part"], row["ours"]["porosity"], "o" if full else "x",
                color="C0" if row["preset"].startswith("table2") else "C3")
        ax.annotate(f"{row['preset']} s{row['scale']:g}",
                    (row["ours"]["S_part"], row["ours"]["porosity"]),
                    textcoords="offset points", xytext=(4, 4), fontsize=6)
    if sweep is not None:
        points = sorted((r["S_part"], r["porosity"]) for r in sweep["rows"])
        ax.plot(*zip(*points, strict=False), "^", color="C2", ms=4,
                label=f"ours, freedom sweep (N = {sweep['n_particles']}, R = 0.1)")
    ax.plot([], [], "o", color="C0", label="ours, Table II series (o full, x scaled)")
    ax.plot([], [], "o", color="C3", label="ours, fractions (o full, x scaled)")
    ax.set_xlabel("order parameter $S_{part}$ [-]")
    ax.set_ylabel("porosity $\\epsilon$ [-]")
    ax.set_xlim(-0.5, 1.0)
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)


def bench_deposition_validation(scale: float = 1.0, presets: Iterable[str] = PRESETS,
                                mode: str = "exact", seed_offset: int = 0) -> dict:
    """Run the paper presets and tabulate them against Ferrage et al. (2015).

    Parameters
    ----------
    scale : float
        Fraction of each preset's particles in (0, 1]; values above 1 are percentages
        (the harness's integer ``--size``). See the module docstring for the scaling.
    presets : iterable of str
        Subset of :data:`PRESETS` to run (default: all six).
    mode : str
        Contact mode, ``exact`` or ``scan`` (rows of both modes share the table).
    seed_offset : int
        Added to each preset's seed (0: the preset's own); rows of several seeds share
        the table, which then gives their spread.

    Returns
    -------
    dict
        ``rows`` (every run in the JSON file, this call's and earlier ones, in table
        order), ``passed`` (all runs of this call pass), ``total_s`` (this call) [s],
        ``truncations`` (:func:`truncation_table` of each fraction).
    """
    scale = _as_fraction(scale)
    presets = tuple(presets)
    unknown = sorted(set(presets) - set(PRESETS))
    if unknown or not presets:
        raise ValueError(f"presets: unknown {unknown} or none; choose from {PRESETS}")
    OUT.mkdir(parents=True, exist_ok=True)
    directory = OUT / STEM
    directory.mkdir(exist_ok=True)
    json_path = OUT / f"{STEM}.json"
    start = time.perf_counter()
    # Particle laws only (no packing): a few seconds, redone so that the table follows them.
    truncations = {name: truncation_table(name) for name in TABLE_IV}
    fresh = []
    for name in presets:
        seed = preset_section(name, scale).get("seed", 1) + seed_offset
        fresh.append(validate_preset(name, scale, directory, mode, seed))
        # Rows of earlier or concurrent calls (other presets or scales) are re-read before
        # every write and kept, so that one table gathers the runs a time budget allows;
        # writing after every preset keeps what a call cut short had finished.
        previous = json.loads(json_path.read_text())["rows"] if json_path.exists() else []
        table = {_row_key(row): row for row in previous + fresh}
        rows = sorted(table.values(), key=lambda r: (PRESETS.index(r["preset"]), r["scale"],
                                                     r.get("mode", "exact"), _seed(r)))
        result = {"rows": rows, "passed": all(r["passed"] for r in fresh),
                  "total_s": time.perf_counter() - start, "truncations": truncations}
        json_path.write_text(json.dumps(result, indent=2))
        write_report(result)
    return result


def bench_deposition_validation_scan(scale: float = 1.0) -> dict:
    """:func:`bench_deposition_validation` with the paper's contact scan (Sec. II B)."""
    return bench_deposition_validation(scale, mode="scan")


def paired_scan_cost(name: str, n_bed: int = 150, n_test: int = 30) -> dict[str, Any]:
    """Cost per particle of the contact scan against exact contacts on the same bed.

    ``n_bed`` particles of a full-scale preset are deposited with exact contacts; each of
    the next ``n_test`` is then settled twice from the same entry pose with the same
    random moves, with exact contacts and with the scan (the preset's n_sp), and the
    exact settlement joins the bed. Returns the mean wall time per particle of each mode
    [s], their ratio, and the mean accepted moves and final tilt [deg] of each mode.
    """
    section = packing_section(dict(preset_section(name), contact_mode="scan"), name)
    rng = np.random.default_rng(section["seed"])
    semi_axes = sample_semi_axes(population_of(section), n_bed + n_test, rng)
    params = parameters_of(section)
    bed = BedIndex(semi_axes, params.box_width, params.contact_distance, params.scan_points)
    scanned = bed.geometry
    exact = scanned.copy()
    exact[8] = 0.0
    amplitudes = np.array([params.slide_amplitude, params.swivel_amplitude,
                           params.rotation_amplitude])
    steepest = np.array([params.steepest_slide, params.steepest_swivel,
                         params.contact_line_swivel])
    record = np.zeros((n_test, 2, 3))  # seconds, accepted moves, tilt [deg]
    for i, axes in enumerate(semi_axes):
        centre, rotation = _entry_pose(axes, params, bed, rng)
        uniforms = rng.random((params.n_cycles * params.attempts_per_cycle, 4))
        kinds = 3 if axes[0] > axes[1] * (1.0 + 1e-12) else 2
        for mode, geometry in enumerate((exact, scanned) if i >= n_bed else (exact,)):
            c, r = centre.copy(), rotation.copy()
            start = time.perf_counter()
            accepted = _settle_kernels.settle(
                c, r, axes, uniforms, amplitudes, params.amplitude_reduction, params.n_cycles,
                kinds, steepest, bed.centers, bed.rotations, bed.axes, bed.extents,
                bed.fine.head, bed.coarse.head, bed.link, geometry, bed.found, bed.shifts,
                bed.drops, bed.witness)
            if i >= n_bed:
                record[i - n_bed, mode] = (time.perf_counter() - start, accepted,
                                           math.degrees(math.acos(min(abs(r[2, 2]), 1.0))))
            if mode == 0:
                settled = c, r
        bed.add(i, *settled)
    mean = record.mean(axis=0)
    return {"preset": name, "n_bed": n_bed, "n_test": n_test,
            "scan_points": params.scan_points,
            "exact_s": float(mean[0, 0]), "scan_s": float(mean[1, 0]),
            "scan_over_exact": float(mean[1, 0] / mean[0, 0]),
            "accepted_exact": float(mean[0, 1]), "accepted_scan": float(mean[1, 1]),
            "tilt_exact_deg": float(mean[0, 2]), "tilt_scan_deg": float(mean[1, 2])}


def bench_deposition_scan_cost(n_test: int = 30) -> dict:
    """Cost per particle of the contact scan against exact contacts, paired (same bed,
    entry poses and moves), for every preset: the issue's bound is 3x."""
    rows = [paired_scan_cost(name, n_test=n_test) for name in PRESETS]
    return {"rows": rows, "largest_ratio": max(row["scan_over_exact"] for row in rows),
            "load_average_1min": os.getloadavg()[0]}


def bench_deposition_seed_spread(seed_offset: int = 1000) -> dict:
    """Every preset again at full scale in both contact modes with its seed plus
    ``seed_offset``, cheapest first, skipping the runs the table already has: the
    table then gives the run-to-run spread."""
    cheapest_first = ("table2_series1", "table2_series2", "table2_series3",
                      "fraction_10-20um", "fraction_1-2um", "fraction_0p1-0p2um")
    json_path = OUT / f"{STEM}.json"
    done = {_row_key(row) for row in json.loads(json_path.read_text())["rows"]} \
        if json_path.exists() else set()
    result: dict = {}
    for name in cheapest_first:
        seed = preset_section(name).get("seed", 1) + seed_offset
        for mode in ("exact", "scan"):
            if (name, 1.0, mode, seed) not in done:
                result = bench_deposition_validation(1.0, (name,), mode, seed_offset)
    return result


def _seed(row: Mapping[str, Any]) -> int:
    """The seed of a row (rows written before seeds were recorded: the preset's)."""
    return int(row.get("seed", preset_section(row["preset"]).get("seed", 1)))


def _row_key(row: Mapping[str, Any]) -> tuple[str, float, str, int]:
    return row["preset"], row["scale"], row.get("mode", "exact"), _seed(row)


def write_report(result: Mapping[str, Any] | None = None) -> None:
    """Write ``deposition_validation.md`` and ``.png`` from a result of
    :func:`bench_deposition_validation` (default: the JSON file), with the sweeps of
    :mod:`benchmarks.deposition` that have been run; runs nothing."""
    if result is None:
        result = json.loads((OUT / f"{STEM}.json").read_text())
    rows = result["rows"]
    appendix = "\n".join(truncation_markdown(name, table)
                         for name, table in result["truncations"].items())
    (OUT / f"{STEM}.md").write_text(markdown_table(rows) + "\n" + spread_markdown(rows) + "\n"
                                    + sweeps_markdown() + "\n" + appendix)
    porosity_order_figure(rows, OUT / f"{STEM}.png", _sweep("freedom"))
