"""macro.mechanics: the powder's push on a pellet through its sectors of the cells' facets
(Eqs. 4.34-4.38) against the pressure on a hemisphere."""

from __future__ import annotations

import numpy as np
import pytest

from macro.mechanics import Mechanics
from shared.mesh import build_mesh


class _Octahedron(Mechanics):
    """A pellet of radius r at the origin, the six container points (+-1, 0, 0), ... around
    it: the eight octant cells."""

    def __init__(self, r: float) -> None:
        points = np.vstack([np.zeros(3), np.eye(3), -np.eye(3)])
        self.mesh = build_mesh(points)
        self.n_pellets, self.n_vertices, self._radius = 1, 7, r

    def vertex_radii(self) -> np.ndarray:
        return np.array([self._radius, 0, 0, 0, 0, 0, 0], dtype=np.float64)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_pressure_on_one_half_pushes_the_pellet_with_p_times_its_cross_section(axis):
    """The cells on one side of a coordinate plane at P, the others at 0: the pellet is
    pushed across the plane by P pi r^2 (a uniform pressure on a hemisphere); equal
    pressures on both sides push it nowhere."""
    model = _Octahedron(0.3)
    mesh = model.mesh
    assert mesh.n_cells == 8 and mesh.n_facets == 12
    upper = mesh.centroids[:, axis] > 0.0
    force = model.hydro_forces(np.where(upper, 2.0e5, 0.0))
    expected = np.zeros(3)
    expected[axis] = -2.0e5 * np.pi * 0.3**2
    np.testing.assert_allclose(force[0], expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(model.hydro_forces(np.full(8, 2.0e5))[0], 0.0, atol=1e-9)
