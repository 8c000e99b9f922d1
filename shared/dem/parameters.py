"""Mechanical parameters of the DEM point model, read from the configuration.

Material values come from ``materials.pellet`` (Caulk 2022, Table 3.1 and Appendix .2),
numerical ones from the stage's ``numerics``; :func:`dem_parameters` builds the object.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["DEMParameters", "dem_parameters", "DEM_MATERIAL_KEYS"]

DEM_MATERIAL_KEYS = (
    "young_modulus_pa", "poisson_ratio", "point_density_kg_m3", "bond_tensile_strength_pa"
)
"""Keys of ``materials.pellet`` that :func:`dem_parameters` reads."""


@dataclass(frozen=True)
class DEMParameters:
    """Material and numerical parameters of the Hertz-Mindlin point model.

    Attributes
    ----------
    young_modulus
        E, micro Young's modulus of the points [Pa] (Table 3.1: 100e8 Pa).
    poisson_ratio
        nu, micro Poisson ratio [1] (Table 3.1: 0.3).
    density
        Density of the point material, giving masses rho 4/3 pi r0^3 [kg/m3]
        (Appendix .2: 2600).
    interaction_radius_factor
        Contacts are detected while the centre distance is below this factor times
        r_a + r_b [1] (Appendix .2: intRadius = 1, i.e. contacts exist while spheres
        overlap).
    damping
        Cundall numerical damping coefficient lambda_d in
        f <- f (1 - lambda_d sign(f v)) per component [1] (Appendix .2: 0.4).
    time_step_safety
        Fraction of the stability bound used as time step [1] (Yade's
        GlobalStiffnessTimeStepper default: 0.8).
    time_step
        Time step of the coupled hydration run [s] (Appendix .2: 4e-9; Table 3.1
        prints 1e-9). Explicit DEM is stable up to :func:`stable_time_step`.
    wall_max_velocity
        Largest speed of a servo-controlled wall [m/s] (Appendix .2: triax.maxVel 1e-4).
    wall_gain
        Fraction of the stiffness-predicted correction a servo wall applies per step
        [1] (Yade's TriaxialStressController stressDamping default: 0.25).
    bond_tensile_strength
        sigma_t, tensile strength of a bond [Pa]: an intact bond carries a tension up
        to sigma_t pi r^2 (r the mean radius of its two points) and breaks beyond. 0
        is the thesis's cohesionless reading: a bond breaks as soon as its
        normal force would turn tensile. Not a parameter of the thesis (see
        :func:`shared.dem.bond_tension` for why the micro model needs it).
    """

    young_modulus: float
    poisson_ratio: float
    density: float
    interaction_radius_factor: float
    damping: float
    time_step_safety: float
    time_step: float
    wall_max_velocity: float
    wall_gain: float
    bond_tensile_strength: float

    def __post_init__(self) -> None:
        for name in ("young_modulus", "density", "interaction_radius_factor", "time_step"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not -1.0 < self.poisson_ratio < 0.5:
            raise ValueError(f"poisson_ratio must lie in (-1, 0.5), got {self.poisson_ratio}")
        if not 0.0 <= self.damping < 1.0:
            raise ValueError(f"damping must lie in [0, 1), got {self.damping}")
        if not self.bond_tensile_strength >= 0.0:
            raise ValueError(
                f"bond_tensile_strength must be >= 0, got {self.bond_tensile_strength}"
            )
        if not 0.0 < self.time_step_safety <= 1.0:
            raise ValueError("time_step_safety must lie in (0, 1]")

    @property
    def effective_modulus(self) -> float:
        """E* of two identical points, E / (2 (1 - nu^2)) [Pa] (Eq. 3.2)."""
        return self.young_modulus / (2.0 * (1.0 - self.poisson_ratio**2))

    @property
    def wall_effective_modulus(self) -> float:
        """E* of a point against a rigid wall, E / (1 - nu^2) [Pa]."""
        return self.young_modulus / (1.0 - self.poisson_ratio**2)

    @property
    def shear_modulus(self) -> float:
        """G = E / (2 (1 + nu)) [Pa]."""
        return self.young_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def shear_coefficient(self) -> float:
        """c_s in k_t = c_s sqrt(R* delta): 2 sqrt(4) G / (2 - nu) [Pa] (Eq. 3.3, Mindlin)."""
        return 2.0 * math.sqrt(4.0) * self.shear_modulus / (2.0 - self.poisson_ratio)




def dem_parameters(material: Mapping[str, Any], numerics: Mapping[str, Any]) -> DEMParameters:
    """The DEM parameters of validated configuration sections.

    Parameters
    ----------
    material
        ``materials.pellet``: ``young_modulus_pa``, ``poisson_ratio``,
        ``point_density_kg_m3``, ``bond_tensile_strength_pa``.
    numerics
        The stage's numerics: ``interaction_radius_factor``, ``dem_damping``,
        ``time_step_safety``, ``dem_time_step_s``, ``wall_max_velocity_m_s``,
        ``wall_gain``.
    """
    return DEMParameters(
        young_modulus=float(material["young_modulus_pa"]),
        poisson_ratio=float(material["poisson_ratio"]),
        density=float(material["point_density_kg_m3"]),
        interaction_radius_factor=float(numerics["interaction_radius_factor"]),
        damping=float(numerics["dem_damping"]),
        time_step_safety=float(numerics["time_step_safety"]),
        time_step=float(numerics["dem_time_step_s"]),
        wall_max_velocity=float(numerics["wall_max_velocity_m_s"]),
        wall_gain=float(numerics["wall_gain"]),
        bond_tensile_strength=float(material["bond_tensile_strength_pa"]),
    )
