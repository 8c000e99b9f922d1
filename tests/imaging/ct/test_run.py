"""The CT stage (imaging.ct.run) on scans without air around the specimen or inside a
container: mask modes, anchors from the grey histogram, per-sample settings, the grid
spacing, against values known by construction."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from imaging.ct import run as ct_run
from imaging.ct.calibration import anchors_through, histogram_peaks
from imaging.ct.io import write_tiff_stack
from imaging.ct.phantom import pellet_phantom
from imaging.ct.settings import ScanResources, grid_spacing
from shared.config import ConfigError, default_config, sample_imaging

CONFIG = default_config()
SOLID_DENSITY, AIR_DENSITY = 2650.0, 1.13
GREY_AIR, GREY_SOLID, NOISE = 6000.0, 42000.0, 400.0
BLOCK = 8


def _granular(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Air and one solid filling the whole field, the air fraction varying block to block:
    the grey volume and each block's air fraction (the porosity to recover)."""
    blocks = (4, 4, 4)
    fraction = rng.uniform(0.15, 0.45, size=blocks)
    air = rng.random(tuple(BLOCK * n for n in blocks)) < np.kron(fraction, np.ones((BLOCK,) * 3))
    grey = np.where(air, GREY_AIR, GREY_SOLID) + rng.normal(0.0, NOISE, air.shape)
    truth = air.reshape(4, BLOCK, 4, BLOCK, 4, BLOCK).mean(axis=(1, 3, 5))
    return np.clip(grey, 0, 65535).astype(np.uint16), truth


def _porosity(tmp: Path, scan: Path, imaging: dict, voxel: float = 1e-4):
    results = tmp / "results"
    entry = {"source": "tiff", "path": str(scan), "voxel_size_m": voxel}
    config = {"sample": entry, "imaging": imaging, "material": CONFIG["materials"]["pellet"],
              "micro_spacing": (1.0, 8)}
    outputs = ct_run.PorosityOutputs(results / "images/scan.nc", results / "porosity/scan.nc",
                                     results / "porosity/scan.png")
    return ct_run.porosity(config, "scan", scan, outputs, resources=ScanResources.from_mapping(imaging))


def test_histogram_peaks_find_two_phases_and_their_line(rng):
    grey, _ = _granular(rng)
    peaks, prominence = histogram_peaks(grey)
    np.testing.assert_allclose(peaks, [GREY_AIR, GREY_SOLID], atol=0.01 * (GREY_SOLID - GREY_AIR))
    assert prominence.min() > 0.05
    # the line through two phases, extended to air and muscovite, holds both phases
    low, high = anchors_through((1000.0, 31000.0), (500.0, 2000.0), 1.13, 3900.0)
    slope = (high - low) / (3900.0 - 1.13)
    assert low + slope * (500.0 - 1.13) == pytest.approx(1000.0, rel=1e-12)
    assert low + slope * (2000.0 - 1.13) == pytest.approx(31000.0, rel=1e-12)


def test_a_scan_that_fills_the_field_gives_each_blocks_air_fraction(rng, tmp_path):
    """Mode full and anchors from the two peaks (air, solid), the specimen's own dry density
    and porosity: the porosity grid is the air fraction of each block (a linear mixture)."""
    grey, truth = _granular(rng)
    scan = write_tiff_stack(grey, tmp_path / "granular.tif")
    mean = float(truth.mean())
    config = copy.deepcopy(CONFIG)
    config["samples"]["granular"] = {"source": "tiff", "path": str(scan), "voxel_size_m": 1e-4,
                                     "imaging": {
        "mask": {"mode": "full"},
        "grid_spacing_m": BLOCK * 1e-4,
        "calibration": {"anchors": "histogram_peaks",
                        "peak_densities_kg_m3": [AIR_DENSITY, SOLID_DENSITY],
                        "dry_density_kg_m3": (1 - mean) * SOLID_DENSITY + mean * AIR_DENSITY,
                        "reference_porosity": mean}}}
    imaging = sample_imaging(config, "granular")
    ds = _porosity(tmp_path, scan, imaging)
    np.testing.assert_allclose(ds["porosity"].values, truth, atol=0.01)
    assert ds.attrs["calibration_anchors"] == "histogram_peaks"
    assert ds.attrs["mask_mode"] == "full"
    np.testing.assert_allclose(ds.attrs["histogram_peak_densities"], [AIR_DENSITY, SOLID_DENSITY])


def test_a_pellet_in_a_container_is_masked_by_the_containers_cylinder(tmp_path):
    """A pellet wrapped in a bright container wall: a cylinder inside the wall and between
    the pellet's ends, with the air grey given, recovers the density of every block inside
    and leaves the wall out."""
    spec = ct_run.phantom_spec(dict(CONFIG["phantom"], shape=[24, 48, 48], seed=2),
                               CONFIG["imaging"]["calibration"], 1e-4)
    grey, density = pellet_phantom(spec)
    radius_vox = spec.radius_fraction * 24
    y, x = np.ogrid[:48, :48]
    r = np.hypot(y - 23.5, x - 23.5)
    grey = grey.copy()
    wall = (r > radius_vox + 0.5) & (r < radius_vox + 2.5)
    grey[:, wall] = 50000  # the container wall, brighter than the clay
    scan = write_tiff_stack(grey, tmp_path / "container.tif")
    imaging = copy.deepcopy(CONFIG["imaging"])
    height = spec.height_fraction * 24
    ends = ((24 - height) / 2 + 1.0) * 1e-4, ((24 + height) / 2 - 1.0) * 1e-4
    imaging["mask"].update(mode="cylinder", cylinder_radius_m=(radius_vox - 1.0) * 1e-4,
                           cylinder_z_m=list(ends))
    imaging["calibration"]["grey_air"] = spec.grey_air
    imaging["grid_spacing_m"] = 6e-4
    ds = _porosity(tmp_path, scan, imaging)
    inside = ds["specimen_fraction"].values == 1.0
    # each block inside has the phantom's own density (flaws open to the side included)
    truth = density.reshape(4, 6, 8, 6, 8, 6).mean(axis=(1, 3, 5))
    assert inside.sum() >= 20
    measured = ds["density"].values[inside]
    assert measured.mean() == pytest.approx(truth[inside].mean(), rel=0.02)
    # block by block, within the blur (0.7 voxel) of the 1200 kg/m3 steps at flaw faces
    assert np.abs(measured - truth[inside]).max() < 200.0
    image = ct_run.read_dataset(tmp_path / "results/images/scan.nc", ["specimen"])
    assert not image["specimen"].values[:, wall].any()


def test_sample_settings_merge_over_the_imaging_section():
    config = copy.deepcopy(CONFIG)
    config["samples"]["other"] = {"source": "phantom", "voxel_size_m": 2e-4,
                                  "imaging": {"mask": {"mode": "full"},
                                              "rev": {"tolerance": 0.2}}}
    own, default = sample_imaging(config, "other"), sample_imaging(config, "pellet")
    assert own["mask"]["mode"] == "full" and own["rev"]["tolerance"] == 0.2
    # keys the sample does not set are the section's
    assert own["mask"]["min_slice_fraction"] == CONFIG["imaging"]["mask"]["min_slice_fraction"]
    assert own["rev"]["n_sizes"] == CONFIG["imaging"]["rev"]["n_sizes"]
    assert default == CONFIG["imaging"]
    config["samples"]["other"]["imaging"]["rev"]["tolerance"] = -1.0
    with pytest.raises(ConfigError, match=r"samples\.other\.imaging\.rev\.tolerance"):
        sample_imaging(config, "other")


def test_grid_spacing_defaults_to_micro_point_spacing():
    micro_spacing = (8e-3, 512)  # micro.specimen_size_m, micro.n_points
    assert grid_spacing(None, micro_spacing) == pytest.approx(1e-3)
    assert grid_spacing(3e-4, micro_spacing) == 3e-4
