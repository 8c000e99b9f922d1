"""Figures of the micro stage (thesis Figs. 3.10-3.16 analogues)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

from shared.figures import new_figure, save_figure

__all__ = ["case_figure", "comparison_figure"]

_AXIS_STYLE = {"x": "-", "y": "--", "z": ":"}
_PHASE_COLOUR = {"water": "tab:blue", "gas": "tab:red"}


def _permeability_panel(ax, ds: xr.Dataset, abscissa: str, label: str = "") -> None:  # type: ignore[no-untyped-def]
    x = ds[abscissa].values
    for phase in ("water", "gas"):
        for axis in ("x", "y", "z"):
            k = ds["permeability"].sel(phase=phase, axis=axis).values
            ax.plot(x, np.where(k > 0, k, np.nan), _AXIS_STYLE[axis], marker="o", ms=3,
                    color=_PHASE_COLOUR[phase], label=f"{label}{phase} {axis}")
    ax.set(yscale="log", ylabel="permeability [m2]")


def case_figure(ds: xr.Dataset, case: str, path: str | Path) -> Path:
    """Permeability vs saturation and suction, crack fabric, porosity histograms of a case."""
    fig, axes = new_figure(2, 2, width=5.0)
    _permeability_panel(axes[0, 0], ds, "saturation")
    axes[0, 0].set(xlabel="saturation [-]", title=f"{case}: permeability vs saturation")
    axes[0, 0].legend(fontsize="x-small", ncol=2)
    _permeability_panel(axes[0, 1], ds, "suction")
    axes[0, 1].set(xscale="log", xlabel="boundary suction [Pa]", title="permeability vs suction")
    axes[0, 1].invert_xaxis()
    saturation = ds["saturation"].values
    for suffix, colour in (("_imbibed", "tab:blue"), ("_gas", "tab:red")):
        fabric = ds[f"crack_fabric{suffix}"].values
        for index, style in zip(range(3), ("-", "--", ":")):
            axes[1, 0].plot(saturation, fabric[:, index, index], style, color=colour, marker="o", ms=3,
                            label=f"{suffix[1:]} {'xyz'[index]}{'xyz'[index]}")
    twin = axes[1, 0].twinx()
    twin.plot(saturation, ds["crack_count"].values, "k-", alpha=0.4)
    twin.set_ylabel("cracks [-]")
    axes[1, 0].set(xlabel="saturation [-]", ylabel="fabric component [m2]",
                   title="crack fabric (diagonal) and count")
    axes[1, 0].legend(fontsize="x-small", ncol=2)
    bins = ds["bin"].values
    colours = np.linspace(0.1, 0.9, ds.sizes["checkpoint"])
    for index, shade in enumerate(colours):
        axes[1, 1].plot(bins, ds["porosity_hist"].isel(checkpoint=index).values,
                        color=(shade, 0.3, 1 - shade),
                        label=f"S = {saturation[index]:.2f}")
    axes[1, 1].set(xlabel="porosity [-]", ylabel="volume fraction [-]",
                   title="porosity distribution through hydration")
    axes[1, 1].legend(fontsize="x-small")
    return save_figure(fig, path)


def comparison_figure(cases: Mapping[str, xr.Dataset], path: str | Path) -> Path:
    """Water and gas permeability (x axis) vs saturation across cases (Figs. 3.11, 3.13)."""
    fig, axes = new_figure(1, 2, width=5.0)
    # tab20 keeps up to twenty cases (default + convergence + scale presets) apart
    colours = plt.get_cmap("tab10" if len(cases) <= 10 else "tab20").colors
    for ax, phase in zip(axes[0], ("water", "gas")):
        for index, (name, ds) in enumerate(cases.items()):
            k = ds["permeability"].sel(phase=phase).mean("axis").values
            ax.plot(ds["saturation"].values, np.where(k > 0, k, np.nan), marker="o", ms=3,
                    label=name, color=colours[index % len(colours)])
        ax.set(yscale="log", xlabel="saturation [-]", ylabel="mean permeability [m2]",
               title=f"{phase} permeability, all cases")
    fig.legend(*axes[0][0].get_legend_handles_labels(), loc="outside right upper",
               fontsize="small")
    return save_figure(fig, path)
