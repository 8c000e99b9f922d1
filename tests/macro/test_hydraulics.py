"""macro.hydraulics: the model's water transport, explicit (Eq. 4.23 with the step of
Eq. 4.58) and implicit, changes the interior water only by the boundary inflow; both
schemes agree; a pellet's tensor permeability is read along the exchange."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import macro.hydraulics
from macro.run import build_model
from macro.transport import limited_rates, mass_rates
from shared.io import write_dataset
from shared.upscaling import PermeabilityTable
from tests._macro_cases import small_config, synthetic_table


def test_water_changes_only_by_the_boundary_inflow(model):
    """Several explicit steps with their local solves: interior water gains exactly the
    water the held end cells gave (1e-10 relative)."""
    start = model.interior_water()
    inflow = 0.0
    for _ in range(6):
        conductance = model.conductances()
        dt = min(model.time_step(conductance), model.saturation_limited_step(conductance))
        rate = mass_rates(model.cells.exchanges.pairs, conductance, model.pressure, model.volume.size)
        inflow -= dt * rate[model.held].sum()  # what the held systems lose
        model.transport(dt, conductance)
        model.solve_local()
    gained = model.interior_water() - start
    assert inflow > 0.0
    assert gained == pytest.approx(inflow, rel=1e-10, abs=0.0)
    assert model.boundary_inflow == pytest.approx(inflow, rel=1e-12, abs=0.0)


def test_model_step_respects_eq_4_58(model):
    """The model's step is at most chi 2 / (alpha_i |dp/dS|_i) for every free system,
    with |dp/dS| from the closed-form derivative of Table 4.2's retention written here."""
    conductance = model.conductances()
    dt = model.time_step(conductance)
    n = model.volume.size
    pairs = model.cells.exchanges.pairs
    total = np.bincount(pairs[:, 0], conductance, minlength=n) + np.bincount(pairs[:, 1], conductance, minlength=n)
    pore = model.volume - model.solid_volume
    sat = model.water_mass / (1000.0 * pore)
    powder = model.material
    shift = powder.reference_porosity - (1.0 - model.solid_volume / model.volume)
    zeta = powder.retention_pressure_reference * np.exp(powder.retention_pressure_porosity_factor * shift)
    lam = powder.retention_exponent_reference * np.exp(powder.retention_exponent_porosity_factor * shift)
    slope = zeta * (1 - lam) / lam * (sat ** (-1 / lam) - 1) ** (-lam) * sat ** (-1 / lam - 1)
    free = ~model.held & ~model.inert
    with np.errstate(divide="ignore"):
        bound = 0.6 * 2.0 / (total / (1000.0 * pore) * slope)
    assert dt <= bound[free].min() * (1 + 1e-9)
    assert dt > 0.0


def test_implicit_steps_change_water_only_by_the_boundary_inflow(model):
    """Whole model steps (implicit transport, local solves, DEM, remeshes): the water of
    the free systems changes exactly by the booked boundary inflow (1e-10 relative)."""
    assert model.settings.transport_scheme == "implicit"
    start = model.interior_water()
    for _ in range(8):
        model.step()
    assert model.boundary_inflow > 0.0
    assert model.interior_water() - start == pytest.approx(model.boundary_inflow, rel=1e-10, abs=0.0)


def test_closed_column_keeps_the_water_of_its_systems(model):
    """Hydrated for four steps, then closed (no held cells): over eight more whole steps
    the water summed over every pellet and cell is unchanged (1e-12 relative), while the
    cells that were held lose a share of theirs to the drier interior (more than 1 %)."""
    for _ in range(4):
        model.step()
    was_held = model.held.copy()
    model.held[:] = False
    total, given = model.water_mass.sum(), model.water_mass[was_held].sum()
    remeshes, inflow = model.counters.remeshes, model.boundary_inflow
    for _ in range(8):
        model.step()
    assert model.counters.remeshes == remeshes  # a remesh would hold the end cells again
    assert model.water_mass.sum() == pytest.approx(total, rel=1e-12, abs=0.0)
    assert model.water_mass[was_held].sum() < 0.99 * given
    assert model.boundary_inflow == inflow


def test_interior_gains_the_water_crossing_from_the_held_cells(model, monkeypatch):
    """Eight whole steps: the free systems' water gain (their states' sum) equals the
    water that crossed the exchanges between a held and a free system, sum over those
    exchanges of dt G (p_held - p_free) at each accepted step's conductances and end-of-step
    pressures (1e-10 relative). Every such exchange carries water into the free system,
    so the flux limiter, which scales a flux by the factor of the system it leaves (never
    a held one), leaves them as they are; no remesh booked water."""
    accepted = []

    def spy(pairs, conductance, pressure, water, dt, free, keep):
        accepted.append((pairs, conductance, pressure, dt))
        return limited_rates(pairs, conductance, pressure, water, dt, free, keep)

    monkeypatch.setattr(macro.hydraulics, "limited_rates", spy)
    # water only: no clay (and the water it carries) extruded across the held cells
    model.settings = dataclasses.replace(model.settings, extrusion=dataclasses.replace(
        model.settings.extrusion, enabled=False))
    start = model.water_mass[~model.held].sum()
    crossed = 0.0
    for _ in range(8):
        accepted.clear()
        model.step()
        pairs, conductance, pressure, dt = accepted[-1]
        ends = model.held[pairs]
        across = ends[:, 0] != ends[:, 1]
        held = np.where(ends[:, 0], pairs[:, 0], pairs[:, 1])[across]
        free = np.where(ends[:, 0], pairs[:, 1], pairs[:, 0])[across]
        assert np.all(pressure[held] >= pressure[free])
        crossed += dt * float(np.sum(conductance[across] * (pressure[held] - pressure[free])))
    assert model.counters.remeshes == 0
    assert crossed > 0.0
    assert model.water_mass[~model.held].sum() - start == pytest.approx(crossed, rel=1e-10, abs=0.0)


def test_explicit_and_implicit_schemes_agree(table_path):
    """The same column hydrated for 3000 s by Eq. 4.23 with Eq. 4.58's step (and a
    saturation change of at most 0.01 per step) and by the linearised implicit scheme with
    steps of 0.3 and 0.03, the mechanics held still (one DEM substep, no powder push, no
    confining stress, no extrusion: otherwise the runs remesh differently): the mean suction
    drops of pellets and powder agree within 6 % (steps of 0.3) and 5 % (0.03), the powder's
    closer with the smaller implicit steps. (The pellets' drop with steps of 0.3 is 4.7 % below
    the explicit one with the damped relaxation, which moved the pellets by up to 4.6 % of a
    radius here, 5.1 % with FIRE's single step from rest per coupled step, which moves them by 0.2 %.)"""
    table = PermeabilityTable.from_file(table_path, "free")
    drops = {}
    for scheme, change in (("explicit", 0.01), ("implicit", 0.3), ("implicit", 0.03)):
        config = small_config(powder_swelling_pressure=False, homogenisation="none")
        # the pellets' confining stress follows the contacts step by step: held at zero, so
        # that the schemes' different step counts do not change the mechanics
        config["macro"]["numerics"].update(transport_scheme=scheme, max_saturation_change=change,
                                           dem_substeps=1, stress_relaxation=1e-12)
        model = build_model(config, "small", table)
        while model.time < 3000.0:
            model.step(max_dt=3000.0 - model.time)
        drops[scheme, change] = model.material.initial_suction - np.array(model.mean_suction())
    reference = drops["explicit", 0.01]
    assert reference.min() > 1e6  # both did hydrate
    np.testing.assert_allclose(drops["implicit", 0.3], reference, rtol=0.06)
    np.testing.assert_allclose(drops["implicit", 0.03], reference, rtol=0.05)
    assert abs(drops["implicit", 0.03][1] - reference[1]) < abs(drops["implicit", 0.3][1] - reference[1])


def test_tensor_permeability_is_read_along_the_exchange(tmp_path):
    """A table whose tensor is 10x larger along the compaction axis z: with every pellet's
    frame the identity, an exchange along z reads k_zz and one along x reads k_xx, and
    d^T K d in general; with random frames the reading changes but stays between them."""
    table = synthetic_table()
    table["k_tensor"].values[..., 2, 2] *= 10.0
    path = tmp_path / "aniso.nc"
    write_dataset(table, path, stage="upscaling", title="anisotropic synthetic table")
    config = small_config()
    config["macro"]["pellet_permeability"] = "tensor"
    model = build_model(config, "small", PermeabilityTable.from_file(path, "free"))
    n_p = model.n_pellets
    model.pellet_frames = np.broadcast_to(np.eye(3), (n_p, 3, 3)).copy()
    k = model.permeabilities()
    pairs = model.cells.exchanges.pairs
    k_i, _ = model.directional_permeabilities(k[pairs[:, 0]], k[pairs[:, 1]])
    tensor = model.table.tensor(-model.pressure[:n_p], "water")
    centres = np.concatenate([model.positions, model.mesh.centroids])
    d = centres[pairs[:, 1]] - centres[pairs[:, 0]]
    d /= np.linalg.norm(d, axis=1)[:, None]
    pellet = pairs[:, 0] < n_p
    xx, zz = tensor[pairs[pellet, 0], 0, 0], tensor[pairs[pellet, 0], 2, 2]
    expected = xx * (d[pellet, 0] ** 2 + d[pellet, 1] ** 2) + zz * d[pellet, 2] ** 2
    np.testing.assert_allclose(k_i[pellet], expected, rtol=1e-10)
    np.testing.assert_allclose(zz / xx, 10.0, rtol=1e-6)
    model.pellet_frames = None
    random = build_model(config, "small", PermeabilityTable.from_file(path, "free"))
    k_r, _ = random.directional_permeabilities(k[pairs[:, 0]], k[pairs[:, 1]])
    assert np.all(k_r[pellet] >= xx * (1 - 1e-9)) and np.all(k_r[pellet] <= zz * (1 + 1e-9))
    assert not np.allclose(k_r[pellet], expected, rtol=1e-3, atol=0.0)
