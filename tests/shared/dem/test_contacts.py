"""shared.dem.contacts: cell-list contact detection against a brute-force O(N^2) search; Verlet list upkeep."""

import numpy as np
import pytest

from shared.dem import detect_contacts, held_points, new_state, pair_values, update_contacts
from tests._defaults import DEM


def _brute_force(positions, radii, factor, skin):
    i, j = np.triu_indices(positions.shape[0], k=1)
    distance = np.linalg.norm(positions[j] - positions[i], axis=1)
    close = distance < factor * (radii[i] + radii[j]) + skin
    return np.stack([i[close], j[close]], axis=1)


def test_cell_list_equals_brute_force_on_polydisperse_random_points():
    rng = np.random.default_rng(11)
    positions = rng.uniform(0.0, 1e-3, (700, 3))
    radii = rng.uniform(2e-5, 8e-5, 700)
    # the last cutoff finds more than four pairs per point: the search runs out of its
    # first buffer and is repeated
    for factor, skin in ((1.0, 0.0), (1.3, 1e-5), (2.5, 5e-5)):
        found = detect_contacts(positions, radii, factor, skin)
        expected = _brute_force(positions, radii, factor, skin)
        assert expected.shape[0] > 500
        np.testing.assert_array_equal(found, expected)
    assert expected.shape[0] > 4 * positions.shape[0]


def test_flat_and_tiny_clouds():
    line = np.c_[np.arange(10) * 1.9, np.zeros(10), np.zeros(10)]
    np.testing.assert_array_equal(
        detect_contacts(line, np.ones(10)), np.c_[np.arange(9), np.arange(1, 10)]
    )
    assert detect_contacts(np.zeros((1, 3)), np.ones(1)).shape == (0, 2)


def test_rebuild_keeps_shear_history_of_surviving_pairs():
    positions = np.array([[0.0, 0, 0], [1.9, 0, 0], [3.8, 0, 0]]) * 1e-3
    state = new_state(positions, np.full(3, 1e-3), DEM, skin_fraction=0.05)
    np.testing.assert_array_equal(state.contacts.pairs, [[0, 1], [1, 2]])
    state.contacts.shear_forces[:] = [[0.0, 1.0, 0.0], [0.0, 2.0, 0.0]]
    state.positions[2, 0] += 1e-3  # far beyond the skin: pair (1, 2) must leave
    assert update_contacts(state, DEM)
    np.testing.assert_array_equal(state.contacts.pairs, [[0, 1]])
    np.testing.assert_array_equal(state.contacts.shear_forces, [[0.0, 1.0, 0.0]])
    assert not update_contacts(state, DEM)


def test_bonds_are_touching_pairs_within_tolerance():
    positions = np.array([[0.0, 0, 0], [2.0005, 0, 0], [0, 1.999, 0]]) * 1e-3
    radii = np.full(3, 1e-3)
    np.testing.assert_array_equal(new_state(positions, radii, DEM).bonds, [[0, 2]])
    np.testing.assert_array_equal(
        new_state(positions, radii, DEM, bond_tolerance=1e-3).bonds, [[0, 1], [0, 2]]
    )


def test_pair_values_merge_agrees_with_a_dictionary_and_rejects_unsorted_lists():
    rng = np.random.default_rng(5)
    keyed = np.unique(np.sort(rng.integers(0, 60, (300, 2)), axis=1), axis=0)
    keyed = keyed[keyed[:, 0] < keyed[:, 1]]
    pairs = np.unique(np.sort(rng.integers(0, 60, (300, 2)), axis=1), axis=0)
    pairs = pairs[pairs[:, 0] < pairs[:, 1]]
    values = rng.normal(size=(keyed.shape[0], 3))
    lookup = {tuple(pair): value for pair, value in zip(keyed.tolist(), values, strict=True)}
    expected = np.array([lookup.get(tuple(pair), np.zeros(3)) for pair in pairs.tolist()])
    assert 0 < sum(tuple(pair) in lookup for pair in pairs.tolist()) < pairs.shape[0]
    assert np.array_equal(pair_values(pairs, keyed, values), expected)
    with pytest.raises(ValueError, match="keyed pairs are not sorted"):
        pair_values(pairs, keyed[::-1], values)
    with pytest.raises(ValueError, match="pairs are not sorted"):
        pair_values(pairs[::-1], keyed, values)


def test_held_points_are_those_of_compressive_contacts_and_intact_bonds():
    rng = np.random.default_rng(8)
    positions = rng.uniform(0.0, 1e-3, (300, 3))
    state = new_state(positions, np.full(300, 6e-5), DEM)
    state.bond_broken[::3] = True
    normal_forces = np.where(rng.random(state.contacts.pairs.shape[0]) < 0.3, 1.0, 0.0)
    expected = np.zeros(300, dtype=bool)
    for (i, j), force in zip(state.contacts.pairs, normal_forces, strict=True):
        expected[[i, j]] |= force > 0.0
    for (i, j), broken in zip(state.bonds, state.bond_broken, strict=True):
        expected[[i, j]] |= not broken
    assert 0 < expected.sum() < 300
    np.testing.assert_array_equal(held_points(state, normal_forces), expected)
