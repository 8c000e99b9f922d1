"""Constitutive laws of the pellet-powder mixture (Caulk 2022, Chap. 4), vectorised.

Units are SI and per Pa: suction s = -p > 0 [Pa], alpha and beta [1/Pa].

The mixture's material is one clay (:class:`MixtureParameters`, a
:class:`shared.materials.ClayLaws`): its retention, permeability and swelling are the
laws of :mod:`shared.retention`, :mod:`shared.permeability` and :mod:`shared.swelling`,
which the micro pellet's clay takes too; this module adds what only the mixture has.

- Retention (Eqs. 4.24-4.26, docs/design.md §3): S(s) = [1 + (s/zeta)^(1/(1-lambda))]^(-lambda),
  zeta and lambda exponential in the porosity, and its inverse s(S), unclamped and
  without range checks (the local problems' Newton iterations probe beyond them).
- Powder permeability (Eqs. 4.16-4.19): k = k_0 exp(b_k (phi - phi_0)) k_r(S).
- Swelling (Eq. 4.28, sign of docs/design.md §3): eps(s) = (beta/alpha)
  [exp(-alpha s) - exp(-alpha s_0)].
- Pellet Young's modulus (Eq. 4.3): E(s) = 3 (1 - 2 nu) exp(alpha s) / beta, capped.
- Swelling under confinement (Eqs. 4.31-4.33, our reading): one pressure of the clay's
  state, P(rho_d, s) = S_ret(s) p'_vc(rho_d), for clay held below its free volume V_f(s),
  and the volume where P = sigma (:func:`confined_volume`). In full: docs/macro.md,
  "Swelling limited by confinement".
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from shared.errors import ConfigError
from shared.materials import ClayLaws, law_parameters
from shared.permeability import intrinsic_permeability, relative_permeability
from shared.retention import (
    van_genuchten_parameters,
    van_genuchten_saturation,
    van_genuchten_suction,
    van_genuchten_suction_slope,
)
from shared.swelling import volumetric_strain

__all__ = [
    "MixtureParameters",
    "MIXTURE_MATERIALS",
    "case_materials",
    "mixture_parameters",
    "onset_ramp",
    "saturation",
    "suction",
    "suction_derivative",
    "powder_permeability",
    "swelling_strain",
    "young_modulus",
    "consolidation_pressure",
    "free_volume",
    "swelling_pressure",
    "confined_pressure",
    "confined_volume",
]

FloatArray = npt.NDArray[np.float64]
MIXTURE_MATERIALS = ("mixture_pellet", "mixture_powder")
"""The sections of ``materials`` the macro model reads (Tables 4.1-4.2)."""


@dataclass(frozen=True)
class MixtureParameters(ClayLaws):
    """Material parameters of the mixture (Tables 4.1-4.2 and the macro section): the
    clay's laws (:class:`shared.materials.ClayLaws`: the retention and permeability of
    Table 4.2, ``materials.mixture_powder``; the swelling alpha, beta and s_0 of Table
    4.1, ``materials.mixture_pellet``, per Pa) and the mixture's own.

    Attributes
    ----------
    poisson_ratio
        nu [1].
    friction
        tan of the pellet-pellet friction angle [1].
    young_bounds
        (min, max) of E(s) [Pa].
    yield_area
        B of Eq. 4.4 read as an area [m2] (:func:`yield_force`); inf: no yield.
    grain_density
        Density of the powder grains [kg/m3].
    beta_v, alpha_v
        Eq. 4.31: beta_v [Pa], alpha_v [m3/kg].
    """

    poisson_ratio: float
    friction: float
    young_bounds: tuple[float, float]
    yield_area: float
    grain_density: float
    beta_v: float
    alpha_v: float


def case_materials(materials: Mapping[str, Any], case: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """The mixture's material sections of one case.

    Parameters
    ----------
    materials
        Validated ``materials`` section.
    case
        The case's entry of ``macro.cases``; its own values (``materials.mixture_pellet``,
        ``materials.mixture_powder``) replace those of ``materials``, key by key.

    Returns
    -------
    dict
        ``{"mixture_pellet": {...}, "mixture_powder": {...}}``, SI units as in the config.
    """
    own = case.get("materials", {})
    return {key: {**materials[key], **own.get(key, {})} for key in MIXTURE_MATERIALS}


def mixture_parameters(materials: Mapping[str, Any], powder: Mapping[str, Any]) -> MixtureParameters:
    """Parameters from validated ``materials`` (mixture_pellet, mixture_powder) and ``macro.powder``."""
    pellet = materials["mixture_pellet"]
    mix = materials["mixture_powder"]
    low, high = (float(v) for v in pellet["young_modulus_bounds_pa"])
    if not low <= high:
        raise ConfigError("materials.mixture_pellet.young_modulus_bounds_pa must be [min, max]")
    # the laws' keys are those of materials.pellet: the retention's and permeability's in
    # the powder's section, the swelling's and s_0 in the pellets' (no key in both)
    return MixtureParameters(
        **law_parameters({**pellet, **mix}),
        poisson_ratio=float(pellet["poisson_ratio"]),
        friction=float(np.tan(np.radians(pellet["friction_angle_deg"]))),
        young_bounds=(low, high),
        yield_area=float(pellet["yield_area_m2"]) if pellet["yield"] else float("inf"),
        grain_density=float(powder["grain_density_kg_m3"]),
        beta_v=float(powder["swelling_beta_v_pa"]),
        alpha_v=float(powder["swelling_alpha_v_m3_per_kg"]),
    )


def saturation(suction: npt.ArrayLike, porosity: npt.ArrayLike, m: MixtureParameters) -> FloatArray:
    """Water saturation S(s, phi) [1] (Eq. 4.24 inverted, docs/design.md §3); 1 for s <= 0."""
    return van_genuchten_saturation(suction, *van_genuchten_parameters(porosity, m))


def suction(sat: npt.ArrayLike, porosity: npt.ArrayLike, m: MixtureParameters) -> FloatArray:
    """Suction s(S, phi) [Pa] (Eq. 4.24): zeta (S^(-1/lambda) - 1)^(1 - lambda); NaN outside (0, 1]."""
    sat = np.asarray(sat, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        value = van_genuchten_suction(sat, *van_genuchten_parameters(porosity, m))
    return np.where((sat > 0.0) & (sat <= 1.0), value, np.nan)


def suction_derivative(sat: npt.ArrayLike, porosity: npt.ArrayLike, m: MixtureParameters) -> FloatArray:
    """|ds/dS| = |dp/dS| [Pa] at fixed porosity (closed form), for the stable step Eq. 4.58."""
    return van_genuchten_suction_slope(sat, *van_genuchten_parameters(porosity, m))


def powder_permeability(sat: npt.ArrayLike, porosity: npt.ArrayLike, m: MixtureParameters) -> FloatArray:
    """Powder water permeability k = k_M k_rM [m2] (Eqs. 4.16-4.19)."""
    return intrinsic_permeability(porosity, m) * relative_permeability(sat, "water", m)


def swelling_strain(suction: npt.ArrayLike, m: MixtureParameters) -> FloatArray:
    """Volumetric swelling strain eps(s) [1] (Eq. 4.28, sign of docs/design.md §3)."""
    return volumetric_strain(suction, m)


def young_modulus(suction: npt.ArrayLike, m: MixtureParameters) -> FloatArray:
    """Pellet Young's modulus E(s) = 3 (1 - 2 nu) exp(alpha s) / beta [Pa] (Eq. 4.3), capped."""
    s = np.asarray(suction, dtype=np.float64)
    with np.errstate(over="ignore"):
        e = 3.0 * (1.0 - 2.0 * m.poisson_ratio) * np.exp(m.swelling_alpha * s) / m.swelling_beta
    return np.clip(e, *m.young_bounds)


def yield_force(suction: npt.ArrayLike, m: MixtureParameters) -> FloatArray:
    """Normal force at which a pellet's contact yields, 3 (1 - 2 nu) B exp(alpha s) / beta [N]
    (Eq. 4.4; E(s) of Eq. 4.3 uncapped times B).

    Our reading: Table 4.1's B = 1.206e-7 "m^-2" is an area [m2]. Read as printed (or as
    dimensionless, as the text says) Eq. 4.4 gives a yield stress of tens of pascals; as
    an area, with the default alpha and beta, it gives 215 N at 132 MPa and 9 N at 1 MPa,
    which a Hertz contact between two 6 mm pellets reaches at a mean contact pressure of
    about 120 MPa dry and 9 MPa wet (:func:`yield_pressure`): the yield stress "normal
    force divided by the contact area" of the text (see :func:`shared.dem.hertz_yield`).
    inf when the yield is off (``materials.mixture_pellet.yield``).
    """
    s = np.asarray(suction, dtype=np.float64)
    if not np.isfinite(m.yield_area):
        return np.full(s.shape, np.inf)
    with np.errstate(over="ignore"):
        return 3.0 * (1.0 - 2.0 * m.poisson_ratio) * m.yield_area * np.exp(m.swelling_alpha * s) / m.swelling_beta


def yield_pressure(suction: npt.ArrayLike, radius: npt.ArrayLike, m: MixtureParameters) -> FloatArray:
    """Mean pressure under which a pellet's surface yields against a rigid flat [Pa]:
    p_y = F_y / (pi a_y^2), a_y^3 = 3 F_y r / (4 E*), E* = E(s) / (1 - nu^2) (Eq. 4.3
    capped, as the contacts use it), F_y of :func:`yield_force`; inf without yield."""
    force = yield_force(suction, m)
    e_star = young_modulus(suction, m) / (1.0 - m.poisson_ratio**2)
    with np.errstate(invalid="ignore"):
        contact = np.cbrt(3.0 * force * np.asarray(radius, dtype=np.float64) / (4.0 * e_star))
        return np.where(np.isfinite(force), force / (np.pi * contact**2), np.inf)


def consolidation_pressure(dry_density: npt.ArrayLike, m: MixtureParameters) -> FloatArray:
    """Swelling pressure of the consolidation line p'_vc = beta_v exp(alpha_v rho_d) [Pa] (Eq. 4.31)."""
    return m.beta_v * np.exp(m.alpha_v * np.asarray(dry_density, dtype=np.float64))


def free_volume(suction: npt.ArrayLike, reference_volume: npt.ArrayLike, m: MixtureParameters) -> FloatArray:
    """Free swelling volume V_f(s) = V_0 (1 + eps(s)) [m3] (Eq. 4.28): the largest volume
    of clay at suction ``suction`` [Pa] whose volume at the initial suction is
    ``reference_volume`` [m3]."""
    return np.asarray(reference_volume, dtype=np.float64) * (1.0 + swelling_strain(suction, m))


def onset_ramp(volume: npt.ArrayLike, free: npt.ArrayLike, strain: float) -> FloatArray:
    """Share of the swelling-pressure law a clay held at ``volume`` presses [1]:
    min(1, (V_f - V) / (strain V_f)), 0 at or above its free volume V_f [m3].

    The onset of confinement is set-valued (:func:`confined_pressure`): at V_f the clay
    holds any stress up to P(m_s / V_f, s). A push that jumps there has no balanced state
    for the pellets pressing a cell at V_f, as a rigid contact has none; this ramp over
    the volumetric strain ``strain`` [1] is the penalty regularisation a contact's
    stiffness is.
    """
    free = np.asarray(free, dtype=np.float64)
    return np.asarray(np.clip((free - np.asarray(volume)) / (strain * free), 0.0, 1.0), dtype=np.float64)


def swelling_pressure(dry_density: npt.ArrayLike, suction: npt.ArrayLike, porosity: npt.ArrayLike,
                      m: MixtureParameters) -> FloatArray:
    """Swelling pressure of confined clay, one law of its state [Pa]:
    P(rho_d, s) = S_ret(s) p'_vc(rho_d) (Eq. 4.31 at saturation, scaled by the water
    saturation as Eq. 4.33 reads: s_w p).

    The same for pellet and powder clay, whatever its history: at saturation, clay of
    dry density 1 490 kg/m3 presses 4.15 MPa (Wang et al. 2013 find one relation between
    swelling pressure and dry density for homogeneous and heterogeneous samples). The
    law holds for clay held below its free swelling volume (:func:`confined_pressure`).

    Parameters
    ----------
    dry_density
        rho_d = m_s / V [kg/m3] (Eq. 4.32).
    suction
        Suction s [Pa].
    porosity
        Porosity of the retention curve S_ret [1].
    """
    return saturation(suction, porosity, m) * consolidation_pressure(dry_density, m)


def confined_pressure(volume: npt.ArrayLike, suction: npt.ArrayLike, solid_mass: npt.ArrayLike,
                      reference_volume: npt.ArrayLike, porosity: npt.ArrayLike,
                      m: MixtureParameters) -> FloatArray:
    """Pressure of clay held at ``volume`` [Pa]: :func:`swelling_pressure` at its dry
    density m_s / V below its free swelling volume V_f(s) (Eq. 4.28), 0 at or above it.

    At V_f itself the clay holds any stress between 0 and P(m_s / V_f, s): it swells
    no further without stress and is compressed only beyond that (:func:`confined_volume`).

    Parameters
    ----------
    volume
        Volume V of the clay (solid and pores) [m3].
    suction
        Suction s [Pa].
    solid_mass
        Dry mass m_s [kg].
    reference_volume
        V_0, the volume at the initial suction [m3].
    porosity
        Porosity of the retention curve S_ret [1].
    """
    volume = np.asarray(volume, dtype=np.float64)
    pressure = swelling_pressure(np.asarray(solid_mass, dtype=np.float64) / volume, suction, porosity, m)
    return np.where(volume < free_volume(suction, reference_volume, m), pressure, 0.0)


def confined_volume(suction: npt.ArrayLike, stress: npt.ArrayLike, solid_mass: npt.ArrayLike,
                    reference_volume: npt.ArrayLike, porosity: npt.ArrayLike,
                    m: MixtureParameters) -> FloatArray:
    """Volume to which clay swells under a confining ``stress`` [m3]: the free swelling
    volume V_f(s) (Eq. 4.28) while the stress is below P(m_s / V_f, s), else the volume
    where :func:`swelling_pressure` meets it, V = alpha_v m_s / ln(sigma / (S_ret beta_v)).

    Parameters are those of :func:`confined_pressure`; ``stress`` >= 0 [Pa].
    """
    s = np.asarray(suction, dtype=np.float64)
    mass = np.asarray(solid_mass, dtype=np.float64)
    free = free_volume(s, reference_volume, m)
    line = np.maximum(np.asarray(stress, dtype=np.float64), 0.0) / (saturation(s, porosity, m) * m.beta_v)
    with np.errstate(divide="ignore", invalid="ignore"):
        held = np.where(line > 1.0, m.alpha_v * mass / np.log(np.maximum(line, 1.0)), np.inf)
    return np.minimum(free, held)
