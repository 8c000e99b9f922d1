"""micro.run.hydrate, the library function: a porosity grid in memory in, the case's
Dataset out, with no file; it is what micro.run.run writes from the same grid on disk."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import micro.run as micro_run
from shared.config import validate_config

from .porosity_grid import porosity_grid, write_porosity_grid


@pytest.fixture
def config():
    """A 125-point CT case with two checkpoints, saved between every two flow steps."""
    return validate_config({
        "samples": {"p": {"source": "phantom", "voxel_size_m": 3e-4}},
        "micro": {"sample": "p", "specimen_size_m": 4e-3, "n_points": 125,
                  "snapshot_interval_s": 0.0, "checkpoints_suction_pa": [132.0e6, 1.0e6],
                  "cases": {"c": {"porosity": "ct"}}},
        "upscaling": {"conditions": {"free": "c", "confined": "c"}},
    })


def test_hydrate_from_memory_is_what_run_writes(config, tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """The Dataset of :func:`hydrate` equals the netCDF that :func:`run` writes (every
    variable bit for bit, every attribute but the provenance and wall times that only
    the file route has), though the file route also saves restart files at every flow
    step; :func:`hydrate` leaves no file behind. Its principal permeabilities sum to
    the trace of its tensors, an identity checked here apart from the eigensolver."""
    monkeypatch.setattr(micro_run.figures, "case_figure", lambda ds, case, path: Path(path))
    monkeypatch.chdir(tmp_path)
    ds = micro_run.hydrate(porosity_grid(4e-4), micro_run.micro_settings(config, "c"))
    assert not any(tmp_path.iterdir())
    grid = write_porosity_grid(tmp_path / "porosity.nc", 4e-4)
    micro_run.run(config, "c", grid, micro_run.CaseOutputs(tmp_path / "c.nc", tmp_path / "c.png"))
    with xr.open_dataset(tmp_path / "c.nc") as written:
        assert sorted(ds.variables) == sorted(written.variables)
        for name in ds.variables:
            x, y = ds[name].values, written[name].values
            assert x.dtype == y.dtype and x.shape == y.shape, name
            assert np.array_equal(x.view(np.uint8), y.view(np.uint8)) if x.dtype.kind == "f" \
                else np.array_equal(x, y), name
            assert ds[name].attrs == written[name].attrs, name
        assert ds.attrs == {k: written.attrs[k] for k in ds.attrs}
    assert ds.sizes["suction"] == 2 and np.all(np.isfinite(ds["permeability_tensor"]))
    trace = np.trace(ds["permeability_tensor"].values, axis1=-2, axis2=-1)
    np.testing.assert_allclose(ds["permeability_principal"].sum("principal").values, trace,
                               rtol=1e-12)
