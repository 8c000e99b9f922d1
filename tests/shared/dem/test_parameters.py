"""shared.dem.parameters: the DEM parameters of the default configuration (Table 3.1,
Appendix .2), the contact moduli against the general Hertz-Mindlin forms, and the checks."""

from __future__ import annotations

import pytest

from shared.dem.parameters import dem_parameters
from tests._defaults import CONFIG, dem


def test_the_defaults_are_table_3_1_and_the_appendix_script() -> None:
    p = dem_parameters(CONFIG["materials"]["pellet"], CONFIG["micro"]["numerics"])
    assert (p.young_modulus, p.poisson_ratio, p.density) == (1e10, 0.3, 2600.0)
    assert (p.interaction_radius_factor, p.damping, p.time_step) == (1.0, 0.4, 4e-9)


def test_contact_moduli_are_the_general_hertz_mindlin_forms() -> None:
    """1/E* = (1 - nu_1^2)/E_1 + (1 - nu_2^2)/E_2 (a rigid wall: E_2 -> inf); G = E/(2(1+nu));
    Mindlin k_t = 8 G* a with 1/G* = (2 - nu_1)/G_1 + (2 - nu_2)/G_2 and a = sqrt(R* delta),
    so c_s = 8 G*; by hand for E = 1e10 Pa, nu = 0.25."""
    p = dem(young_modulus=1e10, poisson_ratio=0.25)
    one = (1.0 - 0.25**2) / 1e10
    assert p.effective_modulus == pytest.approx(1.0 / (2.0 * one), rel=1e-14)
    assert p.wall_effective_modulus == pytest.approx(1.0 / one, rel=1e-14)
    assert p.shear_modulus == pytest.approx(4e9, rel=1e-14)
    assert p.shear_coefficient == pytest.approx(8.0 / (2.0 * (2.0 - 0.25) / 4e9), rel=1e-14)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"young_modulus": 0.0}, "young_modulus must be > 0"),
        ({"time_step": -1e-9}, "time_step must be > 0"),
        ({"poisson_ratio": 0.5}, r"poisson_ratio must lie in \(-1, 0.5\)"),
        ({"damping": 1.0}, r"damping must lie in \[0, 1\)"),
        ({"bond_tensile_strength": -1.0}, "bond_tensile_strength must be >= 0"),
        ({"time_step_safety": 1.5}, r"time_step_safety must lie in \(0, 1\]"),
    ],
)
def test_impossible_values_are_refused(changes, message) -> None:
    with pytest.raises(ValueError, match=message):
        dem(**changes)
