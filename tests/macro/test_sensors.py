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


def test_height_fractions_split_a_triangle_by_area():
    """A triangle with vertex heights 0, 0.5 and 1 has half its area below 0.5 and an
    eighth below 0.25 (similar triangles: (1/4)^2 / (1 * 1/2)); a point load is all in or
    out."""
    from macro.sensors import height_fractions

    tri = np.array([[0.0, 1.0, 0.5]])
    np.testing.assert_allclose(height_fractions(tri, np.array([[0.25], [0.5], [1.0], [-1.0]]))[:, 0],
                               [0.125, 0.5, 1.0, 0.0], rtol=1e-12)
    point = np.array([[0.3, 0.3, 0.3]])
    np.testing.assert_array_equal(height_fractions(point, np.array([[0.2], [0.4]]))[:, 0], [0.0, 1.0])


def test_a_uniform_push_on_a_coarse_wall_reads_its_pressure_in_any_band():
    """A cylinder's wall triangulated in rings 12 mm apart (as coarse as the band), the
    inner rings' points jittered by up to 4 mm (seeded), under a uniform pressure: each
    triangle's radial force spread over the bands by its area reads the pressure wherever
    the band sits (within the chords' 1 % area deficit). Put at the centroids, the same
    forces read 0.90-1.08 of it (rows of triangles counted twice or not at all: what made
    SP80 read 1.5 times SP40 in the default run)."""
    from macro.sensors import WallBands

    rng = np.random.default_rng(1)
    radius, pressure, n_around = 0.03, 4e6, 16
    rings = np.arange(0.0, 0.121, 0.012)
    angle = 2.0 * np.pi * np.arange(n_around) / n_around
    z = rings[:, None] + np.zeros((rings.size, n_around))
    z[1:-1] += rng.uniform(-0.004, 0.004, (rings.size - 2, n_around))
    heights, forces = [], []
    for k in range(rings.size - 1):
        shift = 0.5 * (k % 2) * (angle[1] - angle[0])
        for a in range(n_around):
            b = (a + 1) % n_around
            low_a, low_b = (angle[a], z[k, a]), (angle[b], z[k, b])
            up_a, up_b = (angle[a] + shift, z[k + 1, a]), (angle[b] + shift, z[k + 1, b])
            for corners in ((low_a, low_b, up_a), (low_b, up_b, up_a)):
                xyz = np.array([[radius * np.cos(t), radius * np.sin(t), height] for t, height in corners])
                normal = np.cross(xyz[1] - xyz[0], xyz[2] - xyz[0])
                centre = xyz.mean(axis=0)
                radial = np.array([centre[0], centre[1], 0.0]) / np.hypot(centre[0], centre[1])
                forces.append(pressure * 0.5 * abs(normal @ radial))
                heights.append(xyz[:, 2])
    for middle in np.linspace(0.02, 0.1, 9):
        band = WallBands(("s",), (middle - 0.006,), (middle + 0.006,))
        assert band.pressures(np.array(heights), np.array(forces), radius)[0] == pytest.approx(pressure, rel=0.02)
