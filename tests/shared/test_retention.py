"""Retention curve: hand values, inverse round trip, closed-form derivative, clamping."""

from __future__ import annotations

import numpy as np
import pytest

from shared.retention import retention_parameters, saturation, saturation_derivative, suction
from tests._defaults import CLAY, clay


def test_retention_hand_value_at_reference_pressure() -> None:
    # s = zeta_0 at phi_0: S = (1 + 1)^(-lambda_0) = 2^-0.08 (Table 3.1 values).
    value = saturation(0.03e6, 0.25, CLAY)
    assert value == pytest.approx(2.0**-0.08, rel=1e-14)


def test_retention_parameters_follow_porosity() -> None:
    zeta, exponent = retention_parameters(0.35, CLAY)
    assert zeta == pytest.approx(0.03e6 * np.exp(6.8 * (0.25 - 0.35)), rel=1e-14)
    assert exponent == pytest.approx(0.08 * np.exp(-1.5 * (0.25 - 0.35)), rel=1e-14)


def test_retention_inverse_round_trip(rng: np.random.Generator) -> None:
    suctions = 10.0 ** rng.uniform(2.0, 8.7, 500)
    porosity = rng.uniform(0.12, 0.5, 500)
    water = saturation(suctions, porosity, CLAY)
    assert np.all((water > 0.0) & (water < 1.0))
    np.testing.assert_allclose(suction(water, porosity, CLAY), suctions, rtol=1e-9)


def test_retention_saturated_for_non_positive_suction() -> None:
    np.testing.assert_array_equal(saturation([-1e5, 0.0], 0.25, CLAY), [1.0, 1.0])
    np.testing.assert_array_equal(saturation_derivative([-1e5, 0.0], 0.25, CLAY), [0.0, 0.0])
    assert suction(1.0, 0.25, CLAY) == 0.0


def test_retention_derivative_matches_finite_differences(rng: np.random.Generator) -> None:
    suctions = 10.0 ** rng.uniform(3.0, 8.5, 200)
    porosity = rng.uniform(0.15, 0.45, 200)
    step = 1e-6 * suctions
    # dS/dp = -dS/ds, central differences in suction (O(step^2) error).
    numeric = -(saturation(suctions + step, porosity, CLAY) - saturation(suctions - step, porosity, CLAY)) / (
        2.0 * step
    )
    analytic = saturation_derivative(suctions, porosity, CLAY)
    assert np.all(analytic > 0.0)
    np.testing.assert_allclose(analytic, numeric, rtol=1e-5)


def test_retention_clamps_to_residual_saturation() -> None:
    material = clay(residual_saturation=0.45, saturated_saturation=0.95)
    dry = saturation(5e8, 0.25, material)
    assert dry == 0.45
    assert saturation_derivative(5e8, 0.25, material) == 0.0
    assert saturation(10.0, 0.25, material) == 0.95


def test_retention_rejects_invalid_input() -> None:
    with pytest.raises(ValueError, match="porosity"):
        saturation(1e6, 1.2, CLAY)
    with pytest.raises(ValueError, match="saturation"):
        suction(0.0, 0.25, CLAY)
    with pytest.raises(ValueError, match="residual_saturation"):
        clay(residual_saturation=0.5, saturated_saturation=0.4)


def test_retention_defaults_are_table_3_1() -> None:
    assert CLAY.retention_pressure_reference == 0.03e6
    assert CLAY.retention_exponent_reference == 0.08
    assert CLAY.intrinsic_permeability_reference == 1e-20
    assert CLAY.relative_permeability_exponent == 2.0
