"""Figures of the micro stage (thesis Figs. 3.10-3.16 analogues)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.ticker import MaxNLocator

from shared.figures import new_figure, outside_legend, save_figure

__all__ = ["case_figure", "comparison_figure", "convergence_figure", "scale_figure"]

_AXIS_STYLE = {"x": "-", "y": "--", "z": ":"}
_PHASE_COLOUR = {"water": "tab:blue", "gas": "tab:red"}


def _permeability_panel(ax: Axes, ds: xr.Dataset, abscissa: str, label: str = "") -> None:
    x = ds[abscissa].values
    for phase in ("water", "gas"):
        for axis in ("x", "y", "z"):
            k = ds["permeability"].sel(phase=phase, axis=axis).values
            ax.plot(x, np.where(k > 0, k, np.nan), _AXIS_STYLE[axis], marker="o", ms=3,
                    color=_PHASE_COLOUR[phase], label=f"{label}{phase} {axis}")
    ax.set(yscale="log", ylabel="permeability [m2]")


def case_figure(ds: xr.Dataset, case: str, path: str | Path) -> Path:
    """Permeability vs saturation and suction, crack fabric and count, porosity
    histograms of a case (titled by it); the crack panel says so when no crack opened."""
    fig, axes = new_figure(2, 2, width=6.5)
    fig.suptitle(f"micro case {case}: {int(ds.attrs.get('n_points', 0))} points", fontsize="medium")
    _permeability_panel(axes[0, 0], ds, "saturation")
    axes[0, 0].set(xlabel="saturation [-]", title="permeability vs saturation")
    outside_legend(axes[0, 0], ncol=2)
    _permeability_panel(axes[0, 1], ds, "suction")
    axes[0, 1].set(xscale="log", xlabel="boundary suction [Pa]",
                   title="permeability vs suction (same lines)")
    axes[0, 1].invert_xaxis()
    _crack_panel(axes[1, 0], ds)
    saturation = ds["saturation"].values
    colours = plt.get_cmap("viridis")
    norm = Normalize(float(saturation.min()), float(saturation.max()))
    for index in range(ds.sizes["suction"]):
        axes[1, 1].plot(ds["bin"].values, ds["porosity_hist"].isel(suction=index).values,
                        color=colours(norm(saturation[index])))
    axes[1, 1].set(xlabel="porosity [-]", ylabel="volume fraction [-]",
                   title="porosity distribution through hydration")
    fig.colorbar(ScalarMappable(norm, colours), ax=axes[1, 1], label="saturation [-]")
    return save_figure(fig, path)


def _crack_panel(ax: Axes, ds: xr.Dataset) -> None:
    """The diagonal of the crack fabric of water- and gas-filled cracks against
    saturation, and the number of cracks on a right axis (integer ticks)."""
    count = ds["crack_count"].values
    if not np.any(count > 0):
        ax.axis("off")
        ax.text(0.5, 0.5, "no crack opened in this case", ha="center", va="center",
                transform=ax.transAxes)
        return
    saturation = ds["saturation"].values
    for suffix, colour in (("_imbibed", "tab:blue"), ("_gas", "tab:red")):
        fabric = ds[f"crack_fabric{suffix}"].values
        for index, style in zip(range(3), ("-", "--", ":"), strict=False):
            ax.plot(saturation, fabric[:, index, index], style, color=colour, marker="o", ms=3,
                    label=f"{'water-filled' if suffix == '_imbibed' else 'gas-filled'} "
                          f"{'xyz'[index]}{'xyz'[index]}")
    twin = ax.twinx()
    twin.plot(saturation, count, "k-", alpha=0.4, label="number of cracks (right axis)")
    twin.set_ylabel("number of cracks")
    twin.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set(xlabel="saturation [-]", ylabel="fabric component [m2]",
           title="crack fabric (diagonal) and count")
    handles, labels = ax.get_legend_handles_labels()
    extra, extra_labels = twin.get_legend_handles_labels()
    ax.legend(handles + extra, labels + extra_labels, ncol=2, loc="upper left",
              bbox_to_anchor=(1.3, 1.0), borderaxespad=0.0, fontsize="x-small")


def comparison_figure(cases: Mapping[str, xr.Dataset], path: str | Path) -> Path:
    """Water and gas permeability vs saturation across cases (Figs. 3.11, 3.13): the
    mean permeability is the arithmetic mean of the three directional permeabilities
    k_x, k_y, k_z of a checkpoint (one case, one realization)."""
    fig, axes = new_figure(1, 2, width=5.0)
    fig.suptitle(f"micro cases {', '.join(cases)}", fontsize="medium")
    # tab20 keeps up to twenty cases (default + convergence + scale presets) apart
    palette = plt.get_cmap("tab10" if len(cases) <= 10 else "tab20")
    assert isinstance(palette, ListedColormap)  # a qualitative map: a list of colours
    colours = np.asarray(palette.colors)
    for ax, phase in zip(axes[0], ("water", "gas"), strict=False):
        for index, (name, ds) in enumerate(cases.items()):
            k = ds["permeability"].sel(phase=phase).mean("axis").values
            ax.plot(ds["saturation"].values, np.where(k > 0, k, np.nan), marker="o", ms=3,
                    label=name, color=colours[index % len(colours)])
        ax.set(yscale="log", xlabel="saturation [-]",
               ylabel=f"mean {phase} permeability [m2]",
               title=f"{phase} permeability: arithmetic mean of\nk_x, k_y, k_z per checkpoint")
    fig.legend(*axes[0][0].get_legend_handles_labels(), loc="outside right upper",
               fontsize="small")
    return save_figure(fig, path)


def convergence_figure(ds: xr.Dataset, path: str | Path, n_levels: int = 4) -> Path:
    """Convergence study (Fig. 3.17): tracked quantities against the number of points.

    Top: mean saturation, volumetric strain, water and gas permeability (geometric mean
    of the axes) against N at up to ``n_levels`` checkpoints; bottom: their relative
    change from the previous N, and the cracks, wall time and peak memory per N.

    Parameters
    ----------
    ds
        :func:`micro.studies.convergence_dataset` output.
    path
        Target PNG.
    """
    fig, axes = new_figure(2, 4, width=3.6)
    fig.suptitle(f"convergence study over cases {', '.join(json.loads(ds.attrs.get('cases', '[]')))}",
                 fontsize="medium")
    n = ds["n_points"].values
    levels = np.unique(np.linspace(0, ds.sizes["suction"] - 1, n_levels).round().astype(int))
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, levels.size))
    k = ds["permeability"].where(ds["permeability"] > 0)
    geomean = np.exp(xr.ufuncs.log(k).mean("axis"))
    change = ds["permeability_relative_change"].max("axis")
    top = (("saturation [-]", ds["saturation"], ds["saturation_relative_change"], False),
           ("volumetric strain eps_v [-]", ds["eps_v"], ds["eps_v_relative_change"], False),
           ("k_w [m2]", geomean.sel(phase="water"), change.sel(phase="water"), True),
           ("k_g [m2]", geomean.sel(phase="gas"), change.sel(phase="gas"), True))
    for column, (label, values, relative, log) in enumerate(top):
        for colour, level in zip(colours, levels, strict=False):
            legend = f"s = {float(ds['suction'][level]):.3g} Pa"
            axes[0, column].plot(n, values.isel(suction=level).values, "o-", ms=3, color=colour,
                                 label=legend)
            if column < 2:
                axes[1, column].plot(n, relative.isel(suction=level).values, "o-", ms=3,
                                     color=colour, label=legend)
        axes[0, column].set(xscale="log", yscale="log" if log else "linear",
                            xlabel="number of points", ylabel=label)
    outside_legend(axes[0, 3])  # the same levels in every panel
    for column in (0, 1):
        axes[1, column].set(xscale="log", yscale="log", xlabel="number of points",
                            ylabel=f"relative change of\n{top[column][0].rsplit(' [', 1)[0]} [-]")
    for phase, style in (("water", "o-"), ("gas", "s--")):
        axes[1, 2].plot(n, change.sel(phase=phase).max("suction").values, style, ms=3,
                        color=_PHASE_COLOUR[phase], label=f"{phase}, largest over checkpoints")
    axes[1, 2].set(xscale="log", yscale="log", xlabel="number of points",
                   ylabel="relative change of k\n(largest axis) [-]")
    outside_legend(axes[1, 2])
    last = ds.isel(suction=-1)
    axes[1, 3].plot(n, last["crack_count"].values, "ko-", ms=3, label="cracks (last checkpoint)")
    axes[1, 3].set(xscale="log", xlabel="number of points", ylabel="number of cracks (last checkpoint)")
    axes[1, 3].yaxis.set_major_locator(MaxNLocator(integer=True))
    if "wall_time_s" in ds:
        twin = axes[1, 3].twinx()
        twin.plot(n, ds["wall_time_s"].values, "r^:", ms=3, label="wall time [s]")
        twin.set(yscale="log", ylabel="wall time [s] (red)")
    return save_figure(fig, path)


def scale_figure(ds: xr.Dataset, path: str | Path, n_levels: int = 5) -> Path:
    """Scale study (Fig. 3.18): mean (left) and standard deviation (right) over the
    realizations against the domain fraction, one line per hydration level.

    Columns: water and gas permeability (geometric mean of the axes), crack volume per
    sub-region volume, volumetric strain and saturation; lines: up to ``n_levels``
    checkpoints, labelled by suction and the reference's saturation.

    Parameters
    ----------
    ds
        :func:`micro.studies.scale_dataset` output.
    path
        Target PNG.
    """
    panels: tuple[tuple[str, dict[str, str], str, bool], ...] = (
              ("permeability_geomean", {"phase": "water"}, "water permeability [m2]", True),
              ("permeability_geomean", {"phase": "gas"}, "gas permeability [m2]", True),
              ("crack_volume_fraction", {}, "crack volume fraction [-]", False),
              ("eps_v", {}, "volumetric strain [-]", False),
              ("saturation", {}, "saturation [-]", False))
    # one row per quantity, its mean and its spread side by side; one legend below
    fig, axes = new_figure(len(panels), 2, width=4.2, height=2.6)
    fraction = ds["domain_fraction"].values
    levels = np.unique(np.linspace(0, ds.sizes["suction"] - 1, n_levels).round().astype(int))
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, levels.size))
    reference = ds.isel(realization=0)
    for row, (name, sel, label, log) in enumerate(panels):
        for colour, level in zip(colours, levels, strict=False):
            legend = (f"s = {float(ds['suction'][level]):.3g} Pa, "
                      f"S = {float(reference['saturation'][level]):.2f}")
            for column, stat in enumerate(("mean", "std")):
                values = ds[f"{name}_{stat}"].isel(suction=level).sel(sel).values
                if log:
                    values = np.where(values > 0, values, np.nan)
                axes[row, column].plot(fraction, values, "o-", ms=3, color=colour, label=legend)
        for column, stat in enumerate(("mean", "std. dev. of")):
            axes[row, column].set(xscale="log", yscale="log" if log else "linear",
                                  xlabel="domain fraction [-]", ylabel=f"{stat}\n{label}")
    counts = ", ".join(f"{f:.3g}: {int(n)}" for f, n in zip(fraction, ds["n_realizations"].values, strict=False))
    fig.suptitle(f"scale study of case {ds.attrs.get('reference', '?')}: mean and standard deviation "
                 "over the realizations\n(permeability: geometric mean of k_x, k_y, k_z; realizations "
                 f"per domain fraction {counts})", fontsize="medium")
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc="outside lower center", ncol=3,
               fontsize="x-small", title="hydration level (suction, reference saturation)")
    return save_figure(fig, path)
