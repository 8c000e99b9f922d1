"""Delaunay mesh geometry: hand-made mesh, hull volume, closure, walls, porosity grid."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from scipy.spatial import ConvexHull

from shared.mesh import (
    WALLS,
    boundary_cell_mask,
    build_mesh,
    cell_volumes,
    mesh_from_tetrahedra,
    porosity_at_points,
    update_mesh,
)


def jittered_grid(per_side: int, rng: np.random.Generator, jitter: float = 0.25) -> np.ndarray:
    spacing = 1.0 / per_side
    axis = (np.arange(per_side) + 0.5) * spacing
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    return grid + rng.uniform(-jitter, jitter, grid.shape) * spacing


# O, e1, e2, e3 and P = (0.8, 0.8, 0.8): P lies inside the circumsphere of the unit
# tetrahedron, so the Delaunay mesh is the three tetrahedra (O, P, e_a, e_b) around the
# edge O-P (a 2-3 flip), with hand-computable geometry.
HAND_POINTS = np.array(
    [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.8, 0.8, 0.8]], dtype=np.float64
)


def test_mesh_hand_made_geometry() -> None:
    mesh = build_mesh(HAND_POINTS)
    assert mesh.n_cells == 3
    assert mesh.n_facets == 3
    # Each cell: |P . (e_a x e_b)| / 6 = 0.8 / 6 m3.
    np.testing.assert_allclose(mesh.volumes, 0.8 / 6.0, rtol=1e-14)
    # Internal triangles (O, P, e_a): 1/2 |e_a x P| = 0.4 sqrt(2).
    np.testing.assert_allclose(mesh.facet_areas, 0.4 * np.sqrt(2.0), rtol=1e-14)
    # Circumcentres are permutations of (0.5, 0.5, 0.2): dual lengths 0.3 sqrt(2).
    sorted_centres = np.sort(mesh.circumcentres, axis=1)
    np.testing.assert_allclose(sorted_centres, [[0.2, 0.5, 0.5]] * 3, atol=1e-14)
    np.testing.assert_allclose(mesh.facet_lengths, 0.3 * np.sqrt(2.0), rtol=1e-13)
    assert not mesh.facet_length_fallback.any()
    # Hull: three right triangles of area 1/2 and three of area sqrt(1.64)/2.
    np.testing.assert_allclose(
        np.sort(mesh.boundary_areas), [0.5] * 3 + [0.5 * np.sqrt(1.64)] * 3, rtol=1e-13
    )


def test_mesh_hand_made_normals_and_walls() -> None:
    mesh = build_mesh(HAND_POINTS)
    centre = HAND_POINTS.mean(axis=0)
    outward = np.einsum("ij,ij->i", mesh.boundary_normals, mesh.boundary_centroids - centre)
    assert np.all(outward > 0.0)
    # The coordinate-plane triangles face -x, -y, -z exactly.
    faces = np.isclose(mesh.boundary_areas, 0.5)
    assert sorted(WALLS[w] for w in mesh.boundary_walls[faces]) == ["x-", "y-", "z-"]
    # Normals of internal facets point from cell i to cell j.
    i, j = mesh.facet_cells.T
    towards = np.einsum("ij,ij->i", mesh.facet_normals, mesh.centroids[j] - mesh.centroids[i])
    assert np.all(towards > 0.0)


def test_mesh_volumes_sum_to_convex_hull(rng: np.random.Generator) -> None:
    points = jittered_grid(7, rng) * 7e-3
    mesh = build_mesh(points)
    assert np.all(mesh.volumes > 0.0)
    assert mesh.volumes.sum() == pytest.approx(ConvexHull(points).volume, rel=1e-12)


def test_mesh_cells_are_closed_and_dual_lengths_positive(rng: np.random.Generator) -> None:
    mesh = build_mesh(jittered_grid(6, rng))
    closure = np.zeros((mesh.n_cells, 3))
    weighted = mesh.facet_areas[:, None] * mesh.facet_normals
    np.add.at(closure, mesh.facet_cells[:, 0], weighted)
    np.add.at(closure, mesh.facet_cells[:, 1], -weighted)
    np.add.at(closure, mesh.boundary_cells, mesh.boundary_areas[:, None] * mesh.boundary_normals)
    assert np.abs(closure).max() < 1e-12 * mesh.facet_areas.mean()
    assert np.all(mesh.facet_lengths > 0.0)
    # Each internal facet is shared by exactly two cells, each hull facet by one.
    assert 2 * mesh.n_facets + mesh.boundary_cells.size == 4 * mesh.n_cells


def test_mesh_dual_length_fallback_on_degenerate_ratio(rng: np.random.Generator) -> None:
    points = jittered_grid(5, rng)
    strict = build_mesh(points, min_dual_length_ratio=np.inf)
    assert strict.facet_length_fallback.all()
    i, j = strict.facet_cells.T
    distance = np.linalg.norm(strict.centroids[j] - strict.centroids[i], axis=1)
    np.testing.assert_allclose(strict.facet_lengths, distance, rtol=1e-14)


def test_mesh_boundary_layer_touches_its_wall(rng: np.random.Generator) -> None:
    per_side = 6
    mesh = build_mesh(jittered_grid(per_side, rng))
    layer = 0.5 / per_side
    low = boundary_cell_mask(mesh, ["x-"])
    high = boundary_cell_mask(mesh, ["x+"])
    assert low.sum() > per_side**2 and high.sum() > per_side**2
    # No cell, not even a hull sliver, spans the box from one wall to the opposite one.
    assert not np.any(low & high)
    # distances from the face plane: the mean x of the 36 points with the smallest x
    plane = np.sort(mesh.points[:, 0])[: per_side**2].mean()
    nearest = mesh.points[mesh.tetrahedra[low], 0].min(axis=1) - plane
    hull_cells = np.isin(np.flatnonzero(low), mesh.boundary_cells[mesh.boundary_walls == 0])
    assert np.all((nearest <= layer + 1e-15) | hull_cells)
    assert np.all(mesh.centroids[low, 0] - plane <= 2 * layer * (1 + 1e-12))
    everywhere = boundary_cell_mask(mesh, list(WALLS))
    assert everywhere.sum() < mesh.n_cells


def test_mesh_boundary_layers_leave_out_slivers_along_a_concave_edge() -> None:
    """A dented edge (along z) is filled by a hull sliver spanning 0.8 of the box in z;
    it touches both z walls with a vertex but belongs to neither layer."""
    n = 6
    rng = np.random.default_rng(1)
    grid = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    points = (grid + 0.5 + rng.uniform(-0.2, 0.2, (n**3, 3))) / n
    edge = (points[:, 0] > 1 - 1 / n) & (points[:, 1] < 1 / n)
    points[edge, :2] += np.array([-0.6, 0.6]) / n
    mesh = build_mesh(points)
    spans = np.ptp(mesh.points[mesh.tetrahedra, 2], axis=1) > 0.75
    assert np.any(spans)  # the sliver is there
    low, high = boundary_cell_mask(mesh, ["z-"]), boundary_cell_mask(mesh, ["z+"])
    assert not np.any(low & high) and not np.any((low | high) & spans)


def test_mesh_boundary_layer_survives_a_point_pushed_out_of_its_face(
    rng: np.random.Generator,
) -> None:
    """One point 2 spacings out of the y+ face: the layer still holds the face's cells."""
    per_side = 6
    points = jittered_grid(per_side, rng)
    points[np.argmax(points[:, 1]), 1] += 2.0 / per_side
    mesh = build_mesh(points)
    assert boundary_cell_mask(mesh, ["y+"]).sum() > per_side**2


def test_mesh_rejects_coplanar_points() -> None:
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0.5, 0.5, 0]], dtype=float)
    with pytest.raises(ValueError):
        build_mesh(flat)


def porosity_grid(values: np.ndarray, spacing: float = 0.25) -> xr.DataArray:
    axis = np.arange(values.shape[0]) * spacing - spacing
    return xr.DataArray(values, dims=("z", "y", "x"), coords={"z": axis, "y": axis, "x": axis})


def test_mesh_porosity_trilinear_is_exact_for_linear_fields(rng: np.random.Generator) -> None:
    mesh = build_mesh(jittered_grid(5, rng))
    axis = np.arange(7) * 0.25 - 0.25
    z, y, x = np.meshgrid(axis, axis, axis, indexing="ij")
    grid = porosity_grid(0.3 + 0.05 * x - 0.03 * y + 0.02 * z)
    expected = 0.3 + mesh.centroids @ np.array([0.05, -0.03, 0.02])
    np.testing.assert_allclose(porosity_at_points(mesh.centroids, grid), expected, rtol=1e-13)


def test_mesh_porosity_grid_errors(rng: np.random.Generator) -> None:
    mesh = build_mesh(jittered_grid(4, rng))
    good = np.full((7, 7, 7), 0.3)
    bad = good.copy()
    bad[3, 3, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        porosity_at_points(mesh.centroids, porosity_grid(bad))
    bad[3, 3, 3] = 1.0
    with pytest.raises(ValueError, match=r"\(0, 1\)"):
        porosity_at_points(mesh.centroids, porosity_grid(bad))
    with pytest.raises(ValueError, match="does not cover"):
        porosity_at_points(mesh.centroids, porosity_grid(good[:3, :3, :3]))
    with pytest.raises(ValueError, match="dims"):
        porosity_at_points(mesh.centroids, porosity_grid(good).transpose("x", "y", "z"))


def test_mesh_update_with_moved_points_detects_inversion(rng: np.random.Generator) -> None:
    mesh = build_mesh(jittered_grid(5, rng))
    moved = mesh.points + rng.normal(0.0, 1e-3, mesh.points.shape)
    updated = mesh_from_tetrahedra(moved, mesh.tetrahedra, mesh.neighbours, reorient=False)
    np.testing.assert_array_equal(updated.facet_cells, mesh.facet_cells)
    # Moved points no longer form a convex hull: compare with the divergence theorem
    # on the (same) boundary triangles, V = 1/3 sum (x_f . n_f) A_f.
    enclosed = np.sum(
        np.einsum("ij,ij->i", updated.boundary_centroids, updated.boundary_normals)
        * updated.boundary_areas
    ) / 3.0
    assert updated.volumes.sum() == pytest.approx(enclosed, rel=1e-12)
    inverted = mesh.points.copy()
    a, b, c, d = mesh.tetrahedra[0]
    # Reflect vertex a through the plane of the opposite face (b, c, d).
    normal = np.cross(inverted[c] - inverted[b], inverted[d] - inverted[b])
    normal /= np.linalg.norm(normal)
    inverted[a] -= 2.0 * np.dot(inverted[a] - inverted[b], normal) * normal
    with pytest.raises(ValueError, match="inverted"):
        mesh_from_tetrahedra(inverted, mesh.tetrahedra, mesh.neighbours, reorient=False)


def test_update_mesh_matches_a_rebuild_on_the_same_connectivity(rng: np.random.Generator) -> None:
    mesh = build_mesh(jittered_grid(6, rng))
    # Small enough moves that no hull sliver inverts.
    moved = mesh.points + rng.normal(0.0, 1e-5, mesh.points.shape)
    rebuilt = mesh_from_tetrahedra(moved, mesh.tetrahedra, mesh.neighbours, reorient=False)
    updated = update_mesh(mesh, moved)
    for name in rebuilt.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(updated, name), getattr(rebuilt, name), err_msg=name)
    # The connectivity is shared, not copied: the update allocates geometry only.
    assert updated.facet_cells is mesh.facet_cells
    assert updated.boundary_vertices is mesh.boundary_vertices
    with pytest.raises(ValueError, match="shape"):
        update_mesh(mesh, moved[:-1])


def test_update_mesh_detects_inversion(rng: np.random.Generator) -> None:
    mesh = build_mesh(jittered_grid(4, rng))
    inverted = mesh.points.copy()
    a, b, c, d = mesh.tetrahedra[0]
    normal = np.cross(inverted[c] - inverted[b], inverted[d] - inverted[b])
    normal /= np.linalg.norm(normal)
    inverted[a] -= 2.0 * np.dot(inverted[a] - inverted[b], normal) * normal
    with pytest.raises(ValueError, match="inverted"):
        update_mesh(mesh, inverted)


def test_mesh_facet_normals_point_from_first_to_second_cell(rng: np.random.Generator) -> None:
    mesh = build_mesh(jittered_grid(5, rng))
    i, j = mesh.facet_cells.T
    towards = np.einsum("ij,ij->i", mesh.centroids[j] - mesh.centroids[i], mesh.facet_normals)
    assert np.all(towards > 0.0)
    outwards = np.einsum(
        "ij,ij->i", mesh.boundary_centroids - mesh.centroids[mesh.boundary_cells],
        mesh.boundary_normals,
    )
    assert np.all(outwards > 0.0)


def test_cell_volumes_of_corner_tetrahedra_and_their_mirror_images() -> None:
    """The corner tetrahedron (0, e_x, a e_y, b e_z) has volume a b / 6; swapping two
    vertices flips its sign; the five tetrahedra of a cube's split fill it."""
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3]], dtype=float)
    volumes = cell_volumes(points, np.array([[0, 1, 2, 3], [0, 2, 1, 3]]))
    np.testing.assert_allclose(volumes, [1.0, -1.0], rtol=1e-15)
    cube = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)])
    split = np.array([[0, 1, 2, 4], [3, 1, 2, 7], [5, 1, 4, 7], [6, 2, 4, 7], [1, 2, 4, 7]])
    assert np.abs(cell_volumes(cube, split)).sum() == pytest.approx(1.0, rel=1e-14)
