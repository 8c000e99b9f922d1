"""macro.laws: the mixture's constitutive laws against their inverses, hand values of the
equations at the default parameters (Tables 4.1-4.2), and finite differences."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from macro.laws import (
    confined_pressure,
    confined_volume,
    saturation,
    suction,
    suction_derivative,
    swelling_pressure,
    young_modulus,
)
from tests._macro_cases import swelling
from tests.macro._material import MATERIAL, PHI0, pellet


@pytest.mark.parametrize("suction", [1e6, 1e7, 5e7])
def test_confined_volume_inverts_the_confined_pressure_and_is_free_below_its_onset(suction):
    """Under a stress below P(m_s / V_f, s) the clay stays at its free volume (Eq. 4.28);
    above it, at the volume whose pressure is the stress."""
    v0, _, ms = pellet(suction)
    free = v0 * (1.0 + swelling(suction))
    onset = float(swelling_pressure(ms / free, suction, PHI0, MATERIAL))
    stresses = onset * np.array([0.0, 0.5, 0.999, 1.001, 2.0, 10.0])
    volume = confined_volume(suction, stresses, ms, v0, PHI0, MATERIAL)
    np.testing.assert_allclose(volume[:3], free, rtol=1e-12)
    assert np.all(np.diff(volume[2:]) < 0.0)
    pressure = confined_pressure(volume[3:], suction, ms, v0, PHI0, MATERIAL)
    np.testing.assert_allclose(pressure, stresses[3:], rtol=1e-9)
    assert confined_pressure(1.01 * free, suction, ms, v0, PHI0, MATERIAL) == 0.0


@pytest.mark.parametrize(("dry_density", "expected"), [(1490.0, 4.154e6), (1334.0, 1.448e6)])
def test_saturated_clay_presses_eq_4_31_at_its_dry_density(dry_density, expected):
    """beta_v exp(alpha_v rho_d) with beta_v = 1.78e-4 MPa and alpha_v = 6.75 m3/Mg by hand
    (4.15 MPa at the mock-up's 1.49 Mg/m3), for a pellet and for a loose powder held at
    that dry density: one law, whatever the clay's initial state."""
    assert (MATERIAL.beta_v, MATERIAL.alpha_v) == (178.0, 6.75e-3)
    assert swelling_pressure(dry_density, 0.0, PHI0, MATERIAL) == pytest.approx(expected, rel=1e-3)
    v0, _, ms = pellet(0.0)
    powder_v0 = ms / 1100.0  # a powder of 1.1 Mg/m3 holding the pellet's dry mass
    for reference in (v0, powder_v0):
        held = confined_pressure(ms / dry_density, 0.0, ms, reference, PHI0, MATERIAL)
        assert held == pytest.approx(expected, rel=1e-3)


def test_partially_saturated_clay_presses_its_saturation_times_eq_4_31():
    """Eq. 4.33's s_w p: at 1 MPa suction S = (1 + (1/4.026)^(1/0.74))^-0.26 by hand."""
    sat = (1.0 + (1e6 / 4.026e6) ** (1.0 / 0.74)) ** -0.26
    expected = sat * 178.0 * np.exp(6.75e-3 * 1490.0)
    assert swelling_pressure(1490.0, 1e6, PHI0, MATERIAL) == pytest.approx(expected, rel=1e-12)


def test_retention_at_the_reference_porosity_is_table_4_2s_curve():
    """At phi_0 = 0.25, zeta = 4.026 MPa and lambda = 0.26 (Table 4.2): S(zeta) = 2^-0.26,
    S(0) = 1; s(S) inverts S(s) at other porosities too."""
    assert MATERIAL.reference_porosity == 0.25
    assert saturation(4.026e6, 0.25, MATERIAL) == pytest.approx(2.0**-0.26, rel=1e-12)
    assert saturation(0.0, 0.25, MATERIAL) == 1.0
    s = np.array([1e5, 3e6, 4e7, 1.3e8])
    for porosity in (0.2, 0.25, 0.4):
        np.testing.assert_allclose(suction(saturation(s, porosity, MATERIAL), porosity, MATERIAL), s, rtol=1e-9)
    assert np.isnan(suction(1.2, 0.25, MATERIAL))


def test_suction_derivative_is_the_slope_of_the_suction():
    """The closed form |ds/dS| against a central difference of s(S)."""
    sat = np.array([0.3, 0.6, 0.9])
    h = 1e-6
    slope = (suction(sat - h, 0.3, MATERIAL) - suction(sat + h, 0.3, MATERIAL)) / (2.0 * h)
    np.testing.assert_allclose(suction_derivative(sat, 0.3, MATERIAL), slope, rtol=1e-6)


def test_young_modulus_eq_4_3_within_its_bounds():
    """E = 3 (1 - 2 nu) exp(alpha s) / beta by hand between the bounds, capped outside."""
    m = dataclasses.replace(MATERIAL, young_bounds=(1e6, 1e12))
    s = 5e7
    expected = 3.0 * (1.0 - 2.0 * 0.3) * np.exp(2.4e-8 * s) / 1.6e-8
    assert (m.poisson_ratio, m.swelling_alpha, m.swelling_beta) == (0.3, 2.4e-8, 1.6e-8)
    assert young_modulus(s, m) == pytest.approx(expected, rel=1e-12)
    lower, upper = MATERIAL.young_bounds
    np.testing.assert_array_equal(young_modulus([-1e9, 1e10], MATERIAL), [lower, upper])
