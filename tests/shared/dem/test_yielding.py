"""Contacts of swelling pellets (shared.dem.yielding): Hertz-Mindlin with yield and the
cylinder, against closed forms (Eqs. 4.1-4.9)."""

from __future__ import annotations

import numpy as np
import pytest

from shared.dem import cylinder_contacts as container_contacts
from shared.dem import yielding_hertz_mindlin as hertz_mindlin_pairs


def _pair(overlap, young=(8e8, 4e8)):
    r = np.array([6e-3, 4e-3])
    positions = np.array([[0.0, 0.0, 0.0], [r.sum() - overlap, 0.0, 0.0]])
    return positions, r, np.array(young)


def test_normal_force_is_hertz_with_the_harmonic_modulus():
    positions, r, young = _pair(1e-5)
    nu = 0.3
    forces, torques, stiffness = np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(2)
    shear, plastic = np.zeros((1, 3)), np.zeros(1)
    normal = hertz_mindlin_pairs(positions, np.zeros((2, 3)), np.zeros((2, 3)), r, young, nu, 0.5,
                                 np.array([[0, 1]]), shear, forces, torques, stiffness,
                                 np.full(2, np.inf), plastic, shear, plastic, np.zeros((1, 3)))
    e_star = 1.0 / ((1 - nu**2) / young[0] + (1 - nu**2) / young[1])  # Eq. 4.2
    r_star = r[0] * r[1] / r.sum()
    expected = 4.0 / 3.0 * e_star * np.sqrt(r_star) * 1e-5**1.5  # Eq. 4.1
    assert normal[0] == pytest.approx(expected, rel=1e-12)
    assert forces[0, 0] == pytest.approx(-expected) and forces[1, 0] == pytest.approx(expected)


def test_shear_grows_with_mindlin_stiffness_until_coulomb():
    """Pellet 0 slides along y by 1e-8 m per substep, each committed: the shear force on
    it is -k_t * slip, k_t = 4 G a / (2 - nu) with G the mean shear modulus, until it
    reaches tan(phi) F_n; the torques are the arms times the shear force."""
    positions, r, young = _pair(1e-5)
    nu, friction = 0.3, np.tan(np.radians(30.0))
    shear = np.zeros((1, 3))
    moved = np.array([[0.0, 1e-8, 0.0], [0.0, 0.0, 0.0]])
    a = np.sqrt(r[0] * r[1] / r.sum() * 1e-5)
    k_t = 4.0 * (0.5 * (young[0] + young[1]) / (2 * (1 + nu))) * a / (2 - nu)
    history = []
    for _ in range(600):
        forces, torques, stiffness = np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(2)
        plastic = np.zeros(1)
        normal = hertz_mindlin_pairs(positions, moved, np.zeros((2, 3)), r, young, nu, friction,
                                     np.array([[0, 1]]), shear, forces, torques, stiffness,
                                     np.full(2, np.inf), plastic, shear, plastic, np.zeros((1, 3)))
        history.append(-shear[0, 1])
    history = np.array(history)
    assert history[0] == pytest.approx(k_t * 1e-8, rel=1e-9)
    assert history[3] == pytest.approx(4 * k_t * 1e-8, rel=1e-9)
    assert history.max() == pytest.approx(friction * normal[0], rel=1e-12)
    arm = r[0] - 0.5e-5
    assert torques[0, 2] == pytest.approx(arm * shear[0, 1], rel=1e-12)


def test_uncommitted_shear_depends_on_the_end_displacement_not_the_path():
    """Pellet 0 slides 200 substeps of 5e-8 m along y, past Coulomb's limit, then 150 back.
    Uncommitted (the committed force 0 throughout), its trial shear force is that of the net
    2.5e-6 m in one go, -k_t 2.5e-6 below the limit: a solver's iterations slide nothing.
    Committed at every substep, the contact slid at tan(phi) F_n and unloads elastically
    from there, to k_t 7.5e-6 - tan(phi) F_n on the other side."""
    positions, r, young = _pair(1e-5)
    nu, friction, step = 0.3, np.tan(np.radians(30.0)), 5e-8
    a = np.sqrt(r[0] * r[1] / r.sum() * 1e-5)
    k_t = 4.0 * (0.5 * (young[0] + young[1]) / (2 * (1 + nu))) * a / (2 - nu)
    committed, slip = np.zeros((1, 3)), np.zeros((1, 3))
    explicit = np.zeros((1, 3))
    for sign in [1.0] * 200 + [-1.0] * 150:
        moved = np.array([[0.0, sign * step, 0.0], [0.0, 0.0, 0.0]])
        args = (positions, moved, np.zeros((2, 3)), r, young, nu, friction, np.array([[0, 1]]))
        trial, plastic = np.zeros((1, 3)), np.zeros(1)
        normal = hertz_mindlin_pairs(*args, trial, np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(2),
                                     np.full(2, np.inf), plastic, committed, np.zeros(1), slip)
        hertz_mindlin_pairs(*args, explicit, np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(2),
                            np.full(2, np.inf), plastic, explicit, plastic, np.zeros((1, 3)))
    limit = friction * normal[0]
    assert k_t * 200 * step > limit > k_t * 50 * step and k_t * 150 * step < 2.0 * limit
    np.testing.assert_allclose(slip[0], [0.0, 50 * step, 0.0], rtol=1e-9, atol=1e-20)
    np.testing.assert_allclose(trial[0], [0.0, -k_t * 50 * step, 0.0], rtol=1e-9, atol=1e-15)
    assert explicit[0, 1] == pytest.approx(k_t * 150 * step - limit, rel=1e-9)


def _loaded(overlaps, yield_force, plastic):
    """Normal force of the pair at each overlap in turn (the plastic overlap carried)."""
    out = []
    for overlap in overlaps:
        positions, r, young = _pair(overlap)
        forces, torques, stiffness = np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(2)
        shear = np.zeros((1, 3))
        out.append(hertz_mindlin_pairs(positions, np.zeros((2, 3)), np.zeros((2, 3)), r, young, 0.3, 0.5,
                                       np.array([[0, 1]]), shear, forces, torques, stiffness,
                                       yield_force, plastic, shear, plastic, np.zeros((1, 3)))[0])
    return np.array(out)


def test_contact_yields_at_eq_4_4_and_unloads_elastically():
    """Hertz up to the yield force F_y (the weaker pellet's), where the mean contact
    pressure reaches p_y = F_y / (pi R* delta_y); past it F = pi p_y R* delta, so twice the
    yield overlap carries exactly 2 F_y; unloading is Hertz from the plastic overlap
    delta_p = delta - (F / (4/3 E* sqrt(R*)))^(2/3), and the force vanishes there."""
    _, r, young = _pair(0.0)
    nu = 0.3
    e_star = 1.0 / ((1 - nu**2) / young[0] + (1 - nu**2) / young[1])
    r_star = r[0] * r[1] / r.sum()
    hertz = 4.0 / 3.0 * e_star * np.sqrt(r_star)
    f_y = 20.0
    d_y = (f_y / hertz) ** (2.0 / 3.0)
    plastic = np.zeros(1)
    strength = np.array([50.0, f_y])
    force = _loaded([0.5 * d_y, d_y, 2.0 * d_y], strength, plastic)
    assert force[0] == pytest.approx(hertz * (0.5 * d_y) ** 1.5, rel=1e-12)
    assert force[1] == pytest.approx(f_y, rel=1e-9)
    assert force[2] == pytest.approx(2.0 * f_y, rel=1e-9)
    d_p = 2.0 * d_y - (2.0 * f_y / hertz) ** (2.0 / 3.0)
    assert plastic[0] == pytest.approx(d_p, rel=1e-9)
    back = _loaded([1.5 * d_y, d_p + 1e-9 * d_y, 2.0 * d_y], strength, plastic)
    assert back[0] == pytest.approx(hertz * (1.5 * d_y - d_p) ** 1.5, rel=1e-9)
    assert back[1] < 1e-12 * f_y
    assert back[2] == pytest.approx(2.0 * f_y, rel=1e-9)  # reloading to the last point


def test_plate_contact_yields_like_a_pair_with_a_rigid_flat():
    """A pellet pressed into the lower plate by twice its yield overlap carries 2 F_y
    (R* = r, E* = E / (1 - nu^2)); the curved wall and the upper plate carry nothing."""
    r, young, nu, f_y = 6e-3, 4e8, 0.3, 30.0
    hertz = 4.0 / 3.0 * young / (1 - nu**2) * np.sqrt(r)
    d_y = (f_y / hertz) ** (2.0 / 3.0)
    positions = np.array([[0.0, 0.0, -0.05 + r - 2.0 * d_y]])
    forces, stiffness, plastic, shear = np.zeros((1, 3)), np.zeros(1), np.zeros((1, 3)), np.zeros((1, 3, 3))
    rest = np.zeros((1, 3))
    radial, lower, upper = container_contacts(positions, rest, rest, np.array([r]), np.array([young]), nu, 0.0,
                                              0.03, -0.05, 0.05, forces, np.zeros((1, 3)), stiffness,
                                              np.array([f_y]), plastic, shear, plastic, shear, np.zeros((1, 3, 3)))
    assert lower[0] == pytest.approx(2.0 * f_y, rel=1e-9) and forces[0, 2] == pytest.approx(2.0 * f_y, rel=1e-9)
    assert radial[0] == 0.0 and upper[0] == 0.0 and plastic[0, 1] > 0.0
