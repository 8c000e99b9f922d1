"""The upscaling table (micro.upscaling.table) built from micro results: aggregation,
contract, refusals."""

import numpy as np
import pytest
import xarray as xr

from micro.upscaling import upscaling_table
from shared.config import ConfigError

CHECKPOINTS = np.array([1.32e8, 6e7, 1e7, 1e6, 1e5])
RANGE = (1e6, 1.32e8)


def _micro(seed, checkpoints=CHECKPOINTS):
    """A micro result with the variables the table reads (random positive values)."""
    rng = np.random.default_rng(seed)
    n = checkpoints.size
    k = 10.0 ** rng.uniform(-22, -17, (n, 2, 3))
    root = rng.normal(size=(n, 2, 3, 3))
    tensor = 1e-20 * (root @ np.swapaxes(root, -1, -2) + np.eye(3))
    tensor[..., 0, 2] += 1e-22  # a small asymmetry the table drops
    return xr.Dataset(
        {
            "suction": ("checkpoint", checkpoints, {"units": "Pa", "long_name": "suction"}),
            "saturation": ("checkpoint", rng.uniform(0.3, 1, n), {"units": "1", "long_name": "S"}),
            "eps_v": ("checkpoint", rng.uniform(0, 0.8, n), {"units": "1", "long_name": "eps_v"}),
            "permeability": (("checkpoint", "phase", "axis"), k, {"units": "m2", "long_name": "k"}),
            "permeability_tensor": (("checkpoint", "phase", "i", "j"), tensor,
                                    {"units": "m2", "long_name": "K"}),
        },
        coords={"checkpoint": ("checkpoint", np.arange(n), {"units": "1", "long_name": "index"}),
                "phase": ("phase", ["water", "gas"], {"long_name": "phase"}),
                "axis": ("axis", ["x", "y", "z"], {"long_name": "axis"}),
                "i": ("i", np.arange(3), {"units": "1", "long_name": "row"}),
                "j": ("j", np.arange(3), {"units": "1", "long_name": "column"})},
    )


def test_ensemble_is_averaged_in_log_k_against_numpy():
    members = [_micro(seed) for seed in (1, 2, 3)]
    table = upscaling_table({"free": [(f"r{i}", m) for i, m in enumerate(members)],
                             "confined": [("c", _micro(9))]}, RANGE)
    assert np.all(np.diff(table["suction"].values) > 0)
    np.testing.assert_array_equal(table["suction"].values, np.sort(CHECKPOINTS))
    order = np.argsort(CHECKPOINTS)
    log_k = np.log10(np.stack([m["permeability"].values[order] for m in members]))
    free = table.sel(condition="free")
    # (suction, phase, axis) -> table's (phase, axis, suction)
    np.testing.assert_allclose(free["k"].values, np.moveaxis(10 ** log_k.mean(0), 0, -1), rtol=1e-12)
    np.testing.assert_allclose(free["k_log10_std"].values,
                               np.moveaxis(np.std(log_k, axis=0, ddof=1), 0, -1), rtol=1e-12)
    tensors = np.stack([m["permeability_tensor"].values[order] for m in members])
    symmetric = 0.5 * (tensors + np.swapaxes(tensors, -1, -2))
    np.testing.assert_allclose(free["k_tensor"].values, np.moveaxis(symmetric.mean(0), 0, 1),
                               rtol=1e-12)
    np.testing.assert_allclose(free["saturation"].values,
                               np.mean([m["saturation"].values[order] for m in members], axis=0))
    confined = table.sel(condition="confined")
    assert int(confined["n_realizations"]) == 1 and np.isnan(confined["k_log10_std"]).all()
    np.testing.assert_allclose(confined["k"].sel(phase="gas", axis="z").values,
                               _micro(9)["permeability"].values[order, 1, 2], rtol=1e-12)


@pytest.mark.parametrize(("source", "message"), [
    (_micro(1, np.array([1.32e8, 6e7, 1e7])), "not the suction range"),
    (_micro(1).assign(permeability=lambda d: d["permeability"].where(d["checkpoint"] != 2)),
     "NaN permeability at checkpoint 2"),
    (_micro(1).assign(permeability=lambda d: d["permeability"] * 0.0), "non-positive"),
    (_micro(1).drop_vars("permeability_tensor"), "missing"),
    (_micro(1, np.array([1.32e8, 6e7, 2e7, 1e6, 1e5])), "checkpoints differ"),
])
def test_bad_sources_are_refused_naming_the_file(source, message):
    with pytest.raises(ConfigError, match=message) as err:
        upscaling_table({"free": [("good.nc", _micro(1))], "confined": [("bad.nc", source)]}, RANGE)
    assert "bad.nc" in str(err.value)


def test_a_condition_without_source_is_refused():
    with pytest.raises(ConfigError, match=r"upscaling\.conditions\.free': no source"):
        upscaling_table({"free": [], "confined": [("c", _micro(1))]}, RANGE)
