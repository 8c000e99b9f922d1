"""Wall sensors: hand-placed pellets pressing the wall read as force over band area."""

from __future__ import annotations

import numpy as np
import pytest

from macro.laws import mixture_parameters
from macro.model import MacroModel
from macro.packing import Packing
from macro.settings import macro_settings
from shared.upscaling import PermeabilityTable
from tests._macro_cases import small_config

# (height above the lower plate [m], azimuth [rad], overlap with the wall [m]); the small
# column's sensors S10, S25, S40 read the bands [6, 14), [21, 29), [36, 44) mm and its five
# equal bands are 10 mm high
PRESSING = [(0.0105, 0.0, 1.0e-5), (0.0075, np.pi, 2.0e-5), (0.0255, 0.5 * np.pi, 3.0e-5),
            (0.0185, 1.5 * np.pi, 1.5e-5)]


def _hand_placed_model(table_path, **macro):
    """The pressing pellets, plus one on the axis touching nothing; no pellet touches
    another or a plate."""
    config = small_config(**macro)
    settings = macro_settings(config["macro"], "small")
    r, radius, height = settings.pellet_radius, settings.radius, settings.height
    positions = [[(radius - r + overlap) * np.cos(azimuth), (radius - r + overlap) * np.sin(azimuth),
                  z - 0.5 * height] for z, azimuth, overlap in PRESSING]
    positions.append([0.0, 0.0, 0.035 - 0.5 * height])
    positions = np.array(positions)
    gaps = np.linalg.norm(positions[:, None] - positions[None], axis=-1) + np.eye(len(positions))
    assert gaps.min() > 2.0 * r
    packing = Packing(positions, np.full(len(positions), r), 0.1, 0.0)
    material = mixture_parameters(config["materials"], settings.powder)
    model = MacroModel.create(settings, material, PermeabilityTable.from_file(table_path, "free"), packing)
    return config, model


def _hertz_forces(config):
    """(pressing pellets,) force of each on the wall [N]: a sphere on a plane, written out
    (F = 4/3 E / (1 - nu^2) sqrt(r) delta^(3/2), E = 3 (1 - 2 nu) exp(alpha s0) / beta
    within its bounds), below the yield force."""
    pellet = config["materials"]["mixture_pellet"]
    nu, alpha, beta = pellet["poisson_ratio"], pellet["swelling_alpha_per_pa"], pellet["swelling_beta_per_pa"]
    s0 = pellet["initial_suction_pa"]
    young = np.clip(3 * (1 - 2 * nu) * np.exp(alpha * s0) / beta, *pellet["young_modulus_bounds_pa"])
    r = config["macro"]["pellet_radius_m"]
    force = np.array([4 / 3 * young / (1 - nu**2) * np.sqrt(r) * overlap**1.5 for _, _, overlap in PRESSING])
    assert force.max() < 3 * (1 - 2 * nu) * pellet["yield_area_m2"] * np.exp(alpha * s0) / beta
    return force


def test_hand_placed_pellets_give_hertz_force_over_band_area(table_path):
    """Each pellet pushes the wall with its Hertz force; a sensor reads the forces in its
    band over 2 pi R w, a band without contact reads zero, and the equal bands together
    carry every force."""
    config, model = _hand_placed_model(table_path)
    force = _hertz_forces(config)
    radius = config["macro"]["cylinder_radius_m"]
    band_area = 2 * np.pi * radius * 0.008
    readings = model.readings
    np.testing.assert_allclose(readings.sensors,
                               [(force[0] + force[1]) / band_area, force[2] / band_area, 0.0], rtol=1e-9)
    equal_area = 2 * np.pi * radius * 0.01
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


def test_uniform_powder_push_reads_its_pressure_on_walls_and_plates(table_path):
    """With powder_pressure_on_walls, a powder pressing with the same P in every cell
    loads the container through the cells' triangles on it: the equal bands together read
    the pellets' Hertz forces over the wall's area plus P (within 1 %: the mesh's wall is
    a polyhedron inscribed in the cylinder), and each plate reads P times the area of the
    polygon of the mesh points on it over the plate's area pi R^2."""
    from scipy.spatial import ConvexHull

    config, model = _hand_placed_model(table_path, powder_pressure_on_walls=True)
    push = 2.0e5
    cells = model.n_cells
    model.powder_pressure = lambda: (np.full(cells, push), np.zeros(cells))
    readings = model.relax(0)
    macro = config["macro"]
    radius, height = macro["cylinder_radius_m"], macro["cylinder_height_m"]
    hertz = _hertz_forces(config).sum() / (2 * np.pi * radius * height)
    assert readings.bands.mean() - hertz == pytest.approx(push, rel=0.01)
    for plate, reading in ((0.5 * height, readings.axial_upper), (-0.5 * height, readings.axial_lower)):
        points = model.container[np.isclose(model.container[:, 2], plate, rtol=0, atol=1e-12)]
        polygon = ConvexHull(points[:, :2]).volume
        assert reading == pytest.approx(push * polygon / (np.pi * radius**2), rel=1e-9)
