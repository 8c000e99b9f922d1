"""macro.model: the initial state MacroModel.create sets up, and the bookkeeping of a step
(the coupled behaviour: test_symmetry, test_single_pellet, test_run and the module tests)."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from macro.laws import saturation
from macro.run import build_model
from shared.upscaling import PermeabilityTable
from tests._macro_cases import small_config


def test_a_new_model_is_at_the_initial_suction_except_its_held_ends(model):
    """Held cells at the boundary suction, every other system at the initial suction with
    the retention law's water; pellets are spheres of their radii."""
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


def test_steps_add_up_to_the_models_time_and_honour_max_dt(model):
    dts = [model.step() for _ in range(3)]
    assert all(dt > 0.0 for dt in dts)
    assert model.steps == 3 and model.time == pytest.approx(sum(dts), rel=1e-15)
    short = 0.25 * min(dts)
    assert model.step(max_dt=short) <= short and model.steps == 4


def test_one_thread_and_two_give_the_same_column_to_the_bit(table_path):
    """The parallel kernels (the powder's push and its per-pellet gather, the local
    problems) write each element from its own inputs and sum in the mesh's order, so a job's
    thread count (``macro.threads``) cannot change its results: 6 steps of the small
    column on 1 thread and on 2 hold the same positions, pressures, radii and FIRE
    count."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one core: no second thread to compare with")
    runs = []
    before = numba.get_num_threads()
    try:
        for threads in (1, 2):
            numba.set_num_threads(threads)
            column = build_model(small_config(), "small", PermeabilityTable.from_file(table_path, "free"))
            for _ in range(6):
                column.step()
            runs.append((column.positions.copy(), column.pressure.copy(), column.radii.copy(),
                         column.counters.dem_substeps))
    finally:
        numba.set_num_threads(before)
    (x1, p1, r1, k1), (x2, p2, r2, k2) = runs
    assert k1 == k2 > 0
    np.testing.assert_array_equal(x1, x2)
    np.testing.assert_array_equal(p1, p2)
    np.testing.assert_array_equal(r1, r2)
