"""Hertz-Mindlin contacts of the macro DEM (Eqs. 4.1-4.9) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from macro._kernels import hertz_mindlin_pairs


def _pair(overlap, young=(8e8, 4e8)):
    r = np.array([6e-3, 4e-3])
    positions = np.array([[0.0, 0.0, 0.0], [r.sum() - overlap, 0.0, 0.0]])
    return positions, r, np.array(young)


def test_normal_force_is_hertz_with_the_harmonic_modulus():
    positions, r, young = _pair(1e-5)
    nu = 0.3
    forces, torques, stiffness = np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(2)
    normal = hertz_mindlin_pairs(positions, np.zeros((2, 3)), np.zeros((2, 3)), r, young, nu, 0.5,
                                 np.array([[0, 1]]), np.zeros((1, 3)), forces, torques, stiffness)
    e_star = 1.0 / ((1 - nu**2) / young[0] + (1 - nu**2) / young[1])  # Eq. 4.2
    r_star = r[0] * r[1] / r.sum()
    expected = 4.0 / 3.0 * e_star * np.sqrt(r_star) * 1e-5**1.5  # Eq. 4.1
    assert normal[0] == pytest.approx(expected, rel=1e-12)
    assert forces[0, 0] == pytest.approx(-expected) and forces[1, 0] == pytest.approx(expected)


def test_shear_grows_with_mindlin_stiffness_until_coulomb():
    """Pellet 0 slides along y by 1e-8 m per substep: the shear force on it is
    -k_t * slip, k_t = 4 G a / (2 - nu) with G the mean shear modulus, until it reaches
    tan(phi) F_n; the torques are the arms times the shear force."""
    positions, r, young = _pair(1e-5)
    nu, friction = 0.3, np.tan(np.radians(30.0))
    shear = np.zeros((1, 3))
    moved = np.array([[0.0, 1e-8, 0.0], [0.0, 0.0, 0.0]])
    a = np.sqrt(r[0] * r[1] / r.sum() * 1e-5)
    k_t = 4.0 * (0.5 * (young[0] + young[1]) / (2 * (1 + nu))) * a / (2 - nu)
    history = []
    for _ in range(600):
        forces, torques, stiffness = np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(2)
        normal = hertz_mindlin_pairs(positions, moved, np.zeros((2, 3)), r, young, nu, friction,
                                     np.array([[0, 1]]), shear, forces, torques, stiffness)
        history.append(-shear[0, 1])
    history = np.array(history)
    assert history[0] == pytest.approx(k_t * 1e-8, rel=1e-9)
    assert history[3] == pytest.approx(4 * k_t * 1e-8, rel=1e-9)
    assert history.max() == pytest.approx(friction * normal[0], rel=1e-12)
    arm = r[0] - 0.5e-5
    assert torques[0, 2] == pytest.approx(arm * shear[0, 1], rel=1e-12)
