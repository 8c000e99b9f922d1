"""Material parameters of the partially saturated clay model, read from the configuration.

The values live in the ``materials`` section of the configuration (schema defaults:
Table 3.1 of Caulk (2022) for the pellet clay); :func:`clay_parameters` turns that
section into the one object the constitutive laws take. Field names spell out the
thesis's symbols; the configuration keys carry the units.

:class:`ClayLaws` holds what the laws of :mod:`shared.retention`, :mod:`shared.permeability`
and :mod:`shared.swelling` read, and every stage's clay is one: the micro pellet's
:class:`ClayParameters` adds the fluids and the cracks, the macro mixture's
(:class:`macro.laws.MixtureParameters`) the pellets' contacts and the powder's
consolidation line.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from shared.errors import ConfigError

__all__ = ["ClayLaws", "ClayParameters", "clay_parameters", "law_parameters", "CLAY_CONFIG_KEYS",
           "CLAY_LAW_KEYS"]


@dataclass(frozen=True)
class ClayLaws:
    """Parameters of the clay's constitutive laws: retention, intrinsic and relative
    permeability, swelling.

    Attributes
    ----------
    retention_pressure_reference
        zeta_0, van Genuchten air-entry-like pressure at the reference porosity [Pa].
    retention_exponent_reference
        lambda_0, van Genuchten shape exponent at the reference porosity [1].
    retention_pressure_porosity_factor
        a in zeta(phi) = zeta_0 exp(a (phi_0 - phi)) [1].
    retention_exponent_porosity_factor
        b in lambda(phi) = lambda_0 exp(b (phi_0 - phi)) [1].
    reference_porosity
        phi_0, reference (measured mean) porosity of the retention and permeability
        laws [1]; also the porosity anchor of the CT calibration (Sec. 3.3.4).
    residual_saturation
        S_r, residual water saturation [1].
    saturated_saturation
        S_s, maximal water saturation [1].
    relative_permeability_exponent
        n in k_r = Se^n [1].
    intrinsic_permeability_reference
        k_0, intrinsic permeability at the reference porosity [m2].
    permeability_porosity_factor
        b_k in k_M = k_0 exp(b_k (phi - phi_0)) [1].
    swelling_beta
        beta of the swelling law eps_v = (beta/alpha)[exp(-alpha s) - exp(-alpha s0)]
        [1/Pa].
    swelling_alpha
        alpha of the swelling law [1/Pa].
    initial_suction
        s_0, suction of the reference (as-compacted) state [Pa].
    """

    retention_pressure_reference: float
    retention_exponent_reference: float
    retention_pressure_porosity_factor: float
    retention_exponent_porosity_factor: float
    reference_porosity: float
    residual_saturation: float
    saturated_saturation: float
    relative_permeability_exponent: float
    intrinsic_permeability_reference: float
    permeability_porosity_factor: float
    swelling_beta: float
    swelling_alpha: float
    initial_suction: float

    def __post_init__(self) -> None:
        if not 0.0 <= self.residual_saturation < self.saturated_saturation <= 1.0:
            raise ConfigError(
                "need 0 <= residual_saturation < saturated_saturation <= 1, got "
                f"{self.residual_saturation}, {self.saturated_saturation}"
            )
        if not 0.0 < self.retention_exponent_reference < 1.0:
            raise ConfigError("retention_exponent_reference (lambda_0) must lie in (0, 1)")
        if not 0.0 < self.reference_porosity < 1.0:
            raise ConfigError("reference_porosity (phi_0) must lie in (0, 1)")
        self._check_positive("retention_pressure_reference", "intrinsic_permeability_reference",
                             "swelling_alpha")

    def _check_positive(self, *names: str) -> None:
        for name in names:
            if not getattr(self, name) > 0.0:
                raise ConfigError(f"{name} must be > 0, got {getattr(self, name)}")


@dataclass(frozen=True)
class ClayParameters(ClayLaws):
    """Constitutive parameters of the micro model's clay: the laws' (:class:`ClayLaws`),
    the fluids' and the cracks'.

    Attributes
    ----------
    water_viscosity
        Dynamic viscosity of water [Pa s].
    gas_viscosity
        Dynamic viscosity of the gas phase [Pa s].
    surface_tension
        Gas-water surface tension gamma [N/m].
    crack_roughness_factor
        eta, fraction of a gas-filled crack's facet area still conducting water [1].
    """

    water_viscosity: float
    gas_viscosity: float
    surface_tension: float
    crack_roughness_factor: float

    def __post_init__(self) -> None:
        super().__post_init__()
        self._check_positive("water_viscosity", "gas_viscosity", "surface_tension")


CLAY_CONFIG_KEYS: dict[str, str] = {
    "retention_pressure_reference": "retention_pressure_reference_pa",
    "retention_exponent_reference": "retention_exponent_reference",
    "retention_pressure_porosity_factor": "retention_pressure_porosity_factor",
    "retention_exponent_porosity_factor": "retention_exponent_porosity_factor",
    "reference_porosity": "reference_porosity",
    "residual_saturation": "residual_saturation",
    "saturated_saturation": "saturated_saturation",
    "relative_permeability_exponent": "relative_permeability_exponent",
    "intrinsic_permeability_reference": "intrinsic_permeability_reference_m2",
    "permeability_porosity_factor": "permeability_porosity_factor",
    "water_viscosity": "water_viscosity_pa_s",
    "gas_viscosity": "gas_viscosity_pa_s",
    "surface_tension": "surface_tension_n_per_m",
    "crack_roughness_factor": "crack_roughness_factor",
    "swelling_beta": "swelling_beta_per_pa",
    "swelling_alpha": "swelling_alpha_per_pa",
    "initial_suction": "initial_suction_pa",
}
"""Field of :class:`ClayParameters` -> key of the configuration's ``materials.pellet``."""

CLAY_LAW_KEYS: dict[str, str] = {field.name: CLAY_CONFIG_KEYS[field.name] for field in fields(ClayLaws)}
"""Field of :class:`ClayLaws` -> key of a configuration section (the same keys in
``materials.pellet`` and in the mixture's ``materials.mixture_powder`` and
``materials.mixture_pellet``)."""


def clay_parameters(section: Mapping[str, Any]) -> ClayParameters:
    """The clay parameters of a validated ``materials.pellet`` configuration section.

    Parameters
    ----------
    section
        The section with the schema's defaults filled in (keys carry their units:
        ``retention_pressure_reference_pa``, ``swelling_alpha_per_pa``, ...).
    """
    return ClayParameters(
        **{field: float(section[key]) for field, key in CLAY_CONFIG_KEYS.items()}
    )


def law_parameters(section: Mapping[str, Any]) -> dict[str, float]:
    """The :class:`ClayLaws` fields of a validated configuration section that holds their
    keys (:data:`CLAY_LAW_KEYS`), as floats, to build a stage's material with."""
    return {field: float(section[key]) for field, key in CLAY_LAW_KEYS.items()}
