"""Figure of a macro case: wall pressures against time (Fig. 4.11 analogue), suction and
swelling along the axis at several times (Fig. 4.10 analogue) and the column's permeability
against time."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib.axes import Axes
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from shared.figures import new_figure, outside_legend, plain_number, save_figure

__all__ = ["case_figure", "comparison_figure"]


def case_figure(ds: xr.Dataset, path: str | Path) -> Path:
    """Four panels: sensor and axial pressures vs time; suction and swelling profiles;
    the column's permeability vs time."""
    fig, grid = new_figure(1, 4, width=4.2, height=3.4)
    axes = grid[0]  # type: ignore[index]
    ax = axes[0]
    days = ds["time"].values / 86400.0
    for name, z in zip(ds["sensor"].values, ds["sensor_height"].values, strict=True):
        ax.plot(days, ds["sensor_pressure"].sel(sensor=name).values / 1e6, label=f"{name} ({1e3 * z:.0f} mm)")
    ax.plot(days, ds["axial_pressure_upper"].values / 1e6, "k--", label="axial, upper plate")
    ax.plot(days, ds["axial_pressure_lower"].values / 1e6, "k:", label="axial, lower plate")
    _days_axis(ax, days)
    ax.set_ylabel("pressure [MPa]")
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=2)
    ax.set_title("wall pressures")
    z = ds["z"].values * 100
    # the start, then times a hundredth, a tenth, a third of the run and its end
    wanted = np.array([0.0, 0.01, 0.1, 1.0 / 3.0, 1.0]) * days[-1]
    picks = np.unique(np.abs(days[None, :] - wanted[:, None]).argmin(axis=1))
    for i in picks:
        label = f"{plain_number(days[i])} d"
        axes[1].plot(z, ds["suction_profile"].values[i] / 1e6, label=label)
        axes[2].plot(z, ds["swelling_profile"].values[i], label=label)
    axes[1].set_xlabel("height [cm]")
    axes[1].set_ylabel("suction [MPa]")
    outside_legend(axes[1], title="time")
    axes[1].set_title("suction along the axis")
    axes[2].set_xlabel("height [cm]")
    axes[2].set_ylabel("swelling strain V/V0 - 1 [1]")
    axes[2].set_title("swelling along the axis")
    k_days = ds["permeability_time"].values / 86400.0
    axes[3].semilogy(k_days, ds["column_permeability"].values, "o-")
    _days_axis(axes[3], k_days)
    axes[3].set_ylabel("permeability [m2]")
    axes[3].set_title("column along its axis")
    return save_figure(fig, path)


def comparison_figure(cases: dict[str, xr.Dataset], path: str | Path) -> Path:
    """Cases side by side (e.g. Weibull, homogeneous and random-field powder, with and
    without the powder's push on the walls): mean sensor pressure, axial pressure and
    mean pellet suction against time."""
    fig, grid = new_figure(1, 3, width=4.2, height=3.4)
    axes = grid[0]  # type: ignore[index]
    for name, ds in sorted(cases.items()):
        days = ds["time"].values / 86400.0
        label = f"{name} ({ds.attrs.get('powder_heterogeneity', '?')}" + (
            ", powder on walls)" if ds.attrs.get("powder_pressure_on_walls") else ")")
        axes[0].plot(days, ds["sensor_pressure"].mean("sensor").values / 1e6, label=label)
        axes[1].plot(days, ds["axial_pressure_upper"].values / 1e6, label=label)
        axes[2].plot(days, ds["mean_suction"].sel(material="pellet").values / 1e6, label=label)
    for ax, what in zip(axes, ("mean radial sensor pressure [MPa]", "axial pressure [MPa]",
                               "mean pellet suction [MPa]"), strict=False):
        _days_axis(ax, np.concatenate([ds["time"].values / 86400.0 for ds in cases.values()]))
        ax.set_ylabel(what)
    axes[0].legend(fontsize=6, loc="upper center", bbox_to_anchor=(0.5, -0.22))
    axes[0].set_title("sensors (mean of the named sensors)")
    axes[1].set_title("upper plate")
    axes[2].set_title("hydration")
    return save_figure(fig, path)


def _days_axis(ax: Axes, days: np.ndarray) -> None:
    """Time [d] on a log axis over the last four decades of the run at most (the first
    steps last seconds): labelled ticks at 1, 2 and 5 per decade over up to three
    decades, at the decades over more."""
    ax.set_xlabel("time [d]")
    after = days[days > 0.0]
    if after.size < 2:
        return
    start, end = max(after.min(), 1e-4 * after.max()), after.max()
    ax.set_xscale("log", nonpositive="mask")
    ax.set_xlim(start, end)
    subs = (1.0, 2.0, 5.0) if end / start <= 1e3 else (1.0,)
    ax.xaxis.set_major_locator(LogLocator(base=10.0, subs=subs))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda value, _: plain_number(value)))
    ax.xaxis.set_minor_formatter(NullFormatter())
