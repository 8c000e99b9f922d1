"""The micro stage's configuration helpers, light: the workflow reads them to build its
DAG without importing the model (no numba, no xarray).

- :data:`MATERIAL_KEYS`: the keys of ``materials.pellet`` the micro model reads;
- the studies of ``micro.studies`` (thesis Secs. 3.5.8-3.5.9): the convergence study's
  cases, the scale study's realizations (:func:`scale_realizations`), their checks
  (:func:`check_studies`);
- the sources of the pellet permeability table (:func:`source_names`);
- :class:`MicroSettings`, the validated settings of one case that
  :func:`micro.run.hydrate` takes (built by :func:`micro.run.micro_settings`; its
  field types are the model's, imported here for type checkers only).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from shared.config import ConfigError
from shared.dem.parameters import DEM_MATERIAL_KEYS
from shared.materials import CLAY_CONFIG_KEYS

if TYPE_CHECKING:
    from micro.hydration import HydrationSettings
    from micro.pellet import SpecimenSpec
    from shared.dem.parameters import DEMParameters
    from shared.materials import ClayParameters

__all__ = [
    "MATERIAL_KEYS",
    "MicroSettings",
    "Realization",
    "case_edge_length",
    "case_n_points",
    "check_studies",
    "convergence_cases",
    "realization_case",
    "scale_realizations",
    "source_names",
]

MATERIAL_KEYS = (*CLAY_CONFIG_KEYS.values(), *DEM_MATERIAL_KEYS)
"""Keys of ``materials.pellet`` the micro model reads (its rules' params hold these)."""


@dataclass(frozen=True)
class MicroSettings:
    """Everything one micro case's hydration reads, validated.

    Attributes
    ----------
    name
        The case's name, in log lines and messages.
    specimen
        The specimen: cube edge [m], points, layout, confinement [Pa], seed, offset [m].
    hydration
        The staggered scheme's numerical settings (crack coupling included).
    material, parameters
        Clay and DEM parameters of the case.
    checkpoints
        Boundary suctions of the checkpoints [Pa], decreasing.
    heterogeneous
        True: the porosity field from the CT grid; False: homogeneous at the grid's
        mean over the specimen.
    """

    name: str
    specimen: SpecimenSpec
    hydration: HydrationSettings
    material: ClayParameters
    parameters: DEMParameters
    checkpoints: tuple[float, ...]
    heterogeneous: bool




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


@dataclass(frozen=True)
class Realization:
    """One sub-region of the scale study.

    Attributes
    ----------
    name
        Job name, ``f<fraction>_r<index>`` (``f0p25_r03``).
    domain_fraction
        Sub-cube volume over the reference cube's [1].
    edge_length
        Cube edge [m].
    n_points
        Number of points: the reference's density, at least ``min_points`` [1].
    offset
        Centre of the sub-cube from the scanned specimen's centre [m].
    """

    name: str
    domain_fraction: float
    edge_length: float
    n_points: int
    offset: tuple[float, float, float]


def _scale_section(config: Mapping[str, Any]) -> Mapping[str, Any]:
    return config["micro"].get("studies", {}).get("scale", {})


def scale_realizations(config: Mapping[str, Any]) -> list[Realization]:
    """The realizations of the scale study of a validated configuration (none if undeclared).

    Positions lie on the lattice of the reference's point spacing, centred in the
    reference cube, so that every sub-cube lies inside it and no two realizations of one
    fraction coincide; a fraction's realizations are the first ones of a permutation of
    its lattice seeded by (``seed``, fraction), so that adding realizations keeps the
    earlier ones.

    Raises
    ------
    ConfigError
        If a fraction has fewer distinct positions than ``realizations``.
    """
    scale = _scale_section(config)
    reference = scale.get("reference")
    if reference is None or not scale.get("fractions"):
        return []
    edge = case_edge_length(config, reference)
    count = case_n_points(config, reference)
    spacing = edge / count ** (1.0 / 3.0)
    centre = np.asarray(config["micro"]["cases"][reference]["offset_m"], dtype=float)
    realizations = []
    for fraction in sorted(float(f) for f in scale["fractions"]):
        sub_edge = edge * fraction ** (1.0 / 3.0)
        per_axis = int(np.floor((edge - sub_edge) / spacing + 1e-9)) + 1
        if per_axis**3 < scale["realizations"]:
            raise ConfigError(
                f"config key 'micro.studies.scale.realizations': {scale['realizations']} "
                f"realizations, but a {fraction:g} sub-cube has only {per_axis**3} distinct "
                f"positions one point spacing ({spacing:.3g} m) apart in {reference!r}"
            )
        lattice = spacing * (np.arange(per_axis) - 0.5 * (per_axis - 1))
        rng = np.random.default_rng([scale["seed"], int(round(fraction * 1e12))])
        picks = rng.permutation(per_axis**3)[: scale["realizations"]]
        label = f"{fraction:.6g}".replace(".", "p")
        points = max(scale["min_points"], int(round(count * fraction)))
        for index, pick in enumerate(picks):
            shift = lattice[np.array(np.unravel_index(pick, (per_axis,) * 3))]
            x, y, z = centre + shift
            realizations.append(Realization(
                name=f"f{label}_r{index:02d}", domain_fraction=fraction, edge_length=sub_edge,
                n_points=points, offset=(float(x), float(y), float(z)),
            ))
    return realizations


def realization_case(config: Mapping[str, Any], realization: Realization) -> dict[str, Any]:
    """The micro case of a realization: the reference case on the realization's cube."""
    entry = dict(config["micro"]["cases"][_scale_section(config)["reference"]])
    entry.update(n_points=realization.n_points, specimen_size_m=realization.edge_length,
                 offset_m=list(realization.offset))
    return entry


def check_studies(config: Mapping[str, Any]) -> None:
    """Check the ``micro.studies`` section of a validated configuration.

    Raises
    ------
    ConfigError
        Naming the key, if a study names a case that is not in ``micro.cases``, if two
        convergence cases have the same number of points, if the scale study has
        fractions but no reference (or a reference and no fractions), a homogeneous
        reference, or more realizations than a fraction has distinct positions.
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
    fractions = list(scale.get("fractions", []))
    if fractions and reference is None:
        raise ConfigError(
            "config key 'micro.studies.scale.reference': required when "
            "micro.studies.scale.fractions is not empty"
        )
    if reference is None:
        return
    if not fractions:
        raise ConfigError(
            "config key 'micro.studies.scale.fractions': empty, but a reference "
            f"({reference!r}) is given"
        )
    _known("micro.studies.scale.reference", [reference])
    if known[reference]["porosity"] != "ct":
        raise ConfigError(
            f"config key 'micro.studies.scale.reference': {reference!r} has a homogeneous "
            "porosity; sub-regions of it would all be alike"
        )
    scale_realizations(config)


def source_names(config: Mapping[str, Any]) -> dict[str, list[tuple[str, str]]]:
    """Per condition of ``upscaling.conditions``, its sources as (kind, name) pairs.

    ``kind`` is ``case`` (a micro case) or ``realization`` (a scale-study realization of
    the named domain fraction).
    """
    sources: dict[str, list[tuple[str, str]]] = {}
    for condition, source in config["upscaling"]["conditions"].items():
        if isinstance(source, Mapping):
            sources[condition] = [
                ("realization", r.name) for r in scale_realizations(config)
                if abs(r.domain_fraction - source["scale_fraction"]) < 1e-9
            ]
        else:
            sources[condition] = [("case", name)
                                  for name in ([source] if isinstance(source, str) else source)]
    return sources
