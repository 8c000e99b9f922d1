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
from tests.workflow._chain import ROOT, edited_copy, listed, snakemake, workdir

TINY = {
    "samples": {"pellet": {"source": "phantom", "voxel_size_m": 3.0e-4}},
    "phantom": {"shape": [32, 32, 32], "seed": 1},
    "imaging": {"rev": {"n_sizes": 5, "n_positions": 16, "tolerance": 0.05}},
    "micro": {
        "specimen_size_m": 4.0e-3,
        "n_points": 64,
        "checkpoints_suction_pa": [132.0e6, 60.0e6],
        "cases": {"het": {"porosity": "ct"}, "hom": {"porosity": "homogeneous"}},
    },
    "upscaling": {"conditions": {"free": "het", "confined": "hom"},
                  "suction_range_pa": [60.0e6, 132.0e6]},
    # the small column of tests/_macro_cases.py (about 70 pellets), 10 steps: the macro rule
    # runs on the tiny table, its physics is tested in tests/macro; the ends held at the
    # table's lowest suction (a table must cover a case's range within a decade)
    "macro": {
        "cylinder_height_m": 0.05, "cylinder_radius_m": 0.015, "pellet_radius_m": 4.0e-3,
        "mixture": {"pellet_powder_dry_mass_ratio": None},  # the default's 80/20 packs no small column
        "boundary_suction_pa": 60.0e6,
        "sensors": {name: {"height_m": height, "band_width_m": 0.008}
                    for name, height in (("S10", 0.01), ("S25", 0.025), ("S40", 0.04))},
        "numerics": {"packing_iterations": 1500, "max_steps": 10},
    },
}


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    """The tiny configuration run once to the end for every test of a finished run: the
    phantom sample ``pellet`` through micro, upscaling and macro, and a second sample
    ``sliced``, a scan given as a folder of slices (another phantom written slice by slice)
    with its own REV setting, through the CT rules (no case reads it). A test that changes
    the folder (runs or touches a job, edits the config) works on a copy (``edited_copy``);
    dry runs and the report read it in place."""
    from imaging.ct.io import write_slice_folder
    from imaging.ct.phantom import pellet_phantom
    from imaging.ct.run import phantom_spec
    from shared.config import default_config

    tmp = tmp_path_factory.mktemp("wf_chain")
    defaults = default_config()
    spec = phantom_spec(dict(defaults["phantom"], shape=[32, 32, 32], seed=2),
                        defaults["imaging"]["calibration"], 3.0e-4)
    folder = write_slice_folder(pellet_phantom(spec)[0], tmp / "scan_slices")
    config = yaml.safe_load(yaml.safe_dump(TINY))
    config["samples"]["sliced"] = {"source": "slices", "path": str(folder),
                                   "voxel_size_m": 3.0e-4,
                                   "imaging": {"rev": {"tolerance": 0.1}}}
    (tmp / "wf").mkdir()
    work = workdir(tmp / "wf", config)
    snakemake(work)
    # before any edit, no output's params differ (checked once for every edit below)
    assert not listed(snakemake(work, "--list-changes", "params"))
    return work, folder


@pytest.fixture(scope="module")
def finished(chain):
    """The folder of the finished tiny run."""
    return chain[0]


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
    # micro spacing 4 mm / 64^(1/3) = 1 mm, i.e. blocks of 3.33 -> 3 voxels of 0.3 mm
    assert porosity.attrs["block_voxels"] == 3
    assert np.nanmean(porosity["porosity"].values) == pytest.approx(0.25, abs=0.05)
    assert (finished / "results/porosity/pellet.png").stat().st_size > 10_000
    assert (finished / "results/rev/pellet.png").stat().st_size > 10_000
    assert (finished / "results/logs/imaging_rev/pellet.log").read_text().count("REV") == 1


def test_forcerun_until_reruns_only_that_rule(finished, tmp_path):
    copy = edited_copy(finished, tmp_path / "wf")
    before = {name: (copy / f"results/logs/imaging_{name}/pellet.log").stat().st_mtime_ns
              for name in ("porosity", "rev")}
    result = snakemake(copy, "-R", "imaging_rev", "-U", "imaging_rev")
    after = {name: (copy / f"results/logs/imaging_{name}/pellet.log").stat().st_mtime_ns
             for name in ("porosity", "rev")}
    assert after["porosity"] == before["porosity"]
    assert after["rev"] > before["rev"]
    stats = result.stderr.split("Job stats:")[1].split("total")[0]
    assert "imaging_rev" in stats and "imaging_porosity" not in stats


_PHANTOM = {"results/phantom/pellet.tif"}
_POROSITY = {"results/images/pellet.nc", "results/porosity/pellet.nc",
             "results/porosity/pellet.png"}
_REV = {"results/rev/pellet.nc", "results/rev/pellet.png"}
# the second sample's CT products: the shared imaging and pellet settings reach them too
_SLICED = {"results/images/sliced.nc", "results/porosity/sliced.nc",
           "results/porosity/sliced.png"}


_MICRO = {f"results/micro/{case}.{suffix}" for case in TINY["micro"]["cases"]
          for suffix in ("nc", "png")}
_MACRO = {"results/macro/weibull.nc", "results/macro/weibull.png"}


@pytest.mark.parametrize(
    ("key", "value", "readers"),
    [
        # the phantom is the pellet sample's alone
        ("imaging.calibration.air_density_kg_m3", 1.2, _PHANTOM | _POROSITY | _SLICED),
        ("imaging.calibration.muscovite_density_kg_m3", 3800.0,
         _PHANTOM | _POROSITY | _SLICED),
        ("imaging.calibration.grey_air", 100.0, _POROSITY | _SLICED),
        # the sliced sample sets its own tolerance
        ("imaging.rev.tolerance", 0.1, _REV),
        # the calibration's mean dry density and phi_0 are the pellet's
        ("materials.pellet.dry_density_kg_m3", 2000.0, _POROSITY | _SLICED),
        ("materials.pellet.reference_porosity", 0.3, _POROSITY | _SLICED | _MICRO),
        # a Table 3.1 parameter reruns the micro cases alone (not the table or macro)
        ("materials.pellet.retention_pressure_reference_pa", 4.0e4, _MICRO),
        ("materials.pellet.swelling_beta_per_pa", 1.0e-8, _MICRO),
        # the mock-up's parameters rerun the macro case alone, no micro or imaging rule
        ("materials.mixture_powder.retention_exponent_reference", 0.3, _MACRO),
        # the macro job's threads are a machine resource: the results do not depend on them
        ("macro.threads", 1, set()),
    ],
)
def test_a_config_edit_changes_the_params_of_its_readers_only(
    finished, tmp_path, key, value, readers
):
    """Editing a config key changes the params of the rules whose scripts read it, and
    of no other rule.

    Run on a copy of the finished tiny run (results and ``.snakemake`` metadata, so every
    output's recorded params are there; the micro cases read the porosity grid but no
    ``imaging`` key, the macro case reads the table but no ``materials.pellet`` key), with
    ``snakemake --list-changes params``: it lists the outputs whose recorded params differ
    from the rule's current ones, i.e. the jobs that the params trigger reruns for the
    edit itself, and runs nothing. A dry run (``-n``) would also list the jobs downstream
    of those (they rerun because their inputs change), so it cannot tell a rule that reads
    the key from one that consumes the reader's file. The unedited run lists nothing
    (checked once, in the fixture), so the recorded params are those of the current rules.
    """

    def edit(config):
        *sections, name = key.split(".")
        node = config
        for section in sections:
            node = node.setdefault(section, {})
        node[name] = value

    assert _changed(finished, tmp_path, edit) == readers


def _fails_with(tmp: Path, config: dict, message: str) -> None:
    work = workdir(tmp, config)
    result = snakemake(work, ok=False)
    logs = "".join(p.read_text() for p in (work / "results/logs").rglob("*.log")) if (
        work / "results/logs").exists() else ""
    assert message in result.stderr + logs
    produced = [p for p in (work / "results").rglob("*.nc")] if (work / "results").exists() else []
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
    assert het["permeability"].dims == ("suction", "phase", "axis")
    np.testing.assert_array_equal(het["suction"].values, [132.0e6, 60.0e6])
    assert het.attrs["porosity_source"] == "ct"
    hom = read_dataset(finished / "results/micro/hom.nc", ["permeability"])
    assert hom.attrs["porosity_source"] == "homogeneous"
    # k0 = 1e-20 m2 times k_r = Se^2 with Se about 0.5 and exp(2 (phi - 0.25)) near 1
    assert 1e-22 < float(het["permeability"].sel(phase="water").isel(suction=0).mean()) < 1e-20
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


def _changed(run: Path, tmp: Path, edit) -> set[str]:
    """The outputs whose params change by a config edit, in a copy of a finished run."""
    copy = edited_copy(run, tmp / "wf", edit)
    return listed(snakemake(copy, "--list-changes", "params"))


@pytest.mark.parametrize(
    ("section", "value", "changed"),
    [
        ("rev", {"tolerance": 0.2}, {"results/rev/sliced.nc", "results/rev/sliced.png"}),
        ("mask", {"min_slice_fraction": 0.3},
         {"results/images/sliced.nc", "results/porosity/sliced.nc",
          "results/porosity/sliced.png"}),
    ],
)
def test_a_samples_own_setting_reruns_that_sample_alone(finished, tmp_path, section,
                                                        value, changed):
    def edit(config):
        config["samples"]["sliced"]["imaging"][section] = value

    assert _changed(finished, tmp_path, edit) == changed


def test_the_section_default_reaches_samples_without_their_own_value(finished, tmp_path):
    """imaging.rev.tolerance is the phantom's (it sets none), not the sliced scan's."""

    def edit(config):
        config["imaging"]["rev"]["tolerance"] = 0.3

    assert _changed(finished, tmp_path, edit) == {"results/rev/pellet.nc",
                                                  "results/rev/pellet.png"}


def test_editing_one_slice_reruns_its_sample_and_is_in_the_provenance(chain, tmp_path):
    run, folder = chain
    record = json.loads(read_dataset(run / "results/images/sliced.nc", ["specimen", "grey_preview"])
                        .attrs["inputs"])
    assert record[0]["path"] == str(folder) and record[0]["files"] == 32
    assert len(record[0]["sha256"]) == 64
    edited = tmp_path / "slices"
    shutil.copytree(folder, edited)

    def edit(config):
        config["samples"]["sliced"]["path"] = str(edited)

    copy = edited_copy(run, tmp_path / "wf", edit)
    # the copied folder is newer than the outputs: let the dates settle first
    snakemake(copy, "--touch", "results/rev/sliced.nc")
    assert "Nothing to be done" in snakemake(copy, "-n", "results/rev/sliced.nc").stdout
    import cv2

    page = sorted(edited.glob("*.tif"))[16]
    image = cv2.imread(str(page), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(page), image // 2)
    dry = snakemake(copy, "-n", "results/rev/sliced.nc", "results/rev/pellet.nc")
    stats = dry.stdout.split("Job stats:")[1].split("total")[0]
    assert "imaging_porosity" in stats and "imaging_rev" in stats
    assert "sample=sliced" in dry.stdout and "sample=pellet" not in dry.stdout


def _caption_phrases(caption: Path) -> list[str]:
    """The caption's sentences without a Jinja field, whitespace collapsed."""
    text = " ".join(caption.read_text().split())
    return [s for s in re.split(r"(?<=\.) ", text) if "{{" not in s and len(s.split()) > 5]


def test_every_figure_is_a_report_item_with_a_caption():
    rules = "".join(p.read_text() for p in (ROOT / "workflow/rules").glob("*.smk"))
    figures = re.findall(r"figure=(\S*)\s*\n\s*run_path\((\"[^\"]+\.png\")\)", rules)
    assert len(figures) == 12
    assert all(call == "report(" for call, _ in figures), figures
    for caption in re.findall(r'caption="\.\./report/(\w+\.rst)"', rules):
        assert _caption_phrases(ROOT / "workflow/report" / caption), caption


def test_the_report_holds_the_figures_with_their_captions(finished, tmp_path):
    """``snakemake --report`` on a finished run: each figure with its caption rendered."""
    report = tmp_path / "report.html"
    snakemake(finished, "--report", str(report), "results/rev/pellet.png")
    text = report.read_text()
    text = " ".join(html_module.unescape(text).replace("\\n", " ").split())
    for name in ("workflow", "porosity", "rev"):
        for phrase in _caption_phrases(ROOT / "workflow/report" / f"{name}.rst"):
            assert phrase in text, (name, phrase)
    assert "CT stage, sample pellet:" in text  # the caption's wildcard filled in
    for figure in ("results/porosity/pellet.png", "results/rev/pellet.png"):
        assert f'"{figure}": {{"name": "pellet.png"' in text, figure


def test_an_overlay_from_the_command_line_plans_the_reruns_of_its_key(finished, tmp_path):
    """``--set imaging.rev.n_sizes=6`` as the launcher passes it: REV reruns, nothing else."""
    overlay = tmp_path / "overrides.yaml"
    made = subprocess.run(
        [sys.executable, "-m", "shared.overrides", "--output", str(overlay),
         "--configfile", str(finished / "config/config.yaml"), "--set", "imaging.rev.n_sizes=6"],
        capture_output=True, text=True, timeout=120)
    assert made.returncode == 0, made.stderr
    target = "results/rev/pellet.png"
    result = snakemake(finished, "-n", target, "--configfile", "config/config.yaml", str(overlay))
    planned = set(re.findall(r"^rule (\w+):", result.stdout, re.MULTILINE))
    assert planned == {"imaging_rev"}, result.stdout[-3000:]
    assert "params" in result.stdout.lower()
    unchanged = snakemake(finished, "-n", target, "--configfile", "config/config.yaml")
    assert "Nothing to be done" in unchanged.stdout + unchanged.stderr
