"""The upscaling table: micro permeability curves condensed into one pellet table.

Each condition of the table (``free``, ``confined``) comes from one micro case or from
an ensemble of cases (realizations). Over an ensemble, permeability is averaged in log
(geometric mean, with the standard deviation of log10 k, thesis Sec. 3.5.9 reports the
spread on a log axis), the tensor by the mean of the realizations' symmetric parts, and
saturation and strain arithmetically. The suction coordinate ascends, as the macro
model's interpolator (:mod:`shared.upscaling`) reads it. The functions here do no I/O:
:func:`upscale` is the stage's computation, from datasets in memory and
:class:`UpscalingSettings`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from shared.config import ConfigError, check_ordered_pair
from shared.upscaling import check_table

__all__ = ["SOURCE_VARIABLES", "UpscalingSettings", "upscale", "upscaling_table", "table_rows"]

SOURCE_VARIABLES = ("suction", "saturation", "eps_v", "permeability", "permeability_tensor")
"""Variables a micro result must hold to be a source of the table."""


def _check_source(ds: xr.Dataset, name: str, suction_range: tuple[float, float]) -> None:
    missing = [v for v in SOURCE_VARIABLES if v not in ds]
    if missing:
        raise ConfigError(f"{name}: not a micro result with permeabilities (missing {missing})")
    suction = ds["suction"].values
    low, high = suction_range
    if suction.min() > low * (1 + 1e-9) or suction.max() < high * (1 - 1e-9):
        raise ConfigError(
            f"{name}: its checkpoints span {suction.min():.4g}-{suction.max():.4g} Pa, not the "
            f"suction range {low:.4g}-{high:.4g} Pa of upscaling.suction_range_pa"
        )
    for variable in ("permeability", "permeability_tensor"):
        values = ds[variable].values
        if variable == "permeability":
            bad = ~(np.isfinite(values) & (values > 0))
        else:
            bad = ~np.isfinite(values)
        if bad.any():
            checkpoint = int(np.argwhere(bad)[0][0])
            raise ConfigError(
                f"{name}: non-positive or NaN {variable} at checkpoint {checkpoint} "
                f"({suction[checkpoint]:.4g} Pa): it cannot enter a log-interpolated table"
            )


def upscaling_table(
    sources: Mapping[str, Sequence[tuple[str, xr.Dataset]]],
    suction_range: tuple[float, float],
) -> xr.Dataset:
    """Condense micro results into the pellet permeability table (docs/design.md §2).

    Parameters
    ----------
    sources
        Per condition (``free``, ``confined``), the (name, dataset) pairs of its micro
        results: one case, or the realizations of an ensemble. Every result must have
        the same checkpoints.
    suction_range
        (smallest, largest) suction [Pa] the consumer needs; every source's checkpoints
        must span it.

    Returns
    -------
    xarray.Dataset
        ``k(condition,phase,axis,suction)`` [m2] (geometric mean over realizations),
        ``k_log10_std`` (sample standard deviation of log10 k, NaN for one realization),
        ``k_tensor(condition,phase,suction,i,j)`` [m2], ``saturation`` and ``eps_v``
        ``(condition,suction)``, ``n_realizations(condition)``.

    Raises
    ------
    ConfigError
        Naming the source, if it lacks a variable, misses the suction range, has a
        non-positive or NaN permeability, or has other checkpoints than the first.
    """
    for condition, members in sources.items():
        if not members:
            raise ConfigError(f"config key 'upscaling.conditions.{condition}': no source")
    reference_name, reference = next(iter(sources.values()))[0]
    suction = np.asarray(reference["suction"].values, dtype=float)
    order = np.argsort(suction)
    per_condition: dict[str, dict[str, np.ndarray]] = {}
    for condition, members in sources.items():
        stacks: dict[str, list[np.ndarray]] = {v: [] for v in SOURCE_VARIABLES[1:]}
        for name, ds in members:
            _check_source(ds, name, suction_range)
            if not np.array_equal(ds["suction"].values, suction):
                raise ConfigError(
                    f"{name}: its checkpoints differ from those of {reference_name}; the "
                    "sources of one table share micro.checkpoints_suction_pa"
                )
            for variable in stacks:
                stacks[variable].append(np.asarray(ds[variable].values, dtype=float)[order])
        log_k = np.log10(np.stack(stacks["permeability"]))  # (real, suction, phase, axis)
        tensor = np.stack(stacks["permeability_tensor"])
        per_condition[condition] = {
            "k": 10.0 ** log_k.mean(axis=0),
            "k_log10_std": log_k.std(axis=0, ddof=1) if len(members) > 1
            else np.full(log_k.shape[1:], np.nan),
            "k_tensor": (0.5 * (tensor + np.swapaxes(tensor, -1, -2))).mean(axis=0),
            "saturation": np.stack(stacks["saturation"]).mean(axis=0),
            "eps_v": np.stack(stacks["eps_v"]).mean(axis=0),
            "n_realizations": np.array(len(members)),
        }
    conditions = list(sources)

    def stacked(variable: str) -> np.ndarray:
        return np.stack([per_condition[c][variable] for c in conditions])

    k_dims = ("condition", "phase", "axis", "suction")
    table = xr.Dataset(
        {
            "k": (k_dims, np.moveaxis(stacked("k"), 1, -1),
                  {"units": "m2", "long_name": "pellet permeability (geometric mean over realizations)"}),
            "k_log10_std": (k_dims, np.moveaxis(stacked("k_log10_std"), 1, -1),
                            {"units": "1", "long_name": "standard deviation of log10 k over realizations"}),
            "k_tensor": (("condition", "phase", "suction", "i", "j"),
                         np.moveaxis(stacked("k_tensor"), 1, 2),
                         {"units": "m2", "long_name": "symmetric pellet permeability tensor, mean over realizations"}),
            "saturation": (("condition", "suction"), stacked("saturation"),
                           {"units": "1", "long_name": "pellet water saturation"}),
            "eps_v": (("condition", "suction"), stacked("eps_v"),
                      {"units": "1", "long_name": "pellet volumetric strain from the 132 MPa state"}),
            "n_realizations": ("condition", stacked("n_realizations"),
                               {"units": "1", "long_name": "micro results averaged per condition"}),
        },
        coords={
            "condition": ("condition", np.array(conditions), {"long_name": "mechanical condition"}),
            "phase": ("phase", reference["phase"].values, {"long_name": "fluid phase"}),
            "axis": ("axis", reference["axis"].values, {"long_name": "direction (z: compaction axis)"}),
            "suction": ("suction", suction[order], {"units": "Pa", "long_name": "pellet suction"}),
            "i": ("i", np.arange(3), {"units": "1", "long_name": "tensor row (x, y, z)"}),
            "j": ("j", np.arange(3), {"units": "1", "long_name": "tensor column (x, y, z)"}),
        },
    )
    check_table(table)
    return table


def table_rows(table: xr.Dataset) -> list[tuple[str, float, str, str, float]]:
    """Rows (condition, suction [Pa], phase, axis, k [m2]) of the table's CSV export."""
    frame = table["k"].to_dataframe().reset_index()
    return [
        (str(row.condition), float(row.suction), str(row.phase), str(row.axis), float(row.k))
        for row in frame.itertuples(index=False)
    ]


@dataclass(frozen=True)
class UpscalingSettings:
    """Settings of :func:`upscale`.

    Attributes
    ----------
    suction_range : tuple of float
        (smallest, largest) suction the macro model reads [Pa]
        (``upscaling.suction_range_pa``); every source's checkpoints must span it.

    Raises
    ------
    ConfigError
        Naming ``upscaling.suction_range_pa`` unless smallest < largest.
    """

    suction_range: tuple[float, float]

    def __post_init__(self) -> None:
        check_ordered_pair(self.suction_range, "upscaling.suction_range_pa")
        low, high = self.suction_range
        object.__setattr__(self, "suction_range", (float(low), float(high)))

    @classmethod
    def from_config(cls, upscaling: Mapping[str, Any]) -> UpscalingSettings:
        """The settings of the validated ``upscaling`` section."""
        return cls(tuple(upscaling["suction_range_pa"]))


def upscale(datasets: Mapping[str, Sequence[xr.Dataset | tuple[str, xr.Dataset]]],
            settings: UpscalingSettings) -> xr.Dataset:
    """The pellet permeability table of micro results held in memory.

    Parameters
    ----------
    datasets
        Per condition (``free``, ``confined``), its micro results (datasets of
        :data:`SOURCE_VARIABLES`): one case, or the realizations of an ensemble, each a
        dataset or a (name, dataset) pair; messages name a bare dataset
        ``<condition>[<index>]``.
    settings
        The suction range.

    Returns
    -------
    xarray.Dataset
        The table of :func:`upscaling_table`: ``k(condition, phase, axis, suction)`` [m2],
        ``k_log10_std`` [1], ``k_tensor`` [m2], ``saturation`` and ``eps_v`` [1],
        ``n_realizations``.

    Raises
    ------
    ConfigError
        As :func:`upscaling_table`.
    """
    sources = {
        condition: [member if isinstance(member, tuple) else (f"{condition}[{index}]", member)
                    for index, member in enumerate(members)]
        for condition, members in datasets.items()
    }
    return upscaling_table(sources, settings.suction_range)
