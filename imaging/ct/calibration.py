"""Grey value -> density -> porosity calibration (thesis Sec. 3.3.4).

Grey values are taken linear in density, with black (air) and the brightest grey
(muscovite) as anchors. Porosity is taken linear in density, with the density of air at
porosity 1 and the measured mean dry density of the pellet at its measured mean porosity.
The values are in the configuration (``imaging.calibration``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["Calibration", "grey_anchors", "grey_to_density", "density_to_porosity"]


@dataclass(frozen=True)
class Calibration:
    """Anchors of the two linear maps (densities in kg/m3, grey values unitless).

    Attributes
    ----------
    grey_air, grey_muscovite
        Grey values of air and of the densest mineral [-].
    air_density, muscovite_density
        Densities of air and muscovite [kg/m3].
    dry_density
        Measured mean dry density of the specimen [kg/m3].
    mean_porosity
        Measured mean porosity of the specimen [-] (the material's reference porosity).
    """

    grey_air: float
    grey_muscovite: float
    air_density: float
    muscovite_density: float
    dry_density: float
    mean_porosity: float

    def __post_init__(self) -> None:
        if not self.grey_muscovite > self.grey_air:
            raise ValueError(
                f"grey_muscovite ({self.grey_muscovite}) must exceed grey_air ({self.grey_air})"
            )
        if not self.muscovite_density > self.dry_density > self.air_density > 0:
            raise ValueError(
                "densities must satisfy muscovite_density > dry_density > air_density > 0"
            )
        if not 0.0 < self.mean_porosity < 1.0:
            raise ValueError(f"mean_porosity must lie in (0, 1), got {self.mean_porosity}")


def grey_anchors(
    volume: npt.NDArray[np.unsignedinteger],
    specimen: npt.NDArray[np.bool_],
    muscovite_percentile: float = 99.99,
) -> tuple[float, float]:
    """Estimate the air and muscovite grey values of a scan.

    Air is the median grey outside the specimen; muscovite is a high percentile inside
    it (a percentile rather than the maximum, so a single noisy voxel does not set it).

    Returns
    -------
    grey_air, grey_muscovite : float
    """
    outside = volume[~specimen]
    if outside.size == 0:
        raise ValueError("no air around the specimen: set the grey anchors in the config")
    grey_air = float(np.median(outside))
    grey_muscovite = float(np.percentile(volume[specimen], muscovite_percentile))
    return grey_air, grey_muscovite


def grey_to_density(
    grey: npt.ArrayLike, calibration: Calibration
) -> npt.NDArray[np.floating]:
    """Map grey values to density [kg/m3] linearly through the air and muscovite anchors.

    Float32 input stays float32 (memory of large volumes); anything else gives float64.
    """
    grey = np.asarray(grey)
    dtype = np.float32 if grey.dtype == np.float32 else np.float64
    slope = (calibration.muscovite_density - calibration.air_density) / (
        calibration.grey_muscovite - calibration.grey_air
    )
    density = grey.astype(dtype, copy=True)
    density -= dtype(calibration.grey_air)
    density *= dtype(slope)
    density += dtype(calibration.air_density)
    return density


def density_to_porosity(
    density: npt.ArrayLike, calibration: Calibration
) -> npt.NDArray[np.floating]:
    """Map density [kg/m3] to porosity [-], linear through (air, 1) and (dry density, mean).

    Values are not clamped: out-of-range porosities are for the caller to report.
    """
    density = np.asarray(density)
    slope = (calibration.mean_porosity - 1.0) / (
        calibration.dry_density - calibration.air_density
    )
    return 1.0 + slope * (density - calibration.air_density)
