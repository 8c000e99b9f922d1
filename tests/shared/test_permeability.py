"""shared.permeability: relative and intrinsic permeability, viscosities."""

from __future__ import annotations

import numpy as np
import pytest

from shared.permeability import (
    effective_saturation,
    intrinsic_permeability,
    phase_viscosity,
    porosity_permeability,
    relative_permeability,
)
from tests._defaults import CLAY, clay


def test_permeability_relative_water_and_gas() -> None:
    material = clay(residual_saturation=0.2, saturated_saturation=1.0)
    # Se = (0.6 - 0.2)/0.8 = 0.5, n = 2: water 0.25, gas 0.25; Se = 0.75: water 0.5625.
    np.testing.assert_allclose(relative_permeability([0.6, 0.8], "water", material), [0.25, 0.5625])
    np.testing.assert_allclose(relative_permeability([0.6, 0.8], "gas", material), [0.25, 0.0625])


def test_permeability_relative_is_clamped() -> None:
    material = clay(residual_saturation=0.2, saturated_saturation=0.9)
    np.testing.assert_array_equal(relative_permeability([0.1, 0.95], "water", material), [0.0, 1.0])
    np.testing.assert_array_equal(relative_permeability([0.1, 0.95], "gas", material), [1.0, 0.0])
    with pytest.raises(ValueError, match="phase"):
        relative_permeability(0.5, "oil", material)  # type: ignore[arg-type]


def test_permeability_intrinsic_exponential_in_porosity() -> None:
    assert intrinsic_permeability(0.25, CLAY) == pytest.approx(1e-20, rel=1e-14)
    assert intrinsic_permeability(0.35, CLAY) == pytest.approx(1e-20 * np.exp(0.2), rel=1e-14)


def test_permeability_phase_viscosity() -> None:
    assert phase_viscosity("gas", CLAY) == 1.8e-5


def test_permeability_effective_saturation_spans_the_residual_to_the_saturated() -> None:
    material = clay(residual_saturation=0.1, saturated_saturation=0.9)
    np.testing.assert_allclose(effective_saturation([0.0, 0.1, 0.5, 0.9, 1.0], material),
                               [0.0, 0.0, 0.5, 1.0, 1.0], rtol=1e-14)


def test_permeability_of_porosity_doubles_every_ln2_over_b() -> None:
    """k = k_0 exp(b (phi - phi_0)): k_0 at phi_0, a factor 2 per ln 2 / b of porosity."""
    step = np.log(2.0) / 4.0
    np.testing.assert_allclose(porosity_permeability([0.3, 0.3 + step, 0.3 - step], 2e-19, 4.0, 0.3),
                               [2e-19, 4e-19, 1e-19], rtol=1e-13)
