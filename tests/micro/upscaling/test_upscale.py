"""The upscaling stage's computation in memory (micro.upscaling.upscale): the table of
datasets without files, against NumPy's geometric mean, and equal to what run() writes."""

import numpy as np
import pytest
import xarray as xr

from micro.upscaling import UpscalingSettings, upscale
from micro.upscaling import run as upscaling_run
from shared.config import ConfigError
from shared.io import read_dataset, write_dataset
from tests.micro.upscaling.test_table import RANGE, _micro


def test_upscale_averages_in_log_k_and_equals_the_written_table(tmp_path):
    members = [_micro(1), _micro(2)]
    table = upscale({"free": members, "confined": [_micro(3)]}, UpscalingSettings(RANGE))
    # the geometric mean over the realizations, recomputed here; suction ascending
    k = np.stack([m["permeability"].values for m in members])  # (real, suction, phase, axis)
    order = np.argsort(members[0]["suction"].values)
    expected = np.exp(np.log(k).mean(axis=0))[order]
    np.testing.assert_allclose(table["k"].sel(condition="free").transpose("suction", "phase", "axis"),
                               expected, rtol=1e-12)
    assert int(table["n_realizations"].sel(condition="confined")) == 1
    # run() on the same results written as files writes this table
    paths = {name: write_dataset(ds, tmp_path / f"{name}.nc", stage="micro", title="synthetic")
             for name, ds in (("a", members[0]), ("b", members[1]), ("c", _micro(3)))}
    section = {"conditions": {"free": ["a", "b"], "confined": "c"}, "suction_range_pa": list(RANGE)}
    out = tmp_path / "up" / "table"
    upscaling_run.run(section, {"free": [paths["a"], paths["b"]], "confined": [paths["c"]]},
                      upscaling_run.TableOutputs(*(out.with_suffix(s) for s in (".nc", ".csv", ".png"))))
    written = read_dataset(out.with_suffix(".nc"))
    xr.testing.assert_identical(written.drop_attrs(deep=False), table.drop_attrs(deep=False))


def test_settings_refuse_a_reversed_range():
    with pytest.raises(ConfigError, match=r"upscaling\.suction_range_pa"):
        UpscalingSettings((RANGE[1], RANGE[0]))
