"""Hydro-mechanical point forces (Eqs. 3.28-3.32) and point suctions (Sec. 3.3.5)."""

import numpy as np
import pytest

from micro.forces import (
    facet_vertex_weights,
    hydromechanical_forces,
    point_suction,
    sector_weights,
)
from shared.mesh import build_mesh

EDGE = 1e-3


@pytest.fixture(scope="module")
def cube():
    """Mesh of a unit-mm cube: corners, random points on each face, random interior."""
    rng = np.random.default_rng(5)
    corners = np.array(np.meshgrid([0, EDGE], [0, EDGE], [0, EDGE])).reshape(3, -1).T
    faces = []
    for axis in range(3):
        for side in (0.0, EDGE):
            points = rng.uniform(0.05 * EDGE, 0.95 * EDGE, (12, 3))
            points[:, axis] = side
            faces.append(points)
    interior = rng.uniform(0.1 * EDGE, 0.9 * EDGE, (60, 3))
    points = np.vstack([corners, *faces, interior])
    radii = rng.uniform(0.05, 0.1, points.shape[0]) * EDGE
    return build_mesh(points), radii


def test_sector_weights_of_two_triangles():
    triangle = np.array([[0, 0, 0], [1.0, 0, 0], [0.5, np.sqrt(3) / 2, 0]])
    np.testing.assert_allclose(facet_vertex_weights(triangle, np.ones(3), [[0, 1, 2]]),
                               [[1 / 3, 1 / 3, 1 / 3]], rtol=1e-14)
    # right angle at vertex 0, radii 1, 1, 2: sectors pi/4, pi/8, pi/2 (x 1/2)
    corner = np.array([[0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]])
    np.testing.assert_allclose(facet_vertex_weights(corner, [1.0, 1.0, 2.0], [[0, 1, 2]]),
                               [[2 / 7, 1 / 7, 4 / 7]], rtol=1e-14)


def test_uniform_pressure_loads_only_the_hull(cube):
    mesh, radii = cube
    pressure, saturation = -2e6, 0.4  # chi p = -0.8 MPa: suction pulls the faces in
    forces = hydromechanical_forces(
        mesh, mesh.points, radii, np.full(mesh.n_cells, pressure),
        np.full(mesh.n_cells, saturation),
    )
    scale = 0.8e6 * EDGE**2
    on_hull = np.unique(mesh.boundary_vertices)
    interior = np.setdiff1d(np.arange(mesh.points.shape[0]), on_hull)
    assert interior.size >= 50
    np.testing.assert_allclose(forces[interior], 0.0, atol=1e-13 * scale)
    for axis in range(3):
        for side, sign in ((0.0, -1.0), (EDGE, 1.0)):
            on_face = mesh.points[:, axis] == side
            total = forces[on_face, axis].sum()
            assert total == pytest.approx(sign * pressure * saturation * EDGE**2, rel=1e-12)
    np.testing.assert_allclose(forces.sum(axis=0), 0.0, atol=1e-12 * scale)


def test_linear_pressure_gives_seepage_force_minus_gradient_times_volume(cube):
    """With the exterior continuing the field, the points feel -grad(p) V in total."""
    mesh, radii = cube
    gradient = np.array([3e9, -1e9, 2e9])  # Pa/m
    forces = hydromechanical_forces(
        mesh, mesh.points, radii, mesh.centroids @ gradient, np.ones(mesh.n_cells),
        exterior_pressure=mesh.boundary_centroids @ gradient,
    )
    np.testing.assert_allclose(forces.sum(axis=0), -gradient * EDGE**3, rtol=1e-10)


def test_forces_follow_moved_points(cube):
    mesh, radii = cube
    stretched = mesh.points * np.array([2.0, 1.0, 1.0])
    forces = hydromechanical_forces(
        mesh, stretched, radii, np.full(mesh.n_cells, 1e5), np.ones(mesh.n_cells)
    )
    top = stretched[:, 2] == EDGE
    assert forces[top, 2].sum() == pytest.approx(1e5 * 2.0 * EDGE**2, rel=1e-12)


def test_point_suction_is_volume_weighted_mean_with_guard():
    tetrahedra = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    volumes = np.array([1e-12, 3e-12])
    suction = np.array([1e6, 2e6])
    result = point_suction(tetrahedra, volumes, suction, n_points=6)
    expected_shared = (1e-12 * 1e6 + 3e-12 * 2e6) / 4e-12
    np.testing.assert_allclose(
        result, [1e6, expected_shared, expected_shared, expected_shared, 2e6, expected_shared],
        rtol=1e-14,
    )
    guarded = point_suction(tetrahedra, volumes, suction, n_points=6, fallback=5e5)
    assert guarded[5] == 5e5 and np.all(np.isfinite(guarded))


def test_kernel_matches_numpy_reference_for_random_fields(cube):
    mesh, radii = cube
    rng = np.random.default_rng(8)
    stress = rng.uniform(-1e6, 0.0, mesh.n_cells)
    forces = hydromechanical_forces(mesh, mesh.points, radii, stress, np.ones(mesh.n_cells))
    expected = np.zeros_like(mesh.points)
    for vertices, normals, areas, jumps in (
        (mesh.facet_vertices, mesh.facet_normals, mesh.facet_areas,
         stress[mesh.facet_cells[:, 0]] - stress[mesh.facet_cells[:, 1]]),
        (mesh.boundary_vertices, mesh.boundary_normals, mesh.boundary_areas,
         stress[mesh.boundary_cells]),
    ):
        weights = facet_vertex_weights(mesh.points, radii, vertices)
        for k in range(3):
            np.add.at(expected, vertices[:, k],
                      (weights[:, k] * jumps * areas)[:, None] * normals)
    np.testing.assert_allclose(forces, expected, rtol=1e-9, atol=1e-12 * 1e6 * EDGE**2)


def test_weights_computed_in_the_kernel_equal_precomputed_ones(cube):
    """The on-the-fly sector weights equal sector_weights of the same moved points."""
    mesh, radii = cube
    rng = np.random.default_rng(11)
    moved = mesh.points + rng.uniform(-0.02, 0.02, mesh.points.shape) * EDGE
    swollen = radii * rng.uniform(1.0, 1.2, radii.shape)
    pressure = rng.uniform(-1e7, -1e6, mesh.n_cells)
    saturation = rng.uniform(0.3, 1.0, mesh.n_cells)
    on_the_fly = hydromechanical_forces(mesh, moved, swollen, pressure, saturation)
    precomputed = hydromechanical_forces(
        mesh, moved, swollen, pressure, saturation,
        weights=sector_weights(mesh, moved, swollen),
    )
    np.testing.assert_allclose(on_the_fly, precomputed, rtol=0,
                               atol=1e-13 * np.abs(precomputed).max())
    # Weights of the unmoved points are visibly different: the kernel uses the current ones.
    stale = hydromechanical_forces(
        mesh, moved, swollen, pressure, saturation,
        weights=sector_weights(mesh, mesh.points, radii),
    )
    assert np.abs(stale - precomputed).max() > 1e-6 * np.abs(precomputed).max()
