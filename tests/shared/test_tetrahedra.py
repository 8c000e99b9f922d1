"""shared.tetrahedra: signed volumes, centroids and circumcentres against a hand-computed
tetrahedron and the properties that define them."""

from __future__ import annotations

import numpy as np
import pytest

from shared.tetrahedra import cell_geometry, cell_volumes

# the corner tetrahedron scaled by (2, 3, 4): volume 2 * 3 * 4 / 6 = 4, centroid (0.5, 0.75, 1),
# circumcentre (1, 1.5, 2) (the box's centre: the corner's sphere passes through the box's
# vertices)
CORNER = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 4.0]])


def test_the_corner_tetrahedron_by_hand() -> None:
    cells = np.array([[0, 1, 2, 3], [0, 2, 1, 3]])
    np.testing.assert_allclose(cell_volumes(CORNER, cells), [4.0, -4.0], rtol=1e-15)
    signed, centroids, circumcentres = cell_geometry(CORNER, cells.astype(np.int64))
    np.testing.assert_allclose(signed, [4.0, -4.0], rtol=1e-15)
    np.testing.assert_allclose(centroids, [[0.5, 0.75, 1.0]] * 2, rtol=1e-15)
    np.testing.assert_allclose(circumcentres, [[1.0, 1.5, 2.0]] * 2, rtol=1e-14)


def test_random_cells_against_determinants_and_equidistant_centres(rng: np.random.Generator) -> None:
    """Volumes as det[p - o, q - o, r - o] / 6 (numpy); circumcentres equidistant from the
    four vertices; a translation changes neither volume nor relative centres; the volumes
    of a cube's six Kuhn tetrahedra add up to the cube's."""
    points = rng.normal(size=(40, 3))
    cells = np.array([rng.choice(40, 4, replace=False) for _ in range(30)], dtype=np.int64)
    corners = points[cells]
    det = np.linalg.det(corners[:, 1:] - corners[:, :1]) / 6.0
    np.testing.assert_allclose(cell_volumes(points, cells), det, rtol=1e-10, atol=1e-14)
    signed, centroids, circumcentres = cell_geometry(points, cells)
    np.testing.assert_allclose(signed, det, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(centroids, corners.mean(axis=1), rtol=1e-12, atol=1e-14)
    radii = np.linalg.norm(corners - circumcentres[:, None], axis=2)
    np.testing.assert_allclose(radii, radii[:, :1].repeat(4, axis=1), rtol=1e-8)
    shift = np.array([10.0, -5.0, 3.0])
    moved = cell_geometry(points + shift, cells)
    np.testing.assert_allclose(moved[0], signed, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(moved[2] - shift, circumcentres, rtol=1e-6, atol=1e-9)
    cube = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=np.float64)
    # Kuhn's triangulation of the unit cube along the diagonal 0 -> 7
    kuhn = np.array([[0, 4, 6, 7], [0, 6, 2, 7], [0, 2, 3, 7], [0, 3, 1, 7], [0, 1, 5, 7], [0, 5, 4, 7]])
    volumes = cell_volumes(cube, kuhn)
    assert np.abs(volumes).sum() == pytest.approx(1.0, rel=1e-14)
    np.testing.assert_allclose(np.abs(volumes), 1.0 / 6.0, rtol=1e-14)


def test_a_flat_cell_has_zero_volume_and_no_circumcentre() -> None:
    flat = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    cells = np.array([[0, 1, 2, 3]], dtype=np.int64)
    assert cell_volumes(flat, cells)[0] == 0.0
    signed, _, circumcentres = cell_geometry(flat, cells)
    assert signed[0] == 0.0 and np.isnan(circumcentres).all()
