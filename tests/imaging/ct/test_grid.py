"""Block averaging of the calibrated density on the grid (imaging.ct.grid): the mean kept,
air left out."""

import numpy as np
import pytest

from imaging.ct.calibration import grey_to_density
from imaging.ct.grid import block_average
from tests.imaging.ct.test_calibration import CAL


def test_block_average_conserves_the_mean(rng):
    volume = rng.integers(5000, 50000, size=(20, 18, 17), dtype=np.uint16)
    everywhere = np.ones(volume.shape, dtype=bool)
    grid = block_average(volume, everywhere, CAL, block=4, voxel_size=1e-4)
    sizes = np.multiply.outer(np.multiply.outer([4] * 5, [4] * 4 + [2]), [4] * 4 + [1])
    weights = sizes / sizes.sum()
    voxel_mean = grey_to_density(volume.astype(np.float64), CAL).mean()
    assert (grid.density * weights).sum() == pytest.approx(voxel_mean, rel=1e-6)
    np.testing.assert_allclose(grid.z, (np.array([0, 4, 8, 12, 16]) + 2) * 1e-4)
    np.testing.assert_allclose(grid.x[-1], 16.5e-4)


def test_block_average_ignores_air():
    volume = np.full((8, 8, 8), 1000, dtype=np.uint16)
    volume[:, :, :4] = 31000
    specimen = volume > 2000
    grid = block_average(volume, specimen, CAL, block=4, voxel_size=1.0, min_specimen_fraction=0.5)
    expected = float(grey_to_density(31000.0, CAL))
    np.testing.assert_allclose(grid.density[:, :, 0], expected, rtol=1e-6)
    assert np.isnan(grid.density[:, :, 1]).all()
