"""Material parameters of the partially saturated clay model, in one place.

The defaults are those of Table 3.1 of Caulk (2022) (micro model of a compacted MX80
pellet); where the Appendix .2 reference script differs, the docstring says so. Every
value is in SI units, stated in the field's description.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ClayParameters", "DEFAULT_CLAY"]


@dataclass(frozen=True)
class ClayParameters:
    """Constitutive parameters of the clay (retention, permeability, swelling).

    Attributes
    ----------
    retention_pressure_reference
        zeta_0, van Genuchten air-entry-like pressure at the reference porosity [Pa]
        (Table 3.1: 0.03e6 Pa).
    retention_exponent_reference
        lambda_0, van Genuchten shape exponent at the reference porosity [1]
        (Table 3.1: 0.08).
    retention_pressure_porosity_factor
        a in zeta(phi) = zeta_0 exp(a (phi_0 - phi)) [1] (Table 3.1: 6.8).
    retention_exponent_porosity_factor
        b in lambda(phi) = lambda_0 exp(b (phi_0 - phi)) [1] (Table 3.1: -1.5).
    reference_porosity
        phi_0, reference (mean initial) porosity of retention and permeability laws [1]
        (Sec. 3.3.4: 0.25 for the MX80 pellet).
    residual_saturation
        S_r, residual water saturation [1] (Table 3.1: 0; the script uses 0.01).
    saturated_saturation
        S_s, maximal water saturation [1] (Table 3.1: 1).
    relative_permeability_exponent
        n in k_r = Se^n [1] (Table 3.1: 2; the script uses nUnsatPerm = 1).
    intrinsic_permeability_reference
        k_0, intrinsic permeability at the reference porosity [m2] (Table 3.1: 1e-20).
    permeability_porosity_factor
        b_k in k_M = k_0 exp(b_k (phi - phi_0)) [1] (Table 3.1: 2).
    water_viscosity
        Dynamic viscosity of water [Pa s] (1e-3).
    gas_viscosity
        Dynamic viscosity of the gas phase [Pa s] (Table 3.1: 1.8e-5).
    surface_tension
        Gas-water surface tension gamma [N/m] (Table 3.1: 7.28e-2).
    crack_roughness_factor
        eta, fraction of a gas-filled crack's facet area still conducting water [1]
        (Table 3.1: 0.001).
    swelling_beta
        beta of the swelling law eps_v = (beta/alpha)[exp(-alpha s) - exp(-alpha s0)]
        [1/Pa] (Table 3.1: 0.8e-8, printed as 'Pa'; the script uses 2.0e-8).
    swelling_alpha
        alpha of the swelling law [1/Pa] (Table 3.1: 2.102e-8, printed as 'Pa').
    initial_suction
        s_0, suction of the reference (as-compacted) state [Pa] (Sec. 3.5.1: 132e6).
    """

    retention_pressure_reference: float = 0.03e6
    retention_exponent_reference: float = 0.08
    retention_pressure_porosity_factor: float = 6.8
    retention_exponent_porosity_factor: float = -1.5
    reference_porosity: float = 0.25
    residual_saturation: float = 0.0
    saturated_saturation: float = 1.0
    relative_permeability_exponent: float = 2.0
    intrinsic_permeability_reference: float = 1e-20
    permeability_porosity_factor: float = 2.0
    water_viscosity: float = 1e-3
    gas_viscosity: float = 1.8e-5
    surface_tension: float = 7.28e-2
    crack_roughness_factor: float = 1e-3
    swelling_beta: float = 0.8e-8
    swelling_alpha: float = 2.102e-8
    initial_suction: float = 132e6

    def __post_init__(self) -> None:
        if not 0.0 <= self.residual_saturation < self.saturated_saturation <= 1.0:
            raise ValueError(
                "need 0 <= residual_saturation < saturated_saturation <= 1, got "
                f"{self.residual_saturation}, {self.saturated_saturation}"
            )
        if not 0.0 < self.retention_exponent_reference < 1.0:
            raise ValueError("retention_exponent_reference (lambda_0) must lie in (0, 1)")
        positive = (
            "retention_pressure_reference",
            "intrinsic_permeability_reference",
            "water_viscosity",
            "gas_viscosity",
            "surface_tension",
            "swelling_alpha",
        )
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")


DEFAULT_CLAY = ClayParameters()
