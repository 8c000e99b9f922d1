"""Mechanical parameters of the DEM point model (Caulk 2022, Table 3.1 and Appendix .2)."""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["DEMParameters", "DEFAULT_DEM"]


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
    confining_stress
        Compressive stress imposed by the servo walls on each axis [Pa]
        (Sec. 3.5.4: 10e6 in the confined case, 0 for free swelling).
    bond_tensile_strength
        sigma_t, tensile strength of a bond [Pa]: an intact bond carries a tension up
        to sigma_t pi r^2 (r the mean radius of its two points) and breaks beyond. 0
        (default) is the thesis's cohesionless reading: a bond breaks as soon as its
        normal force would turn tensile. Not a parameter of the thesis (see
        :func:`shared.dem.bond_tension` for why the micro model needs it).
    """

    young_modulus: float = 100e8
    poisson_ratio: float = 0.3
    density: float = 2600.0
    interaction_radius_factor: float = 1.0
    damping: float = 0.4
    time_step_safety: float = 0.8
    time_step: float = 4e-9
    wall_max_velocity: float = 1e-4
    wall_gain: float = 0.25
    confining_stress: float = 0.0
    bond_tensile_strength: float = 0.0

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


DEFAULT_DEM = DEMParameters()
