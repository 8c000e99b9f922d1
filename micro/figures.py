"""Figures of the micro stage (thesis Figs. 3.10-3.16 analogues)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

from shared.figures import new_figure, outside_legend, save_figure

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
    fig, axes = new_figure(2, 2, width=6.5)
    _permeability_panel(axes[0, 0], ds, "saturation")
    axes[0, 0].set(xlabel="saturation [-]", title=f"{case}: permeability vs saturation")
    outside_legend(axes[0, 0], ncol=2)
    _permeability_panel(axes[0, 1], ds, "suction")
    axes[0, 1].set(xscale="log", xlabel="boundary suction [Pa]", title="permeability vs suction")
    axes[0, 1].invert_xaxis()
    saturation = ds["saturation"].values
    for suffix, colour in (("_imbibed", "tab:blue"), ("_gas", "tab:red")):
        fabric = ds[f"crack_fabric{suffix}"].values
        for index, style in zip(range(3), ("-", "--", ":"), strict=False):
            axes[1, 0].plot(saturation, fabric[:, index, index], style, color=colour, marker="o", ms=3,
                            label=f"{suffix[1:]} {'xyz'[index]}{'xyz'[index]}")
    twin = axes[1, 0].twinx()
    twin.plot(saturation, ds["crack_count"].values, "k-", alpha=0.4)
    twin.set_ylabel("cracks [-]")
    axes[1, 0].set(xlabel="saturation [-]", ylabel="fabric component [m2]",
                   title="crack fabric (diagonal) and count")
    outside_legend(axes[1, 0], ncol=2, bbox_to_anchor=(1.3, 1.0))
    bins = ds["bin"].values
    colours = np.linspace(0.1, 0.9, ds.sizes["suction"])
    for index, shade in enumerate(colours):
        axes[1, 1].plot(bins, ds["porosity_hist"].isel(suction=index).values,
                        color=(shade, 0.3, 1 - shade),
                        label=f"S = {saturation[index]:.2f}")
    axes[1, 1].set(xlabel="porosity [-]", ylabel="volume fraction [-]",
                   title="porosity distribution through hydration")
    outside_legend(axes[1, 1])
    return save_figure(fig, path)


def comparison_figure(cases: Mapping[str, xr.Dataset], path: str | Path) -> Path:
    """Water and gas permeability vs saturation across cases (Figs. 3.11, 3.13): the
    mean permeability is the arithmetic mean of the three directional permeabilities
    k_x, k_y, k_z of a checkpoint (one case, one realization)."""
    fig, axes = new_figure(1, 2, width=5.0)
    # tab20 keeps up to twenty cases (default + convergence + scale presets) apart
    colours = plt.get_cmap("tab10" if len(cases) <= 10 else "tab20").colors
    for ax, phase in zip(axes[0], ("water", "gas"), strict=False):
        for index, (name, ds) in enumerate(cases.items()):
            k = ds["permeability"].sel(phase=phase).mean("axis").values
            ax.plot(ds["saturation"].values, np.where(k > 0, k, np.nan), marker="o", ms=3,
                    label=name, color=colours[index % len(colours)])
        ax.set(yscale="log", xlabel="saturation [-]",
               ylabel=f"mean {phase} permeability (m²)",
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
    n = ds["n_points"].values
    levels = np.unique(np.linspace(0, ds.sizes["suction"] - 1, n_levels).round().astype(int))
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, levels.size))
    k = ds["permeability"].where(ds["permeability"] > 0)
    geomean = np.exp(np.log(k).mean("axis"))
    change = ds["permeability_relative_change"].max("axis")
    top = (("saturation", ds["saturation"], ds["saturation_relative_change"], False),
           ("eps_v", ds["eps_v"], ds["eps_v_relative_change"], False),
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
    outside_legend(axes[0, 0])
    for column in (0, 1):
        axes[1, column].set(xscale="log", yscale="log", xlabel="number of points",
                            ylabel=f"relative change of {top[column][0]}")
    for phase, style in (("water", "o-"), ("gas", "s--")):
        axes[1, 2].plot(n, change.sel(phase=phase).max("suction").values, style, ms=3,
                        color=_PHASE_COLOUR[phase], label=f"{phase}, largest over checkpoints")
    axes[1, 2].set(xscale="log", yscale="log", xlabel="number of points",
                   ylabel="relative change of k (largest axis)")
    outside_legend(axes[1, 2])
    last = ds.isel(suction=-1)
    axes[1, 3].plot(n, last["crack_count"].values, "ko-", ms=3, label="cracks (last checkpoint)")
    axes[1, 3].set(xscale="log", xlabel="number of points", ylabel="cracks [-]")
    if "wall_time_s" in ds:
        twin = axes[1, 3].twinx()
        twin.plot(n, ds["wall_time_s"].values, "r^:", ms=3, label="wall time [s]")
        twin.set(yscale="log", ylabel="wall time [s] (red)")
    return save_figure(fig, path)


def scale_figure(ds: xr.Dataset, path: str | Path, n_levels: int = 5) -> Path:
    """Scale study (Fig. 3.18): mean (top) and standard deviation (bottom) over the
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
    panels = (("permeability_geomean", {"phase": "water"}, "water permeability (m²)", True),
              ("permeability_geomean", {"phase": "gas"}, "gas permeability (m²)", True),
              ("crack_volume_fraction", {}, "crack volume fraction (-)", False),
              ("eps_v", {}, "volumetric strain (-)", False),
              ("saturation", {}, "saturation (-)", False))
    fig, axes = new_figure(2, len(panels), width=3.6)
    fraction = ds["domain_fraction"].values
    levels = np.unique(np.linspace(0, ds.sizes["suction"] - 1, n_levels).round().astype(int))
    colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.9, levels.size))
    reference = ds.isel(realization=0)
    for column, (name, sel, label, log) in enumerate(panels):
        for colour, level in zip(colours, levels, strict=False):
            legend = (f"s = {float(ds['suction'][level]):.3g} Pa, "
                      f"S = {float(reference['saturation'][level]):.2f}")
            for row, stat in enumerate(("mean", "std")):
                values = ds[f"{name}_{stat}"].isel(suction=level).sel(sel).values
                if log:
                    values = np.where(values > 0, values, np.nan)
                axes[row, column].plot(fraction, values, "o-", ms=3, color=colour, label=legend)
        for row, stat in enumerate(("mean", "standard deviation of")):
            ax = axes[row, column]
            ax.set(xscale="log", yscale="log" if log else "linear",
                   xlabel="domain fraction [-]", ylabel=f"{stat} {label}")
    outside_legend(axes[0, 0])
    counts = ", ".join(f"{f:.3g}: {int(n)}" for f, n in zip(fraction, ds["n_realizations"].values, strict=False))
    fig.suptitle(f"scale study: mean and standard deviation over the realizations of a domain "
                 f"fraction (permeability: geometric mean of k_x, k_y, k_z); realizations per "
                 f"domain fraction ({counts})", fontsize="small")
    return save_figure(fig, path)
