"""Delaunay repair of moved points, checked against Qhull's tetrahedralisation from scratch."""

from __future__ import annotations

import numpy as np
import pytest

from shared import delaunay
from shared.delaunay import _inside_or_undecided, same_cells, update_delaunay
from shared.mesh import build_mesh, cell_volumes, mesh_from_tetrahedra
from tests.shared.test_mesh import jittered_grid


def rows(tetrahedra: np.ndarray) -> set[tuple[int, ...]]:
    return set(map(tuple, np.sort(tetrahedra, axis=1).tolist()))


def facet_set(mesh) -> set[tuple[int, ...]]:
    return set(map(tuple, np.sort(mesh.facet_vertices, axis=1).tolist()))


@pytest.mark.parametrize(("move", "threads"), [(0.005, 1), (0.005, 3), (0.03, 1), (0.03, 2),
                                                (0.1, 1), (0.1, 2)])
def test_repair_gives_qhull_tetrahedralisation(
    move: float, threads: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Small to large moves (the largest invert cells), the cells to redo triangulated
    in one to three groups: the repaired cells, their neighbours and hence facets are
    Qhull's from scratch."""
    monkeypatch.setattr(delaunay, "get_num_threads", lambda: threads)
    rng = np.random.default_rng(3)
    before = jittered_grid(12, rng)
    mesh = build_mesh(before)
    after = before + rng.normal(0.0, move / 12, before.shape)
    if move == 0.1:
        assert np.any(cell_volumes(after, mesh.tetrahedra) < 0)
    repaired = update_delaunay(after, mesh.tetrahedra, mesh.neighbours, 0.0)
    assert repaired is not None
    cells, neighbours = repaired
    scratch = build_mesh(after)
    assert rows(cells) == rows(scratch.tetrahedra)
    assert np.all(cell_volumes(after, cells) > 0)
    rebuilt = mesh_from_tetrahedra(after, cells, neighbours, reorient=False)
    assert facet_set(rebuilt) == facet_set(scratch)
    assert rebuilt.boundary_cells.size == scratch.boundary_cells.size
    # each neighbour shares exactly the face opposite the vertex it is listed under
    for c in range(0, cells.shape[0], 97):
        for k in range(4):
            if neighbours[c, k] >= 0:
                shared = set(cells[c]) & set(cells[neighbours[c, k]])
                assert shared == set(cells[c]) - {cells[c, k]}


@pytest.mark.parametrize("move", [0.03, 0.1])
def test_repair_does_not_depend_on_the_thread_count(
    move: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The cells to redo triangulated in one, two or three groups (one per thread): the
    same cells with the same vertex order, in the same order, so that a run's sums
    round alike whatever its thread count."""
    rng = np.random.default_rng(8)
    before = jittered_grid(12, rng)
    mesh = build_mesh(before)
    after = before + rng.normal(0.0, move / 12, before.shape)
    results = []
    for threads in (1, 2, 3):
        monkeypatch.setattr(delaunay, "get_num_threads", lambda threads=threads: threads)
        repaired = update_delaunay(after, mesh.tetrahedra, mesh.neighbours, 0.0)
        assert repaired is not None
        results.append(repaired)
    assert results[0][0].shape[0] > mesh.n_cells // 2
    for cells, neighbours in results[1:]:
        np.testing.assert_array_equal(cells, results[0][0])
        np.testing.assert_array_equal(neighbours, results[0][1])
    assert np.all(cell_volumes(after, results[0][0]) > 0.0)


def test_repair_keeps_the_cells_still_delaunay() -> None:
    """Points that did not move: every previous cell is kept, in its order."""
    mesh = build_mesh(jittered_grid(8, np.random.default_rng(5)))
    cells, neighbours = update_delaunay(mesh.points, mesh.tetrahedra, mesh.neighbours, 0.0)
    np.testing.assert_array_equal(cells, mesh.tetrahedra)
    np.testing.assert_array_equal(neighbours, mesh.neighbours)


def test_repair_refuses_cospherical_points() -> None:
    """A cubic lattice has no unique Delaunay tetrahedralisation (eight cospherical
    corners per cube): no cell can be certified, and the caller must use Qhull."""
    axis = np.arange(5.0)
    lattice = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    mesh = build_mesh(lattice + 1e-3 * np.random.default_rng(0).normal(size=lattice.shape))
    assert update_delaunay(lattice, mesh.tetrahedra, mesh.neighbours, 0.0) is None


def test_insphere_sign_on_the_unit_tetrahedron() -> None:
    """Circumsphere of O, e1, e2, e3: centre (1/2, 1/2, 1/2), radius^2 3/4."""
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2, 0.2, 0.2],
                       [1.1, 1.1, 0.0], [1.0, 1.0, 1.0], [0.9, 0.9, 0.9]], dtype=np.float64)
    cell = np.arange(4)
    verdicts = [_inside_or_undecided(points, cell, p) for p in range(4, 8)]
    # inside; outside (distance^2 0.87 > 0.75); on the sphere counts as inside; inside
    assert verdicts == [True, False, True, True]


def test_same_cells_matches_vertex_sets_in_any_order() -> None:
    old = np.array([[0, 1, 2, 3], [1, 2, 3, 4], [2, 3, 4, 5]])
    new = np.array([[4, 3, 2, 1], [5, 6, 7, 8], [3, 2, 1, 0]])
    np.testing.assert_array_equal(same_cells(old, new, 9), [1, -1, 0])
