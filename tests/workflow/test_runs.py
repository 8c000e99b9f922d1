"""Named runs (``run_name``, shared/runs.py) and the scan sizes checked when the config
loads (shared/scan_sizes.py), on Snakemake's plans (dry runs): no job runs here."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from shared.config import ConfigError, default_config, validate_config
from shared.runs import drop_removed_entries, run_folder
from shared.scan_sizes import check_scan_sizes, sample_grid_spacing, sample_point_spacing
from tests.workflow._chain import ROOT, snakemake, workdir


def _planned(result) -> set[str]:
    """The output files of a dry run's jobs."""
    files = set()
    for line in result.stdout.splitlines():
        match = re.match(r"\s+output: (.*)", line)
        if match:
            files |= {name.strip() for name in match.group(1).split(",")}
    return files


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """The workflow with the repository's config folder, nothing run."""
    return workdir(tmp_path_factory.mktemp("runs"), None)


def test_a_named_run_plans_the_same_products_in_its_own_folder(folder):
    default = _planned(snakemake(folder, "-n"))
    named = _planned(snakemake(folder, "-n", "--config", "run_name=myscan"))
    assert "results/macro/weibull.nc" in default
    assert "results/upscaling/pellet_permeability.nc" in default
    # every product of the named run is the default's, moved under results/myscan/
    assert named == {path.replace("results/", "results/myscan/", 1) for path in default}
    assert not default & named


def test_a_run_named_like_a_stage_folder_is_refused(folder):
    result = snakemake(folder, "-n", "--config", "run_name=micro", ok=False)
    assert "config key 'run_name'" in result.stderr
    assert "results/micro/" in result.stderr


def test_the_run_folder_follows_the_name():
    assert run_folder({"run_name": None}) == "results"
    assert run_folder({}) == "results"
    assert run_folder({"run_name": "scan_b"}) == "results/scan_b"


def test_an_entry_set_to_null_is_removed_and_the_rest_validates():
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    config["packings"]["monodisperse_small"] = None
    config["micro"]["cases"]["homogeneous"] = None
    removed = drop_removed_entries(config)
    assert removed == ["packings.monodisperse_small", "micro.cases.homogeneous"]
    assert config["packings"] == {}
    assert sorted(config["micro"]["cases"]) == ["confined", "heterogeneous", "uncoupled_cracks"]
    # a null case left in is refused by the schema, and validation removes it first
    other = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    other["micro"]["cases"]["uncoupled_cracks"] = None
    assert "uncoupled_cracks" not in validate_config(other)["micro"]["cases"]


def _scan_config(**case) -> dict:
    """The default config with one micro case on a 40 x 30 x 50 scan of 0.1 mm voxels."""
    config = default_config()
    config["samples"]["scan"] = {"source": "raw", "path": "scan.raw", "voxel_size_m": 1.0e-4,
                                 "raw": {"shape": [40, 30, 50], "dtype": "uint16",
                                         "byte_order": "little"}}
    config["micro"]["cases"]["mine"] = {"porosity": "ct", "sample": "scan", "offset_m": [0, 0, 0],
                                        **case}
    return config


def test_the_grid_spacing_follows_the_smallest_case_on_the_sample():
    config = _scan_config(specimen_size_m=2.0e-3, n_points=125)
    config["micro"]["cases"]["larger"] = {"porosity": "ct", "sample": "scan", "specimen_size_m": 3.0e-3}
    # 2 mm / 1000^(1/3) = 0.2 mm at micro.n_points, whatever the case's own point count;
    # the default's cases on the phantom keep 7 mm / 10
    assert sample_point_spacing(config, "scan") == [2.0e-3, 1000]
    assert sample_grid_spacing(config, "scan") == pytest.approx(2.0e-4)
    assert sample_point_spacing(config, "pellet") == [7.0e-3, 1000]
    config["samples"]["scan"]["imaging"] = {"grid_spacing_m": 2.5e-4}
    assert sample_grid_spacing(config, "scan") == 2.5e-4


def test_a_cube_that_fits_the_scan_passes_and_a_larger_one_is_refused_naming_the_keys():
    # y: 30 voxels of 0.1 mm = 3 mm; less one 0.25 mm spacing, 2.75 mm hold a 2.5 mm cube
    check_scan_sizes(_scan_config(specimen_size_m=2.5e-3), {"scan": (40, 30, 50)})
    with pytest.raises(ConfigError) as caught:
        # 3 mm less 0.28 mm
        check_scan_sizes(_scan_config(specimen_size_m=2.8e-3), {"scan": (40, 30, 50)})
    message = str(caught.value)
    for part in ("micro.cases.mine.specimen_size_m", "samples.scan.voxel_size_m",
                 "samples.scan.imaging.grid_spacing_m", "along y", "3 mm", "at most 2.72 mm"):
        assert part in message, message


def test_an_offset_counts_twice_against_the_extent():
    config = _scan_config(specimen_size_m=2.0e-3, n_points=125)
    config["micro"]["cases"]["mine"]["offset_m"] = [0.0, 0.0, 1.0e-3]
    # z: 4 mm - 0.2 mm - 2 x 1 mm = 1.8 mm < 2 mm
    with pytest.raises(ConfigError, match="along z.*twice offset_m"):
        check_scan_sizes(config, {"scan": (40, 30, 50)})


def test_a_scan_too_small_for_a_case_stops_the_workflow_before_any_job(tmp_path):
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    config["phantom"]["shape"] = [32, 32, 32]  # 6.4 mm of 0.2 mm voxels, the cubes are 7 mm
    result = snakemake(workdir(tmp_path, config), "-n", ok=False)
    assert "micro.cases." in result.stderr and "does not fit in sample 'pellet'" in result.stderr
    assert "Job stats" not in result.stdout
