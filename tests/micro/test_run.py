"""The micro result file written by micro.run is xarray-friendly: the suction labels the
checkpoints."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from micro.pellet import POROSITY_BINS
from micro.run import _SCALARS, _dataset
from shared.io import read_dataset, write_dataset

SUCTIONS = np.array([132.0e6, 38.0e6, 4.0e6])


def _records(n: int) -> list[dict[str, object]]:
    rng = np.random.default_rng(5)
    records = []
    for _ in range(n):
        record: dict[str, object] = {name: float(rng.uniform()) for name in _SCALARS}
        record["permeability"] = 10.0 ** rng.uniform(-22, -19, (2, 3))
        record["permeability_tensor"] = np.stack([np.diag(10.0 ** rng.uniform(-22, -19, 3))] * 2)
        for suffix in ("", "_imbibed", "_gas"):
            record[f"crack_fabric{suffix}"] = rng.uniform(0, 1e-8, (3, 3))
        record["porosity_hist"] = rng.dirichlet(np.ones(POROSITY_BINS.size - 1))
        records.append(record)
    return records


def test_suction_is_a_coordinate_of_the_checkpoints(tmp_path: Path) -> None:
    """Written and read back, ``suction`` is a coordinate along ``checkpoint`` (still the
    dimension): swapping the dimensions selects a checkpoint by its suction."""
    path = tmp_path / "c.nc"
    write_dataset(_dataset(_records(3), SUCTIONS), path, stage="micro", title="test")
    ds = read_dataset(path, ["suction", "permeability"])
    assert ds["suction"].dims == ("checkpoint",)
    assert "suction" in ds.coords and "suction" not in ds.data_vars
    assert ds["permeability"].dims == ("checkpoint", "phase", "axis")
    by_suction = ds.swap_dims(checkpoint="suction")
    picked = by_suction.sel(suction=40.0e6, method="nearest")
    assert int(picked["checkpoint"]) == 1
    np.testing.assert_array_equal(picked["permeability"].values,
                                  ds["permeability"].isel(checkpoint=1).values)
    assert ds["suction"].attrs["units"] == "Pa"


@pytest.mark.parametrize("n", [2])
def test_a_partial_run_labels_its_checkpoints(n: int) -> None:
    """A run stopped early labels only its finished checkpoints."""
    ds = _dataset(_records(n), SUCTIONS)
    np.testing.assert_array_equal(ds["suction"].values, SUCTIONS[:n])
