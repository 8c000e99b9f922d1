"""shared.dem.points: cube specimens (counts, bounds, determinism, separation)."""

import numpy as np
import pytest

from shared.dem import cube_points


def test_grid_fills_cube_with_touching_radii():
    positions, radii = cube_points(1000, np.random.default_rng(3), edge_length=7e-3, jitter=0.2)
    assert positions.shape == (1000, 3)
    spacing = 7e-3 / 10
    assert radii == pytest.approx(np.full(1000, spacing / 2), rel=1e-14)
    # jitter of 0.2 h moves a node at most 0.1 h from its cell centre
    assert positions.min() >= 0.5 * spacing - 0.1 * spacing - 1e-15
    assert positions.max() <= 7e-3 - 0.4 * spacing + 1e-15


def test_same_seed_same_points():
    first = cube_points(500, np.random.default_rng(7), kind="random")
    second = cube_points(500, np.random.default_rng(7), kind="random")
    np.testing.assert_array_equal(first[0], second[0])


def test_random_packing_respects_min_separation():
    positions, radii = cube_points(
        800, np.random.default_rng(1), kind="random", min_separation=0.7, radius_factor=1.2
    )
    spacing = 7e-3 / 800 ** (1 / 3)
    distances = np.linalg.norm(positions[:, None] - positions[None], axis=2)
    np.fill_diagonal(distances, np.inf)
    assert positions.shape == (800, 3)
    assert distances.min() >= 0.7 * spacing
    assert np.all((positions >= 0.0) & (positions <= 7e-3))
    assert radii[0] == pytest.approx(0.6 * spacing, rel=1e-14)
