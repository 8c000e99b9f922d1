"""Figures of the micro stage (thesis Figs. 3.10-3.16 analogues)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

from shared.figures import new_figure, save_figure

__all__ = ["case_figure", "comparison_figure", "convergence_figure", "scale_figure"]

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


def convergence_figure(ds: xr.Dataset, path: str | Path) -> Path:
    """Convergence study (Fig. 3.17): last-checkpoint values vs n_points, eps_v vs saturation.

    Parameters
    ----------
    ds
        :func:`micro.studies.convergence_dataset` output.
    path
        Target PNG.
    """
    fig, axes = new_figure(2, 2, width=5.0)
    n = ds["n_points"].values
    last = ds.isel(checkpoint=-1)
    suction = float(last["suction"])
    ax = axes[0, 0]
    ax.plot(n, last["eps_v"].values, "ko-", ms=4)
    ax.set(xscale="log", xlabel="number of points", ylabel="eps_v [-]",
           title=f"volumetric strain at s = {suction:.3g} Pa")
    ax = axes[0, 1]
    for name, style, colour, label in (("crack_count", "o-", "k", "all"),
                                       ("crack_count_imbibed", "o--", "tab:blue", "imbibed"),
                                       ("crack_count_gas", "s:", "tab:red", "gas-filled")):
        ax.plot(n, last[name].values, style, color=colour, ms=4, label=label)
    ax.set(xscale="log", xlabel="number of points", ylabel="cracks [-]",
           title=f"crack count at s = {suction:.3g} Pa")
    ax.legend(fontsize="x-small")
    ax = axes[1, 0]
    for phase in ("water", "gas"):
        for axis in ("x", "y", "z"):
            k = last["permeability"].sel(phase=phase, axis=axis).values
            ax.plot(n, np.where(k > 0, k, np.nan), _AXIS_STYLE[axis], marker="o", ms=4,
                    color=_PHASE_COLOUR[phase], label=f"{phase} {axis}")
    ax.set(xscale="log", yscale="log", xlabel="number of points", ylabel="permeability [m2]",
           title=f"k_w and k_g at s = {suction:.3g} Pa")
    ax.legend(fontsize="x-small", ncol=2)
    ax = axes[1, 1]
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, n.size))
    for index, count in enumerate(n):
        row = ds.isel(n_points=index)
        ax.plot(row["saturation"].values, row["eps_v"].values, "o-", ms=3, color=colours[index],
                label=f"N = {count}")
    ax.set(xlabel="saturation [-]", ylabel="eps_v [-]", title="volumetric strain vs saturation")
    ax.legend(fontsize="x-small")
    return save_figure(fig, path)


def _band(ax, x, mean, std, colour, label, positive=False):  # type: ignore[no-untyped-def]
    """Mean line and a mean +- std band (no band where std is NaN, one realization)."""
    if positive:
        mean = np.where(mean > 0, mean, np.nan)
    ax.plot(x, mean, "o-", ms=3, color=colour, label=label)
    lower, upper = mean - std, mean + std
    if positive:
        # on a log axis the band's lower edge stops at a decade below the smallest mean
        floor = np.nanmin(mean) / 10 if np.any(np.isfinite(mean)) else np.nan
        lower = np.where(lower > 0, lower, floor)
    ax.fill_between(x, lower, upper, color=colour, alpha=0.2, linewidth=0)


def scale_figure(ds: xr.Dataset, path: str | Path) -> Path:
    """Scale study (Fig. 3.18): mean +- std over realizations per domain fraction.

    Rows: water and gas permeability vs mean saturation (x, y, z axes), then the
    volumetric strain, the crack count and the mean porosity. One colour per domain
    fraction; the band is mean +- the sample standard deviation (absent for one
    realization).

    Parameters
    ----------
    ds
        :func:`micro.studies.scale_dataset` output.
    path
        Target PNG.
    """
    fig, axes = new_figure(3, 3, width=4.2)
    fractions = ds["domain_fraction"].values
    colours = plt.get_cmap("tab10").colors
    for index, fraction in enumerate(fractions):
        row = ds.isel(domain_fraction=index)
        colour = colours[index % len(colours)]
        label = f"{fraction:.3g} ({int(row['n_realizations'])} real.)"
        s = row["saturation_mean"].values
        for r, phase in enumerate(("water", "gas")):
            for c, axis in enumerate(("x", "y", "z")):
                sel = {"phase": phase, "axis": axis}
                _band(axes[r, c], s, row["permeability_mean"].sel(sel).values,
                      row["permeability_std"].sel(sel).values, colour, label, positive=True)
                axes[r, c].set(yscale="log", xlabel="mean saturation [-]",
                               ylabel="permeability [m2]", title=f"{phase} permeability, {axis}")
        for c, (name, ylabel) in enumerate((("eps_v", "eps_v [-]"), ("crack_count", "cracks [-]"),
                                            ("porosity_mean", "mean porosity [-]"))):
            _band(axes[2, c], s, row[f"{name}_mean"].values, row[f"{name}_std"].values, colour, label)
            axes[2, c].set(xlabel="mean saturation [-]", ylabel=ylabel, title=f"{name} vs saturation")
    axes[0, 0].legend(title="domain fraction", fontsize="x-small")
    return save_figure(fig, path)
