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

__all__ = ["WallBands", "named_sensors", "equal_bands"]

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
            (n,) height of each load's contact point above the lower plate [m].
        forces
            (n,) radial force of each load on the wall, outwards [N].
        radius
            Radius of the container [m].
        """
        lower, upper = np.asarray(self.lower)[:, None], np.asarray(self.upper)[:, None]
        inside = (heights >= lower) & (heights < upper)
        return (inside @ forces) / (self.area_share * 2.0 * np.pi * radius * self.widths)


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
            raise ValueError(
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
