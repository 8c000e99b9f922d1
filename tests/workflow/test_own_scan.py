"""Your own scan through the whole chain (docs/howto-own-scan.md): a scan given as a
folder of slices informs a micro case (``micro.cases.<case>.sample``), whose curve makes
the upscaling table that a macro case reads.

Each product records the sha256 of the files it read (``inputs``); the test follows that
lineage back from the macro result to the scan's images, each hash against the file on
disk.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from shared.io import read_dataset
from shared.provenance import file_sha256
from tests.workflow._chain import snakemake, workdir


def _inputs(path: Path) -> dict[str, str]:
    """The files a product read, path -> sha256 (its ``inputs`` attribute)."""
    return {entry["path"]: entry["sha256"] for entry in json.loads(read_dataset(path).attrs["inputs"])}


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    from imaging.ct.io import write_slice_folder
    from imaging.ct.phantom import pellet_phantom
    from imaging.ct.run import phantom_spec
    from shared.config import default_config

    tmp = tmp_path_factory.mktemp("own_scan")
    defaults = default_config()
    spec = phantom_spec(dict(defaults["phantom"], shape=[32, 32, 32], seed=5),
                        defaults["imaging"]["calibration"], 3.0e-4)
    folder = write_slice_folder(pellet_phantom(spec)[0], tmp / "my_scan")
    macro = {
        "cylinder_height_m": 0.05, "cylinder_radius_m": 0.015, "pellet_radius_m": 4.0e-3,
        "boundary_suction_pa": 60.0e6,  # the table's lowest suction (it covers 60-132 MPa)
        "sensors": {"S10": {"height_m": 0.01, "band_width_m": 0.008}},
        "cases": {"mine": {}},
        "numerics": {"packing_iterations": 1500, "max_steps": 5},
    }
    config = {
        "samples": {
            "pellet": {"source": "phantom", "voxel_size_m": 3.0e-4},
            "scan": {"source": "slices", "path": str(folder), "voxel_size_m": 3.0e-4},
        },
        "micro": {
            "specimen_size_m": 4.0e-3, "n_points": 64,
            "checkpoints_suction_pa": [132.0e6, 60.0e6],
            "cases": {"mine": {"porosity": "ct", "sample": "scan"}},
        },
        "upscaling": {"conditions": {"free": "mine", "confined": "mine"},
                      "suction_range_pa": [60.0e6, 132.0e6]},
        "macro": macro,
    }
    (tmp / "wf").mkdir()
    work = workdir(tmp / "wf", config)
    snakemake(work, "results/macro/mine.nc")
    return work


def test_the_scan_reaches_the_macro_model_through_micro_and_the_table(chain):
    lineage = [
        ("results/macro/mine.nc", "results/upscaling/pellet_permeability.nc"),
        ("results/upscaling/pellet_permeability.nc", "results/micro/mine.nc"),
        ("results/micro/mine.nc", "results/porosity/scan.nc"),
        ("results/porosity/scan.nc", "results/images/scan.nc"),
    ]
    for product, source in lineage:
        read = _inputs(chain / product)
        assert source in read, f"{product} read {sorted(read)}"
        assert read[source] == file_sha256(chain / source)
    assert read_dataset(chain / "results/micro/mine.nc").attrs["porosity_source"] == "ct"
    # the phantom sample, which no case of this run reads, was not built
    assert not (chain / "results/porosity/pellet.nc").exists()


def test_the_macro_case_ran_on_the_scans_table(chain):
    macro = read_dataset(chain / "results/macro/mine.nc", ["sensor_pressure"])
    assert int(macro.attrs["steps"]) == 5
    table = read_dataset(chain / "results/upscaling/pellet_permeability.nc", ["k"])
    assert float(table["k"].min()) > 0.0
