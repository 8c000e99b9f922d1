"""The REV figure reads: one length unit, the tolerance drawn, labelled log ticks,
legends off the data."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from imaging.ct.figures import rev_figure
from tests._figures import check_figure, kept_figures  # noqa: F401


def _rev() -> xr.Dataset:
    window = np.geomspace(2e-4, 1.6e-3, 6)  # less than one decade
    length = np.geomspace(1e-5, 1e-3, 20)
    f = np.exp(-length / 1e-4)
    scalar = ((), 0.0)
    ds = xr.Dataset({
        "porosity_mean": ("window", 0.3 + 0.01 / window * 1e-3),
        "porosity_std": ("window", 0.05 * 1e-3 / window * 1e-1),
        "interface_mean": ("window", np.full(6, 2e3)),
        "interface_std": ("window", 1e2 * window[0] / window),
        "porosity_centred": ("window_centred", np.full(4, 0.3)),
        "interface_centred": ("window_centred", np.full(4, 2e3)),
        "calibrated_porosity_mean": ("window", np.full(6, 0.28)),
        "porosity_total": ((), 0.3), "interface_total": ((), 2e3),
        "w_rev_porosity_centred": ((), 8e-4), "w_rev_interface_centred": ((), np.nan),
        "chord_pore": (("direction", "length"), np.stack([f] * 3)),
        "chord_solid": (("direction", "length"), np.stack([f] * 3)),
        "R_p": scalar, "R_s": ((), 1.5),
    }, coords={"window": window, "window_centred": np.geomspace(3e-4, 1.6e-3, 4),
               "length": length, "direction": ["x", "y", "z"]})
    ds.attrs["rev_tolerance"] = 0.02
    return ds


def test_rev_figure(tmp_path: Path, kept_figures) -> None:  # noqa: F811
    rev_figure(_rev(), tmp_path / "rev.png")
    fig = kept_figures[-1]
    labels = check_figure(fig)
    assert {"window edge [mm]", "chord length r [mm]", "porosity [-]"} <= labels
    legend_texts = [t.get_text() for ax in fig.get_axes() if ax.get_legend()
                    for t in ax.get_legend().get_texts()]
    assert any("REV tolerance" in text for text in legend_texts)


def test_porosity_figure(tmp_path: Path, kept_figures) -> None:  # noqa: F811
    from imaging.ct.figures import porosity_figure

    rng = np.random.default_rng(2)
    axis = np.linspace(0.0, 4e-3, 8)
    image = xr.Dataset({"grey_preview": (("z_preview", "y_preview", "x_preview"),
                                         rng.integers(0, 60000, (8, 8, 8)))},
                       coords={"z_preview": axis, "y_preview": axis, "x_preview": axis})
    porosity = xr.Dataset({"porosity": (("z", "y", "x"), rng.uniform(0.2, 0.4, (8, 8, 8))),
                           "density": (("z", "y", "x"), rng.uniform(1600, 2000, (8, 8, 8)))},
                          coords={"z": axis, "y": axis, "x": axis})
    porosity_figure(image, porosity, tmp_path / "p.png")
    labels = check_figure(kept_figures[-1])
    assert {"x [mm]", "porosity [-]", "density [kg/m3]"} <= labels
