"""shared.dem.fire: FIRE's constants, and static equilibria it reaches against closed
forms (Hertz under a body force, Coulomb's limit on a frictional wall)."""

from __future__ import annotations

import numpy as np
import pytest

from shared.dem import FireState, cylinder_contacts, fire_step, yielding_hertz_mindlin

YOUNG, NU = 4e8, 0.3
E_STAR_WALL = YOUNG / (1 - NU**2)
HEIGHT, CYLINDER = 0.1, 0.05
FAR = np.full(1, np.inf)


def test_time_step_grows_after_n_min_positive_steps_and_halves_on_negative_power():
    """Bitzek et al.'s rules with the standard constants: from rest (no power to judge),
    the time step stays at dt_start = 0.1 for N_min = 5 steps of positive power, then
    grows by 1.1 per step (alpha by 0.99); a step of negative power halves it, resets
    alpha to 0.1 and stops every row."""
    state = FireState()
    velocities = np.zeros((2, 3))
    force = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    for _ in range(7):
        fire_step(state, velocities, force, np.ones(2))
    # the first step from rest, then six positive ones: the sixth grows the time step
    assert state.dt == pytest.approx(0.1 * 1.1, rel=1e-12)
    assert state.alpha == pytest.approx(0.1 * 0.99, rel=1e-12)
    step = fire_step(state, velocities, -force, np.ones(2))
    assert state.dt == pytest.approx(0.1 * 1.1 * 0.5, rel=1e-12)
    assert state.alpha == 0.1
    # from rest: v = dt F / m, untouched by the mixing (it is along F already)
    np.testing.assert_allclose(step, -state.dt**2 * force, rtol=1e-12)


def _relax(positions, radii, forces_at, steps=20000, tolerance=1e-10):
    """FIRE on translations until the largest force is below ``tolerance`` times the
    largest load, each mass the sphere's contact stiffness (at least that of a 1e-3 r
    overlap on a plate), each step at most 1e-3 r; returns the positions and the number
    of steps."""
    velocities = np.zeros_like(positions)
    state = FireState()
    floor = 2.0 * E_STAR_WALL * radii * np.sqrt(1e-3)
    moved = np.zeros_like(positions)
    for k in range(steps):
        forces, stiffness, scale = forces_at(positions, moved)
        if np.abs(forces).max() < tolerance * scale:
            return positions, k
        moved = fire_step(state, velocities, forces, np.maximum(stiffness, floor), 1e-3 * radii)
        positions = positions + moved
    raise AssertionError(f"no balance after {steps} steps, largest force {np.abs(forces).max():.3g} N")


def test_sphere_on_a_plate_under_a_body_force_sinks_by_hertz():
    """A sphere of radius r pushed onto the lower plate by F sinks by
    delta = (3 F / (4 E* sqrt(r)))^(2/3), E* = E / (1 - nu^2) (rigid plate)."""
    r, load = 5e-3, 20.0
    radii, young = np.array([r]), np.array([YOUNG])

    def forces_at(x, moved):
        forces = np.array([[0.0, 0.0, -load]])
        stiffness = np.zeros(1)
        plastic, shear = np.zeros((1, 3)), np.zeros((1, 3, 3))
        cylinder_contacts(x, moved, np.zeros((1, 3)), radii, young, NU, 0.0, CYLINDER, -0.5 * HEIGHT,
                          0.5 * HEIGHT, forces, np.zeros((1, 3)), stiffness, FAR, plastic, shear, plastic, shear,
                          np.zeros((1, 3, 3)))
        return forces, stiffness, load

    start = np.array([[0.0, 0.0, -0.5 * HEIGHT + r + 1e-4]])
    positions, _ = _relax(start, radii, forces_at)
    delta = -0.5 * HEIGHT + r - positions[0, 2]
    assert delta == pytest.approx((3.0 * load / (4.0 * E_STAR_WALL * np.sqrt(r))) ** (2.0 / 3.0), rel=1e-8)


def test_column_of_spheres_carries_the_weight_above_each_contact():
    """Three spheres stacked on the lower plate under a body force F each: the plate
    carries 3 F and the contacts above 2 F and F, each sinking by Hertz's
    (3 F_k / (4 E* sqrt(R*)))^(2/3), E* = E / (2 (1 - nu^2)) between equal spheres,
    R* = r / 2; the friction carries nothing (no tangential load)."""
    r, load, n = 4e-3, 5.0, 3
    radii, young = np.full(n, r), np.full(n, YOUNG)
    pairs = np.array([[0, 1], [1, 2]])

    def forces_at(x, moved):
        forces = np.zeros((n, 3))
        forces[:, 2] = -load
        stiffness = np.zeros(n)
        shear, plastic = np.zeros((2, 3)), np.zeros(2)
        yielding_hertz_mindlin(x, moved, np.zeros((n, 3)), radii, young, NU, 0.5, pairs, shear,
                               forces, np.zeros((n, 3)), stiffness, np.full(n, np.inf), plastic, shear, plastic,
                               np.zeros((2, 3)))
        wall_plastic, wall_shear = np.zeros((n, 3)), np.zeros((n, 3, 3))
        cylinder_contacts(x, moved, np.zeros((n, 3)), radii, young, NU, 0.0, CYLINDER, -0.5 * HEIGHT,
                          0.5 * HEIGHT, forces, np.zeros((n, 3)), stiffness, np.full(n, np.inf),
                          wall_plastic, wall_shear, wall_plastic, wall_shear, np.zeros((n, 3, 3)))
        return forces, stiffness, n * load

    start = np.zeros((n, 3))
    start[:, 2] = -0.5 * HEIGHT + r + 2.0 * r * np.arange(n) + 1e-5
    positions, _ = _relax(start, radii, forces_at)
    e_pair = YOUNG / (2.0 * (1.0 - NU**2))
    expected = -0.5 * HEIGHT + r - (3.0 * n * load / (4.0 * E_STAR_WALL * np.sqrt(r))) ** (2.0 / 3.0)
    for k in range(n):
        assert positions[k, 2] == pytest.approx(expected, rel=1e-9)
        if k + 1 < n:
            carried = (n - 1 - k) * load
            expected += 2.0 * r - (3.0 * carried / (4.0 * e_pair * np.sqrt(0.5 * r))) ** (2.0 / 3.0)


def _wall_contact(friction, tangential, steps):
    """A sphere pressed against the curved wall by N = 10 N (along +x) and loaded by
    ``tangential`` along z, its rotation held (a free sphere would roll); FIRE's steps on
    its translation, from a committed state at rest (the steps commit nothing, as in the
    macro model's relaxation). Returns the final position, the wall's trial shear force on
    it and whether it balanced."""
    r, normal = 5e-3, 10.0
    radii, young = np.array([r]), np.array([YOUNG])
    shear, plastic, slip = np.zeros((1, 3, 3)), np.zeros((1, 3)), np.zeros((1, 3, 3))
    x = np.array([[CYLINDER - r + 1e-5, 0.0, 0.0]])
    velocities, state = np.zeros((1, 3)), FireState()
    moved = np.zeros((1, 3))
    for _ in range(steps):
        forces = np.array([[normal, 0.0, tangential]])
        stiffness = np.zeros(1)
        # plates 1 m away: a sliding sphere does not reach them
        cylinder_contacts(x, moved, np.zeros((1, 3)), radii, young, NU, friction, CYLINDER, -1.0, 1.0,
                          forces, np.zeros((1, 3)), stiffness, FAR, plastic, shear, np.zeros((1, 3)),
                          np.zeros((1, 3, 3)), slip)
        if np.abs(forces).max() < 1e-9 * normal:
            return x, shear[0, 0], True
        moved = fire_step(state, velocities, forces, stiffness, np.full(1, 1e-3 * r))
        x = x + moved
    return x, shear[0, 0], False


def test_wall_friction_holds_below_coulomb_and_lets_slide_above():
    """mu = tan(20 deg): a tangential load of 0.9 mu N is held (the shear force balances
    it, the sphere stays within an elastic slip), 1.1 mu N is not (the sphere slides
    along the wall, the shear force at mu N); frictionless, any load slides."""
    mu, normal = np.tan(np.radians(20.0)), 10.0
    x, shear, balanced = _wall_contact(mu, 0.9 * mu * normal, 5000)
    assert balanced
    assert shear[2] == pytest.approx(-0.9 * mu * normal, rel=1e-8)
    # Mindlin's elastic slip T / k_t, k_t = 8 G a / (2 - nu) at a = sqrt(r delta) of
    # N's Hertz overlap: FIRE's overshoots, uncommitted, slid nothing
    r = 5e-3
    a = np.sqrt(r * (3.0 * normal / (4.0 * E_STAR_WALL * np.sqrt(r))) ** (2.0 / 3.0))
    k_t = 8.0 * YOUNG / (2.0 * (1.0 + NU)) * a / (2.0 - NU)
    assert x[0, 2] == pytest.approx(0.9 * mu * normal / k_t, rel=1e-6)
    x, shear, balanced = _wall_contact(mu, 1.1 * mu * normal, 5000)
    assert not balanced
    assert shear[2] == pytest.approx(-mu * normal, rel=1e-9)
    assert x[0, 2] > 1e-3
    x, shear, balanced = _wall_contact(0.0, 1e-3 * normal, 2000)
    assert not balanced and x[0, 2] > 1e-3 and np.all(shear == 0.0)
