"""REV analysis and interface counting against known structures."""

import numpy as np
import pytest

from imaging.morphology import centred_rev_size, interface_area, rev_analyses, rev_analysis
from imaging.morphology.rev import rev_size, window_sizes, window_sums


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


def testcentred_rev_size_ignores_the_whole_image() -> None:
    """The centred-window REV is the smallest edge from which every larger window is within
    the tolerance; the whole image matches itself, so it alone does not count."""
    edges = np.array([1.0, 2.0, 4.0, 8.0])
    assert centred_rev_size(edges, np.array([0.5, 0.005, 0.002, 0.0]), True, 0.01) == 2.0
    assert centred_rev_size(edges, np.array([0.5, 0.005, 0.03, 0.0]), True, 0.01) != 8.0
    assert np.isnan(centred_rev_size(edges, np.array([0.5, 0.005, 0.03, 0.0]), True, 0.01))
    assert centred_rev_size(edges, np.array([0.5, 0.005, 0.03, 0.0]), False, 0.01) == 8.0
    # the tolerance is the entry's rev_tolerance
    assert centred_rev_size(edges, np.array([0.5, 0.005, 0.03, 0.0]), True, 0.05) == 2.0


@pytest.mark.parametrize("chunk_slices", [None, 1, 3, 7])
def test_window_sums_match_direct_sums_whatever_the_slabs(rng, chunk_slices):
    """Slab-by-slab window sums against numpy over the same boxes: the field, the pore
    voxels and the unlike neighbours inside each box, with slabs that cut the windows."""
    field = rng.random((17, 23, 19))
    binary = rng.random((17, 23, 19)) < 0.4
    edges = rng.integers(1, 17, size=(60, 3))
    starts = rng.integers(0, np.array(field.shape) - edges + 1)
    sums = window_sums(field, binary, starts, edges, chunk_slices=chunk_slices, workers=2)
    for k, (start, edge) in enumerate(zip(starts, edges, strict=True)):
        box = tuple(slice(s, s + e) for s, e in zip(start, edge, strict=True))
        assert sums.field[k] == pytest.approx(field[box].sum(), rel=1e-12)
        assert sums.pore[k] == np.count_nonzero(binary[box])
        inside = binary[box].view(np.uint8)
        assert sums.faces[k] == sum(np.count_nonzero(np.diff(inside, axis=a)) for a in range(3))


def test_a_dask_image_gives_the_numpy_result(rng):
    """The same analysis on a dask array chunked along z (slabs cut through pores and
    windows) and on numpy: identical windows, integer statistics equal, field to rounding."""
    import dask.array as da
    from scipy.ndimage import gaussian_filter

    smooth = gaussian_filter(rng.standard_normal((40, 36, 32)), 1.5)
    binary = smooth > 0.3 * smooth.std()
    field = np.clip(0.5 + smooth, 0, 1).astype(np.float32)
    kwargs = dict(binary=None, n_sizes=5, n_positions=500)
    direct = rev_analysis(binary, 1e-6, np.random.default_rng(3), **{**kwargs, "binary": binary})
    chunked = rev_analysis(da.from_array(binary, chunks=(7, 36, 32)), 1e-6,
                           np.random.default_rng(3),
                           **{**kwargs, "binary": da.from_array(binary, chunks=(7, 36, 32))})
    for name in ("porosity_mean", "porosity_std", "interface_mean", "interface_std",
                 "porosity_centred", "interface_centred"):
        np.testing.assert_array_equal(getattr(direct, name), getattr(chunked, name))
    direct = rev_analysis(field, 1e-6, np.random.default_rng(3), **kwargs)
    chunked = rev_analysis(da.from_array(field, chunks=(9, 36, 32)), 1e-6,
                           np.random.default_rng(3), **kwargs)
    np.testing.assert_allclose(direct.porosity_std, chunked.porosity_std, rtol=1e-9)
    np.testing.assert_allclose(direct.porosity_centred, chunked.porosity_centred, rtol=1e-12)


def test_every_position_when_there_are_few_windows(rng):
    """With fewer positions than n_positions, the statistics are those of every window
    (numpy over all of them) and do not depend on the seed."""
    binary = rng.random((12, 14, 13)) < 0.35
    results = [rev_analysis(binary, 1e-6, np.random.default_rng(seed), n_sizes=4,
                            max_window_fraction=0.6) for seed in (0, 1)]
    for index, width in enumerate(results[0].window):
        windows = np.lib.stride_tricks.sliding_window_view(binary, (width,) * 3)
        fractions = windows.mean(axis=(-3, -2, -1))
        assert results[0].porosity_mean[index] == pytest.approx(fractions.mean(), rel=1e-12)
        assert results[0].porosity_std[index] == pytest.approx(fractions.std(), rel=1e-9)
    np.testing.assert_array_equal(results[0].porosity_std, results[1].porosity_std)


def test_default_window_count_keeps_the_curve_within_one_percent_between_seeds(rng):
    """With more positions than windows, the default 2^20 random windows per edge give
    mean and std curves of two seeds within 1 % of the porosity (64 windows did not)."""
    from scipy.ndimage import gaussian_filter

    smooth = gaussian_filter(rng.standard_normal((112, 112, 112)), 2.0)
    binary = smooth > 0.5 * smooth.std()
    curves = [rev_analysis(binary, 1e-6, np.random.default_rng(seed), n_positions=2**20,
                           n_sizes=3, max_window_fraction=0.1) for seed in (0, 1)]
    assert (112 - curves[0].window[0] + 1) ** 3 > 2**20  # random, not every position
    level = curves[0].porosity_total
    for name in ("porosity_mean", "porosity_std"):
        difference = np.abs(getattr(curves[0], name) - getattr(curves[1], name))
        assert difference.max() < 0.01 * level, name
    few = [rev_analysis(binary, 1e-6, np.random.default_rng(seed), n_positions=64, n_sizes=3,
                        max_window_fraction=0.1) for seed in (0, 1)]
    assert np.abs(few[0].porosity_mean - few[1].porosity_mean).max() > 0.01 * level


def test_one_pass_gives_the_field_and_the_binary_images_rev(rng):
    """rev_analyses of a field with a binary image: the first result is the field's
    (rev_analysis of it), the second the binary image's pore fraction, as if the binary
    image were analysed alone; same windows for both."""
    field = rng.random((20, 22, 24))
    binary = field > 0.7
    both = rev_analyses(field, 1e-6, np.random.default_rng(5), binary=binary, n_sizes=4,
                        n_positions=300)
    alone = [rev_analysis(image, 1e-6, np.random.default_rng(5), binary=binary, n_sizes=4,
                          n_positions=300) for image in (field, binary)]
    for result, reference in zip(both, alone, strict=True):
        for name in ("porosity_mean", "porosity_std", "porosity_centred", "interface_std"):
            np.testing.assert_allclose(getattr(result, name), getattr(reference, name),
                                       rtol=1e-12)
    assert both[1].porosity_total == pytest.approx(binary.mean())
