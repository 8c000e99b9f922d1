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
    """A 2 x 2 grid titled by the case (the file's stem): sensor and axial pressures vs
    time, the column's permeability vs time (its value at t = 0 drawn at the time axis's
    left edge), suction and swelling along the axis at a few times (one legend)."""
    fig, axes = new_figure(2, 2, width=5.0, height=3.6)
    case = Path(path).stem
    fig.suptitle(f"macro case {case}: {int(ds.attrs.get('n_pellets', 0))} pellets, "
                 f"{ds.attrs.get('powder_heterogeneity', '?')} powder", fontsize="medium")
    ax = axes[0, 0]
    days = ds["time"].values / 86400.0
    for name, z in zip(ds["sensor"].values, ds["sensor_height"].values, strict=True):
        ax.plot(days, ds["sensor_pressure"].sel(sensor=name).values / 1e6, label=f"{name} ({1e3 * z:.0f} mm)")
    ax.plot(days, ds["axial_pressure_upper"].values / 1e6, "k--", label="axial, upper plate")
    ax.plot(days, ds["axial_pressure_lower"].values / 1e6, "k:", label="axial, lower plate")
    _days_axis(ax, days)
    ax.set_ylabel("pressure [MPa]")
    outside_legend(ax)
    ax.set_title("wall pressures")
    _permeability_panel(axes[0, 1], ds)
    z = ds["z"].values * 100
    # the start, then times a hundredth, a tenth, a third of the run and its end
    wanted = np.array([0.0, 0.01, 0.1, 1.0 / 3.0, 1.0]) * days[-1]
    picks = np.unique(np.abs(days[None, :] - wanted[:, None]).argmin(axis=1))
    suction_ax, swelling_ax = axes[1, 0], axes[1, 1]
    for i in picks:
        label = f"{plain_number(days[i])} d"
        suction_ax.plot(z, ds["suction_profile"].values[i] / 1e6, label=label)
        swelling_ax.plot(z, ds["swelling_profile"].values[i], label=label)
    suction_ax.set(xlabel="height above the lower plate [cm]", ylabel="suction [MPa]",
                   title="suction along the axis")
    swelling_ax.set(xlabel="height above the lower plate [cm]", ylabel="swelling strain V/V0 - 1 [1]",
                    title="swelling along the axis")
    outside_legend(swelling_ax, title="time")  # the same lines in both profile panels
    return save_figure(fig, path)


def _permeability_panel(ax: Axes, ds: xr.Dataset) -> None:
    """The column's permeability against time; the measurement at t = 0, which a log time
    axis cannot show, as an open marker at its left edge."""
    k_days = ds["permeability_time"].values / 86400.0
    k = ds["column_permeability"].values
    ax.semilogy(k_days, k, "o-", label="measured")
    left = _days_axis(ax, k_days)
    if left is not None and np.any(k_days <= 0.0):
        ax.plot([left], [k[k_days <= 0.0][0]], "s", mfc="none", color="C0", clip_on=False,
                label="t = 0 (at the left edge)")
        outside_legend(ax)
    ax.set_ylabel("permeability along the axis [m2]")
    ax.set_title("column permeability")


def comparison_figure(cases: dict[str, xr.Dataset], path: str | Path) -> Path:
    """Cases side by side (e.g. Weibull, homogeneous and random-field powder, with and
    without the powder's push on the walls): mean sensor pressure, axial pressure and
    mean pellet suction against time."""
    fig, grid = new_figure(1, 3, width=4.2, height=3.4)
    fig.suptitle(f"macro cases {', '.join(sorted(cases))}", fontsize="medium")
    axes = grid[0]
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


def _days_axis(ax: Axes, days: np.ndarray) -> float | None:
    """Time [d] on a log axis over the last four decades of the run at most (the first
    steps last seconds): labelled ticks at 1, 2 and 5 per decade over up to three
    decades, at the decades over more. Returns the axis's left limit [d] (None: a
    linear axis, fewer than two times after the start)."""
    ax.set_xlabel("time [d]")
    after = days[days > 0.0]
    if after.size < 2:
        return None
    start, end = max(after.min(), 1e-4 * after.max()), after.max()
    ax.set_xscale("log", nonpositive="mask")
    ax.set_xlim(start, end)
    subs = (1.0, 2.0, 5.0) if end / start <= 1e3 else (1.0,)
    ax.xaxis.set_major_locator(LogLocator(base=10.0, subs=subs))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda value, _: plain_number(value)))
    ax.xaxis.set_minor_formatter(NullFormatter())
    return float(start)
