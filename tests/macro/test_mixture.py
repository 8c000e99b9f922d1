"""macro.mixture: the container's points, and the solid and facet angles of the cells."""

from __future__ import annotations

import numpy as np
import pytest

from macro.mixture import container_points, facet_angles, solid_angles


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
