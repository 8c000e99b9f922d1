"""The validated settings of a micro case, from a validated configuration.

:func:`micro_settings` gathers them into the :class:`micro.config.MicroSettings` that
:func:`micro.run.hydrate` takes; the other functions build its parts (the specimen, the
staggered scheme's numerics, the clay and DEM parameters).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from micro.config import MicroSettings
from micro.hydration import HydrationSettings
from micro.pellet import SpecimenSpec
from shared.config import ConfigError
from shared.dem.parameters import DEMParameters, dem_parameters
from shared.materials import ClayParameters, clay_parameters

__all__ = ["case_material", "case_parameters", "case_settings", "hydration_settings", "micro_settings"]


def case_settings(config: Mapping[str, Any], case: str) -> tuple[SpecimenSpec, HydrationSettings, bool]:
    """Specimen, numerical settings and porosity source (True: CT grid) of a case.

    Raises
    ------
    ConfigError
        If the case is unknown.
    """
    micro = config["micro"]
    if case not in micro["cases"]:
        raise ConfigError(f"config key 'micro.cases.{case}': no such case")
    entry = micro["cases"][case]
    spec = SpecimenSpec(
        edge_length=entry.get("specimen_size_m", micro["specimen_size_m"]),
        n_points=entry.get("n_points", micro["n_points"]), layout=micro["layout"],
        jitter=micro["jitter"], confinement=entry["confinement_pa"], seed=micro["seed"],
        offset=tuple(entry["offset_m"]),
    )
    settings = hydration_settings(micro["numerics"], entry["crack_coupling"])
    return spec, settings, entry["porosity"] == "ct"


def hydration_settings(numerics: Mapping[str, Any], cracks: bool) -> HydrationSettings:
    """The staggered scheme's settings from a validated ``micro.numerics`` section."""
    return HydrationSettings(
        initial_time_step=numerics["initial_time_step_s"],
        time_step_growth=numerics["time_step_growth"],
        max_flow_steps=numerics["max_flow_steps"],
        hydraulic_tolerance=numerics["hydraulic_tolerance"],
        unbalanced_force_tolerance=numerics["unbalanced_force_tolerance"],
        max_relaxation_steps=numerics["max_relaxation_steps"],
        final_relaxations=numerics["final_relaxations"],
        check_interval=numerics["check_interval"],
        ramp_steps=numerics["ramp_steps"],
        damping=numerics["relaxation_damping"],
        max_step_fraction=numerics["max_step_fraction"],
        porosity_bounds=tuple(numerics["porosity_bounds"]),
        cracks=cracks,
        solver=numerics["solver"],
        amg_unknowns=numerics["amg_unknowns"],
    )


def case_material(config: Mapping[str, Any], case: str) -> dict[str, Any]:
    """``materials.pellet`` with this case's own values (``micro.cases.<case>.materials``)."""
    return {**config["materials"]["pellet"], **config["micro"]["cases"][case]["materials"]}


def case_parameters(config: Mapping[str, Any], case: str) -> tuple[ClayParameters, DEMParameters]:
    """Clay and DEM parameters of a case, from its material and ``micro.numerics``."""
    material = case_material(config, case)
    return clay_parameters(material), dem_parameters(material, config["micro"]["numerics"])


def micro_settings(config: Mapping[str, Any], case: str) -> MicroSettings:
    """The validated settings of a case (:class:`micro.config.MicroSettings`) from a
    validated configuration: its ``micro`` section (with at least this case) and
    ``materials.pellet``.

    Raises
    ------
    ConfigError
        If the case is unknown.
    """
    spec, settings, heterogeneous = case_settings(config, case)
    material, parameters = case_parameters(config, case)
    return MicroSettings(name=case, specimen=spec, hydration=settings, material=material,
                         parameters=parameters,
                         checkpoints=tuple(config["micro"]["checkpoints_suction_pa"]),
                         heterogeneous=heterogeneous)
