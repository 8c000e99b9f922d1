"""One pellet alone in the container, through the whole macro model (mesh, transport,
pressure-volume problem, DEM against the container).

In a box smaller than its free swelling (1.06 radii, where the container must press more
than the onset of confinement), the pellet hydrated to the boundary suction
presses on the container with the confined swelling pressure of its final dry density
(Eq. 4.31 times its saturation, docs/macro.md), and the container's readings carry that
stress; in a box larger than its free swelling it reaches Eq. 4.28's strain and touches
nothing.
"""

from __future__ import annotations

import numpy as np
import pytest

from macro.laws import case_materials, mixture_parameters, saturation, swelling_strain
from macro.model import MacroModel
from macro.packing import Packing
from macro.settings import macro_settings
from shared.upscaling import PermeabilityTable
from tests._macro_cases import small_config, write_table

PELLET_RADIUS = 4e-3
STEPS = 100


def _hydrated(tmp_path, box: float) -> MacroModel:
    """The pellet at the container's centre, hydrated for STEPS steps (the boundary suction
    is reached in about 50); ``box``: the container's radius and half-height over the
    pellet's radius. The powder does not push (the pellet alone meets the container)."""
    radius = box * PELLET_RADIUS
    fraction = PELLET_RADIUS**3 / (1.5 * radius**3)
    config = small_config(pellet_permeability="scalar", powder_swelling_pressure=False, homogenisation="none",
                          cylinder_radius_m=radius, cylinder_height_m=2.0 * radius,
                          cases={"one": {}}, sensors={"wall": {"height_m": radius, "band_width_m": radius}})
    config["macro"]["powder"]["heterogeneity"] = "homogeneous"
    config["macro"]["mixture"] = {"dry_density_kg_m3": 1300.0, "pellet_powder_dry_mass_ratio": None,
                                  "packing_fraction": fraction}
    settings = macro_settings(config["macro"], "one")
    material = mixture_parameters(case_materials(config["materials"], {}), settings.powder)
    table = PermeabilityTable.from_file(write_table(tmp_path / "k.nc"), "free")
    model = MacroModel.create(settings, material, table,
                              Packing(np.zeros((1, 3)), np.array([PELLET_RADIUS]), fraction, 0.0))
    for _ in range(STEPS):
        model.step()
    return model


def test_confined_pellet_presses_with_the_swelling_pressure_of_its_dry_density(tmp_path):
    model = _hydrated(tmp_path, 1.06)
    s, m = model.settings, model.material
    suction = -model.pressure[0]
    assert suction == pytest.approx(s.boundary_suction, rel=5e-3)
    free = model.reference_volume[0] * (1.0 + swelling_strain(suction, m))
    volume = model.volume[0]
    assert volume < 0.99 * free
    # Eq. 4.31 at the pellet's final dry density, times its saturation (Eq. 4.33), by hand
    dry_density = model.solid_mass()[0] / volume
    law = float(saturation(suction, m.reference_porosity, m)) * 178.0 * np.exp(6.75e-3 * dry_density)
    assert law > 1e5
    assert model.stress[0] == pytest.approx(law, rel=0.05)
    # the container's readings: both plates and the curved wall (one band over the
    # pellet's equator) carry the stress over the pellet's surface
    readings = model.readings
    plates = (readings.axial_upper + readings.axial_lower) * np.pi * s.radius**2
    wall = readings.sensors[0] * 2.0 * np.pi * s.radius * s.radius
    assert readings.axial_upper == pytest.approx(readings.axial_lower, rel=1e-6)
    assert (plates + wall) / (4.0 * np.pi * model.radii[0] ** 2) == pytest.approx(law, rel=0.05)


def test_free_pellet_reaches_eq_4_28(tmp_path):
    model = _hydrated(tmp_path, 1.4)
    suction = -model.pressure[0]
    assert suction == pytest.approx(model.settings.boundary_suction, rel=1e-2)
    strain = model.volume[0] / model.reference_volume[0] - 1.0
    assert strain == pytest.approx(float(swelling_strain(suction, model.material)), rel=0.01)
    readings = model.readings
    assert readings.sensors[0] == 0.0 and readings.axial_upper == 0.0 and readings.axial_lower == 0.0
