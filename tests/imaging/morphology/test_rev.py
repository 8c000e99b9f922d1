"""REV analysis and interface counting against known structures."""

import numpy as np
import pytest

from imaging.morphology.rev import interface_area, rev_analysis, rev_size, window_sizes


def test_random_structure_converges_to_its_porosity(rng):
    porosity = 0.3
    binary = rng.random((64, 64, 64)) < porosity
    result = rev_analysis(binary.astype(np.float32), 1e-6, rng, binary=binary, n_sizes=8,
                          n_positions=48, tolerance=0.05, max_window_fraction=0.5)
    largest = result.window[-1] ** 3
    # binomial spread of a window mean: sqrt(p (1 - p) / n)
    sigma = np.sqrt(porosity * (1 - porosity) / largest)
    assert result.porosity_mean[-1] == pytest.approx(porosity, abs=4 * sigma)
    np.testing.assert_allclose(result.porosity_std[-2:], np.sqrt(
        porosity * (1 - porosity) / result.window[-2:] ** 3), rtol=0.35)
    assert result.w_rev_porosity <= result.window[-1] * 1e-6
    # uncorrelated voxels: faces between unlike neighbours, 3 per voxel, p 2 p (1 - p)
    expected_faces = 3 * 2 * porosity * (1 - porosity) / 1e-6 * (2 / 3)
    assert result.interface_total == pytest.approx(expected_faces, rel=0.02)


def test_sphere_interface_area_within_five_percent():
    n, radius = 72, 24.0
    z, y, x = np.ogrid[:n, :n, :n]
    centre = (n - 1) / 2
    ball = (z - centre) ** 2 + (y - centre) ** 2 + (x - centre) ** 2 <= radius**2
    area = interface_area(ball, voxel_size=2e-6)
    assert area == pytest.approx(4 * np.pi * (radius * 2e-6) ** 2, rel=0.05)


def test_slab_interface_needs_no_correction_factor_inverse():
    """A plane normal to z is counted exactly: faces = area, so corrected = 2/3 area."""
    image = np.zeros((10, 12, 14), dtype=bool)
    image[5:] = True
    assert interface_area(image, 1.0) == pytest.approx(2 / 3 * 12 * 14)


def test_rev_size_picks_the_first_window_that_stays_below():
    edges = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    assert rev_size(edges, np.array([0.5, 0.005, 0.02, 0.008, 0.001]), 0.01) == 4.0
    assert np.isnan(rev_size(edges, np.array([0.5, 0.4, 0.3, 0.2, 0.1]), 0.01))


def test_window_sizes_are_distinct_and_bounded():
    sizes = window_sizes(40, 12, 2)
    assert sizes[0] == 2 and sizes[-1] == 40
    assert np.all(np.diff(sizes) > 0)


def test_nan_field_is_refused(rng):
    field = rng.random((8, 8, 8)).astype(np.float32)
    field[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        rev_analysis(field, 1.0, rng)
