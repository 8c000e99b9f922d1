"""shared.dem.state: a new state's masses, inertia, bonds and stress-free overlaps by hand,
and the shape checks of the dataclasses."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from shared.dem.state import new_state
from tests._defaults import dem

PARAMETERS = dem(density=2000.0)


def _chain():
    """Three points on the x axis: 0 and 1 overlap by 0.1 mm, 2 is 0.5 mm from 1 (not touching)."""
    positions = np.array([[0.0, 0.0, 0.0], [1.9e-3, 0.0, 0.0], [4.4e-3, 0.0, 0.0]])
    radii = np.array([1e-3, 1e-3, 1e-3])
    return positions, radii


def test_a_new_state_is_at_rest_with_solid_sphere_masses():
    positions, radii = _chain()
    radii[2] = 2e-3
    positions[2, 0] = 5e-3  # a larger point, 0.1 mm from point 1
    state = new_state(positions, radii, PARAMETERS)
    mass = 2000.0 * 4.0 / 3.0 * np.pi * np.array([1e-9, 1e-9, 8e-9])
    np.testing.assert_allclose(state.masses, mass, rtol=1e-14)
    np.testing.assert_allclose(state.inertia, 0.4 * mass * np.array([1e-6, 1e-6, 4e-6]), rtol=1e-14)
    assert state.n_points == 3 and state.time == 0.0
    assert not state.velocities.any() and not state.spins.any() and not state.fixed.any()
    np.testing.assert_array_equal(state.reference_radii, radii)
    positions[0, 0] = 1.0  # the state holds copies
    assert state.positions[0, 0] == 0.0 and state.contacts.detection_positions[0, 0] == 0.0


def test_bonds_overlaps_and_the_contact_list():
    """Pair (0, 1) overlaps by 0.1 mm and is bonded; (1, 2) is 0.5 mm apart: a candidate only
    within the skin. Stress-free bonds keep that overlap as the bond's and the contact's
    reference; otherwise both are zero."""
    positions, radii = _chain()
    loaded = new_state(positions, radii, PARAMETERS)
    np.testing.assert_array_equal(loaded.bonds, [[0, 1]])
    np.testing.assert_array_equal(loaded.bond_overlaps, [0.0])
    assert not loaded.bond_broken.any()
    np.testing.assert_array_equal(loaded.contacts.pairs, [[0, 1]])  # skin 0.1 mm < 0.5 mm
    wide = new_state(positions, radii, PARAMETERS, skin_fraction=0.6)
    assert wide.contacts.skin == pytest.approx(0.6e-3, rel=1e-14)
    np.testing.assert_array_equal(wide.contacts.pairs, [[0, 1], [1, 2]])
    free = new_state(positions, radii, PARAMETERS, skin_fraction=0.6, stress_free_bonds=True)
    np.testing.assert_allclose(free.bond_overlaps, [1e-4], rtol=1e-9)
    np.testing.assert_allclose(free.contacts.reference_overlaps, [1e-4, 0.0], rtol=1e-9)
    assert free.contacts.shear_forces.shape == (2, 3) and not free.contacts.shear_forces.any()


def test_arrays_of_the_wrong_shape_are_refused():
    state = new_state(*_chain(), PARAMETERS)
    with pytest.raises(ValueError, match=r"velocities must have shape \(3, 3\)"):
        dataclasses.replace(state, velocities=np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"masses must have shape \(3,\)"):
        dataclasses.replace(state, masses=np.zeros(4))
