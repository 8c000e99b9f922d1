"""Transport: mass balance against boundary fluxes, the stable step of Eq. 4.58, the
implicit scheme against a dense solve and against the explicit one, conservative remesh."""

from __future__ import annotations

import numpy as np
import pytest

from macro.run import build_model
from macro.transport import implicit_pressures, limited_rates, mass_rates, stable_time_step
from shared.io import write_dataset
from shared.upscaling import PermeabilityTable
from tests._macro_cases import small_config, synthetic_table


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


def test_implicit_steps_change_water_only_by_the_boundary_inflow(model):
    """Whole model steps (implicit transport, local solves, DEM, remeshes): the water of
    the free systems changes exactly by the booked boundary inflow (1e-10 relative)."""
    assert model.settings.transport_scheme == "implicit"
    start = model.interior_water()
    for _ in range(8):
        model.step()
    assert model.boundary_inflow > 0.0
    assert model.interior_water() - start == pytest.approx(model.boundary_inflow, rel=1e-10)


def test_implicit_pressures_are_the_dense_backward_euler_solution(rng):
    """A random graph of 30 systems, 5 held: the sparse CHOLMOD solve equals
    (C/dt + L_FF) p' = C/dt p + G_FH p_H assembled densely here."""
    n = 30
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n) if rng.uniform() < 0.2])
    conductance = rng.uniform(1e-13, 1e-12, len(pairs))
    pressure = -rng.uniform(1e6, 1e8, n)
    capacity = rng.uniform(1e-12, 1e-10, n)
    free = np.ones(n, dtype=bool)
    free[:5] = False
    dt = 50.0
    laplacian = np.zeros((n, n))
    for (i, j), g in zip(pairs, conductance, strict=True):
        laplacian[i, i] += g
        laplacian[j, j] += g
        laplacian[i, j] -= g
        laplacian[j, i] -= g
    f, h = np.flatnonzero(free), np.flatnonzero(~free)
    matrix = np.diag(capacity[f] / dt) + laplacian[np.ix_(f, f)]
    rhs = capacity[f] / dt * pressure[f] - laplacian[np.ix_(f, h)] @ pressure[h]
    expected = np.linalg.solve(matrix, rhs)
    got = implicit_pressures(pairs, conductance, pressure, capacity, dt, free)
    np.testing.assert_allclose(got[f], expected, rtol=1e-10)
    np.testing.assert_array_equal(got[h], pressure[h])


def test_remesh_conserves_the_powder(model):
    """A forced remesh moves the powder's solid, water and the initial void into the new
    cells: totals conserved to round-off, the water crossing held cells booked as inflow."""
    for _ in range(3):
        model.step()
    cells = slice(model.n_pellets, None)
    active = ~model.inert[cells]
    solid = model.solid_volume[cells][active].sum()
    void = model.initial_void.sum()
    balance = model.interior_water() - model.boundary_inflow
    model.positions += rng_jitter(model)
    model._remesh()
    active = ~model.inert[cells]
    assert model.solid_volume[cells][active].sum() == pytest.approx(solid, rel=1e-12)
    assert model.initial_void.sum() == pytest.approx(void, rel=1e-12)
    assert model.interior_water() - model.boundary_inflow == pytest.approx(balance, rel=1e-12)
    assert model.remeshes >= 1


def rng_jitter(model):
    """A displacement of 5 % of a radius that changes the Delaunay connectivity."""
    return np.random.default_rng(3).normal(0.0, 0.05 * model.radii.mean(), model.positions.shape)


def test_explicit_and_implicit_schemes_agree(table_path):
    """The same column hydrated for 3000 s by Eq. 4.23 with Eq. 4.58's step (and a
    saturation change of at most 0.01 per step) and by the linearised implicit scheme with
    steps of 0.3 and 0.03, the mechanics held still (one DEM substep, no powder push, no
    confining stress: otherwise the runs remesh differently): the mean suction drops of pellets and powder
    agree within 5 %, the powder's closer with the smaller implicit steps."""
    table = PermeabilityTable.from_file(table_path, "free")
    drops = {}
    for scheme, change in (("explicit", 0.01), ("implicit", 0.3), ("implicit", 0.03)):
        config = small_config(powder_swelling_pressure=False)
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
    np.testing.assert_allclose(drops["implicit", 0.3], reference, rtol=0.05)
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
    k_i, _ = model._directional_permeabilities(k[model._exchanges.pairs[:, 0]], k[model._exchanges.pairs[:, 1]])
    tensor = model.table.tensor(-model.pressure[:n_p], "water")
    pairs = model._exchanges.pairs
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
    k_r, _ = random._directional_permeabilities(k[pairs[:, 0]], k[pairs[:, 1]])
    assert np.all(k_r[pellet] >= xx * (1 - 1e-9)) and np.all(k_r[pellet] <= zz * (1 + 1e-9))
    assert not np.allclose(k_r[pellet], expected, rtol=1e-3, atol=0.0)


def test_flux_limiter_keeps_water_and_conserves_it(rng):
    """A tiny wet system between large dry ones over a long step: its outflows are scaled so
    that it keeps 1 % of its water; the rates still sum to zero; systems that are not
    limited get exactly the unlimited rates of Eq. 4.22."""
    n = 6
    pairs = np.array([[0, 1], [0, 2], [0, 3], [3, 4], [4, 5]])
    conductance = rng.uniform(1e-13, 1e-12, len(pairs))
    pressure = np.array([-1e6, -1e8, -1e8, -5e7, -5e7, -5e7])
    water = np.array([1e-9, 1.0, 1.0, 1.0, 1.0, 1.0])
    free = np.ones(n, dtype=bool)
    dt = 1e4
    rate, limited = limited_rates(pairs, conductance, pressure, water, dt, free, 0.01)
    plain = mass_rates(pairs, conductance, pressure, n)
    assert limited == 1 and -dt * plain[0] > water[0]
    assert -dt * rate[0] == pytest.approx(0.99 * water[0], rel=1e-12)
    assert rate.sum() == pytest.approx(0.0, abs=1e-12 * np.abs(plain).max())
    np.testing.assert_allclose(rate[4:], plain[4:], rtol=1e-12)
