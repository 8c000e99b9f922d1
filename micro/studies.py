"""Studies over micro cases: convergence in the number of points, and scale (sub-regions).

The studies are aggregates of finished cases (``results/micro/<case>.nc``, docs/design.md §2):

- convergence (thesis Sec. 3.5.8): the per-checkpoint outputs of cases that differ in
  their number of points, stacked along a new dimension ``n_points`` (ascending);
- scale (thesis Sec. 3.5.9): sub-cubes of volume fraction f of a reference case's cube
  (:func:`micro.config.scale_realizations`), each hydrated as a specimen of its own;
  per realization and, grouped by ``domain_fraction``, the mean and the sample standard
  deviation (``ddof=1``) over the realizations, per checkpoint.

Declared in ``micro.studies`` (helpers in :mod:`micro.config`); the functions here do
no file I/O. Placement of the sub-cubes and the reference's NaN spread: docs/micro.md,
"micro.studies".
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import xarray as xr

from micro.config import Realization
from micro.run import phase_wall_times
from shared.errors import InputError

__all__ = [
    "convergence_dataset",
    "scale_dataset",
]

# coordinates the cases share; they must agree exactly between cases
_SHARED_COORDS = ("checkpoint", "phase", "axis", "i", "j", "bin", "principal")
# per-case attributes that vary along the convergence study, kept as variables
_CASE_ATTRS = {
    "n_cells": ("1", "number of tetrahedra of the mesh"),
    "wall_time_s": ("s", "wall time of the case's run"),
    "peak_memory_mb": ("MiB", "peak resident memory of the case's run"),
}
# quantities whose relative change between successive point counts the convergence
# study reports (thesis Sec. 3.5.8 tracks the first three)
_TRACKED = ("saturation", "eps_v", "permeability", "porosity_mean", "crack_count", "crack_volume")


# ---------------------------------------------------------------------------------------
# datasets
# ---------------------------------------------------------------------------------------


def _checkpoint_variables(ds: xr.Dataset) -> list[str]:
    """Data variables over the checkpoints (dimension ``suction``)."""
    return [name for name, var in ds.data_vars.items()
            if "suction" in var.dims]


def _check_alike(cases: Mapping[str, xr.Dataset]) -> tuple[str, list[str]]:
    """First case's name and the variables to aggregate; checks that the cases agree.

    Raises
    ------
    ValueError
        If there is no case, or the cases differ in their checkpoints (suctions), their
        shared coordinates or their variables.
    """
    if not cases:
        raise InputError("a study needs at least one case")
    first = next(iter(cases))
    base = cases[first]
    names = _checkpoint_variables(base)
    for name, ds in cases.items():
        if sorted(_checkpoint_variables(ds)) != sorted(names):
            raise InputError(f"case {name!r} has other variables than case {first!r}")
        for coord in _SHARED_COORDS:
            if coord in base.coords and not np.array_equal(ds[coord].values, base[coord].values):
                raise InputError(f"case {name!r} differs from case {first!r} in coordinate {coord!r}")
        if not np.allclose(ds["suction"].values, base["suction"].values, rtol=1e-12, atol=0.0):
            raise InputError(f"case {name!r} has other checkpoint suctions than case {first!r}")
    return first, names


def _shared_coords(base: xr.Dataset) -> dict[str, xr.Variable]:
    return {name: base[name].variable.copy() for name in _SHARED_COORDS if name in base.coords}


def convergence_dataset(cases: Mapping[str, xr.Dataset]) -> xr.Dataset:
    """The per-checkpoint outputs of micro cases stacked over their number of points.

    Parameters
    ----------
    cases
        Micro outputs (``results/micro/<case>.nc``) by case name; each has the attribute
        ``n_points`` (the count the case ran with) and the same checkpoints.

    Returns
    -------
    xr.Dataset
        Every variable over ``suction`` (the checkpoints) of the inputs, with a new
        leading dimension ``n_points`` in ascending order: ``saturation(n_points,
        suction)``, ``permeability(n_points, suction, phase, axis)`` [m2], ...;
        ``suction`` [Pa] and ``checkpoint(suction)``; ``n_cells``, ``wall_time_s`` and ``peak_memory_mb``
        over ``n_points`` when the inputs record them, ``wall_time_phase(n_points,
        run_phase)`` [s] when some do (NaN where one does not); ``<var>_relative_change`` of the
        tracked quantities (saturation, eps_v, permeability, porosity_mean, crack_count,
        crack_volume), |x_N - x_N-1| / |x_N|. Attribute ``cases``: the case names in
        ``n_points`` order.

    Raises
    ------
    ValueError
        If two cases have the same ``n_points``, a case lacks it, or the cases differ in
        checkpoints, coordinates or variables.
    """
    first, names = _check_alike(cases)
    counts: dict[str, int] = {}
    for name, ds in cases.items():
        if "n_points" not in ds.attrs:
            raise InputError(f"case {name!r} has no attribute 'n_points'")
        counts[name] = int(ds.attrs["n_points"])
    order = sorted(cases, key=lambda name: counts[name])
    for a, b in zip(order, order[1:], strict=False):
        if counts[a] == counts[b]:
            raise InputError(f"cases {a!r} and {b!r} have the same n_points ({counts[a]})")
    base = cases[first]
    data: dict[str, Any] = {}
    for var in names:
        data[var] = xr.Variable(("n_points", *base[var].dims),
                                np.stack([cases[name][var].values for name in order]),
                                dict(base[var].attrs))
    for attr, (units, long_name) in _CASE_ATTRS.items():
        if all(attr in cases[name].attrs for name in order):
            data[attr] = ("n_points", np.array([float(cases[name].attrs[attr]) for name in order]),
                          {"units": units, "long_name": long_name})
    times = {name: phase_wall_times(cases[name].attrs) for name in order}
    phases = sorted({phase for name in order for phase in times[name]})
    if phases:
        data["wall_time_phase"] = (
            ("n_points", "run_phase"),
            np.array([[times[name].get(phase, np.nan) for phase in phases] for name in order]),
            {"units": "s", "long_name": "wall time of the case's run per phase (NaN: not "
                                        "recorded)"})
    for var in _TRACKED:
        if var in data:
            values = np.asarray(data[var].values, dtype=float)
            change = np.full_like(values, np.nan)
            change[1:] = np.abs(np.diff(values, axis=0)) / np.abs(values[1:])
            data[f"{var}_relative_change"] = xr.Variable(
                data[var].dims, change,
                {"units": "1", "long_name": f"|change| of {var} from the previous n_points, "
                                           "relative to its value (NaN for the first)"})
    coords: dict[str, Any] = _shared_coords(base)
    coords["suction"] = base["suction"].variable.copy()
    coords["n_points"] = ("n_points", np.array([counts[name] for name in order], dtype=np.int64),
                          {"units": "1", "long_name": "number of DEM points of the case"})
    if phases:
        coords["run_phase"] = ("run_phase", np.array(phases),
                               {"long_name": "phase of a micro run (micro.run.run)"})
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update(study="convergence", cases=json.dumps(order))
    return ds


def _with_derived(ds: xr.Dataset, edge_length: float) -> xr.Dataset:
    """A case's outputs plus the scale study's derived quantities."""
    out = ds.copy()
    log_k = np.log(np.where(ds["permeability"].values > 0, ds["permeability"].values, np.nan))
    out["permeability_geomean"] = (
        ("suction", "phase"), np.exp(log_k.mean(axis=-1)),
        {"units": "m2", "long_name": "geometric mean of the x, y, z permeabilities"},
    )
    out["crack_volume_fraction"] = (
        "suction", ds["crack_volume"].values / edge_length**3,
        {"units": "1", "long_name": "crack volume per sub-region volume"},
    )
    return out


def scale_dataset(
    reference: tuple[str, xr.Dataset],
    reference_edge_m: float,
    realizations: Sequence[tuple[Realization, xr.Dataset]],
) -> xr.Dataset:
    """Per realization and per domain fraction (mean, std) outputs of the scale study.

    Parameters
    ----------
    reference
        Name and micro output of the full-size case (domain fraction 1).
    reference_edge_m
        Its cube edge [m].
    realizations
        Each realization (:func:`micro.config.scale_realizations`) with its micro output; all share
        the reference's checkpoints.

    Returns
    -------
    xr.Dataset
        Every variable over ``suction`` (the checkpoints) of the inputs, plus
        ``permeability_geomean(suction, phase)`` [m2] and ``crack_volume_fraction``:
        per realization (``<var>(realization, suction, ...)``, the reference first,
        with ``realization_fraction``, ``realization_size_m`` and
        ``realization_offset_m(realization, xyz)``), and as ``<var>_mean`` and
        ``<var>_std`` over ``domain_fraction`` (ascending). The standard deviation is the
        sample one (``ddof=1``); NaN for a group of one realization, such as the
        reference. Also ``n_realizations(domain_fraction)``,
        ``specimen_size_m(domain_fraction)`` [m] and ``suction`` [Pa].

    Raises
    ------
    ValueError
        If the cases differ in checkpoints, coordinates or variables, or a realization
        is larger than the reference.
    """
    name, ref_ds = reference
    members = [(name, 1.0, reference_edge_m, (np.nan,) * 3, ref_ds)]
    for realization, ds in realizations:
        if realization.domain_fraction > 1:
            raise InputError(f"{realization.name} is larger than the reference {name!r}")
        members.append((realization.name, realization.domain_fraction, realization.edge_length,
                        realization.offset, ds))
    cases = {m[0]: _with_derived(m[4], m[2]) for m in members}
    first, names = _check_alike(cases)
    base = cases[first]
    levels = sorted({m[1] for m in members})
    groups = [[m[0] for m in members if m[1] == level] for level in levels]
    data: dict[str, Any] = {}
    for var in names:
        attrs = dict(base[var].attrs)
        per_case = np.stack([np.asarray(cases[m[0]][var].values, dtype=float) for m in members])
        data[var] = (("realization", *base[var].dims), per_case, attrs)
        means, stds = [], []
        for group in groups:
            rows = per_case[[i for i, m in enumerate(members) if m[0] in group]]
            means.append(rows.mean(axis=0))
            stds.append(rows.std(axis=0, ddof=1) if len(group) > 1
                        else np.full(rows.shape[1:], np.nan))
        dims = ("domain_fraction", *base[var].dims)
        long_name = attrs.get("long_name", var)
        data[f"{var}_mean"] = (dims, np.stack(means), {
            "units": attrs.get("units", "1"), "long_name": f"mean over realizations of: {long_name}"})
        data[f"{var}_std"] = (dims, np.stack(stds), {
            "units": attrs.get("units", "1"),
            "long_name": f"sample standard deviation (ddof=1) over realizations of: {long_name}; "
                         "NaN for one realization"})
    data["n_realizations"] = ("domain_fraction", np.array([len(g) for g in groups], dtype=np.int64),
                              {"units": "1", "long_name": "number of realizations"})
    data["specimen_size_m"] = ("domain_fraction", reference_edge_m * np.array(levels) ** (1 / 3),
                               {"units": "m", "long_name": "cube edge of the realizations"})
    data["realization_fraction"] = ("realization", np.array([m[1] for m in members]),
                                    {"units": "1", "long_name": "domain fraction of the realization"})
    data["realization_size_m"] = ("realization", np.array([m[2] for m in members]),
                                  {"units": "m", "long_name": "cube edge of the realization"})
    data["realization_offset_m"] = (("realization", "xyz"), np.array([m[3] for m in members]),
                                    {"units": "m", "long_name": "centre of the sub-cube from the "
                                     "scanned specimen's centre (NaN: the reference)"})
    coords: dict[str, Any] = _shared_coords(base)
    coords["suction"] = base["suction"].variable.copy()
    coords["domain_fraction"] = ("domain_fraction", np.array(levels), {
        "units": "1", "long_name": "sub-specimen volume / reference specimen volume"})
    coords["realization"] = ("realization", np.array([m[0] for m in members]),
                             {"long_name": "realization (the reference first)"})
    coords["xyz"] = ("xyz", np.array(["x", "y", "z"]), {"long_name": "direction"})
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update(study="scale", reference=name, reference_size_m=reference_edge_m)
    return ds
