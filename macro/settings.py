"""The settings of one macro case from the validated ``macro`` section, and the mixture's
make-up (pellet packing fraction and powder porosity from the target dry density)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from macro.newton import NewtonSettings
from macro.sensors import WallBands, equal_bands, named_sensors
from shared.errors import ConfigError

SENSOR_AREA_SHARES = {"band": 1.0, "script": 0.5}
"""``macro.sensor_area``: the share of a band's wall area 2 pi R w its forces are divided by."""

__all__ = ["ExtrusionSettings", "MacroSettings", "extrusion_settings", "macro_settings", "mixture_fractions",
           "powder_porosity"]

RANDOM_CLOSE_PACKING = 0.64
"""Densest random packing of equal spheres, in bulk [1]: the ceiling of the pellet
packing fraction. The container's walls lower what it holds (0.585-0.589 with pellet
radius 3.5 mm in the default container, 0.548-0.550 with 5.99 mm; radius 2 mm holds 0.60:
benchmarks/reference/macro_packing.json); :func:`macro.run.build_model` refuses a
packing left overlapping."""



@dataclass(frozen=True)
class ExtrusionSettings:
    """``macro.homogenisation`` and ``macro.extrusion`` (workflow/schemas/config.schema.yaml).

    Attributes
    ----------
    enabled
        ``homogenisation: extrusion``; False: the thesis's immobile powder (``none``).
    mobility
        M_0 [m2/(Pa s)].
    mobile_saturation
        S_c, the saturation below which clay does not flow [1].
    max_solid_change
        Largest fraction of a system's solid that leaves it in one step [1].
    """

    enabled: bool
    mobility: float
    mobile_saturation: float
    max_solid_change: float


def extrusion_settings(macro: Mapping[str, Any], case: Mapping[str, Any]) -> ExtrusionSettings:
    """The extrusion settings of a case (its own ``homogenisation`` and ``extrusion`` first)."""
    section = {**macro["extrusion"], **case.get("extrusion", {})}
    return ExtrusionSettings(
        enabled=str(case.get("homogenisation", macro["homogenisation"])) == "extrusion",
        mobility=float(section["mobility_m2_per_pa_s"]),
        mobile_saturation=float(section["mobile_saturation"]),
        max_solid_change=float(section["max_solid_change"]),
    )


@dataclass(frozen=True)
class MacroSettings:
    """The macro section of one case (see workflow/schemas/config.schema.yaml, ``macro``)."""

    height: float
    radius: float
    pellet_radius: float
    pellet_radius_spread: float
    packing_fraction: float
    dry_density: float
    pellet_porosity: float
    powder: Mapping[str, Any]
    table_condition: str
    pellet_permeability: str
    boundary_suction: float
    max_suction: float
    density: float
    viscosity: float
    conductivity_factor: float
    powder_pressure: bool
    retention_follows_porosity: bool
    powder_on_walls: bool
    sensors: WallBands
    bands: WallBands
    vtk_snapshots: int
    column_permeability_times: tuple[float, ...]
    seed: int
    chi: float
    max_saturation_change: float
    transport_scheme: str
    max_time_step: float
    max_time: float
    max_steps: int
    records: int
    snapshot_interval: float
    stop_window: float
    stop_tolerance: float
    stop_pressure_tolerance: float
    stop_after: float
    newton: NewtonSettings
    packing_sweeps: int
    min_cell_void_fraction: float
    container_spacing: float
    dem_substeps: int
    dem_balance_tolerance: float
    dem_rigid_correction: bool
    powder_onset_strain: float
    wall_friction: float
    stress_relaxation: float
    extrusion: ExtrusionSettings


def macro_settings(macro: Mapping[str, Any], case: str) -> MacroSettings:
    """Settings of one case: the ``macro`` section with ``macro.cases[case]`` applied.

    Raises
    ------
    KeyError
        Naming ``macro.cases`` when the case is not declared.
    ValueError
        Naming ``macro.sensors.<name>`` when a sensor's band reaches outside the container.
    """
    if case not in macro["cases"]:
        raise KeyError(f"macro.cases has no case {case!r} (has {sorted(macro['cases'])})")
    over = macro["cases"][case]
    num = macro["numerics"]
    powder = dict(macro["powder"])
    if "heterogeneity" in over:
        powder["heterogeneity"] = over["heterogeneity"]
    mixture = {**macro["mixture"], **over.get("mixture", {})}
    share = SENSOR_AREA_SHARES[str(macro["sensor_area"])]
    fraction, dry_density = mixture_fractions(mixture, float(macro["pellet_porosity"]),
                                              float(powder["grain_density_kg_m3"]))
    return MacroSettings(
        height=float(macro["cylinder_height_m"]),
        radius=float(macro["cylinder_radius_m"]),
        pellet_radius=float(over.get("pellet_radius_m", macro["pellet_radius_m"])),
        pellet_radius_spread=float(over.get("pellet_radius_spread", macro["pellet_radius_spread"])),
        packing_fraction=fraction,
        dry_density=dry_density,
        pellet_porosity=float(macro["pellet_porosity"]),
        powder=powder,
        table_condition=str(over.get("table_condition", macro["table_condition"])),
        pellet_permeability=str(over.get("pellet_permeability", macro["pellet_permeability"])),
        boundary_suction=float(macro["boundary_suction_pa"]),
        max_suction=float(macro["max_suction_pa"]),
        density=float(macro["water_density_kg_m3"]),
        viscosity=float(macro["water_viscosity_pa_s"]),
        conductivity_factor=float(over.get("conductivity_factor", macro["conductivity_factor"])),
        retention_follows_porosity=bool(macro["retention_follows_porosity"]),
        powder_pressure=bool(over.get("powder_swelling_pressure", macro["powder_swelling_pressure"])),
        powder_on_walls=bool(over.get("powder_pressure_on_walls", macro["powder_pressure_on_walls"])),
        sensors=named_sensors(macro["sensors"], float(macro["cylinder_height_m"]), share),
        bands=equal_bands(int(macro["sensor_bands"]), float(macro["cylinder_height_m"]), share),
        vtk_snapshots=int(macro["vtk_snapshots"]),
        column_permeability_times=tuple(sorted(float(t) for t in macro["column_permeability_times_s"])),
        seed=int(over.get("seed", macro["seed"])),
        chi=float(num["stability_factor"]),
        max_saturation_change=float(num["max_saturation_change"]),
        transport_scheme=str(num["transport_scheme"]),
        max_time_step=float(num["max_time_step_s"]),
        max_time=float(num["max_time_s"]),
        max_steps=int(num["max_steps"]),
        records=int(num["records"]),
        snapshot_interval=float(num["snapshot_interval_s"]),
        stop_window=float(num["stop_window_fraction"]),
        stop_tolerance=float(num["stop_tolerance"]),
        stop_pressure_tolerance=float(num["stop_pressure_tolerance"]),
        stop_after=float(num["stop_after_s"]),
        newton=NewtonSettings(
            tolerance=float(num["newton_tolerance"]),
            max_iterations=int(num["newton_max_iterations"]),
            barrier_start=float(num["newton_barrier_start"]),
            barrier_decay=float(num["newton_barrier_decay"]),
            relaxation_start=float(num["newton_relaxation_start"]),
            derivative_step=float(num["newton_derivative_step"]),
        ),
        packing_sweeps=int(num["packing_iterations"]),
        min_cell_void_fraction=float(num["min_cell_void_fraction"]),
        container_spacing=float(num["container_point_spacing"]),
        dem_substeps=int(num["dem_substeps"]),
        dem_balance_tolerance=float(num["dem_balance_tolerance"]),
        dem_rigid_correction=bool(num["dem_rigid_correction"]),
        powder_onset_strain=float(num["powder_onset_strain"]),
        wall_friction=float(np.tan(np.radians(float(macro["wall_friction_angle_deg"])))),
        stress_relaxation=float(num["stress_relaxation"]),
        extrusion=extrusion_settings(macro, over),
    )


def mixture_fractions(mixture: Mapping[str, Any], pellet_porosity: float,
                      grain_density: float) -> tuple[float, float]:
    """Pellet packing fraction [1] and the mixture's dry density [kg/m3] from the
    validated ``macro.mixture`` section.

    The dry density is the target; the pellets' share of the dry mass is set by the
    pellet/powder dry-mass ratio when given (pellet fraction
    rho_d ratio / ((1 + ratio) rho_d,pellet)), else by ``packing_fraction``; the powder
    holds the rest of the dry mass.

    Raises
    ------
    ValueError
        Naming ``macro.mixture`` when the pellets alone are denser than the target or
        the fraction exceeds random close packing (the packing itself refuses the
        fractions that a container's walls put out of reach, :func:`macro.run.build_model`).
    """
    dry_density = float(mixture["dry_density_kg_m3"])
    pellet_density = grain_density * (1.0 - pellet_porosity)
    ratio = mixture.get("pellet_powder_dry_mass_ratio")
    if ratio is None:
        fraction = float(mixture["packing_fraction"])
    else:
        fraction = dry_density * float(ratio) / ((1.0 + float(ratio)) * pellet_density)
    if not 0.0 < fraction <= RANDOM_CLOSE_PACKING:
        raise ConfigError(
            f"macro.mixture: a pellet packing fraction of {fraction:.3g} (dry density "
            f"{dry_density:g} kg/m3, pellet/powder dry-mass ratio {ratio}, pellet dry density "
            f"{pellet_density:.4g} kg/m3) cannot be packed at random (at most {RANDOM_CLOSE_PACKING}, "
            "random close packing; the container's walls lower it further)")
    if fraction * pellet_density > dry_density:
        raise ConfigError(
            f"macro.mixture: the pellets alone (packing fraction {fraction:.3g}, dry density "
            f"{pellet_density:.4g} kg/m3) are denser than macro.mixture.dry_density_kg_m3 = "
            f"{dry_density:g}")
    return fraction, dry_density



def powder_porosity(dry_mass: float, grain_mass: float) -> float:
    """Initial porosity of the powder [1]: its ``dry_mass`` [kg] (the mixture's target
    minus the pellets') over ``grain_mass`` [kg], the mass of grains that would fill its
    volume (the cells' powder volumes, set by the heterogeneity field).

    Raises
    ------
    ValueError
        Naming ``macro.mixture`` when the powder's mass does not fit in its volume or is
        not positive.
    """
    porosity = 1.0 - dry_mass / grain_mass
    if not 0.0 < porosity < 1.0:
        raise ConfigError(
            f"macro.mixture: the powder's dry mass ({dry_mass:.4g} kg: the target dry density "
            f"minus the pellets') gives a powder porosity of {porosity:.3g} in the volume the "
            "powder fills (macro.powder); change macro.mixture.dry_density_kg_m3 or the pellets' share")
    return float(porosity)

