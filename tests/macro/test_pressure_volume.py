"""macro.pressure_volume: the local problems solved by the Newton kernel hold each system's
water at the state the laws give (retention and confined swelling, macro.laws)."""

from __future__ import annotations

import dataclasses

import numpy as np

from macro.laws import saturation


def test_solved_systems_sit_on_the_retention_curve_and_the_swelling_volume(model):
    """Water added to every free system (a tenth of its pore space's remaining room): after
    the local solves no water is lost, every suction fell, each system's saturation is the
    retention law's at its solved suction, and each pellet's volume is the confined swelling
    volume there, below its cap. The Newton tolerance is tightened from the default 1e-3
    (Eq. 4.51) so that the comparison holds to 1e-7."""
    newton = dataclasses.replace(model.settings.newton, tolerance=1e-10, max_iterations=80)
    model.settings = dataclasses.replace(model.settings, newton=newton)
    free = ~model.held & ~model.inert
    before = -model.pressure.copy()
    room = model.settings.density * (model.volume - model.solid_volume) - model.water_mass
    model.water_mass[free] += 0.1 * room[free]
    water = model.water_mass.copy()
    model.solve_local()
    np.testing.assert_array_equal(model.water_mass, water)
    suction = -model.pressure
    assert (suction[free] < before[free]).all()
    law = saturation(suction, model.retention_porosity(), model.material)
    np.testing.assert_allclose(model.saturations()[free], law[free], rtol=1e-7)
    pellets = slice(None, model.n_pellets)
    assert free[pellets].all()
    assert (model.volume[pellets] < model.max_volume[pellets] * (1.0 - 1e-9)).all()
    np.testing.assert_allclose(model.volume[pellets], model.swelling_volume(suction)[pellets], rtol=1e-7)
