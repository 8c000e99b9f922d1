"""Powder heterogeneity: the gstools random field's statistics and the Weibull draws."""

from __future__ import annotations

import numpy as np
import pytest

from macro.field import cell_porosity, gaussian_field
from tests._defaults import CONFIG


def test_random_field_has_the_requested_mean_variance_and_correlation_length():
    """Exponential covariance var exp(-r / l): empirical variogram on a 40^3 grid over
    8 correlation lengths against var (1 - exp(-h / l)); fitted l within 20 %."""
    ell, std, mean = 0.01, 0.05, 0.2
    axis = np.linspace(0.0, 8 * ell, 40)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    values = gaussian_field(grid, mean, std, ell, seed=3).reshape(40, 40, 40)
    assert values.mean() == pytest.approx(mean, abs=0.25 * std)
    assert values.var() == pytest.approx(std**2, rel=0.25)
    spacing = axis[1] - axis[0]
    lags, gammas = [], []
    for k in range(1, 12):
        diff = np.concatenate([(values[k:] - values[:-k]).ravel(), (values[:, k:] - values[:, :-k]).ravel(),
                               (values[:, :, k:] - values[:, :, :-k]).ravel()])
        lags.append(k * spacing)
        gammas.append(0.5 * np.mean(diff**2))
    lags, gammas = np.array(lags), np.array(gammas)
    candidates = np.linspace(0.3 * ell, 3 * ell, 271)
    misfit = [np.sum((gammas - values.var() * (1 - np.exp(-lags / c))) ** 2) for c in candidates]
    assert candidates[int(np.argmin(misfit))] == pytest.approx(ell, rel=0.2)


def test_weibull_porosity_has_the_requested_mean_and_clamps(rng):
    powder = dict(CONFIG["macro"]["powder"], heterogeneity="weibull")
    values = cell_porosity(np.zeros((20000, 3)), powder, rng, seed=0)
    low, high = powder["porosity_clamp"]
    assert values.min() >= low and values.max() <= high
    # Weibull of shape 4 and mean 0.2 has std 0.2 * 0.2805 = 0.056; the clamps move the mean little
    assert values.mean() == pytest.approx(powder["mean_porosity"], abs=0.005)
    assert values.std() == pytest.approx(0.2 * 0.2805, rel=0.1)
