"""Particle orientations (imaging.packing.orientation): Euler angles round trip, normals,
downward normals folded up."""

from __future__ import annotations

import numpy as np
import pytest

from imaging.packing import euler_angles, normals, rotation_matrices


def test_euler_round_trip_and_normals() -> None:
    rng = np.random.default_rng(1)
    euler = np.stack([rng.uniform(0, 2 * np.pi, 200), rng.uniform(0.01, np.pi / 2, 200),
                      rng.uniform(0, 2 * np.pi, 200)], axis=1)
    rot = rotation_matrices(euler)
    assert np.allclose(euler_angles(rot), euler, atol=1e-9)
    phi, theta = euler[:, 0], euler[:, 1]
    expected = np.stack(
        [np.sin(theta) * np.sin(phi), -np.sin(theta) * np.cos(phi), np.cos(theta)], 1)
    assert np.allclose(normals(rot), expected, atol=1e-12)


def test_downward_normals_are_folded_up() -> None:
    rot = rotation_matrices([[0.4, 2.5, 1.0]])
    assert euler_angles(rot)[0, 1] == pytest.approx(np.pi - 2.5)
    assert normals(rot)[0, 2] == pytest.approx(-np.cos(2.5))
