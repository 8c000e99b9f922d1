"""The packing stage's computation in memory (imaging.packing.dataset.build_packing): the
zone porosity against the particles' volumes and the box, the volumes against the
elliptic-disk formula, and the Dataset equal to what run() writes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from imaging.packing.config import packing_settings
from imaging.packing.dataset import build_packing
from imaging.packing.run import PackingOutputs, run
from shared.io import read_dataset

TINY = {"n_particles": 25, "box_width_m": 3e-6, "attempts_per_cycle": 150, "voxel_resolution": 64,
        "seed": 4, "image_analyses": False}


def test_build_packing_gives_disk_volumes_and_the_written_file(tmp_path: Path) -> None:
    settings = packing_settings(TINY)
    ds = build_packing(settings)
    a, b, half_h = ds["semi_axes"].values.T
    volume = np.pi * a * b * 2 * half_h
    np.testing.assert_allclose(ds["volume"].values, volume, rtol=1e-12)
    # the linear zone's porosity: 1 - solid volume of the barycentres inside / zone volume
    z = ds["center"].sel(xyz="z").values
    z_min, z_max = float(ds["z_min"]), float(ds["z_max"])
    inside = (z > z_min) & (z <= z_max)
    assert inside.sum() == int(ds["in_zone"].sum()) > 0
    zone = ds.attrs["box_width"] ** 2 * (z_max - z_min)
    assert float(ds["porosity"]) == pytest.approx(1 - volume[inside].sum() / zone, rel=1e-12)
    assert ds.sizes["particle"] == 25
    run(settings, "tiny", PackingOutputs(tmp_path / "tiny.nc", tmp_path / "tiny.png"))
    written = read_dataset(tmp_path / "tiny.nc")
    # the settling time is the wall time of the run, the one variable that differs
    xr.testing.assert_identical(written.drop_attrs(deep=False).drop_vars("settle_time"),
                                ds.drop_attrs(deep=False).drop_vars("settle_time"))
    assert written.attrs["n_particles"] == 25
