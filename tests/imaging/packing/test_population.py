"""Particle populations (Table I laws)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from imaging.packing import (
    Population,
    sample_semi_axes,
)

MICRON2 = 1e-12


def test_lognormal_laws_of_the_fine_fraction() -> None:
    """Table I, 0.1-0.2 um: basal surface (0.005 um^2, 0.901), R (0.089, 0.695),
    l_a / l_b (1.695, 0.304), the latter truncated below 1."""
    population = Population(0.005 * MICRON2, 0.901, 0.089, 0.695, 1.695, 0.304)
    semi = sample_semi_axes(population, 3000, np.random.default_rng(11))
    a, b, c = semi.T
    surface = np.pi * a * b / MICRON2
    aspect = c / np.sqrt(a * b)
    ratio = a / b
    assert stats.kstest(surface, stats.lognorm(s=0.901, scale=0.005).cdf).pvalue > 0.01
    assert stats.kstest(aspect, stats.lognorm(s=0.695, scale=0.089).cdf).pvalue > 0.01
    law = stats.lognorm(s=0.304, scale=1.695)
    below = law.cdf(1.0)
    assert stats.kstest(ratio, lambda x: (law.cdf(x) - below) / (1 - below)).pvalue > 0.01
    assert ratio.min() >= 1.0


def test_truncated_basal_surface() -> None:
    population = Population(0.111 * MICRON2, 1.987, 0.093, 0.473, 1.464, 0.22,
                            basal_surface_max=7.0 * MICRON2)
    semi = sample_semi_axes(population, 2000, np.random.default_rng(2))
    assert np.max(np.pi * semi[:, 0] * semi[:, 1]) <= 7.0 * MICRON2


def test_monodisperse_disks_have_the_requested_shape() -> None:
    population = Population(np.pi / 4 * MICRON2, aspect_ratio_median=0.1)
    semi = sample_semi_axes(population, 10, np.random.default_rng(0))
    assert semi[:, 0] == pytest.approx(np.full(10, 0.5e-6))
    assert semi[:, 1] == pytest.approx(np.full(10, 0.5e-6))
    assert semi[:, 2] == pytest.approx(np.full(10, 0.05e-6))


def test_sampling_is_deterministic_for_a_seed() -> None:
    population = Population(MICRON2, 0.5, 0.1, 0.3, 1.3, 0.1)
    first = sample_semi_axes(population, 50, np.random.default_rng(9))
    again = sample_semi_axes(population, 50, np.random.default_rng(9))
    other = sample_semi_axes(population, 50, np.random.default_rng(10))
    assert np.array_equal(first, again)
    assert not np.array_equal(first, other)


@pytest.mark.parametrize("field, value", [("axis_ratio_median", 0.8), ("aspect_ratio_sigma", -0.1)])
def test_invalid_population(field: str, value: float) -> None:
    population = Population(MICRON2, **{field: value})
    with pytest.raises(ValueError, match=field):
        sample_semi_axes(population, 5, np.random.default_rng(0))
