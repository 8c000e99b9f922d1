"""macro.model: the initial state MacroModel.create sets up, and the bookkeeping of a step
(the coupled behaviour: test_symmetry, test_single_pellet, test_run and the module tests)."""

from __future__ import annotations

import numpy as np
import pytest

from macro.laws import saturation


def test_a_new_model_is_at_the_initial_suction_except_its_held_ends(model):
    """Held cells at the boundary suction, every other system at the initial suction with
    the retention law's water; pellets are spheres of their radii at rest."""
    s0, s_b = model.material.initial_suction, model.settings.boundary_suction
    held = model.held
    assert held.any() and not held[:model.n_pellets].any()
    np.testing.assert_array_equal(model.pressure[held], -s_b)
    np.testing.assert_array_equal(model.pressure[~held], -s0)
    porosity = np.full(model.volume.size, model.material.reference_porosity)
    assert not model.settings.retention_follows_porosity
    water = model.settings.density * saturation(s0, porosity, model.material) * (model.volume - model.solid_volume)
    np.testing.assert_allclose(model.water_mass[~held], water[~held], rtol=1e-12)
    np.testing.assert_allclose(model.volume[:model.n_pellets], 4.0 / 3.0 * np.pi * model.radii**3, rtol=1e-12)
    assert (model.time, model.steps) == (0.0, 0)
    assert not model.velocities.any()


def test_steps_add_up_to_the_models_time_and_honour_max_dt(model):
    dts = [model.step() for _ in range(3)]
    assert all(dt > 0.0 for dt in dts)
    assert model.steps == 3 and model.time == pytest.approx(sum(dts), rel=1e-15)
    short = 0.25 * min(dts)
    assert model.step(max_dt=short) <= short and model.steps == 4
