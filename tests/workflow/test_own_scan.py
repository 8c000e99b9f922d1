"""Your own scan through the whole chain, as docs/howto-own-scan.md walks it: the how-to's
overlay file, read from the page, on a raw scan of another size than the phantom's, in a
run of its own name (``run_name``) beside the default's.

Each product records the sha256 of the files it read (``inputs``); the test follows that
lineage back from the macro result to the scan's images, each hash against the file on
disk. A second test file (``fast.yaml``) only makes the run small: fewer points, two
checkpoints, a small macro column, two of the default's four micro cases.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import yaml

from shared.io import read_dataset
from shared.provenance import file_sha256
from tests.workflow._chain import ROOT, snakemake, workdir

SHAPE = [40, 56, 60]
"""The test scan's voxel counts (z, y, x): 4.0 x 5.6 x 6.0 mm of 0.1 mm voxels; the
phantom's pellet, of radius 0.92 x 2.8 mm, holds the how-to's 2 mm cube with one grid
spacing around it."""

FAST = {
    "imaging": {"rev": {"n_sizes": 5, "n_positions": 16, "tolerance": 0.05}},
    "micro": {
        "n_points": 64,
        "checkpoints_suction_pa": [132.0e6, 60.0e6],
        "cases": {"homogeneous": None, "uncoupled_cracks": None},
        "studies": {"scale": {"reference": None, "fractions": []}},
    },
    "upscaling": {"suction_range_pa": [60.0e6, 132.0e6]},
    "macro": {
        "cylinder_height_m": 0.05, "cylinder_radius_m": 0.015, "pellet_radius_m": 4.0e-3,
        "mixture": {"pellet_powder_dry_mass_ratio": None},  # the default's 80/20 packs no small column
        "boundary_suction_pa": 60.0e6,  # the table's lowest suction (it covers 60-132 MPa)
        "sensors": {"S10": {"height_m": 0.01, "band_width_m": 0.008}},
        "numerics": {"packing_iterations": 1500, "max_steps": 5},
    },
}


def howto_overlay() -> dict:
    """The overlay file of docs/howto-own-scan.md (the YAML block after its marker)."""
    page = (ROOT / "docs" / "howto-own-scan.md").read_text()
    block = re.search(r"<!-- the overlay of tests/workflow/test_own_scan.py[^>]*-->\s*```yaml\n(.*?)```",
                      page, re.S)
    assert block, "docs/howto-own-scan.md lost its overlay block"
    return yaml.safe_load(block.group(1))


def _inputs(path: Path) -> dict[str, str]:
    """The files a product read, path -> sha256 (its ``inputs`` attribute)."""
    return {entry["path"]: entry["sha256"] for entry in json.loads(read_dataset(path).attrs["inputs"])}


def _files(work: Path, overlay: dict, name: str) -> list[str]:
    """``--configfile`` arguments: the default config, then ``overlay`` and the fast file."""
    (work / f"{name}.yaml").write_text(yaml.safe_dump(overlay))
    (work / "fast.yaml").write_text(yaml.safe_dump(FAST))
    return ["--configfile", "config/config.yaml", f"{name}.yaml", "fast.yaml"]


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    """A default product (the phantom's scan), then the how-to's run to its end."""
    from imaging.ct.phantom import pellet_phantom
    from imaging.ct.run import phantom_spec
    from shared.config import default_config

    work = workdir(tmp_path_factory.mktemp("own_scan"), None)
    overlay = howto_overlay()
    defaults = default_config()
    spec = phantom_spec(dict(defaults["phantom"], shape=SHAPE, seed=5, n_flaws=0),
                        defaults["imaging"]["calibration"], 1.0e-4)
    scan = work / overlay["samples"]["myscan"]["path"]  # relative to the workflow's folder
    scan.parent.mkdir(parents=True)
    pellet_phantom(spec)[0].astype("<u2").tofile(scan)
    overlay["samples"]["myscan"].update(voxel_size_m=1.0e-4, raw=dict(
        overlay["samples"]["myscan"]["raw"], shape=SHAPE))
    snakemake(work, "results/phantom/pellet.tif")
    files = _files(work, overlay, "my_scan")
    snakemake(work, *files)
    return work, overlay, files


def test_the_scan_reaches_the_macro_model_through_micro_and_the_table(chain):
    work, _, _ = chain
    run = "results/myscan"
    lineage = [
        (f"{run}/macro/weibull.nc", f"{run}/upscaling/pellet_permeability.nc"),
        (f"{run}/upscaling/pellet_permeability.nc", f"{run}/micro/heterogeneous.nc"),
        (f"{run}/micro/heterogeneous.nc", f"{run}/porosity/myscan.nc"),
        (f"{run}/porosity/myscan.nc", f"{run}/images/myscan.nc"),
    ]
    for product, source in lineage:
        read = _inputs(work / product)
        assert source in read, f"{product} read {sorted(read)}"
        assert read[source] == file_sha256(work / source)
    assert read_dataset(work / f"{run}/micro/heterogeneous.nc").attrs["porosity_source"] == "ct"
    # the sample the overlay removed was not built in the run, nor the removed cases
    assert not (work / f"{run}/porosity/pellet.nc").exists()
    assert sorted(p.name for p in (work / run / "micro").glob("*.nc")) == [
        "confined.nc", "heterogeneous.nc"]
    macro = read_dataset(work / f"{run}/macro/weibull.nc", ["sensor_pressure"])
    assert int(macro.attrs["steps"]) == 5


def test_the_grid_spacing_is_the_overlays_case_spacing(chain):
    work, overlay, _ = chain
    grid = read_dataset(work / "results/myscan/porosity/myscan.nc", ["porosity"])
    # 2 mm / 64^(1/3) = 0.5 mm: blocks of 5 voxels of 0.1 mm (the default's 0.7 mm: 7)
    assert overlay["micro"]["specimen_size_m"] == 2.0e-3
    assert int(grid.attrs["block_voxels"]) == 5
    # the calibration's pair is the overlay's
    assert float(grid.attrs["dry_density"]) == 1600.0
    assert float(grid.attrs["mean_porosity_anchor"]) == 0.40


def test_switching_runs_reruns_nothing(chain):
    work, _, files = chain
    again = snakemake(work, "-n", *files)
    assert "Nothing to be done" in again.stdout + again.stderr
    default = snakemake(work, "-n", "results/phantom/pellet.tif")
    assert "Nothing to be done" in default.stdout + default.stderr


def test_a_cube_larger_than_the_scan_is_refused_before_any_job(chain):
    work, overlay, _ = chain
    larger = yaml.safe_load(yaml.safe_dump(overlay))
    larger["micro"]["specimen_size_m"] = 3.5e-3  # z: 4.0 mm less 0.875 mm < 3.5 mm
    result = snakemake(work, "-n", *_files(work, larger, "larger"), ok=False)
    assert "micro.cases.heterogeneous.specimen_size_m" in result.stderr
    assert "samples.myscan.voxel_size_m" in result.stderr and "along z" in result.stderr


def test_the_report_and_inspect_read_the_named_run(chain, tmp_path):
    import subprocess
    import sys

    work, _, files = chain
    report = tmp_path / "myscan.html"
    snakemake(work, *files, "--report", str(report))
    text = report.read_text()
    for figure in ("results/myscan/porosity/myscan.png", "results/myscan/macro/weibull.png",
                   "results/myscan/micro/heterogeneous.png"):
        assert f'"{figure}"' in text, figure
    assert '"results/porosity/' not in text  # the default's figures are not this run's
    summary = subprocess.run([sys.executable, "-m", "shared.inspect", "results/myscan/micro/confined.nc"],
                             cwd=work, capture_output=True, text=True, timeout=120)
    assert summary.returncode == 0, summary.stderr
    assert "suction" in summary.stdout and "input: results/myscan/porosity/myscan.nc" in summary.stdout
