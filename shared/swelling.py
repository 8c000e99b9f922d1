"""Suction-driven volumetric swelling of DEM points (docs/design.md §3, Eq. 3.21).

eps_v(s) = (beta/alpha) [exp(-alpha s) - exp(-alpha s_0)], positive (swelling) when the
suction falls below s_0, with alpha and beta per Pa. A point's radius follows its volume,
r = r_0 (1 + eps_v)^(1/3) (the reading docs/design.md uses for the inconsistent Eq. 3.23).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from shared.errors import ConfigError
from shared.materials import ClayLaws

__all__ = ["swelling_strain", "volumetric_strain", "swollen_radius"]

FloatArray = npt.NDArray[np.float64]


def swelling_strain(
    suction: npt.ArrayLike, alpha: float, beta: float, initial_suction: float
) -> FloatArray:
    """eps_v = (beta / alpha) [exp(-alpha s) - exp(-alpha s_0)] [1] (Eqs. 3.21, 4.28).

    Parameters
    ----------
    suction
        Suction s [Pa].
    alpha, beta
        Parameters of the law [1/Pa].
    initial_suction
        s_0, suction of the reference state [Pa].
    """
    suction = np.asarray(suction, dtype=np.float64)
    return (beta / alpha) * (np.exp(-alpha * suction) - np.exp(-alpha * initial_suction))


def volumetric_strain(
    suction: npt.ArrayLike, material: ClayLaws
) -> FloatArray:
    """Volumetric swelling strain eps_v relative to the state at ``initial_suction``.

    Parameters
    ----------
    suction
        Suction s [Pa].
    material
        Clay parameters: swelling_alpha [1/Pa], swelling_beta [1/Pa],
        initial_suction s_0 [Pa].

    Returns
    -------
    ndarray
        eps_v [1], shape of ``suction``; > 0 for s < s_0.
    """
    return swelling_strain(
        suction, material.swelling_alpha, material.swelling_beta, material.initial_suction
    )


def swollen_radius(
    reference_radius: npt.ArrayLike, volumetric_strain: npt.ArrayLike
) -> FloatArray:
    """Radius of a point whose volume grew by ``volumetric_strain``: r_0 (1 + eps_v)^(1/3).

    Parameters
    ----------
    reference_radius
        Radius r_0 at the reference state [m].
    volumetric_strain
        eps_v [1], broadcastable with ``reference_radius``; must exceed -1.

    Returns
    -------
    ndarray
        Radius [m], broadcast shape.

    Raises
    ------
    shared.errors.ConfigError
        If 1 + eps_v <= 0 (a point cannot lose all its volume), naming the swelling keys.
    """
    strain = np.asarray(volumetric_strain, dtype=np.float64)
    if np.any(~(strain > -1.0)):
        raise ConfigError(
            f"volumetric strain must exceed -1 (NaN not allowed), got {strain[~(strain > -1.0)].flat[0]:g}: "
            "check the swelling law's materials.pellet.swelling_alpha_per_pa and materials.pellet.swelling_beta_per_pa "
            "(or a case's own materials)")
    return np.asarray(reference_radius, dtype=np.float64) * np.cbrt(1.0 + strain)
