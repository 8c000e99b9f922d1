"""The macro case figure reads: named sensors, both plates, days on a log axis with plain
ticks, legends off the curves."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from macro.figures import case_figure, comparison_figure
from tests._figures import check_figure, kept_figures  # noqa: F401


def _case() -> xr.Dataset:
    seconds = np.concatenate([[0.0], np.geomspace(60.0, 210 * 86400.0, 40)])
    z = np.linspace(0.0, 0.12, 13)
    rise = 1 - np.exp(-seconds / 2e6)
    return xr.Dataset({
        "sensor_pressure": (("time", "sensor"), np.outer(rise, [2e6, 2.5e6, 3e6])),
        "sensor_height": ("sensor", [0.02, 0.04, 0.08]),
        "axial_pressure_upper": ("time", 4e6 * rise),
        "axial_pressure_lower": ("time", 3.5e6 * rise),
        "suction_profile": (("time", "z"), np.outer(1 - rise, 1.3e8 * np.ones(13))),
        "swelling_profile": (("time", "z"), np.outer(rise, 0.2 * np.ones(13))),
        "column_permeability": ("permeability_time", np.geomspace(1e-19, 1e-20, 5)),
    }, coords={"time": seconds, "sensor": ["SP20", "SP40", "SP80"], "z": z,
               "permeability_time": np.concatenate([[0.0], np.geomspace(3600.0, 210 * 86400.0, 4)])})


def test_case_figure(tmp_path: Path, kept_figures) -> None:  # noqa: F811
    case_figure(_case(), tmp_path / "m.png")
    fig = kept_figures[-1]
    labels = check_figure(fig)
    assert {"time [d]", "pressure [MPa]", "height above the lower plate [cm]"} <= labels
    # a 2 x 2 grid titled by the case (the file's stem), not a strip
    assert fig._suptitle.get_text().startswith("macro case m:")
    assert len(fig.get_axes()) == 4 and fig.get_size_inches()[0] < 2 * fig.get_size_inches()[1]
    # the measurement at t = 0 is drawn, at the time axis's left edge
    permeability = fig.get_axes()[1]
    (start,) = [line for line in permeability.get_lines() if line.get_label().startswith("t = 0")]
    assert start.get_xdata()[0] == permeability.get_xlim()[0]
    assert start.get_ydata()[0] == 1e-19
    texts = [t.get_text() for ax in fig.get_axes() if ax.get_legend()
             for t in ax.get_legend().get_texts()]
    for name in ("SP20", "SP40", "SP80", "upper plate", "lower plate"):
        assert any(name in text for text in texts), name
    assert not any("e+" in text for text in texts)
    pressures = fig.get_axes()[0]
    assert pressures.get_xscale() == "log"
    assert all("e" not in t.get_text() for t in pressures.get_xticklabels())


def test_comparison_figure(tmp_path: Path, kept_figures) -> None:  # noqa: F811
    cases = {}
    for name, factor in (("weibull", 1.0), ("homogeneous", 0.8)):
        ds = _case()
        ds["sensor_pressure"] = ds["sensor_pressure"] * factor
        ds["mean_suction"] = (("time", "material"),
                              np.stack([ds["suction_profile"].values[:, 0]] * 2, axis=1))
        ds = ds.assign_coords(material=["pellet", "powder"])
        ds.attrs["powder_heterogeneity"] = name
        cases[name] = ds
    comparison_figure(cases, tmp_path / "cmp.png")
    labels = check_figure(kept_figures[-1])
    assert {"time [d]", "axial pressure [MPa]", "mean pellet suction [MPa]"} <= labels
