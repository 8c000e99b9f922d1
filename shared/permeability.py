"""Permeability laws of the clay: relative and intrinsic (porosity-dependent).

docs/design.md §3 (thesis Eqs. 3.17, 3.18; the cubic law of cracks, Eq. 3.37, is in
:mod:`micro.cracks`). The effective saturation
Se = (S - S_r)/(S_s - S_r) is clamped to [0, 1] (not floored at S_r: docs/yade.md
§8.8); the gas phase uses 1 - Se.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import numpy.typing as npt

from shared.materials import ClayLaws, ClayParameters

__all__ = [
    "Phase",
    "effective_saturation",
    "relative_permeability",
    "intrinsic_permeability",
    "porosity_permeability",
    "phase_viscosity",
]

FloatArray = npt.NDArray[np.float64]
Phase = Literal["water", "gas"]


def effective_saturation(
    saturation: npt.ArrayLike, material: ClayLaws
) -> FloatArray:
    """Effective water saturation Se = (S - S_r)/(S_s - S_r), clamped to [0, 1].

    Parameters
    ----------
    saturation
        Water saturation [1].
    material
        Clay parameters (S_r, S_s).

    Returns
    -------
    ndarray
        Se [1], shape of ``saturation``.
    """
    saturation = np.asarray(saturation, dtype=np.float64)
    span = material.saturated_saturation - material.residual_saturation
    return np.clip((saturation - material.residual_saturation) / span, 0.0, 1.0)


def relative_permeability(
    saturation: npt.ArrayLike,
    phase: Phase,
    material: ClayLaws,
) -> FloatArray:
    """Relative permeability k_r = Se^n (water) or (1 - Se)^n (gas), in [0, 1].

    Parameters
    ----------
    saturation
        Water saturation [1] (for both phases).
    phase
        ``"water"`` or ``"gas"``.
    material
        Clay parameters (S_r, S_s, n).

    Returns
    -------
    ndarray
        k_r [1], shape of ``saturation``.
    """
    effective = effective_saturation(saturation, material)
    if phase == "gas":
        effective = 1.0 - effective
    elif phase != "water":
        raise ValueError(f"phase must be 'water' or 'gas', got {phase!r}")
    return effective**material.relative_permeability_exponent


def intrinsic_permeability(
    porosity: npt.ArrayLike, material: ClayLaws
) -> FloatArray:
    """Intrinsic permeability k_M = k_0 exp(b_k (phi - phi_0)) (thesis Eq. 3.18).

    Parameters
    ----------
    porosity
        Porosity [1].
    material
        Clay parameters (k_0 [m2], b_k, phi_0).

    Returns
    -------
    ndarray
        k_M [m2], shape of ``porosity``.
    """
    return porosity_permeability(
        porosity, material.intrinsic_permeability_reference,
        material.permeability_porosity_factor, material.reference_porosity,
    )


def porosity_permeability(
    porosity: npt.ArrayLike, reference: float, factor: float, reference_porosity: float
) -> FloatArray:
    """k = k_0 exp(b_k (phi - phi_0)) [m2] (Eqs. 3.18, 4.19).

    Parameters
    ----------
    porosity
        Porosity phi [1].
    reference
        k_0 [m2] at ``reference_porosity`` phi_0 [1].
    factor
        b_k [1].
    """
    porosity = np.asarray(porosity, dtype=np.float64)
    return reference * np.exp(factor * (porosity - reference_porosity))


def phase_viscosity(phase: Phase, material: ClayParameters) -> float:
    """Dynamic viscosity of ``phase`` [Pa s]."""
    if phase == "water":
        return material.water_viscosity
    if phase == "gas":
        return material.gas_viscosity
    raise ValueError(f"phase must be 'water' or 'gas', got {phase!r}")
