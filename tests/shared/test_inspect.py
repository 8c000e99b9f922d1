"""The inspect command summarises variables, units, ranges and provenance."""

import numpy as np
import xarray as xr

from shared.inspect import main
from shared.io import write_dataset


def test_inspect_prints_units_ranges_and_provenance(tmp_path, capsys):
    values = np.array([0.2, np.nan, 0.35])
    ds = xr.Dataset({"porosity": (("z",), values, {"units": "1", "long_name": "porosity"})},
                    coords={"z": ("z", [0.0, 1e-3, 2e-3], {"units": "m", "long_name": "height"})})
    path = write_dataset(ds, tmp_path / "p.nc", stage="imaging", title="demo", seed=11)
    assert main([str(path)]) == 0
    out = capsys.readouterr().out
    assert "porosity" in out and "[1]" in out and "0.2 .. 0.35 (1 NaN)" in out
    assert "seed: 11" in out and "stage: imaging" in out


def test_inspect_fails_cleanly_on_a_bad_file(tmp_path, capsys):
    bad = tmp_path / "bad.nc"
    bad.write_text("nope")
    assert main([str(bad)]) == 1
    assert "bad.nc" in capsys.readouterr().err
