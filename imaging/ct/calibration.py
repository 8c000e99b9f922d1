"""Grey value -> density -> porosity calibration (thesis Sec. 3.3.4).

Grey values are taken linear in density, with black (air) and the brightest grey
(muscovite) as anchors. Porosity is taken linear in density, with the density of air at
porosity 1 and the measured mean dry density of the pellet at its measured mean porosity.
The values are in the configuration (``imaging.calibration``).

A scan without air or without muscovite can anchor the grey-density line on two other
phases of known density instead: the two most prominent peaks of its grey histogram
(:func:`histogram_peaks`), mapped to the equivalent air and muscovite greys
(:func:`anchors_through`) so that the rest of the calibration is unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from imaging.ct.mask import grey_sample
from shared.errors import ConfigError, InputError

__all__ = [
    "Calibration",
    "grey_anchors",
    "histogram_quantile",
    "histogram_peaks",
    "anchors_through",
    "grey_to_density",
    "density_to_porosity",
]

_HISTOGRAM_BINS = 512
PEAK_PROMINENCE = 0.05
"""A histogram peak counts if it rises this fraction of the highest bin above its
surroundings (:func:`scipy.signal.find_peaks` prominence)."""


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
            raise ConfigError(
                f"grey_muscovite ({self.grey_muscovite}) must exceed grey_air ({self.grey_air})"
            )
        if not self.muscovite_density > self.dry_density > self.air_density > 0:
            raise ConfigError(
                "densities must satisfy muscovite_density > dry_density > air_density > 0"
            )
        if not 0.0 < self.mean_porosity < 1.0:
            raise ConfigError(f"mean_porosity must lie in (0, 1), got {self.mean_porosity}")


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
        raise InputError("no air around the specimen: set the grey anchors in the config")
    size = 1 << (8 * volume.dtype.itemsize)
    return (histogram_quantile(np.bincount(outside, minlength=size), 50.0),
            histogram_quantile(np.bincount(volume[specimen], minlength=size),
                               muscovite_percentile))


def histogram_quantile(counts: npt.NDArray[np.integer], percentile: float) -> float:
    """The ``percentile`` of the integer values whose histogram is ``counts`` (value ``v``
    counted ``counts[v]`` times), interpolated linearly between ranks as
    :func:`numpy.percentile` does on the values themselves."""
    cumulative = np.cumsum(counts, dtype=np.int64)
    total = int(cumulative[-1])
    if total == 0:
        raise InputError("no value to take a percentile of")
    rank = percentile / 100.0 * (total - 1)
    below, above = int(np.floor(rank)), int(np.ceil(rank))
    low = float(np.searchsorted(cumulative, below, side="right"))
    high = float(np.searchsorted(cumulative, above, side="right"))
    return low + (rank - below) * (high - low)


def histogram_peaks(
    volume: npt.NDArray[np.unsignedinteger], n_peaks: int = 2
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The ``n_peaks`` most prominent peaks of a volume's grey histogram.

    The histogram of an evenly strided sample of at most 4 Mi voxels
    (:func:`imaging.ct.mask.grey_sample`, or that sample itself; sqrt(n)/2 bins, 16
    to 512, over the grey range) is smoothed by a Gaussian of one bin before the peaks
    are found (:func:`scipy.signal.find_peaks`, prominence ``PEAK_PROMINENCE``); a peak's
    grey is then refined by a mean shift over the voxels within two bins of it.

    Returns
    -------
    greys, prominences : ndarray
        The peaks' grey values in increasing order, and their prominence as a fraction of
        the highest bin.

    Raises
    ------
    ValueError
        If the histogram has fewer than ``n_peaks`` peaks (the message lists those found).
    """
    from scipy.ndimage import gaussian_filter1d
    from scipy.signal import find_peaks

    sample = grey_sample(volume)
    low, high = float(sample.min()), float(sample.max())
    if high <= low:
        raise InputError("the scan is uniform: its grey histogram has no two peaks")
    bins = int(np.clip(np.sqrt(sample.size) / 2.0, 16, _HISTOGRAM_BINS))
    counts, edges = np.histogram(sample, bins=bins, range=(low, high))
    smooth = gaussian_filter1d(counts.astype(np.float64), 1.0, mode="constant")
    padded = np.concatenate([[0.0], smooth, [0.0]])  # a peak may sit in an end bin
    found, props = find_peaks(padded, prominence=PEAK_PROMINENCE * smooth.max())
    found -= 1
    prominence = props["prominences"] / smooth.max()
    greys = 0.5 * (edges[found] + edges[found + 1])
    if found.size < n_peaks:
        listed = ", ".join(f"{g:.6g}" for g in greys) or "none"
        raise InputError(
            f"the grey histogram has {found.size} peak(s) ({listed}), not {n_peaks}"
        )
    best = np.sort(np.argsort(prominence)[::-1][:n_peaks])
    values = np.sort(sample.astype(np.float64))
    reach = 2.0 * (edges[1] - edges[0])
    refined = []
    for grey in greys[best]:
        for _ in range(5):  # mean shift with a flat window: to the mode of a symmetric peak
            window = values[np.searchsorted(values, grey - reach):
                            np.searchsorted(values, grey + reach, side="right")]
            grey = float(window.mean()) if window.size else grey
        refined.append(grey)
    return np.array(refined), prominence[best]


def anchors_through(
    greys: tuple[float, float],
    densities: tuple[float, float],
    air_density: float,
    muscovite_density: float,
) -> tuple[float, float]:
    """The air and muscovite greys of the grey-density line through two (grey, density)
    points [-]: the anchors of :class:`Calibration` equivalent to those two phases."""
    (g1, g2), (rho1, rho2) = greys, densities
    if not (g2 - g1) * (rho2 - rho1) > 0:
        raise InputError(
            f"the phases at greys {g1:.6g} and {g2:.6g} need increasing densities, got "
            f"{rho1:g} and {rho2:g} kg/m3"
        )
    slope = (g2 - g1) / (rho2 - rho1)
    return g1 + slope * (air_density - rho1), g1 + slope * (muscovite_density - rho1)


def grey_to_density(
    grey: npt.ArrayLike, calibration: Calibration
) -> npt.NDArray[np.floating]:
    """Map grey values to density [kg/m3] linearly through the air and muscovite anchors.

    Float32 input stays float32 (memory of large volumes); anything else gives float64.
    """
    grey = np.asarray(grey)
    dtype: type[np.floating] = np.float32 if grey.dtype == np.float32 else np.float64
    slope = (calibration.muscovite_density - calibration.air_density) / (
        calibration.grey_muscovite - calibration.grey_air
    )
    density: npt.NDArray[np.floating] = grey.astype(dtype, copy=True)
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
