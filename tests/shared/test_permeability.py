"""shared.permeability: relative and intrinsic permeability, viscosities."""

from __future__ import annotations

import numpy as np
import pytest

from shared.permeability import (
    intrinsic_permeability,
    phase_viscosity,
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
