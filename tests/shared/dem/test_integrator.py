"""Leapfrog with Cundall damping: energy, Hertz collision time, rest, stability bound."""

from dataclasses import replace

import numpy as np
import pytest

from shared.dem import (
    contacts_need_update,
    cube_points,
    limit_speed,
    new_state,
    stable_time_step,
    step,
)
from tests._defaults import DEM

# Hertz contacts alone: the chain tests are about the contact stiffness
UNDAMPED = replace(DEM, damping=0.0, bond_tensile_strength=0.0)
RADIUS = 1e-3
E_STAR = 100e8 / (2.0 * (1.0 - 0.3**2))


def kinetic_energy(state):
    """Kinetic energy sum 1/2 (m |v|^2 + I |omega|^2) [J] (half-step rates)."""
    translation = (state.masses * (state.velocities**2).sum(axis=1)).sum()
    rotation = (state.inertia * (state.spins**2).sum(axis=1)).sum()
    return float(0.5 * (translation + rotation))


def _collision(time_step):
    positions = np.array([[0.0, 0, 0], [2.02 * RADIUS, 0, 0]])
    state = new_state(positions, np.full(2, RADIUS), DEM, skin_fraction=0.05)
    state.velocities[:, 0] = [0.1, -0.1]
    energy_before = kinetic_energy(state)
    steps_in_contact = 0
    for _ in range(5000):
        report = step(state, time_step, UNDAMPED)
        steps_in_contact += bool(report.normal_forces.size and report.normal_forces[0] > 0.0)
        if state.positions[1, 0] - state.positions[0, 0] > 2.05 * RADIUS:
            break
    return state, energy_before, steps_in_contact


def test_undamped_collision_conserves_energy_and_lasts_hertz_time():
    state, energy_before, steps_in_contact = _collision(5e-8)
    # leapfrog leaves an O(dt^2) energy error: 7e-7 at 360 steps per impact
    assert kinetic_energy(state) == pytest.approx(energy_before, rel=1e-5)
    np.testing.assert_allclose(state.velocities[:, 0], [-0.1, 0.1], rtol=1e-5)
    # Hertz impact duration 2.868 (m*^2 / (R* E*^2 v))^(1/5) (Johnson, Contact Mechanics)
    mass = 2600.0 * 4.0 / 3.0 * np.pi * RADIUS**3
    duration = 2.868 * ((mass / 2) ** 2 / (RADIUS / 2 * E_STAR**2 * 0.2)) ** 0.2
    # counting whole steps resolves the 18 us impact to 0.3 %
    assert steps_in_contact * 5e-8 == pytest.approx(duration, rel=0.01)


def _chain(n_free, overlap):
    """Free points between two fixed ones, every contact at the same overlap."""
    spacing = 2.0 * RADIUS - overlap
    positions = np.c_[np.arange(n_free + 2) * spacing, np.zeros(n_free + 2), np.zeros(n_free + 2)]
    state = new_state(positions, np.full(n_free + 2, RADIUS), DEM)
    state.fixed[[0, -1]] = True
    return state


def test_damped_chain_comes_to_rest_at_uniform_overlap():
    state = _chain(5, 1e-5)
    state.positions[1:-1, 0] += np.random.default_rng(0).uniform(-2e-6, 2e-6, 5)
    time_step = stable_time_step(state, DEM)
    for _ in range(3000):
        report = step(state, time_step, DEM)
    assert kinetic_energy(state) < 1e-20
    gaps = np.diff(state.positions[:, 0])
    # equilibrium of equal springs in series: the total compression is shared evenly
    np.testing.assert_allclose(gaps, 2.0 * RADIUS - 1e-5, rtol=1e-9)
    assert np.abs(report.forces[1:-1]).max() < 1e-9 * report.normal_forces.max()


@pytest.mark.parametrize("factor, bound", [(1.0, 2.0), (2.0, None)])
def test_stable_time_step_bounds_chain_oscillations(factor, bound):
    """The bound keeps a compressed chain's energy bounded; twice the bound blows it up.

    Axial waves of 5 free points between fixed ends go unstable above
    2 / omega_max = sqrt(m / k) / sin(5 pi / 12); the bound, which also covers the
    spins, sits 1.89 times below (so leapfrog's half-step kinetic energy overshoots by
    at most 1 / (1 - (omega dt / 2)^2) = 1.4 at the bound).
    """
    state = _chain(5, 1e-5)
    state.velocities[1:-1, 0] = np.random.default_rng(1).uniform(-1e-4, 1e-4, 5)
    time_step = factor * stable_time_step(state, UNDAMPED, safety=1.0)
    energy = kinetic_energy(state)
    peak = energy
    for _ in range(2000):
        step(state, time_step, UNDAMPED)
        peak = max(peak, kinetic_energy(state))
    if bound is None:
        assert not peak < 1e4 * energy
    else:
        assert peak < bound * energy


def test_oscillation_period_between_two_fixed_points():
    """Small axial oscillation: T = 2 pi sqrt(m / (2 k)), k = 2 E* sqrt(R* delta_0)."""
    overlap = 1e-5
    state = _chain(1, overlap)
    state.velocities[1, 0] = 1e-5  # amplitude about 2e-8 m, 0.2 % of the overlap
    time_step = 0.02 * stable_time_step(state, UNDAMPED, safety=1.0)
    crossings = []
    start = state.positions[1, 0]
    previous = 0.0
    n = 0
    while len(crossings) < 6 and n < 20000:  # five whole periods (about 400 steps each)
        n += 1
        step(state, time_step, UNDAMPED)
        offset = state.positions[1, 0] - start
        if previous < 0.0 <= offset:
            crossings.append(n - offset / (offset - previous))
        previous = offset
    stiffness = 2.0 * E_STAR * np.sqrt(RADIUS / 2 * overlap)
    mass = 2600.0 * 4.0 / 3.0 * np.pi * RADIUS**3
    period = 2.0 * np.pi * np.sqrt(mass / (2.0 * stiffness))
    measured = np.diff(crossings).mean() * time_step
    assert len(crossings) == 6
    assert measured == pytest.approx(period, rel=1e-3)


def test_same_start_same_trajectory():
    """Serial kernels sum in a fixed order: two runs agree bit for bit."""
    runs = []
    for _ in range(2):
        positions, radii = cube_points(216, np.random.default_rng(9), jitter=0.2,
                                       radius_factor=1.02, edge_length=1e-3)
        state = new_state(positions, radii, DEM)
        for _ in range(200):
            step(state, min(0.5 * stable_time_step(state, DEM), 1e-8), DEM)
        runs.append(np.concatenate([state.positions, state.velocities, state.spins]))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_limit_speed_caps_only_the_fast_points_and_keeps_their_direction(
    rng: np.random.Generator,
) -> None:
    positions, radii = cube_points(64, rng)
    state = new_state(positions, radii, DEM)
    state.velocities[:] = rng.normal(0.0, 1.0, state.velocities.shape)
    before = state.velocities.copy()
    speed = np.linalg.norm(before, axis=1)
    limit = float(np.median(speed))
    limit_speed(state, limit)
    after = np.linalg.norm(state.velocities, axis=1)
    fast = speed > limit
    np.testing.assert_allclose(after[fast], limit, rtol=1e-14)
    np.testing.assert_array_equal(state.velocities[~fast], before[~fast])
    np.testing.assert_allclose(state.velocities[fast] / after[fast, None],
                               before[fast] / speed[fast, None], rtol=1e-14)


def test_contacts_need_update_once_a_point_has_moved_half_the_skin(
    rng: np.random.Generator,
) -> None:
    positions, radii = cube_points(64, rng)
    state = new_state(positions, radii, DEM)
    skin = state.contacts.skin
    # a pair's gap closes by at most twice the largest displacement
    state.positions[7] += np.array([0.3, 0.4, 0.0]) / 0.5 * 0.49 * skin
    assert not contacts_need_update(state)
    state.positions[7] += np.array([0.3, 0.4, 0.0]) / 0.5 * 0.02 * skin
    assert contacts_need_update(state)


def test_bond_rates_are_the_row_sums_of_the_intact_bond_springs():
    """Row sums of M^-1/2 K M^-1/2 for springs k = E* (r_i + r_j) / 2 on the intact
    bonds, summed here by numpy's bincount, bit for bit."""
    from shared.dem.integrator import _bond_rates

    rng = np.random.default_rng(3)
    positions, radii = cube_points(300, rng, jitter=0.2)
    state = new_state(positions, radii * rng.uniform(0.9, 1.1, radii.size), DEM)
    state.bond_broken[rng.random(state.bonds.shape[0]) < 0.3] = True
    intact = state.bonds[~state.bond_broken]
    stiffness = DEM.effective_modulus * 0.5 * state.radii[intact].sum(axis=1)
    root = np.sqrt(state.masses[intact])
    coupling = stiffness * (1.0 / root[:, 0] + 1.0 / root[:, 1])
    expected = np.bincount(intact.ravel(), (coupling[:, None] / root).ravel(),
                           minlength=state.n_points)
    assert DEM.bond_tensile_strength > 0.0 and np.count_nonzero(expected) > 200
    np.testing.assert_array_equal(_bond_rates(state, DEM), expected)
    assert not np.any(_bond_rates(state, replace(DEM, bond_tensile_strength=0.0)))
