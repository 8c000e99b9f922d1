"""The CT stage's computations in memory (imaging.ct.porosity, imaging.ct.rev): a two-phase
phantom's porosity grid against its volume fractions known by construction, the same
Dataset whether the scan is a numpy array, a dask array or a DataArray, and the Datasets
equal to what the stage's run() writes."""

from __future__ import annotations

import copy

import dask.array as da
import numpy as np
import pytest
import xarray as xr

from imaging.ct import run as ct_run
from imaging.ct.io import write_tiff_stack
from imaging.ct.phantom import pellet_phantom
from imaging.ct.porosity import porosity_grid, scan_datasets
from imaging.ct.rev import scan_rev
from imaging.ct.settings import PorositySettings, RevSettings, ScanResources
from shared.config import default_config
from shared.errors import InputError
from shared.io import netcdf_safe_attrs, read_dataset

CONFIG = default_config()
VOXEL = 1e-4
BLOCK = 4
GREY_AIR, GREY_SOLID = 1000, 30000
AIR, DRY, PHI_0, MUSCOVITE = 1.13, 1500.0, 0.45, 3900.0
SOLID = AIR + (DRY - AIR) / (1.0 - PHI_0)
"""Density of the solid phase [kg m-3]: porosity 0 on the calibration's line through
(air, 1) and (dry density, reference porosity)."""


def _settings(**changes) -> PorositySettings:
    calibration = dict(CONFIG["imaging"]["calibration"], porosity_bounds=[0.0, 1.0],
                       grey_air=float(GREY_AIR), air_density_kg_m3=AIR,
                       muscovite_density_kg_m3=MUSCOVITE, dry_density_kg_m3=DRY,
                       reference_porosity=PHI_0)
    # the muscovite grey on the line through (air, GREY_AIR) and (SOLID, GREY_SOLID)
    calibration["grey_muscovite"] = GREY_AIR + (GREY_SOLID - GREY_AIR) * (MUSCOVITE - AIR) / (SOLID - AIR)
    mask = dict(CONFIG["imaging"]["mask"], mode="full")
    values = dict(grid_spacing=BLOCK * VOXEL, calibration=calibration, mask=mask,
                  min_specimen_fraction=0.5, material=CONFIG["materials"]["pellet"])
    values.update(changes)
    return PorositySettings(**values)


def _layered(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Air and solid filling an 8 x 8 x 8 grid of 4-voxel blocks: in each block the first
    k of its 4 slices are air (k drawn in 1..3); the grey volume and each block's air
    fraction k / 4."""
    k = rng.integers(1, 4, size=(8, 8, 8))
    layer = np.arange(BLOCK)[None, :, None, None, None, None]
    air = layer < k[:, None, :, None, :, None]
    air = np.broadcast_to(air, (8, BLOCK, 8, BLOCK, 8, BLOCK)).reshape((8 * BLOCK,) * 3)
    grey = np.where(air, GREY_AIR, GREY_SOLID).astype(np.uint16)
    return grey, k / BLOCK


def test_the_porosity_grid_of_a_two_phase_phantom_is_its_air_fraction(rng):
    grey, fraction = _layered(rng)
    grid = porosity_grid(grey, _settings(), voxel_size=VOXEL)
    # the voxels are calibrated in float32 (eps 6e-8 of ~2700 kg m-3): 1e-8 in porosity
    np.testing.assert_allclose(grid["porosity"].values, fraction, rtol=0, atol=1e-6)
    np.testing.assert_allclose(grid["density"].values, fraction * AIR + (1 - fraction) * SOLID,
                               rtol=1e-6)
    assert grid.attrs["grid_spacing"] == pytest.approx(BLOCK * VOXEL, rel=1e-12)
    np.testing.assert_allclose(grid["z"].values, (np.arange(8) + 0.5) * BLOCK * VOXEL, rtol=1e-12)
    assert grid.attrs["porosity_mean"] == pytest.approx(fraction.mean(), abs=1e-6)


def test_a_numpy_a_dask_array_and_a_dataarray_give_one_grid(rng):
    grey, _ = _layered(rng)
    settings = _settings()
    reference = porosity_grid(grey, settings, voxel_size=VOXEL)
    # thin slabs read by two workers, and the voxel size carried by the DataArray
    thin = porosity_grid(da.from_array(grey, chunks=(3, 16, 16)), settings, voxel_size=VOXEL,
                         resources=ScanResources(workers=2))
    carried = porosity_grid(xr.DataArray(grey, dims=("z", "y", "x"), attrs={"voxel_size": VOXEL}),
                            settings)
    xr.testing.assert_identical(thin, reference)
    xr.testing.assert_identical(carried, reference)
    with pytest.raises(ValueError, match="voxel size"):
        porosity_grid(grey, settings)


def test_settings_refuse_a_bad_value_naming_it():
    with pytest.raises(ValueError, match="grid_spacing"):
        _settings(grid_spacing=0.0)
    with pytest.raises(ValueError, match="mask mode"):
        _settings(mask={"mode": "sphere"})


def test_the_datasets_are_what_the_stage_writes(tmp_path):
    """A phantom scan: the in-memory image, grid and REV equal, variable for variable,
    the files that run.porosity and run.rev write from the scan's TIFF."""
    spec = ct_run.phantom_spec(dict(CONFIG["phantom"], shape=[40, 48, 48], seed=3),
                               CONFIG["imaging"]["calibration"], 2e-4)
    grey = pellet_phantom(spec)[0]
    scan = write_tiff_stack(grey, tmp_path / "p.tif")
    imaging = copy.deepcopy(CONFIG["imaging"])
    imaging["rev"].update(n_positions=200, n_sizes=4)
    settings = PorositySettings.from_config("p", dict(imaging, grid_spacing_m=6e-4),
                                            CONFIG["materials"]["pellet"], (1.0, 8))
    rev_settings = RevSettings(imaging["rev"], imaging["chords"], "p")
    image, grid = scan_datasets(grey, settings, voxel_size=2e-4)
    rev = scan_rev(grey, image, grid, rev_settings)
    entry = {"source": "tiff", "path": str(scan), "voxel_size_m": 2e-4}
    out = ct_run.PorosityOutputs(tmp_path / "image.nc", tmp_path / "porosity.nc",
                                 tmp_path / "porosity.png")
    ct_run.porosity({"sample": entry, "imaging": dict(imaging, grid_spacing_m=6e-4),
                     "material": CONFIG["materials"]["pellet"], "micro_spacing": (1.0, 8)}, "p", scan, out)
    ct_run.rev({"sample": entry, "settings": imaging}, "p", ct_run.RevInputs(scan, out.image, out.porosity),
               ct_run.RevOutputs(tmp_path / "rev.nc", tmp_path / "rev.png"))
    for memory, path in ((image, out.image), (grid, out.porosity), (rev, tmp_path / "rev.nc")):
        written = read_dataset(path)
        xr.testing.assert_identical(written.drop_attrs(deep=False)[list(memory.data_vars)],
                                    memory.compute().drop_attrs(deep=False))
        for key, value in netcdf_safe_attrs(memory.attrs).items():
            np.testing.assert_equal(written.attrs[key], value, err_msg=key)
    # a specimen image of another scan is refused, naming it
    with pytest.raises(InputError, match="no specimen mask"):
        scan_rev(grey[:-2], image, grid, rev_settings)
