"""Seed ensembles of a macro case: statistics over the heterogeneity (thesis Sec. 4.10).

An ensemble ``macro.ensembles.<name>: {case, seeds}`` runs its case once per seed (the
seed of the packing and of the powder field) as the cases ``<name>_s<seed>``, its
members. :func:`ensemble_statistics` puts the members' wall pressures and mean
saturations on one time axis, spaced geometrically from the latest first step of the
members to the earliest end of a member (the members stop near equilibrium at different
times; every member is present at every time), linearly interpolated in time, and
reduces them to their mean and a band between two quantiles over the members.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import xarray as xr
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from shared.errors import InputError
from shared.figures import new_figure, save_figure
from shared.io import read_dataset, write_outputs

__all__ = [
    "EnsembleOutputs",
    "QUANTITIES",
    "ensemble_statistics",
    "plot_ensemble",
    "ensemble_figure",
    "run",
]

FloatArray = npt.NDArray[np.float64]
QUANTITIES = ("sensor_pressure", "axial_pressure_upper", "axial_pressure_lower", "mean_saturation")
"""The member variables an ensemble reduces, each over ``time`` and its other dimensions."""
OPTIONAL = ("axial_pressure_lower",)
"""Quantities reduced only when every member has them."""


def _common_times(members: Mapping[str, xr.Dataset], points: int) -> FloatArray:
    """``points`` times [s] spaced geometrically from the latest first step of the members
    to the earliest end of a member."""
    starts, ends = [], []
    for name, ds in members.items():
        time = ds["time"].values
        if not (time > 0.0).any():
            raise InputError(f"ensemble member {name}: no record after t = 0")
        starts.append(time[time > 0.0].min())
        ends.append(time.max())
    start, end = max(starts), min(ends)
    if not start < end:
        raise InputError(
            f"ensemble members end before the latest first step ({end:.6g} s <= {start:.6g} s): "
            "no common time axis"
        )
    return np.geomspace(start, end, points)


def _on_times(da: xr.DataArray, times: FloatArray) -> xr.DataArray:
    """``da`` linearly interpolated in time onto ``times`` [s], its other dimensions kept."""
    moved = da.transpose("time", ...)
    columns = moved.values.reshape(moved.shape[0], -1)
    source = moved["time"].values
    values = np.stack([np.interp(times, source, column) for column in columns.T], axis=-1)
    coords = {k: v for k, v in moved.coords.items() if "time" not in v.dims}
    return xr.DataArray(values.reshape((times.size, *moved.shape[1:])), dims=moved.dims,
                        coords={**coords, "time": times}, attrs=da.attrs)


def ensemble_statistics(
    members: Mapping[str, xr.Dataset],
    points: int = 100,
    quantiles: Sequence[float] = (0.1, 0.9),
) -> xr.Dataset:
    """The members on a common time axis, their mean and a quantile band.

    Parameters
    ----------
    members
        Member name -> its ``results/macro/<member>.nc`` dataset, with ``time`` [s],
        ``sensor_pressure(time, sensor)`` [Pa], ``axial_pressure_upper(time)`` [Pa],
        ``mean_saturation(time, material)`` [1] and optionally
        ``axial_pressure_lower(time)`` [Pa]; the ``sensor`` coordinates must agree.
    points
        Number of times of the common axis.
    quantiles
        The band's (low, high) quantiles over the members (linear interpolation between
        order statistics; (0, 1) is the min-max band).

    Returns
    -------
    xarray.Dataset
        Per quantity ``q``: ``q(member, time, ...)`` the members on the common axis,
        ``q_mean(time, ...)`` their mean and ``q_band(quantile, time, ...)`` the band;
        ``member_end_time(member)`` [s]; ``time`` [s] spaced geometrically from the latest
        first step to the earliest end of a member.

    Raises
    ------
    ValueError
        If there is no member, a member lacks a quantity or has other sensors, or the
        members have no common time span.
    """
    if not members:
        raise InputError("an ensemble needs at least one member")
    names = list(members)
    first = members[names[0]]
    for name, ds in members.items():
        missing = [q for q in QUANTITIES if q not in OPTIONAL and q not in ds.variables]
        if missing:
            raise InputError(f"ensemble member {name}: missing variable(s) {missing}")
        if not ds.indexes["sensor"].equals(first.indexes["sensor"]):
            raise InputError(
                f"ensemble member {name}: sensors {list(ds['sensor'].values)} differ from "
                f"those of {names[0]} ({list(first['sensor'].values)})"
            )
    times = _common_times(members, points)
    present = [q for q in QUANTITIES if all(q in ds.variables for ds in members.values())]
    low, high = (float(q) for q in quantiles)
    data: dict[str, Any] = {}
    for q in present:
        stacked = xr.concat([_on_times(members[n][q], times) for n in names], dim="member",
                            coords="minimal", compat="override")
        units, long_name = first[q].attrs["units"], first[q].attrs["long_name"]
        data[q] = stacked.assign_attrs(units=units, long_name=f"{long_name}, each member")
        data[f"{q}_mean"] = stacked.mean("member").assign_attrs(
            units=units, long_name=f"{long_name}, mean over the members")
        data[f"{q}_band"] = stacked.quantile([low, high], dim="member").assign_attrs(
            units=units, long_name=f"{long_name}, quantiles over the members")
    data["member_end_time"] = xr.DataArray(
        [float(members[n]["time"].values.max()) for n in names], dims="member",
        attrs={"units": "s", "long_name": "simulated time at the member's end"})
    ds = xr.Dataset(data).assign_coords(member=("member", names))
    ds["time"].attrs = {"units": "s", "long_name": "simulated time (common axis of the members)"}
    ds["member"].attrs = {"units": "1", "long_name": "ensemble member (macro case)"}
    ds["quantile"].attrs = {"units": "1", "long_name": "quantile over the members"}
    if all("seed" in members[n].attrs for n in names):
        ds = ds.assign_coords(seed=("member", [int(members[n].attrs["seed"]) for n in names],
                                    {"units": "1", "long_name": "seed of the member"}))
    ds.attrs.update(
        members=len(names),
        time_axis="geometric from the latest first step to the earliest end of a member; "
                  "members interpolated linearly in time",
        band=f"quantiles {low:g}-{high:g} over the members (linear between order statistics)",
    )
    return ds


def _sensor_label(value: Any) -> str:
    """A sensor's legend label: its name, or ``sensor <number>``."""
    return str(value) if isinstance(value, str) else f"sensor {value}"


def plot_ensemble(ds: xr.Dataset, title: str = "") -> Figure:
    """Mean line and band against time (days, log axis) of each sensor (one colour each),
    of the axial pressures and of the mean saturations; each panel's legend below it."""
    fig, grid = new_figure(1, 3, width=4.4, height=4.0)
    axes = grid[0]
    days = ds["time"].values / 86400.0
    low, high = (100.0 * float(q) for q in ds["quantile"].values)

    def draw(ax: Axes, name: str, label: str, scale: float, **where: Any) -> None:
        mean = ds[f"{name}_mean"].sel(where).values / scale
        band = ds[f"{name}_band"].sel(where).values / scale
        (line,) = ax.plot(days, mean)
        patch = ax.fill_between(days, band[0], band[1], color=line.get_color(), alpha=0.25,
                                linewidth=0)
        handles.setdefault(ax, []).append(((patch, line), label))

    handles: dict[Axes, list[tuple[tuple[Any, Any], str]]] = {}
    for sensor in ds["sensor"].values:
        draw(axes[0], "sensor_pressure", _sensor_label(sensor), 1e6, sensor=sensor)
    draw(axes[1], "axial_pressure_upper", "upper plate", 1e6)
    if "axial_pressure_lower_mean" in ds:
        draw(axes[1], "axial_pressure_lower", "lower plate", 1e6)
    for material in ds["material"].values:
        draw(axes[2], "mean_saturation", str(material), 1.0, material=material)
    for ax, ylabel, heading in zip(
        axes,
        ("radial wall pressure [MPa]", "axial pressure [MPa]", "mean saturation [1]"),
        ("wall sensors", "plates", "hydration"), strict=False,
    ):
        ax.set_xscale("log")
        ax.set_xlabel("time [d]")
        ax.set_ylabel(ylabel)
        ax.set_title(heading)
        pairs, labels = zip(*handles[ax], strict=False)
        ax.legend(pairs, labels, fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16),
                  ncol=3)
    fig.suptitle(f"{title + ': ' if title else ''}mean over {ds.sizes['member']} members "
                 f"(line) and {low:g}-{high:g} % quantile band")
    return fig


def ensemble_figure(ds: xr.Dataset, path: str | Path, title: str = "") -> Path:
    """Write :func:`plot_ensemble`'s figure as PNG."""
    return save_figure(plot_ensemble(ds, title), path)


class EnsembleOutputs(NamedTuple):
    """The files of :func:`run`: ``results/macro/ensemble_<name>.nc`` and its PNG."""

    result: str | Path
    figure: str | Path


def run(
    settings: Mapping[str, Any],
    name: str,
    member_paths: Sequence[str | Path],
    outputs: EnsembleOutputs,
    *,
    rule: str | None = None,
) -> xr.Dataset:
    """Reduce an ensemble's member results to its netCDF file and its figure.

    Parameters
    ----------
    settings
        The ensemble's validated entry (``case``, ``seeds``, ``time_points``,
        ``band_quantiles``).
    name
        Name in ``macro.ensembles``.
    member_paths
        The members' ``results/macro/<member>.nc``; their file names are the members'.
    outputs
        ``results/macro/ensemble_<name>.nc`` and ``.png``.
    rule
        Snakemake rule name for the provenance.

    Raises
    ------
    shared.io.OutputError
        If a member's file is missing or lacks a required quantity (naming the file).
    """
    required = [q for q in QUANTITIES if q not in OPTIONAL]
    members = {Path(path).stem: read_dataset(path, required) for path in member_paths}
    ds = ensemble_statistics(members, settings["time_points"], settings["band_quantiles"])
    title = f"ensemble {name} (case {settings['case']})"
    write_outputs(ds, outputs.result, stage="macro", title=f"claychain macro ensemble {name}",
                  config={"ensemble": name, **settings}, inputs=member_paths, rule=rule,
                  wildcards={"ensemble": name}, references="Caulk (2022) thesis Sec. 4.10",
                  figure=(outputs.figure, lambda path: ensemble_figure(ds, path, title)))
    return ds
