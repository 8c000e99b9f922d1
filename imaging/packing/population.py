"""Particle populations: sizes and shapes of flat elliptic disks (Ferrage et al. 2015, Table I).

A disk has semi-axes l_a >= l_b in its basal plane and thickness h. Its basal surface is
S = pi l_a l_b, its equivalent diameter d = 2 sqrt(l_a l_b) (diameter of the disk of
equal basal surface) and its aspect ratio R = h / d. A population draws S, R and the
axis ratio e = l_a / l_b from independent log-normal laws of median m and log standard
deviation sigma (sigma = 0 gives a monodisperse population). The axis ratio is >= 1 by
definition, so it follows the log-normal law truncated below 1 (values under 1 are
redrawn). The basal surface law can be truncated above a largest surface the same way,
for wide laws whose tail would not fit in the box.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from shared.errors import ConfigError

__all__ = ["Population", "sample_semi_axes", "equivalent_diameter", "volumes"]


@dataclass(frozen=True)
class Population:
    """Log-normal laws of the particle shape parameters.

    Attributes
    ----------
    basal_surface_median : float
        Median basal surface pi l_a l_b [m^2].
    basal_surface_sigma : float
        Standard deviation of ln(basal surface) [1].
    aspect_ratio_median : float
        Median h / (2 sqrt(l_a l_b)) [1].
    aspect_ratio_sigma : float
        Standard deviation of ln(aspect ratio) [1].
    axis_ratio_median : float
        Median l_a / l_b [1], at least 1.
    axis_ratio_sigma : float
        Standard deviation of ln(l_a / l_b) [1].
    basal_surface_max : float or None
        Largest basal surface [m^2]; larger draws are redrawn. None: no bound.
    """

    basal_surface_median: float
    basal_surface_sigma: float = 0.0
    aspect_ratio_median: float = 0.1
    aspect_ratio_sigma: float = 0.0
    axis_ratio_median: float = 1.0
    axis_ratio_sigma: float = 0.0
    basal_surface_max: float | None = None

    @property
    def median_diameter(self) -> float:
        """Equivalent diameter of the median basal surface, 2 sqrt(S / pi) [m]."""
        return float(2.0 * np.sqrt(self.basal_surface_median / np.pi))

    @property
    def median_semi_major_axis(self) -> float:
        """l_a of the particle of median basal surface and median axis ratio [m]."""
        return float(np.sqrt(self.basal_surface_median * self.axis_ratio_median / np.pi))


def _lognormal(
    rng: np.random.Generator, median: float, sigma: float, n: int
) -> npt.NDArray[np.float64]:
    return median * np.exp(sigma * rng.standard_normal(n))


def _truncated_lognormal(
    rng: np.random.Generator, median: float, sigma: float, n: int, low: float, high: float
) -> npt.NDArray[np.float64]:
    values = _lognormal(rng, median, sigma, n)
    outside = (values < low) | (values > high)
    while np.any(outside):
        values[outside] = _lognormal(rng, median, sigma, int(outside.sum()))
        outside = (values < low) | (values > high)
    return values


def sample_semi_axes(
    population: Population, n: int, rng: np.random.Generator
) -> npt.NDArray[np.float64]:
    """Draw the semi-axes of ``n`` particles.

    Parameters
    ----------
    population : Population
    n : int
        Number of particles.
    rng : numpy.random.Generator
        Source of randomness; the result depends only on its state.

    Returns
    -------
    ndarray, shape (n, 3)
        (l_a, l_b, h / 2) [m].

    Raises
    ------
    ValueError
        If the median axis ratio is below 1, a sigma is negative or the largest basal
        surface is below the median.
    """
    if population.axis_ratio_median < 1.0:
        raise ConfigError("axis_ratio_median: l_a / l_b must be at least 1")
    high = np.inf if population.basal_surface_max is None else population.basal_surface_max
    if high <= population.basal_surface_median:
        raise ConfigError("basal_surface_max_m2: must exceed the median basal surface")
    for name in ("basal_surface_sigma", "aspect_ratio_sigma", "axis_ratio_sigma"):
        if getattr(population, name) < 0.0:
            raise ConfigError(f"{name}: must be >= 0")
    surface = _truncated_lognormal(rng, population.basal_surface_median,
                                   population.basal_surface_sigma, n, 0.0, high)
    aspect = _lognormal(rng, population.aspect_ratio_median, population.aspect_ratio_sigma, n)
    ratio = _truncated_lognormal(rng, population.axis_ratio_median, population.axis_ratio_sigma,
                                 n, 1.0, np.inf)
    la = np.sqrt(surface * ratio / np.pi)
    lb = np.sqrt(surface / (ratio * np.pi))
    half_thickness = aspect * np.sqrt(la * lb)
    return np.stack([la, lb, half_thickness], axis=1)


def equivalent_diameter(semi_axes: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Diameter of the disk of equal basal surface, 2 sqrt(l_a l_b) [m], per particle."""
    return 2.0 * np.sqrt(semi_axes[:, 0] * semi_axes[:, 1])


def volumes(semi_axes: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Particle volumes pi l_a l_b h [m^3]."""
    return 2.0 * np.pi * semi_axes[:, 0] * semi_axes[:, 1] * semi_axes[:, 2]
