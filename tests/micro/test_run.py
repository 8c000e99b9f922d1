"""The micro result file written by micro.run is xarray-friendly: the suction labels the
checkpoints."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from micro.pellet import POROSITY_BINS
from micro.results import SCALARS, records_dataset
from shared.io import read_dataset, write_dataset

SUCTIONS = np.array([132.0e6, 38.0e6, 4.0e6])


def _records(n: int) -> list[dict[str, object]]:
    rng = np.random.default_rng(5)
    records = []
    for _ in range(n):
        record: dict[str, object] = {name: float(rng.integers(1, 50)) if dtype is np.int64
                                     else float(rng.uniform()) for name, (_, _, dtype) in SCALARS.items()}
        record["permeability"] = 10.0 ** rng.uniform(-22, -19, (2, 3))
        record["permeability_tensor"] = np.stack([np.diag(10.0 ** rng.uniform(-22, -19, 3))] * 2)
        for suffix in ("", "_imbibed", "_gas"):
            record[f"crack_fabric{suffix}"] = rng.uniform(0, 1e-8, (3, 3))
        record["porosity_hist"] = rng.dirichlet(np.ones(POROSITY_BINS.size - 1))
        records.append(record)
    return records


def test_suction_indexes_the_checkpoints_and_counts_are_integers(tmp_path: Path) -> None:
    """Written and read back, ``suction`` is the checkpoints' dimension coordinate
    (``ds.sel(suction=...)`` works as a user types it), the checkpoint's number a coordinate
    along it, and the counts are integers."""
    path = tmp_path / "c.nc"
    write_dataset(records_dataset(_records(3), SUCTIONS), path, stage="micro", title="test")
    ds = read_dataset(path, ["suction", "permeability"])
    assert ds["suction"].dims == ("suction",) and "suction" in ds.indexes
    assert ds["permeability"].dims == ("suction", "phase", "axis")
    picked = ds.sel(suction=SUCTIONS[1])
    assert int(picked["checkpoint"]) == 1
    np.testing.assert_array_equal(picked["permeability"].values,
                                  ds["permeability"].isel(suction=1).values)
    assert ds["suction"].attrs["units"] == "Pa"
    assert ds["checkpoint"].dims == ("suction",)
    for name in ("crack_count", "crack_count_imbibed", "crack_count_gas", "n_remesh",
                 "flow_steps", "dem_steps", "balanced"):
        assert ds[name].dtype.kind == "i", name
    assert ds["crack_area"].dtype.kind == "f"


@pytest.mark.parametrize("n", [2])
def test_a_partial_run_labels_its_checkpoints(n: int) -> None:
    """A run stopped early labels only its finished checkpoints."""
    ds = records_dataset(_records(n), SUCTIONS)
    np.testing.assert_array_equal(ds["suction"].values, SUCTIONS[:n])
