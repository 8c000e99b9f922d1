"""The Snakemake workflow end to end on a tiny configuration, in a temporary copy."""

from __future__ import annotations

import html as html_module
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from shared.io import read_dataset

ROOT = Path(__file__).resolve().parents[2]

TINY = {
    "samples": {"pellet": {"source": "phantom", "voxel_size_m": 3.0e-4}},
    "phantom": {"shape": [40, 40, 40], "seed": 1},
    "imaging": {"rev": {"n_sizes": 5, "n_positions": 16, "tolerance": 0.05}},
    "micro": {
        "specimen_size_m": 4.0e-3,
        "n_points": 216,
        "checkpoints_suction_pa": [132.0e6, 60.0e6],
        "cases": {"het": {"porosity": "ct"}, "hom": {"porosity": "homogeneous"}},
    },
    "upscaling": {"conditions": {"free": "het", "confined": "hom"},
                  "suction_range_pa": [60.0e6, 132.0e6]},
    # the small column of tests/_macro_cases.py (about 70 pellets), 10 steps: the macro rule
    # runs on the tiny table, its physics is tested in tests/macro
    "macro": {
        "cylinder_height_m": 0.05, "cylinder_radius_m": 0.015, "pellet_radius_m": 4.0e-3,
        "sensors": {name: {"height_m": height, "band_width_m": 0.008}
                    for name, height in (("S10", 0.01), ("S25", 0.025), ("S40", 0.04))},
        "numerics": {"packing_iterations": 1500, "max_steps": 10},
    },
}


def _workdir(tmp: Path, config: dict) -> Path:
    shutil.copy(ROOT / "Snakefile", tmp / "Snakefile")
    shutil.copytree(ROOT / "workflow", tmp / "workflow")
    (tmp / "config").mkdir()
    (tmp / "config" / "config.yaml").write_text(yaml.safe_dump(config))
    return tmp


def _snakemake(workdir: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "snakemake", "--cores", "2", *args],
        cwd=workdir, capture_output=True, text=True, timeout=600,
    )


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    workdir = _workdir(tmp_path_factory.mktemp("wf"), TINY)
    result = _snakemake(workdir)
    assert result.returncode == 0, result.stderr[-3000:]
    return workdir


def test_products_have_the_contracted_variables(finished):
    porosity = read_dataset(finished / "results/porosity/pellet.nc", ["porosity", "density"])
    rev = read_dataset(finished / "results/rev/pellet.nc",
                       ["porosity_mean", "porosity_std", "interface_mean", "interface_std",
                        "w_rev_porosity", "w_rev_interface", "chord_pore", "chord_solid",
                        "R_p", "R_s"])
    for ds in (porosity, rev):
        assert ds.attrs["stage"] == "imaging"
        assert len(ds.attrs["config_sha256"]) == 64
        for name in ds.variables:
            assert "units" in ds[name].attrs or name == "direction"
    # micro spacing 4 mm / 216^(1/3) = 0.667 mm, i.e. blocks of 2.22 -> 2 voxels of 0.3 mm
    assert porosity.attrs["block_voxels"] == 2
    assert np.nanmean(porosity["porosity"].values) == pytest.approx(0.25, abs=0.05)
    assert (finished / "results/porosity/pellet.png").stat().st_size > 10_000
    assert (finished / "results/rev/pellet.png").stat().st_size > 10_000
    assert (finished / "results/logs/imaging_rev/pellet.log").read_text().count("REV") == 1


def test_forcerun_until_reruns_only_that_rule(finished):
    before = {name: (finished / f"results/logs/imaging_{name}/pellet.log").stat().st_mtime_ns
              for name in ("porosity", "rev")}
    result = _snakemake(finished, "-R", "imaging_rev", "-U", "imaging_rev")
    assert result.returncode == 0, result.stderr[-3000:]
    after = {name: (finished / f"results/logs/imaging_{name}/pellet.log").stat().st_mtime_ns
             for name in ("porosity", "rev")}
    assert after["porosity"] == before["porosity"]
    assert after["rev"] > before["rev"]
    stats = result.stderr.split("Job stats:")[1].split("total")[0]
    assert "imaging_rev" in stats and "imaging_porosity" not in stats


@pytest.fixture(scope="module")
def micro_finished(tmp_path_factory):
    """The tiny run up to the micro cases: the CT rules and the micro cases that read the
    porosity grid (no aggregate or upscaling rule, whose state is not at stake here)."""
    workdir = _workdir(tmp_path_factory.mktemp("wf_micro"), TINY)
    targets = ["results/rev/pellet.nc", "results/porosity/pellet.png",
               *(f"results/micro/{case}.nc" for case in TINY["micro"]["cases"])]
    result = _snakemake(workdir, *targets)
    assert result.returncode == 0, result.stderr[-3000:]
    # before any edit, no output's params differ (checked once for every edit below)
    unchanged = _snakemake(workdir, "--list-changes", "params")
    assert unchanged.returncode == 0, unchanged.stderr[-3000:]
    assert not [line for line in unchanged.stdout.splitlines() if line.startswith("results/")]
    return workdir


_PHANTOM = {"results/phantom/pellet.tif"}
_POROSITY = {"results/images/pellet.nc", "results/porosity/pellet.nc",
             "results/porosity/pellet.png"}
_REV = {"results/rev/pellet.nc", "results/rev/pellet.png"}


_MICRO = {f"results/micro/{case}.{suffix}" for case in TINY["micro"]["cases"]
          for suffix in ("nc", "png")}


@pytest.mark.parametrize(
    ("key", "value", "readers"),
    [
        ("imaging.calibration.air_density_kg_m3", 1.2, _PHANTOM | _POROSITY),
        ("imaging.calibration.muscovite_density_kg_m3", 3800.0, _PHANTOM | _POROSITY),
        ("imaging.calibration.grey_air", 100.0, _POROSITY),
        ("imaging.rev.tolerance", 0.1, _REV),
        # the calibration's mean dry density and phi_0 are the pellet's
        ("materials.pellet.dry_density_kg_m3", 2000.0, _POROSITY),
        ("materials.pellet.reference_porosity", 0.3, _POROSITY | _MICRO),
        # a Table 3.1 parameter reruns the micro cases alone
        ("materials.pellet.retention_pressure_reference_pa", 4.0e4, _MICRO),
        ("materials.pellet.swelling_beta_per_pa", 1.0e-8, _MICRO),
        # the mock-up's parameters rerun no micro or imaging rule
        ("materials.mixture_powder.retention_exponent_reference", 0.3, set()),
    ],
)
def test_a_config_edit_changes_the_params_of_its_readers_only(
    micro_finished, tmp_path, key, value, readers
):
    """Editing a config key changes the params of the rules whose scripts read it, and
    of no other rule.

    Run on a copy of a finished tiny run of the CT rules and the micro cases (results and
    ``.snakemake`` metadata, so every output's recorded params are there; the micro cases
    read the porosity grid but no ``imaging`` key), with ``snakemake --list-changes
    params``: it lists the outputs whose recorded params differ from the rule's current
    ones, i.e. the jobs that the params trigger reruns for the edit itself, and runs
    nothing. A dry run
    (``-n``) would also list the jobs downstream of those (they rerun because their
    inputs change), so it cannot tell a rule that reads the key from one that consumes
    the reader's file. The unedited run lists nothing (checked once, in the fixture), so
    the recorded params are those of the current rules.
    """
    workdir = tmp_path / "wf"
    shutil.copytree(micro_finished, workdir, symlinks=True)
    config_path = workdir / "config" / "config.yaml"
    config = yaml.safe_load(config_path.read_text())
    *sections, name = key.split(".")
    node = config
    for section in sections:
        node = node.setdefault(section, {})
    node[name] = value
    config_path.write_text(yaml.safe_dump(config))
    result = _snakemake(workdir, "--list-changes", "params")
    assert result.returncode == 0, result.stderr[-3000:]
    listed = {line.strip() for line in result.stdout.splitlines() if line.startswith("results/")}
    assert listed == readers


def _fails_with(tmp: Path, config: dict, message: str) -> None:
    workdir = _workdir(tmp, config)
    result = _snakemake(workdir)
    assert result.returncode != 0
    logs = "".join(p.read_text() for p in (workdir / "results/logs").rglob("*.log")) if (
        workdir / "results/logs").exists() else ""
    assert message in result.stderr + logs
    produced = [p for p in (workdir / "results").rglob("*.nc")] if (workdir / "results").exists() else []
    assert not any(p.parent.name in ("porosity", "rev") for p in produced)


def test_voxel_size_zero_is_a_config_error(tmp_path):
    config = yaml.safe_load(yaml.safe_dump(TINY))
    config["samples"]["pellet"]["voxel_size_m"] = 0
    _fails_with(tmp_path, config, "samples.pellet.voxel_size_m")


def test_unknown_key_is_a_config_error(tmp_path):
    config = yaml.safe_load(yaml.safe_dump(TINY))
    config["imaging"]["rev"]["windows"] = 4
    _fails_with(tmp_path, config, "imaging.rev.windows")


def test_missing_scan_is_named(tmp_path):
    config = yaml.safe_load(yaml.safe_dump(TINY))
    config["samples"]["pellet"] = {"source": "tiff", "path": str(tmp_path / "absent.tif"),
                                   "voxel_size_m": 3e-4}
    _fails_with(tmp_path, config, "absent.tif")


def test_truncated_scan_is_named(tmp_path):
    scan = tmp_path / "cut.tif"
    import cv2

    pages = [np.full((16, 16), 40000, np.uint16) for _ in range(8)]
    cv2.imwritemulti(str(scan), pages)
    scan.write_bytes(scan.read_bytes()[:600])
    config = yaml.safe_load(yaml.safe_dump(TINY))
    config["samples"]["pellet"] = {"source": "tiff", "path": str(scan), "voxel_size_m": 3e-4}
    (tmp_path / "w").mkdir()
    _fails_with(tmp_path / "w", config, "cut.tif")


def test_micro_products(finished):
    het = read_dataset(finished / "results/micro/het.nc",
                       ["suction", "saturation", "eps_v", "porosity_mean", "permeability",
                        "crack_area", "crack_volume", "crack_count", "crack_fabric",
                        "porosity_hist"])
    assert het["permeability"].dims == ("checkpoint", "phase", "axis")
    np.testing.assert_array_equal(het["suction"].values, [132.0e6, 60.0e6])
    assert het.attrs["porosity_source"] == "ct"
    hom = read_dataset(finished / "results/micro/hom.nc", ["permeability"])
    assert hom.attrs["porosity_source"] == "homogeneous"
    # k0 = 1e-20 m2 times k_r = Se^2 with Se about 0.5 and exp(2 (phi - 0.25)) near 1
    assert 1e-22 < float(het["permeability"].sel(phase="water").isel(checkpoint=0).mean()) < 1e-20
    assert (finished / "results/micro/comparison.png").stat().st_size > 10_000


def test_macro_product_ran_the_configured_steps(finished):
    """The macro rule read the tiny table and stopped at the max_steps guard."""
    log = (finished / "results/logs/macro_case/weibull.log").read_text()
    assert "case weibull: 66 pellets" in log and "stopped (max_steps)" in log
    assert (finished / "results/macro/weibull.nc").stat().st_size > 0
    assert (finished / "results/macro/weibull.png").stat().st_size > 10_000


def test_bad_packing_key_is_named(tmp_path):
    config = yaml.safe_load(yaml.safe_dump(TINY))
    config["packings"] = {"flat": {"n_particles": 0}}
    _fails_with(tmp_path, config, "packings.flat.n_particles")


@pytest.fixture(scope="module")
def two_samples(tmp_path_factory):
    """The CT rules for two samples: the phantom, and a scan given as a folder of slices
    (the same phantom written slice by slice), each with its own REV setting."""
    from imaging.ct.io import write_slice_folder
    from imaging.ct.phantom import pellet_phantom
    from imaging.ct.run import phantom_spec
    from shared.config import default_config

    tmp = tmp_path_factory.mktemp("wf_samples")
    defaults = default_config()
    spec = phantom_spec(dict(defaults["phantom"], shape=[32, 32, 32], seed=2),
                        defaults["imaging"]["calibration"], 3.0e-4)
    folder = write_slice_folder(pellet_phantom(spec)[0], tmp / "scan_slices")
    config = yaml.safe_load(yaml.safe_dump(TINY))
    config["samples"]["sliced"] = {"source": "slices", "path": str(folder),
                                   "voxel_size_m": 3.0e-4,
                                   "imaging": {"rev": {"tolerance": 0.1}}}
    (tmp / "wf").mkdir()
    workdir = _workdir(tmp / "wf", config)
    result = _snakemake(workdir, "results/rev/pellet.nc", "results/rev/sliced.nc")
    assert result.returncode == 0, result.stderr[-3000:]
    return workdir, folder


def _copy_with(workdir: Path, tmp: Path, edit) -> tuple[Path, set[str]]:
    """A copy of a finished run with a config edit, and the outputs whose params changed."""
    copy = tmp / "wf"
    shutil.copytree(workdir, copy, symlinks=True)
    path = copy / "config" / "config.yaml"
    config = yaml.safe_load(path.read_text())
    edit(config)
    path.write_text(yaml.safe_dump(config))
    result = _snakemake(copy, "--list-changes", "params")
    assert result.returncode == 0, result.stderr[-3000:]
    return copy, {line.strip() for line in result.stdout.splitlines()
                  if line.startswith("results/")}


@pytest.mark.parametrize(
    ("section", "value", "changed"),
    [
        ("rev", {"tolerance": 0.2}, {"results/rev/sliced.nc", "results/rev/sliced.png"}),
        ("mask", {"min_slice_fraction": 0.3},
         {"results/images/sliced.nc", "results/porosity/sliced.nc",
          "results/porosity/sliced.png"}),
    ],
)
def test_a_samples_own_setting_reruns_that_sample_alone(two_samples, tmp_path, section,
                                                        value, changed):
    workdir, _ = two_samples

    def edit(config):
        config["samples"]["sliced"]["imaging"][section] = value

    _, listed = _copy_with(workdir, tmp_path, edit)
    assert listed == changed


def test_the_section_default_reaches_samples_without_their_own_value(two_samples, tmp_path):
    """imaging.rev.tolerance is the phantom's (it sets none), not the sliced scan's."""
    workdir, _ = two_samples

    def edit(config):
        config["imaging"]["rev"]["tolerance"] = 0.3

    _, listed = _copy_with(workdir, tmp_path, edit)
    assert listed == {"results/rev/pellet.nc", "results/rev/pellet.png"}


def test_editing_one_slice_reruns_its_sample_and_is_in_the_provenance(two_samples, tmp_path):
    workdir, folder = two_samples
    record = json.loads(read_dataset(workdir / "results/images/sliced.nc", ["specimen", "grey_preview"])
                        .attrs["inputs"])
    assert record[0]["path"] == str(folder) and record[0]["files"] == 32
    assert len(record[0]["sha256"]) == 64
    copy = tmp_path / "wf"
    shutil.copytree(workdir, copy, symlinks=True)
    edited = tmp_path / "slices"
    shutil.copytree(folder, edited)
    path = copy / "config" / "config.yaml"
    config = yaml.safe_load(path.read_text())
    config["samples"]["sliced"]["path"] = str(edited)
    path.write_text(yaml.safe_dump(config))
    # the copied folder is newer than the outputs: let the dates settle first
    assert _snakemake(copy, "--touch", "results/rev/sliced.nc").returncode == 0
    assert "Nothing to be done" in _snakemake(copy, "-n", "results/rev/sliced.nc").stdout
    import cv2

    page = sorted(edited.glob("*.tif"))[16]
    image = cv2.imread(str(page), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(page), image // 2)
    dry = _snakemake(copy, "-n", "results/rev/sliced.nc", "results/rev/pellet.nc")
    assert dry.returncode == 0, dry.stderr[-3000:]
    stats = dry.stdout.split("Job stats:")[1].split("total")[0]
    assert "imaging_porosity" in stats and "imaging_rev" in stats
    assert "sample=sliced" in dry.stdout and "sample=pellet" not in dry.stdout


def _caption_phrases(caption: Path) -> list[str]:
    """The caption's sentences without a Jinja field, whitespace collapsed."""
    text = " ".join(caption.read_text().split())
    return [s for s in re.split(r"(?<=\.) ", text) if "{{" not in s and len(s.split()) > 5]


@pytest.fixture(scope="module")
def imaged(tmp_path_factory):
    """The CT stage of the tiny configuration, finished (the cheapest run with figures)."""
    workdir = _workdir(tmp_path_factory.mktemp("wf_ct"), TINY)
    result = _snakemake(workdir, "results/rev/pellet.png")
    assert result.returncode == 0, result.stderr[-3000:]
    return workdir


def test_every_figure_is_a_report_item_with_a_caption():
    rules = "".join(p.read_text() for p in (ROOT / "workflow/rules").glob("*.smk"))
    figures = re.findall(r"figure=(\S*)\s*\n\s*(\"[^\"]+\.png\")", rules)
    assert len(figures) == 12
    assert all(call == "report(" for call, _ in figures), figures
    for caption in re.findall(r'caption="\.\./report/(\w+\.rst)"', rules):
        assert _caption_phrases(ROOT / "workflow/report" / caption), caption


def test_the_report_holds_the_figures_with_their_captions(imaged):
    """``snakemake --report`` on a finished run: each figure with its caption rendered."""
    result = _snakemake(imaged, "--report", "report.html", "results/rev/pellet.png")
    assert result.returncode == 0, result.stderr[-3000:]
    text = (imaged / "report.html").read_text()
    text = " ".join(html_module.unescape(text).replace("\\n", " ").split())
    for name in ("workflow", "porosity", "rev"):
        for phrase in _caption_phrases(ROOT / "workflow/report" / f"{name}.rst"):
            assert phrase in text, (name, phrase)
    assert "CT stage, sample pellet:" in text  # the caption's wildcard filled in
    for figure in ("results/porosity/pellet.png", "results/rev/pellet.png"):
        assert f'"{figure}": {{"name": "pellet.png"' in text, figure


def test_an_overlay_from_the_command_line_plans_the_reruns_of_its_key(imaged, tmp_path):
    """``--set imaging.rev.n_sizes=6`` as the launcher passes it: REV reruns, nothing else."""
    overlay = tmp_path / "overrides.yaml"
    made = subprocess.run(
        [sys.executable, "-m", "shared.overrides", "--output", str(overlay),
         "--configfile", str(imaged / "config/config.yaml"), "--set", "imaging.rev.n_sizes=6"],
        capture_output=True, text=True, timeout=120)
    assert made.returncode == 0, made.stderr
    target = "results/rev/pellet.png"
    result = _snakemake(imaged, "-n", target, "--configfile", "config/config.yaml", str(overlay))
    assert result.returncode == 0, result.stderr[-3000:]
    planned = set(re.findall(r"^rule (\w+):", result.stdout, re.MULTILINE))
    assert planned == {"imaging_rev"}, result.stdout[-3000:]
    assert "params" in result.stdout.lower()
    unchanged = _snakemake(imaged, "-n", target, "--configfile", "config/config.yaml")
    assert "Nothing to be done" in unchanged.stdout + unchanged.stderr
