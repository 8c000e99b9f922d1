"""macro.sensors: wall sensors, hand-placed pellets pressing the wall read as force over band area."""

from __future__ import annotations

import numpy as np
import pytest

from macro.settings import macro_settings
from tests._macro_cases import small_config
from tests.macro._hand_placed import hand_placed_model, hertz_forces


@pytest.mark.parametrize(("sensor_area", "share"), [("band", 1.0), ("script", 0.5)])
def test_hand_placed_pellets_give_hertz_force_over_band_area(table_path, sensor_area, share):
    """Each pellet pushes the wall with its Hertz force; a sensor reads the forces in its
    band over 2 pi R w (the script's pi R w with ``sensor_area: script``), a band without
    contact reads zero, and the equal bands together carry every force (the pellets'
    contacts alone: the powder's push on the walls off)."""
    config, model = hand_placed_model(table_path, sensor_area=sensor_area, powder_pressure_on_walls=False)
    force = hertz_forces(config)
    radius = config["macro"]["cylinder_radius_m"]
    band_area = share * 2 * np.pi * radius * 0.008
    readings = model.readings
    np.testing.assert_allclose(readings.sensors,
                               [(force[0] + force[1]) / band_area, force[2] / band_area, 0.0], rtol=1e-9)
    equal_area = share * 2 * np.pi * radius * 0.01
    np.testing.assert_allclose(readings.bands, [force[1] / equal_area, (force[0] + force[3]) / equal_area,
                                                force[2] / equal_area, 0.0, 0.0], rtol=1e-9)
    assert readings.axial_upper == 0.0 and readings.axial_lower == 0.0


def test_sensor_band_outside_the_container_is_named():
    """A band reaching above the lid (46 to 54 mm of a 50 mm column) or below the lower
    plate: refused, naming the sensor's key."""
    for name, height in (("SP50", 0.05), ("SP2", 0.002)):
        config = small_config(sensors={"S25": {"height_m": 0.025, "band_width_m": 0.008},
                                       name: {"height_m": height, "band_width_m": 0.008}})
        with pytest.raises(ValueError, match=rf"macro\.sensors\.{name}: .* reaches outside the container"):
            macro_settings(config["macro"], "small")
