"""Calibration against values known by construction, and the calibrated phantom's block porosity."""

import numpy as np
import pytest

from imaging.ct.calibration import Calibration, density_to_porosity, grey_anchors, grey_to_density
from imaging.ct.grid import block_average
from imaging.ct.mask import specimen_mask
from imaging.ct.phantom import PhantomSpec, pellet_phantom

ANCHORS = {"air_density": 1.13, "muscovite_density": 3900.0, "dry_density": 2120.0,
           "mean_porosity": 0.25}
CAL = Calibration(grey_air=1000.0, grey_muscovite=61000.0, **ANCHORS)


def _grey_of(density: np.ndarray, cal: Calibration) -> np.ndarray:
    """Invert the grey -> density law by hand (the law's definition, Sec. 3.3.4)."""
    fraction = (density - cal.air_density) / (cal.muscovite_density - cal.air_density)
    return cal.grey_air + fraction * (cal.grey_muscovite - cal.grey_air)


def test_known_density_gives_its_porosity(rng):
    porosity_true = rng.uniform(0.05, 0.9, size=(6, 7, 8))
    # porosity = 1 - (1 - n_mean) (rho - rho_air) / (rho_dry - rho_air), solved for rho
    density = CAL.air_density + (1 - porosity_true) * (CAL.dry_density - CAL.air_density) / (
        1 - CAL.mean_porosity
    )
    recovered = density_to_porosity(grey_to_density(_grey_of(density, CAL), CAL), CAL)
    np.testing.assert_allclose(recovered, porosity_true, rtol=0, atol=1e-9)


def test_anchor_points():
    assert grey_to_density(CAL.grey_air, CAL) == pytest.approx(1.13, abs=1e-12)
    assert grey_to_density(CAL.grey_muscovite, CAL) == pytest.approx(3900.0, rel=1e-12)
    assert density_to_porosity(2120.0, CAL) == pytest.approx(0.25, abs=1e-12)
    assert density_to_porosity(1.13, CAL) == pytest.approx(1.0, abs=1e-12)


def test_invalid_calibration_is_refused():
    with pytest.raises(ValueError, match="grey_muscovite"):
        Calibration(grey_air=5.0, grey_muscovite=5.0, **ANCHORS)
    with pytest.raises(ValueError, match="mean_porosity"):
        Calibration(grey_air=0.0, grey_muscovite=1.0, **{**ANCHORS, "mean_porosity": 1.2})


def test_phantom_calibration_recovers_true_block_porosity():
    """Cross-check: porosity from the phantom's grey values vs from its true density."""
    spec = PhantomSpec(shape=(48, 48, 48), voxel_size=2e-4, noise_std=200.0, seed=3)
    grey, density = pellet_phantom(spec)
    specimen = specimen_mask(grey)
    cal = Calibration(grey_air=spec.grey_air, grey_muscovite=spec.grey_muscovite, **ANCHORS)
    grid = block_average(grey, specimen, cal, block=4, voxel_size=spec.voxel_size)
    true = np.full(grid.porosity.shape, np.nan)
    sums = density.reshape(12, 4, 12, 4, 12, 4) * specimen.reshape(12, 4, 12, 4, 12, 4)
    counts = specimen.reshape(12, 4, 12, 4, 12, 4).sum(axis=(1, 3, 5))
    interior = counts == 64
    true[interior] = density_to_porosity(sums.sum(axis=(1, 3, 5))[interior] / 64, cal)
    # blur mixes neighbouring blocks, noise averages out over 64 voxels
    error = np.abs(grid.porosity[interior] - true[interior])
    assert np.median(error) < 0.01
    assert grey_anchors(grey, specimen)[0] == pytest.approx(spec.grey_air, abs=3 * 200.0)


@pytest.mark.parametrize("percentile", [0.0, 12.5, 50.0, 99.99, 100.0])
def test_histogram_quantile_is_numpys_percentile(rng, percentile):
    values = rng.integers(0, 400, size=rng.integers(1, 2000))
    from imaging.ct.calibration import histogram_quantile

    assert histogram_quantile(np.bincount(values, minlength=400), percentile) == pytest.approx(
        np.percentile(values, percentile), rel=1e-12, abs=1e-12)
