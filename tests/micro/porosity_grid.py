"""A random CT porosity grid as the imaging stage writes it, for micro runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from shared.io import write_dataset


def porosity_grid(spacing: float, size: int = 14, seed: int = 0) -> xr.Dataset:
    """A size^3 grid of porosity 0.25 +- 0.03 (clipped to [0.05, 0.6]), voxels ``spacing``
    [m] apart, as the imaging stage's Dataset (in memory)."""
    rng = np.random.default_rng(seed)
    values = np.clip(0.25 + 0.03 * rng.standard_normal((size, size, size)), 0.05, 0.6)
    axis = np.arange(size) * spacing
    grid = xr.DataArray(values, dims=("z", "y", "x"), coords={"z": axis, "y": axis, "x": axis},
                        attrs={"units": "1", "long_name": "porosity"})
    ds = grid.to_dataset(name="porosity")
    for name in "zyx":
        ds[name].attrs.update(units="m", long_name=name)
    return ds


def write_porosity_grid(path: Path, spacing: float, size: int = 14, seed: int = 0) -> Path:
    """:func:`porosity_grid` written to ``path`` as an imaging-stage netCDF."""
    write_dataset(porosity_grid(spacing, size, seed), path, stage="imaging", title="test grid")
    return path
