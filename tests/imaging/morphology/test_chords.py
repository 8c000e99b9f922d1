"""Chord lengths of structures whose chords are known by construction."""

import numpy as np
import pytest

from imaging.morphology.chords import chord_lengths


def _slabs(thickness_pore: int, thickness_solid: int, repeats: int, lateral: int) -> np.ndarray:
    period = np.r_[np.ones(thickness_pore, bool), np.zeros(thickness_solid, bool)]
    column = np.tile(period, repeats)
    return np.broadcast_to(column[:, None, None], (column.size, lateral, lateral)).copy()


def test_stacked_slabs_give_their_thickness_along_z():
    voxel = 0.5e-6
    image = _slabs(thickness_pore=3, thickness_solid=5, repeats=6, lateral=10)
    result = chord_lengths(image, voxel)
    assert result.mean_pore[2] == pytest.approx(3 * voxel)
    assert result.mean_solid[2] == pytest.approx(5 * voxel)
    # every lateral line runs through one phase from border to border: no complete chord
    assert result.count_pore[:2].sum() == 0 and result.count_solid[:2].sum() == 0
    # the first slab touches the border and is left out: 5 pore chords per column, 5 solid
    assert result.count_pore[2, 2] == 5 * 100
    assert result.count_solid[2, 4] == 5 * 100


def test_distribution_is_normalised_and_edges_can_be_included(rng):
    image = rng.random((30, 30, 30)) < 0.4
    result = chord_lengths(image, 1e-6, include_edges=True)
    integral = (result.f_pore * 1e-6).sum(axis=1)
    np.testing.assert_allclose(integral, 1.0, rtol=1e-12)
    # with edges included every voxel belongs to exactly one chord per direction
    voxel_counts = (result.count_pore * np.arange(1, 31)).sum(axis=1)
    np.testing.assert_array_equal(voxel_counts, image.sum())


def _expected_complete_chord_mean(stay: float, line: int) -> float:
    """Mean of complete runs in a line of ``line`` independent voxels.

    A run of exactly k voxels of a phase of probability ``stay`` bounded on both sides
    inside the line has probability (1 - stay)^2 stay^k at each of (line - k - 1) starts.
    """
    k = np.arange(1, line - 1)
    weight = (line - k - 1) * stay**k
    return float((k * weight).sum() / weight.sum())


def test_random_medium_mean_chord_is_geometric(rng):
    """Uncorrelated voxels: chord lengths are geometric, truncated by the line length."""
    p, n = 0.35, 80
    image = rng.random((n, n, n)) < p
    result = chord_lengths(image, 1.0)
    np.testing.assert_allclose(result.mean_pore, _expected_complete_chord_mean(p, n), rtol=0.01)
    np.testing.assert_allclose(result.mean_solid, _expected_complete_chord_mean(1 - p, n), rtol=0.01)
    assert result.R_p == pytest.approx(1.0, abs=0.02)


@pytest.mark.parametrize("include_edges", [False, True])
def test_slabs_do_not_change_the_chords(rng, include_edges):
    """A dask image in thin slabs (chords along z cross several of them) and numpy slabs
    of other sizes give the counts of the whole image read at once."""
    import dask.array as da

    image = rng.random((37, 11, 13)) < 0.2  # long solid runs along z
    image[:, 3, 4] = False  # one solid chord through every slab: cut at both ends
    image[5:30, 6, 6] = False
    image[[4, 30], 6, 6] = True  # a solid chord of 25 voxels bounded by pores
    whole = chord_lengths(image, 1e-6, include_edges)
    assert whole.count_solid[2, 24] >= 1
    for chunked in (chord_lengths(da.from_array(image, chunks=(4, 11, 13)), 1e-6, include_edges,
                                  workers=2),
                    chord_lengths(image, 1e-6, include_edges, chunk_slices=1),
                    chord_lengths(image, 1e-6, include_edges, chunk_slices=10)):
        np.testing.assert_array_equal(chunked.count_pore, whole.count_pore)
        np.testing.assert_array_equal(chunked.count_solid, whole.count_solid)
    through = chord_lengths(np.zeros((9, 2, 2), bool), 1e-6, True, chunk_slices=2)
    assert through.count_solid[2, 8] == 4  # four lines, each one chord of 9 voxels
