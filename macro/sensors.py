"""Radial pressure sensors on the container's curved wall.

The mock-up (thesis Sec. 4.8, Fig. 4.9) reads the radial swelling pressure at named
heights above the lower plate (SP20, SP40, SP80 at 20, 40 and 80 mm of the 120 mm
column; SP40 and SP80 are equidistant from the wetted ends). A sensor here is a band of
the curved wall centred on its height: it reads the radial forces whose contact point
lies in the band, divided by the band's wall area 2 pi R w. The Appendix .1 script's
``getPressure`` reads equal height bands instead (:func:`equal_bands`); it divides by
pi R w, half the band's area (``macro.sensor_area: script``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from shared.errors import ConfigError

__all__ = ["WallBands", "equal_bands", "height_fractions", "named_sensors"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class WallBands:
    """Height bands of the curved wall read as pressure sensors.

    Parameters
    ----------
    names
        One name per band.
    lower, upper
        Bottom and top of each band above the lower plate [m]; a load at height z is in
        a band when lower <= z < upper (bands may overlap).
    area_share
        The area a band's forces are divided by, as a share of its wall area 2 pi R w:
        1 (``macro.sensor_area: band``), or 0.5, the script's pi R w (``script``).
    """

    names: tuple[str, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    area_share: float = 1.0

    @property
    def heights(self) -> FloatArray:
        """Middle of each band above the lower plate [m]."""
        return 0.5 * (np.asarray(self.lower) + np.asarray(self.upper))

    @property
    def widths(self) -> FloatArray:
        """Height of each band [m]."""
        return np.asarray(self.upper) - np.asarray(self.lower)

    def pressures(self, heights: FloatArray, forces: FloatArray, radius: float) -> FloatArray:
        """Radial pressure read by each band [Pa].

        Parameters
        ----------
        heights
            (n,) height of each point load above the lower plate [m], or (n, 3) the
            heights of the vertices of each triangle a load is spread over (the powder's
            push on a hull triangle): its force is shared among the bands by the
            triangle's area in each (:func:`height_fractions`), not put at its centroid,
            so that bands about as high as the triangles read no rows twice.
        forces
            (n,) radial force of each load on the wall, outwards [N].
        radius
            Radius of the container [m].
        """
        heights = np.asarray(heights, dtype=np.float64)
        vertices = heights if heights.ndim == 2 else np.repeat(heights[:, None], 3, axis=1)
        lower, upper = np.asarray(self.lower)[:, None], np.asarray(self.upper)[:, None]
        inside = height_fractions(vertices, upper) - height_fractions(vertices, lower)
        return (inside @ forces) / (self.area_share * 2.0 * np.pi * radius * self.widths)


def height_fractions(vertices: FloatArray, level: FloatArray) -> FloatArray:
    """Fraction of each triangle's area below each ``level`` [1], (levels, n).

    A planar triangle's area is spread along any axis as a tent over its vertices'
    coordinates z_1 <= z_2 <= z_3: the fraction below h is (h - z_1)^2 / ((z_3 - z_1)
    (z_2 - z_1)) up to z_2 and 1 - (z_3 - h)^2 / ((z_3 - z_1) (z_3 - z_2)) above. A point
    (three equal heights) is below h when its height is (a step: z < h).

    Parameters
    ----------
    vertices
        (n, 3) heights of each triangle's vertices [m].
    level
        (levels, 1) heights [m].
    """
    z1, z2, z3 = np.sort(vertices, axis=1).T
    h = np.asarray(level, dtype=np.float64)
    span = z3 - z1
    with np.errstate(divide="ignore", invalid="ignore"):
        rising = (h - z1) ** 2 / (span * (z2 - z1))
        falling = 1.0 - (z3 - h) ** 2 / (span * (z3 - z2))
    fraction = np.where(h <= z1, 0.0, np.where(h >= z3, 1.0, np.where(h <= z2, rising, falling)))
    return np.where(span > 0.0, fraction, (h > z1).astype(np.float64))


def named_sensors(sensors: Mapping[str, Mapping[str, Any]], height: float, area_share: float = 1.0) -> WallBands:
    """The bands of ``macro.sensors`` (name -> {height_m, band_width_m}).

    Parameters
    ----------
    sensors
        The validated ``macro.sensors`` mapping; heights above the lower plate [m].
    height
        Height of the container [m].
    area_share
        :attr:`WallBands.area_share`.

    Raises
    ------
    ValueError
        Naming the key ``macro.sensors.<name>`` when its band reaches outside the
        container (it would read fewer contacts than its area assumes).
    """
    names, lower, upper = [], [], []
    for name, sensor in sensors.items():
        middle, half = float(sensor["height_m"]), 0.5 * float(sensor["band_width_m"])
        if middle - half < 0.0 or middle + half > height:
            raise ConfigError(
                f"macro.sensors.{name}: its band from {middle - half:.4g} to {middle + half:.4g} m "
                f"(height_m +- band_width_m / 2) reaches outside the container (0 to {height:.4g} m, "
                "macro.cylinder_height_m)")
        names.append(str(name))
        lower.append(middle - half)
        upper.append(middle + half)
    return WallBands(tuple(names), tuple(lower), tuple(upper), area_share)


def equal_bands(count: int, height: float, area_share: float = 1.0) -> WallBands:
    """``count`` equal bands covering the wall (Appendix .1 getPressure), named ``band k``
    from the bottom.

    Parameters
    ----------
    count
        Number of bands.
    height
        Height of the container [m].
    area_share
        :attr:`WallBands.area_share`.
    """
    edges = np.linspace(0.0, height, count + 1).tolist()
    return WallBands(tuple(f"band {k}" for k in range(count)), tuple(edges[:-1]), tuple(edges[1:]), area_share)
