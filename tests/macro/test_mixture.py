"""macro.mixture: the cells fill the container (the mesh of the pellet centres and the
container's points), and the solid and facet angles of the cells."""

from __future__ import annotations

import numpy as np
import pytest

from macro.mixture import container_points, facet_angles, solid_angles
from macro.run import build_model
from shared.upscaling import PermeabilityTable
from tests._macro_cases import small_config


def test_cells_fill_the_container_and_the_ends_are_held(table_path):
    """Cell voids plus the pellet parts inside the cells add up to the volume of the
    container's inscribed prism (the rings' polygons; between the exact cylinder and
    it within the chord loss n sin(2 pi / n) / (2 pi)); no pellet is on the mesh's hull, so
    the solid angles around each add up to 4 pi and the pellet parts to the pellets'
    volume (round-off); held cells are those on a plate."""
    config = small_config()
    model = build_model(config, "small", PermeabilityTable.from_file(table_path, "free"))
    macro = config["macro"]
    height, radius = macro["cylinder_height_m"], macro["cylinder_radius_m"]
    cylinder = np.pi * radius**2 * height
    mesh = model.mesh
    spacing = 2.0 * float(model.radii.mean())
    n_around = int(np.ceil(2.0 * np.pi * radius / spacing))
    polygon = n_around * np.sin(2.0 * np.pi / n_around) / (2.0 * np.pi)
    assert polygon * cylinder * (1.0 - 0.01) < mesh.volumes.sum() <= cylinder * (1.0 + 1e-9)
    pellets = (4.0 / 3.0 * np.pi * model.radii**3).sum()
    np.testing.assert_allclose(model.initial_void.sum() + pellets, mesh.volumes.sum(), rtol=1e-9)
    # every container point is a vertex; held cells touch a plate, free cells do not
    assert np.unique(mesh.tetrahedra).size == model.n_pellets + model.container.shape[0]
    n_p = model.n_pellets
    touches = model.on_plate[mesh.tetrahedra].any(axis=1)
    held, inert = model.held[n_p:], model.inert[n_p:]
    np.testing.assert_array_equal(held, touches & ~inert)
    assert model.neglected_void_fraction() < 0.05


def test_container_points_lie_on_the_wall_and_plates_without_cocircular_rings(rng):
    """Points on the cylinder or a plate, spaced about as asked, and no two on one ring at
    exactly the same height (the jitter that keeps the Delaunay cells from going flat)."""
    points, on_plate = container_points(0.1, 0.02, 0.005, rng)
    rho = np.hypot(points[:, 0], points[:, 1])
    side = np.isclose(rho, 0.02, rtol=1e-12)
    ends = np.isclose(np.abs(points[:, 2]), 0.05, rtol=1e-12)
    assert (side | ends).all() and (on_plate == ends).all()
    inner = points[side & ~ends]
    assert np.unique(inner[:, 2]).size == inner.shape[0]
    from scipy.spatial import cKDTree

    nearest = cKDTree(points).query(points, k=2)[0][:, 1]
    assert 0.5 * 0.005 < np.median(nearest) < 1.2 * 0.005


def test_solid_and_facet_angles_of_the_corner_tetrahedron():
    """The corner (0, e_x, e_y, e_z): an octant, 4 pi / 8, at the right-angled corner; at
    each other vertex the spherical excess of its three dihedral angles (Girard), pi / 2
    on its axis and arccos(1 / sqrt 3) twice against the slanted face, less pi. Every
    face's angles sum to pi, the equilateral face's are pi / 3, the right ones' pi / 2."""
    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    omega = solid_angles(points, np.array([[0, 1, 2, 3]]))
    assert omega[0, 0] == pytest.approx(np.pi / 2, rel=1e-12)
    np.testing.assert_allclose(omega[0, 1:], np.pi / 2 + 2.0 * np.arccos(1.0 / np.sqrt(3.0)) - np.pi, rtol=1e-12)
    faces = np.array([[1, 2, 3], [0, 1, 2], [0, 2, 3], [0, 3, 1]])
    angles = facet_angles(points, faces)
    np.testing.assert_allclose(angles.sum(axis=1), np.pi, rtol=1e-12)
    np.testing.assert_allclose(angles[0], np.pi / 3, rtol=1e-12)
    np.testing.assert_allclose(angles[1:, 0], np.pi / 2, rtol=1e-12)
