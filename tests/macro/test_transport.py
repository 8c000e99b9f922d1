"""Explicit transport: mass balance against boundary fluxes, the stable step of Eq. 4.58."""

from __future__ import annotations

import numpy as np
import pytest
from tests._macro_cases import small_config

from macro.run import build_model
from macro.transport import mass_rates, stable_time_step
from shared.upscaling import PermeabilityTable


@pytest.fixture
def model(table_path):
    config = small_config()
    table = PermeabilityTable.from_file(table_path, "free")
    return build_model(config, "small", table)


def test_water_changes_only_by_the_boundary_inflow(model):
    """Several explicit steps with their local solves: interior water gains exactly the
    water the held end cells gave (1e-10 relative)."""
    start = model.interior_water()
    inflow = 0.0
    for _ in range(6):
        conductance = model.conductances()
        dt = min(model.time_step(conductance), model.saturation_limited_step(conductance))
        rate = mass_rates(model._exchanges.pairs, conductance, model.pressure, model.volume.size)
        inflow -= dt * rate[model.held].sum()  # what the held systems lose
        model.transport(dt, conductance)
        model.solve_local()
    gained = model.interior_water() - start
    assert inflow > 0.0
    assert gained == pytest.approx(inflow, rel=1e-10)
    assert model.boundary_inflow == pytest.approx(inflow, rel=1e-12)


def test_stable_step_of_eq_4_58_by_hand():
    """Three systems in a chain, G = 1e-12 and 3e-12 kg/(Pa s): alpha_i = sum G / (rho n V)."""
    pairs = np.array([[0, 1], [1, 2]])
    conductance = np.array([1e-12, 3e-12])
    pore = np.array([2e-9, 1e-9, 4e-9])
    slope = np.array([1e8, 5e7, 2e8])
    held = np.array([False, False, True])
    # system 0: 1e-12 / (1000 * 2e-9) * 1e8 = 50; system 1: 4e-12 / (1000 * 1e-9) * 5e7 = 200
    dt = stable_time_step(pairs, conductance, pore, slope, held, 1000.0, 0.6)
    assert dt == pytest.approx(0.6 * 2.0 / 200.0, rel=1e-12)


def test_model_step_respects_eq_4_58(model):
    """The model's step is at most chi 2 / (alpha_i |dp/dS|_i) for every free system,
    with |dp/dS| from the closed-form derivative of Table 4.2's retention written here."""
    conductance = model.conductances()
    dt = model.time_step(conductance)
    n = model.volume.size
    pairs = model._exchanges.pairs
    total = np.bincount(pairs[:, 0], conductance, minlength=n) + np.bincount(pairs[:, 1], conductance, minlength=n)
    pore = model.volume - model.solid_volume
    sat = model.water_mass / (1000.0 * pore)
    powder = model.material
    shift = powder.reference_porosity - (1.0 - model.solid_volume / model.volume)
    zeta = powder.zeta0 * np.exp(powder.retention_a * shift)
    lam = powder.lambda0 * np.exp(powder.retention_b * shift)
    slope = zeta * (1 - lam) / lam * (sat ** (-1 / lam) - 1) ** (-lam) * sat ** (-1 / lam - 1)
    free = ~model.held & ~model.inert
    with np.errstate(divide="ignore"):
        bound = 0.6 * 2.0 / (total / (1000.0 * pore) * slope)
    assert dt <= bound[free].min() * (1 + 1e-9)
    assert dt > 0.0
