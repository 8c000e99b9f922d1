"""Hand-placed pellets pressing the wall of the small column, and their Hertz forces:
shared by the sensor and readings tests."""

from __future__ import annotations

import numpy as np

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


def hand_placed_model(table_path, **macro):
    """The pressing pellets, plus one on the axis touching nothing; no pellet touches
    another or a plate."""
    config = small_config(**macro)
    settings = macro_settings(config["macro"], "small")
    r, radius, height = settings.pellet_radius, settings.radius, settings.height
    positions = [[(radius - r + overlap) * np.cos(azimuth), (radius - r + overlap) * np.sin(azimuth),
                  z - 0.5 * height] for z, azimuth, overlap in PRESSING]
    positions.append([0.0, 0.0, 0.035 - 0.5 * height])
    positions = np.array(positions)
    return config, placed_model(table_path, config, positions)


def placed_model(table_path, config, positions):
    """The small column (``config``) with pellets at ``positions`` (n, 3) [m], none
    touching another."""
    settings = macro_settings(config["macro"], "small")
    r = settings.pellet_radius
    gaps = np.linalg.norm(positions[:, None] - positions[None], axis=-1) + np.eye(len(positions))
    assert gaps.min() > 2.0 * r
    packing = Packing(positions, np.full(len(positions), r), 0.1, 0.0)
    material = mixture_parameters(config["materials"], settings.powder)
    return MacroModel.create(settings, material, PermeabilityTable.from_file(table_path, "free"), packing)


def hertz_forces(config):
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
