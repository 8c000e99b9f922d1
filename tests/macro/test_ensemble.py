"""macro.ensemble: seed ensembles' statistics on a common time axis, figure, product (the
members as cases: test_config.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

from macro import ensemble
from macro.ensemble import (
    ensemble_figure,
    ensemble_statistics,
    plot_ensemble,
)
from shared.io import read_dataset, write_dataset
from tests._figures import check_figure, kept_figures  # noqa: F401

OFFSETS = np.arange(8.0)  # member k is the curve shifted up by k
SLOPES = {"sensor": np.array([1.0, 2.0, 3.0]), "axial": 5.0, "lower": 4.0}


def _member(k: int, sensors, lower: bool = True) -> xr.Dataset:
    """A member whose every reading is a line in time plus OFFSETS[k], on its own grid:
    first step at 10 (k + 1) s, end at 1e6 (k + 1) s, 40 + k records."""
    t = np.concatenate([[0.0], np.geomspace(10.0 * (k + 1), 1.0e6 * (k + 1), 40 + k)])
    c = OFFSETS[k]
    data = {
        "sensor_pressure": (("time", "sensor"), t[:, None] * SLOPES["sensor"] + c,
                            {"units": "Pa", "long_name": "radial pressure"}),
        "axial_pressure_upper": ("time", SLOPES["axial"] * t + c, {"units": "Pa", "long_name": "axial"}),
        "mean_saturation": (("time", "material"), np.column_stack([0 * t + c, 0 * t + 2 * c]),
                            {"units": "1", "long_name": "mean saturation"}),
    }
    if lower:
        data["axial_pressure_lower"] = ("time", SLOPES["lower"] * t + c,
                                        {"units": "Pa", "long_name": "axial lower"})
    coords = {"time": ("time", t, {"units": "s", "long_name": "time"}),
              "sensor": ("sensor", sensors, {"units": "1", "long_name": "sensor"}),
              "material": ("material", ["pellet", "powder"], {"units": "1", "long_name": "m"})}
    return xr.Dataset(data, coords=coords, attrs={"seed": k})


def _members(sensors=("SP20", "SP40", "SP80"), lower=True):
    return {f"e_s{k}": _member(k, list(sensors), lower) for k in range(OFFSETS.size)}


@pytest.mark.parametrize("sensors", [("SP20", "SP40", "SP80"), (0, 1, 2)])
def test_shifted_copies_give_the_curve_plus_the_offsets_statistics(sensors):
    """Eight copies of one line shifted by 0..7: the mean is the line + 3.5 and the
    10-90 % band the line + 0.7 and + 6.3 (quantile p of 0..7 interpolated at 7 p),
    on times from the latest first step (80 s) to the earliest end (1e6 s)."""
    ds = ensemble_statistics(_members(sensors), points=30, quantiles=(0.1, 0.9))
    t = ds["time"].values
    assert t[0] == pytest.approx(80.0) and t[-1] == pytest.approx(1.0e6) and t.size == 30
    np.testing.assert_allclose(t[1:] / t[:-1], (1.0e6 / 80.0) ** (1 / 29))
    assert list(ds["sensor"].values) == list(sensors)
    line = t[:, None] * SLOPES["sensor"]
    np.testing.assert_allclose(ds["sensor_pressure_mean"].values, line + 3.5)
    band = ds["sensor_pressure_band"].transpose("quantile", "time", "sensor").values
    np.testing.assert_allclose(band[0], line + 0.7)
    np.testing.assert_allclose(band[1], line + 6.3)
    for name, slope in (("axial_pressure_upper", SLOPES["axial"]),
                        ("axial_pressure_lower", SLOPES["lower"])):
        np.testing.assert_allclose(ds[f"{name}_mean"].values, slope * t + 3.5)
        np.testing.assert_allclose(ds[f"{name}_band"].values, [slope * t + 0.7, slope * t + 6.3])
    np.testing.assert_allclose(ds["mean_saturation_mean"].sel(material="powder"), 7.0)
    # each member on the common axis is its own line
    np.testing.assert_allclose(ds["axial_pressure_upper"].sel(member="e_s5").values, 5.0 * t + 5.0)
    np.testing.assert_allclose(ds["member_end_time"].values, 1.0e6 * (OFFSETS + 1))
    assert list(ds["seed"].values) == list(range(8))


def test_quantiles_zero_and_one_give_the_min_max_band():
    ds = ensemble_statistics(_members(), points=5, quantiles=(0.0, 1.0))
    t = ds["time"].values
    np.testing.assert_allclose(ds["axial_pressure_upper_band"].values, [5.0 * t, 5.0 * t + 7.0])


def test_the_lower_plate_is_reduced_only_when_every_member_has_it():
    members = _members()
    members["e_s3"] = members["e_s3"].drop_vars("axial_pressure_lower")
    ds = ensemble_statistics(members, points=5)
    assert "axial_pressure_lower_mean" not in ds and "axial_pressure_upper_mean" in ds


def test_members_with_other_sensors_are_refused_naming_the_member():
    members = _members()
    members["e_s6"] = _member(6, ["SP20", "SP40", "SP60"])
    with pytest.raises(ValueError, match="ensemble member e_s6: sensors"):
        ensemble_statistics(members)


def test_the_figure_has_log_days_and_its_legends_outside_the_data(tmp_path):
    ds = ensemble_statistics(_members(), points=20)
    fig = plot_ensemble(ds, "ensemble e")
    fig.canvas.draw()
    axes = fig.axes
    assert [ax.get_ylabel() for ax in axes] == [
        "radial wall pressure [MPa]", "axial pressure [MPa]", "mean saturation [1]"]
    renderer = fig.canvas.get_renderer()
    for ax in axes:
        assert ax.get_xlabel() == "time [d]" and ax.get_xscale() == "log"
        legend = ax.get_legend()
        assert not legend.get_window_extent(renderer).overlaps(ax.get_window_extent(renderer))
    assert [t.get_text() for t in axes[0].get_legend().get_texts()] == ["SP20", "SP40", "SP80"]
    assert [t.get_text() for t in axes[1].get_legend().get_texts()] == ["upper plate",
                                                                          "lower plate"]
    assert "10-90 %" in fig.get_suptitle()
    path = ensemble_figure(ds, tmp_path / "e.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_run_writes_the_product_from_the_members_files(tmp_path, kept_figures):  # noqa: F811
    paths = []
    for name, ds in _members().items():
        paths.append(write_dataset(ds, tmp_path / f"{name}.nc", stage="macro", title=name))
    settings = {"case": "small", "seeds": list(range(8)), "time_points": 12,
                "band_quantiles": [0.1, 0.9]}
    ensemble.run(settings, "e", paths,
                 ensemble.EnsembleOutputs(tmp_path / "ensemble_e.nc", tmp_path / "ensemble_e.png"),
                 rule="macro_ensemble")
    ds = read_dataset(tmp_path / "ensemble_e.nc", ["sensor_pressure_mean", "sensor_pressure_band"])
    assert list(ds["member"].values) == [f"e_s{k}" for k in range(8)]
    assert ds.sizes["time"] == 12 and ds["time"].attrs["units"] == "s"
    assert json.loads(ds.attrs["config_json"])["band_quantiles"] == [0.1, 0.9]
    assert len(json.loads(ds.attrs["inputs"])) == 8
    assert (tmp_path / "ensemble_e.png").stat().st_size > 0
    assert "time [d]" in check_figure(kept_figures[-1])
