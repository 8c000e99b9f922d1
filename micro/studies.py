"""Studies over micro cases: convergence in the number of points, and scale (sub-regions).

The studies are aggregates of finished cases (``results/micro/<case>.nc``, DESIGN §2):

- convergence (thesis Sec. 3.5.8): the per-checkpoint outputs of cases that differ in
  their number of points, stacked along a new dimension ``n_points`` (ascending);
- scale (thesis Sec. 3.5.9): sub-region realizations grouped by their ``domain_fraction``
  (sub-specimen volume over the reference specimen's), with the mean and the sample
  standard deviation (``ddof=1``) over the realizations of each group, per checkpoint.
  The full-size reference case is domain fraction 1, a single realization whose standard
  deviation is NaN (undefined for one sample), not 0.

The studies are declared in ``micro.studies`` of the configuration; :func:`check_studies`
refuses a study that names an unknown case. The functions here do no file I/O.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

import numpy as np
import xarray as xr

from shared.config import ConfigError

__all__ = [
    "check_studies",
    "convergence_cases",
    "scale_cases",
    "case_edge_length",
    "case_n_points",
    "convergence_dataset",
    "scale_dataset",
]

# coordinates the cases share; they must agree exactly between cases
_SHARED_COORDS = ("checkpoint", "phase", "axis", "i", "j", "bin")
# per-case attributes that vary along the convergence study, kept as variables
_CASE_ATTRS = {
    "n_cells": ("1", "number of tetrahedra of the mesh"),
    "wall_time_s": ("s", "wall time of the case's run"),
}


# ---------------------------------------------------------------------------------------
# configuration
# ---------------------------------------------------------------------------------------


def case_edge_length(config: Mapping[str, Any], case: str) -> float:
    """Cube edge [m] of a case: its ``specimen_size_m``, else ``micro.specimen_size_m``."""
    micro = config["micro"]
    return float(micro["cases"][case].get("specimen_size_m", micro["specimen_size_m"]))


def case_n_points(config: Mapping[str, Any], case: str) -> int:
    """Configured number of points of a case: its ``n_points``, else ``micro.n_points``."""
    micro = config["micro"]
    return int(micro["cases"][case].get("n_points", micro["n_points"]))


def convergence_cases(config: Mapping[str, Any]) -> list[str]:
    """Cases of the convergence study (empty: no study)."""
    return list(config["micro"].get("studies", {}).get("convergence", []))


def scale_cases(config: Mapping[str, Any]) -> list[str]:
    """Reference and realizations of the scale study (empty: no study)."""
    scale = config["micro"].get("studies", {}).get("scale", {})
    cases = list(scale.get("cases", []))
    return [scale["reference"], *cases] if cases else []


def check_studies(config: Mapping[str, Any]) -> None:
    """Check the ``micro.studies`` section of a validated configuration.

    Raises
    ------
    ConfigError
        Naming the key, if a study names a case that is not in ``micro.cases``, if two
        convergence cases have the same number of points, if the scale study has
        realizations but no reference (or a reference and no realizations), lists its
        reference among its realizations, or has a realization larger than the reference.
    """
    micro = config["micro"]
    studies = micro.get("studies", {})
    known = micro["cases"]

    def _known(key: str, names: list[str]) -> None:
        for name in names:
            if name not in known:
                raise ConfigError(
                    f"config key '{key}': {name!r} is not a case of micro.cases "
                    f"(cases: {', '.join(sorted(known))})"
                )

    convergence = list(studies.get("convergence", []))
    _known("micro.studies.convergence", convergence)
    seen: dict[int, str] = {}
    for name in convergence:
        count = case_n_points(config, name)
        if count in seen:
            raise ConfigError(
                f"config key 'micro.studies.convergence': cases {seen[count]!r} and {name!r} "
                f"have the same number of points ({count})"
            )
        seen[count] = name

    scale = studies.get("scale", {})
    reference = scale.get("reference")
    cases = list(scale.get("cases", []))
    if cases and reference is None:
        raise ConfigError(
            "config key 'micro.studies.scale.reference': required when "
            "micro.studies.scale.cases is not empty"
        )
    if reference is not None and not cases:
        raise ConfigError(
            "config key 'micro.studies.scale.cases': empty, but a reference "
            f"({reference!r}) is given"
        )
    if reference is None:
        return
    _known("micro.studies.scale.reference", [reference])
    _known("micro.studies.scale.cases", cases)
    if reference in cases:
        raise ConfigError(
            f"config key 'micro.studies.scale.cases': the reference {reference!r} is "
            "listed among the realizations"
        )
    edge = case_edge_length(config, reference)
    for name in cases:
        if case_edge_length(config, name) > edge * (1 + 1e-12):
            raise ConfigError(
                f"config key 'micro.studies.scale.cases': {name!r} "
                f"({case_edge_length(config, name):g} m) is larger than the reference "
                f"{reference!r} ({edge:g} m)"
            )


# ---------------------------------------------------------------------------------------
# datasets
# ---------------------------------------------------------------------------------------


def _checkpoint_variables(ds: xr.Dataset) -> list[str]:
    """Data variables over checkpoints, except the boundary suction (shared by all)."""
    return [name for name, var in ds.data_vars.items()
            if "checkpoint" in var.dims and name != "suction"]


def _check_alike(cases: Mapping[str, xr.Dataset]) -> tuple[str, list[str]]:
    """First case's name and the variables to aggregate; checks that the cases agree.

    Raises
    ------
    ValueError
        If there is no case, or the cases differ in their checkpoints (suctions), their
        shared coordinates or their variables.
    """
    if not cases:
        raise ValueError("a study needs at least one case")
    first = next(iter(cases))
    base = cases[first]
    names = _checkpoint_variables(base)
    for name, ds in cases.items():
        if sorted(_checkpoint_variables(ds)) != sorted(names):
            raise ValueError(f"case {name!r} has other variables than case {first!r}")
        for coord in _SHARED_COORDS:
            if coord in base.coords and not np.array_equal(ds[coord].values, base[coord].values):
                raise ValueError(f"case {name!r} differs from case {first!r} in coordinate {coord!r}")
        if not np.allclose(ds["suction"].values, base["suction"].values, rtol=1e-12, atol=0.0):
            raise ValueError(f"case {name!r} has other checkpoint suctions than case {first!r}")
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
        Every variable over ``checkpoint`` of the inputs (except ``suction``), with a new
        leading dimension ``n_points`` in ascending order: ``saturation(n_points,
        checkpoint)``, ``permeability(n_points, checkpoint, phase, axis)`` [m2], ...;
        ``suction(checkpoint)`` [Pa]; ``n_cells(n_points)`` and ``wall_time_s(n_points)``
        when the inputs record them. Attribute ``cases``: the case names in ``n_points``
        order.

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
            raise ValueError(f"case {name!r} has no attribute 'n_points'")
        counts[name] = int(ds.attrs["n_points"])
    order = sorted(cases, key=lambda name: counts[name])
    for a, b in zip(order, order[1:]):
        if counts[a] == counts[b]:
            raise ValueError(f"cases {a!r} and {b!r} have the same n_points ({counts[a]})")
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
    data["suction"] = base["suction"].variable.copy()
    coords: dict[str, Any] = _shared_coords(base)
    coords["n_points"] = ("n_points", np.array([counts[name] for name in order], dtype=np.int64),
                          {"units": "1", "long_name": "number of DEM points of the case"})
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update(study="convergence", cases=json.dumps(order))
    return ds


def scale_dataset(
    cases: Mapping[str, xr.Dataset],
    edge_length_m: Mapping[str, float],
    reference: str,
) -> xr.Dataset:
    """Mean and standard deviation over realizations per domain fraction and checkpoint.

    Parameters
    ----------
    cases
        Micro outputs by case name: the reference (full size) and the realizations
        (sub-regions), all with the same checkpoints.
    edge_length_m
        Cube edge [m] of each case (``specimen_size_m`` of its configuration).
    reference
        Name of the full-size case; its volume is the unit of ``domain_fraction``.

    Returns
    -------
    xr.Dataset
        Over ``domain_fraction`` (ascending, = (edge / reference edge)^3) and the
        inputs' dimensions: ``<var>_mean`` and ``<var>_std`` for every variable over
        ``checkpoint`` (``permeability_mean(domain_fraction, checkpoint, phase, axis)``
        [m2], ``saturation_mean``, ``eps_v_std``, ...). The standard deviation is the
        sample one (``ddof=1``); it is NaN for a group of one realization, such as the
        reference at domain fraction 1. Also ``n_realizations(domain_fraction)``,
        ``specimen_size_m(domain_fraction)`` [m] and ``suction(checkpoint)`` [Pa].
        Attribute ``realizations``: JSON of case name -> domain fraction.

    Raises
    ------
    ValueError
        If the reference is not among the cases, an edge length is missing or not
        positive, a case is larger than the reference, or the cases differ in
        checkpoints, coordinates or variables.
    """
    if reference not in cases:
        raise ValueError(f"the reference {reference!r} is not among the cases")
    missing = [name for name in cases if name not in edge_length_m]
    if missing:
        raise ValueError(f"no edge length for case(s) {missing}")
    first, names = _check_alike(cases)
    edges = {name: float(edge_length_m[name]) for name in cases}
    if any(edge <= 0 for edge in edges.values()):
        raise ValueError(f"edge lengths must be positive, got {edges}")
    # rounded so that 3.5e-3 / 7e-3 and its float neighbours form one group
    fractions = {name: float(np.round((edges[name] / edges[reference]) ** 3, 12)) for name in cases}
    if any(fraction > 1 for fraction in fractions.values()):
        raise ValueError(f"a case is larger than the reference {reference!r}: {fractions}")
    levels = sorted(set(fractions.values()))
    groups = [[name for name in cases if fractions[name] == level] for level in levels]
    base = cases[first]
    data: dict[str, Any] = {}
    for var in names:
        dims = ("domain_fraction", *base[var].dims)
        means, stds = [], []
        for group in groups:
            values = np.stack([np.asarray(cases[name][var].values, dtype=float) for name in group])
            means.append(values.mean(axis=0))
            stds.append(values.std(axis=0, ddof=1) if len(group) > 1
                        else np.full(values.shape[1:], np.nan))
        units = base[var].attrs.get("units", "1")
        long_name = base[var].attrs.get("long_name", var)
        data[f"{var}_mean"] = (dims, np.stack(means),
                               {"units": units, "long_name": f"mean over realizations of: {long_name}"})
        data[f"{var}_std"] = (dims, np.stack(stds),
                              {"units": units,
                               "long_name": f"sample standard deviation (ddof=1) over realizations "
                                            f"of: {long_name}; NaN for one realization"})
    data["n_realizations"] = ("domain_fraction", np.array([len(g) for g in groups], dtype=np.int64),
                              {"units": "1", "long_name": "number of realizations"})
    data["specimen_size_m"] = ("domain_fraction", np.array([edges[g[0]] for g in groups]),
                               {"units": "m", "long_name": "cube edge of the realizations"})
    data["suction"] = base["suction"].variable.copy()
    coords: dict[str, Any] = _shared_coords(base)
    coords["domain_fraction"] = ("domain_fraction", np.array(levels),
                                 {"units": "1",
                                  "long_name": "sub-specimen volume / reference specimen volume"})
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update(study="scale", reference=reference,
                    reference_size_m=edges[reference],
                    realizations=json.dumps({name: fractions[name] for name in cases}))
    return ds
