"""Hertz-Mindlin forces of two spheres against the closed-form laws."""

import dataclasses

import numpy as np
import pytest

from shared.dem import bond_tension, contact_forces, new_state
from tests._defaults import DEM

E_STAR = 100e8 / (2.0 * (1.0 - 0.3**2))  # two identical points, Table 3.1 E and nu
G = 100e8 / (2.0 * 1.3)


def _pair(radius_a, radius_b, overlap):
    positions = np.array([[0.0, 0.0, 0.0], [radius_a + radius_b - overlap, 0.0, 0.0]])
    return new_state(positions, np.array([radius_a, radius_b]), DEM)


@pytest.mark.parametrize("overlap", [1e-7, 3e-6, 2e-5])
def test_normal_force_is_hertz(overlap):
    state = _pair(1e-4, 2.5e-4, overlap)
    forces, _, normal = contact_forces(state, 1e-9, DEM)
    r_eff = 1e-4 * 2.5e-4 / 3.5e-4
    expected = 4.0 / 3.0 * E_STAR * np.sqrt(r_eff) * overlap**1.5
    assert normal[0] == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(forces[1], [expected, 0.0, 0.0], rtol=1e-12)
    np.testing.assert_allclose(forces.sum(axis=0), 0.0, atol=1e-12 * expected)


def test_stiffness_follows_swollen_radii():
    state = _pair(1e-4, 1e-4, 0.0)
    state.radii *= 1.01  # swelling after contact creation: overlap 2e-6
    _, _, normal = contact_forces(state, 1e-9, DEM)
    expected = 4.0 / 3.0 * E_STAR * np.sqrt(1.01e-4 / 2) * 2e-6**1.5
    assert normal[0] == pytest.approx(expected, rel=1e-12)


def test_shear_force_is_mindlin_tangent_stiffness_times_slip():
    overlap, slip_speed, time_step = 2e-6, 1e-3, 1e-9
    state = _pair(1e-4, 1e-4, overlap)
    state.velocities[1, 1] = slip_speed
    for _ in range(10):
        forces, torques, _ = contact_forces(state, time_step, DEM)
    k_t = 2.0 * np.sqrt(4 * 0.5e-4) * G / (2.0 - 0.3) * np.sqrt(overlap)
    slip = 10 * slip_speed * time_step
    # b slides along +y relative to a: the shear force drags a along +y
    np.testing.assert_allclose(state.contacts.shear_forces[0], [0.0, k_t * slip, 0.0],
                               rtol=1e-12)
    assert forces[1, 1] == pytest.approx(-k_t * slip, rel=1e-12)
    # both spheres are turned the same way, arm (r - delta/2) times the shear force
    arm = 1e-4 - overlap / 2
    np.testing.assert_allclose(torques, [[0, 0, arm * k_t * slip]] * 2, rtol=1e-12)


def test_rigid_rotation_of_a_pair_creates_no_shear():
    state = _pair(1e-4, 1.5e-4, 2e-6)
    spin = np.array([0.3, -2.0, 5.0])  # rad/s, whole pair turning as one body
    state.spins[:] = spin
    state.velocities[:] = np.cross(spin, state.positions)
    contact_forces(state, 1e-6, DEM)
    np.testing.assert_allclose(state.contacts.shear_forces, 0.0, atol=1e-15)
    state.spins[:] = 0.0  # without the spins, the same motion would shear the contact
    contact_forces(state, 1e-6, DEM)
    assert np.abs(state.contacts.shear_forces).max() > 1e-6


def test_separated_pair_has_no_force_and_loses_history():
    state = _pair(1e-4, 1e-4, -1e-6)
    state.contacts.shear_forces[:] = 1.0
    forces, _, normal = contact_forces(state, 1e-9, DEM)
    assert normal[0] == 0.0 and np.all(forces == 0.0)
    assert np.all(state.contacts.shear_forces == 0.0)


def test_kernel_matches_numpy_reference_on_random_assembly():
    rng = np.random.default_rng(4)
    positions = rng.uniform(0.0, 1e-3, (300, 3))
    radii = rng.uniform(6e-5, 1.2e-4, 300)
    state = new_state(positions, radii, DEM)
    forces, _, normal = contact_forces(state, 1e-9, DEM)
    i, j = state.contacts.pairs.T
    d = positions[j] - positions[i]
    distance = np.linalg.norm(d, axis=1)
    overlap = np.maximum(radii[i] + radii[j] - distance, 0.0)
    magnitude = 4.0 / 3.0 * E_STAR * np.sqrt(radii[i] * radii[j] / (radii[i] + radii[j]))
    magnitude = magnitude * overlap**1.5
    push = magnitude[:, None] * d / distance[:, None]
    expected = np.zeros_like(positions)
    np.add.at(expected, j, push)
    np.add.at(expected, i, -push)
    assert np.count_nonzero(magnitude) > 200
    np.testing.assert_allclose(normal, magnitude, rtol=1e-12)
    np.testing.assert_allclose(forces, expected, rtol=1e-10, atol=1e-12 * magnitude.max())


def _bonded_pair(overlap, strength):
    """Two points of radius 1e-4 m built at ``overlap`` as their stress-free state."""
    positions = np.array([[0.0, 0.0, 0.0], [2e-4 - overlap, 0.0, 0.0]])
    parameters = dataclasses.replace(DEM, bond_tensile_strength=strength)
    return new_state(positions, np.full(2, 1e-4), parameters, stress_free_bonds=True), parameters


def _pair_force(state, parameters):
    forces, _, _ = contact_forces(state, 1e-9, parameters)
    return bond_tension(state, parameters, forces)[1, 0]


def test_stress_free_bond_loads_only_beyond_its_reference_overlap():
    state, parameters = _bonded_pair(5e-6, 1e7)
    assert _pair_force(state, parameters) == 0.0
    state.positions[1, 0] -= 2e-6  # 2 um more overlap than the stress-free 5 um
    expected = 4.0 / 3.0 * E_STAR * np.sqrt(0.5e-4) * 2e-6**1.5
    assert _pair_force(state, parameters) == pytest.approx(expected, rel=1e-12)


def test_uniform_swelling_of_a_stress_free_bond_loads_nothing():
    state, parameters = _bonded_pair(5e-6, 1e7)
    state.radii *= 1.1
    state.positions *= 1.1  # the swollen pair is the stress-free one, scaled
    assert abs(_pair_force(state, parameters)) < 1e-12 * E_STAR * 1e-4 * 5e-6


def test_bond_pulls_back_linearly_and_breaks_at_its_strength():
    """Tension E* r u; the bond breaks at sigma_t pi r^2, i.e. u = sigma_t pi r / E*."""
    strength = 1e7
    state, parameters = _bonded_pair(5e-6, strength)
    breaking = strength * np.pi * 1e-4 / E_STAR
    state.positions[1, 0] += 0.5 * breaking
    assert _pair_force(state, parameters) == pytest.approx(-E_STAR * 1e-4 * 0.5 * breaking,
                                                           rel=1e-9)
    state.positions[1, 0] += 0.51 * breaking
    assert _pair_force(state, parameters) == 0.0
    assert state.bond_broken.all()
    state.positions[1, 0] -= 1.01 * breaking  # back to the stress-free overlap
    assert abs(_pair_force(state, parameters)) < 1e-12 * E_STAR * 1e-4 * 5e-6


def test_without_strength_a_bond_breaks_at_its_first_stretch():
    state, parameters = _bonded_pair(0.0, 0.0)
    state.positions[1, 0] += 1e-9
    assert _pair_force(state, parameters) == 0.0
    assert state.bond_broken.all()


def test_steps_do_not_depend_on_the_thread_count(monkeypatch):
    """Forces, shear history and motion of a random assembly after 20 steps, with spins
    and drifting velocities, bit for bit with the serial twins of the parallel kernels
    (400 points, below ``PARALLEL_MIN_ROWS``) and with the parallel kernels forced, on
    one and on two threads."""
    import numba

    from shared.dem import _kernels, step

    def run(threads, parallel_min_rows):
        monkeypatch.setattr(_kernels, "PARALLEL_MIN_ROWS", parallel_min_rows)
        rng = np.random.default_rng(5)
        state = new_state(rng.uniform(0.0, 1e-3, (400, 3)), rng.uniform(6e-5, 1.2e-4, 400), DEM)
        state.velocities[:] = rng.normal(0.0, 1e-3, state.velocities.shape)
        state.spins[:] = rng.normal(0.0, 10.0, state.spins.shape)
        before = numba.get_num_threads()
        numba.set_num_threads(threads)
        try:
            reports = [step(state, 1e-8, DEM) for _ in range(20)]
        finally:
            numba.set_num_threads(before)
        return [state.positions, state.velocities, state.spins, state.contacts.shear_forces,
                reports[-1].forces, reports[-1].torques, reports[-1].normal_forces]

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has a single thread here")
    serial = run(2, _kernels.PARALLEL_MIN_ROWS)
    assert 400 < _kernels.PARALLEL_MIN_ROWS
    assert np.count_nonzero(serial[-1]) > 100
    for other in (run(1, 0), run(2, 0)):
        for a, b in zip(serial, other, strict=True):
            assert np.array_equal(a, b)
