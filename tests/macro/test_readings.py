"""macro.readings: what the model reports, the container's loads and the means of its state."""

from __future__ import annotations

import numpy as np
import pytest

from tests.macro._hand_placed import hand_placed_model, hertz_forces


def test_uniform_powder_push_reads_its_pressure_on_walls_and_plates(table_path):
    """With powder_pressure_on_walls, a powder pressing with the same P in every cell
    loads the container through the cells' triangles on it: the equal bands together read
    the pellets' Hertz forces over the wall's area plus P (within 1 %: the mesh's wall is
    a polyhedron inscribed in the cylinder), and each plate reads P times the area of the
    polygon of the mesh points on it over the plate's area pi R^2."""
    from scipy.spatial import ConvexHull

    config, model = hand_placed_model(table_path, powder_pressure_on_walls=True)
    push = 2.0e5
    cells = model.n_cells
    uniform = np.full(cells, push)
    model.push_field = lambda: lambda positions: (model.hydro_forces(uniform), uniform, np.zeros(model.n_pellets),
                                                   False)
    readings = model.relax(0)
    macro = config["macro"]
    radius, height = macro["cylinder_radius_m"], macro["cylinder_height_m"]
    hertz = hertz_forces(config).sum() / (2 * np.pi * radius * height)
    assert readings.bands.mean() - hertz == pytest.approx(push, rel=0.01)
    for plate, reading in ((0.5 * height, readings.axial_upper), (-0.5 * height, readings.axial_lower)):
        points = model.container[np.isclose(model.container[:, 2], plate, rtol=0, atol=1e-12)]
        polygon = ConvexHull(points[:, :2]).volume
        assert reading == pytest.approx(push * polygon / (np.pi * radius**2), rel=1e-9)


def test_a_new_models_means_and_invariants_are_its_initial_state(table_path):
    """The hand-placed pellets and the cells around them, new: the pellets are at the
    configured initial suction, the powder between it and the held ends' boundary
    suction; the pellets hold rho phi_p (4/3 pi r^3) S(s_0) each and the held cells
    rho S(s_b) of their pores, with Table 4.2's retention curve at its reference
    porosity written out here, S = [1 + (s / zeta)^(1 / (1 - lambda))]^(-lambda); and
    nothing has shrunk (only the held cells, wetter, have swollen)."""
    config, model = hand_placed_model(table_path)
    s0 = config["materials"]["mixture_pellet"]["initial_suction_pa"]
    pellets, powder = model.mean_suction()
    assert pellets == pytest.approx(s0, rel=1e-12)
    assert model.held.any() and model.settings.boundary_suction < powder < s0
    retention = config["materials"]["mixture_powder"]
    zeta, lam = retention["retention_pressure_reference_pa"], retention["retention_exponent_reference"]

    def saturation(suction):
        return (1.0 + (suction / zeta) ** (1.0 / (1.0 - lam))) ** -lam

    macro = config["macro"]
    density = macro["water_density_kg_m3"]
    pellet = density * macro["pellet_porosity"] * 4.0 / 3.0 * np.pi * macro["pellet_radius_m"] ** 3 * saturation(s0)
    invariants = model.invariants()
    assert invariants["water_pellets"] == pytest.approx(model.n_pellets * pellet, rel=1e-12, abs=0.0)
    pores = (model.volume - model.solid_volume)[model.held].sum()
    assert invariants["water_held"] == pytest.approx(
        density * saturation(macro["boundary_suction_pa"]) * pores, rel=1e-12, abs=0.0)
    half = 0.5 * macro["cylinder_height_m"]
    swelling, _ = model.profiles(np.linspace(-half, half, 6))
    assert (swelling[np.isfinite(swelling)] >= -1e-12).all()
