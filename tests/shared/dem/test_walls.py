"""Rigid walls: Hertz force of a sphere on a wall, free swelling, servo stress control."""

from dataclasses import replace

import numpy as np
import pytest

from shared.dem import (
    cube_points,
    new_state,
    stable_time_step,
    step,
    unbalanced_force,
    wall_forces,
    walls_around,
)
from tests._defaults import DEM


def wall_stresses(walls, loads):
    """(6,) compressive stress on each wall [Pa]: force over current face area."""
    return loads.force / walls.face_areas()


def test_sphere_on_wall_is_hertz_with_rigid_wall():
    state = new_state(np.array([[0.0, 0.0, 0.0]]), np.array([1e-4]), DEM)
    walls = walls_around(state.positions, state.radii)
    walls.upper[2] -= 3e-6  # top wall indents the sphere by 3 um
    forces = np.zeros((1, 3))
    loads = wall_forces(state, walls, forces, DEM)
    expected = 4.0 / 3.0 * 100e8 / (1.0 - 0.3**2) * np.sqrt(1e-4) * 3e-6**1.5
    assert forces[0] == pytest.approx([0.0, 0.0, -expected], rel=1e-12)
    assert loads.force[5] == pytest.approx(expected, rel=1e-12)
    assert np.count_nonzero(loads.force) == 1


def test_inactive_walls_leave_free_swelling_unconstrained():
    positions, radii = cube_points(27, np.random.default_rng(0), edge_length=3e-4)
    state = new_state(positions, radii, DEM)
    walls = walls_around(positions, radii, active=False)
    state.radii *= 1.05
    forces = np.zeros_like(positions)
    loads = wall_forces(state, walls, forces, DEM)
    assert np.all(forces == 0.0) and np.all(loads.force == 0.0)


def test_servo_walls_reach_confining_stress():
    target = 2e6
    parameters = replace(DEM, wall_max_velocity=0.5, wall_gain=0.5)
    positions, radii = cube_points(
        64, np.random.default_rng(2), edge_length=4e-4, jitter=0.1, radius_factor=1.01
    )
    state = new_state(positions, radii, DEM)
    walls = walls_around(positions, radii, target_stress=target)
    walls.lower -= 1e-6  # start just off the specimen
    walls.upper += 1e-6
    for _ in range(1500):
        time_step = stable_time_step(state, parameters, walls)
        report = step(state, time_step, parameters, walls=walls)
    np.testing.assert_allclose(wall_stresses(walls, report.wall_loads), target, rtol=1e-3)
    assert unbalanced_force(report.forces, report.normal_forces) < 1e-3


def test_confined_cubic_lattice_overlaps_follow_hertz():
    """A 4 x 4 x 4 simple cubic lattice under 5 MPa per axis: each of the 16 columns
    carries sigma A / 16, so neighbour centres sit 2 r - delta apart with
    F = 4/3 E* sqrt(r / 2) delta^(3/2) (delta = 1.2 um here, matched to 1e-9)."""
    target = 5e6
    parameters = replace(DEM, wall_max_velocity=0.5, wall_gain=0.5)
    positions, radii = cube_points(
        64, np.random.default_rng(0), edge_length=4e-4, jitter=0.0, radius_factor=1.001
    )
    state = new_state(positions, radii, DEM)
    walls = walls_around(positions, radii, target_stress=target)
    for _ in range(3000):
        report = step(state, stable_time_step(state, parameters, walls), parameters, walls=walls)
    column_force = target * walls.face_areas()[0] / 16
    e_star = 100e8 / (2.0 * (1.0 - 0.3**2))
    overlap = (column_force / (4.0 / 3.0 * e_star * np.sqrt(radii[0] / 2))) ** (2.0 / 3.0)
    i, j = state.contacts.pairs[report.normal_forces > 0].T
    spacing = np.linalg.norm(state.positions[j] - state.positions[i], axis=1)
    assert spacing.size == 3 * 48
    np.testing.assert_allclose(2 * radii[0] - spacing, overlap, rtol=1e-9)
