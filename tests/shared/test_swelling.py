"""shared.swelling: the swelling strain law (Eq. 3.21) and the radius that follows the volume."""

from __future__ import annotations

import numpy as np
import pytest

from shared.swelling import swelling_strain, swollen_radius, volumetric_strain
from tests._defaults import clay


def test_swelling_strain_hand_values() -> None:
    material = clay(swelling_alpha=2e-8, swelling_beta=1e-8, initial_suction=1e8)
    assert volumetric_strain(1e8, material) == 0.0
    # (1e-8/2e-8) (exp(0) - exp(-2)) at zero suction.
    assert volumetric_strain(0.0, material) == pytest.approx(0.5 * (1.0 - np.exp(-2.0)), rel=1e-14)
    assert volumetric_strain(2e8, material) < 0.0


def test_swelling_radius_follows_volume() -> None:
    assert swollen_radius(1e-4, 0.331) == pytest.approx(1.1e-4, rel=1e-12)
    with pytest.raises(ValueError, match="exceed -1"):
        swollen_radius(1e-4, -1.0)


def test_swelling_strain_hand_value_and_change_of_reference() -> None:
    """(beta / alpha) (exp(-alpha s) - exp(-alpha s0)) by hand, and the strain from s0 to s
    is the strain from s0 to s1 plus that from s1 to s (the reference only shifts it)."""
    alpha, beta = 1e-8, 2e-8
    assert swelling_strain(0.0, alpha, beta, 5e7) == pytest.approx(2.0 * (1.0 - np.exp(-0.5)), rel=1e-14)
    suction = np.array([0.0, 1e7, 3e7, 1.2e8])
    np.testing.assert_allclose(swelling_strain(suction, alpha, beta, 9e7),
                               swelling_strain(suction, alpha, beta, 4e7) + swelling_strain(4e7, alpha, beta, 9e7),
                               rtol=1e-12, atol=1e-15)
    # falls monotonically with suction: drying shrinks
    assert np.all(np.diff(swelling_strain(suction, alpha, beta, 9e7)) < 0.0)
