"""Fill-reducing order of the flow unknowns: a permutation, separators last, little fill."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from sksparse.cholmod import cholesky

from shared.dem.points import cube_points
from shared.fv import assemble_matrix, flow_pattern, steady_pressure
from shared.mesh import WALLS, boundary_cell_mask, build_mesh
from shared.ordering import locality_order, nested_dissection
from shared.solver import SPDSolver


def _factor_entries(lower: sp.csc_matrix, ordering_method: str) -> int:
    return int(cholesky(lower, ordering_method=ordering_method).L().nnz)


def test_ordering_of_a_chain_ends_with_its_middle_separator() -> None:
    n = 100
    centres = np.c_[np.arange(n, dtype=np.float64), np.zeros(n), np.zeros(n)]
    order = nested_dissection(centres, np.c_[np.arange(n - 1), np.arange(1, n)])
    np.testing.assert_array_equal(np.sort(order), np.arange(n))
    separator = int(order[-1])
    assert abs(separator - n / 2) <= 1
    # one half first, then the other: no edge joins them except through the separator
    np.testing.assert_array_equal(np.sort(order[:separator]), np.arange(separator))


def test_ordering_leaves_coincident_centres_uncut() -> None:
    edges = np.c_[np.arange(39), np.arange(1, 40)]
    np.testing.assert_array_equal(nested_dissection(np.zeros((40, 3)), edges), np.arange(40))


def test_ordering_gives_little_fill(rng: np.random.Generator) -> None:
    # the jittered grid of tests/shared/test_fv.py (12 per side, +-0.3 spacing)
    mesh = build_mesh(cube_points(12**3, rng, jitter=0.6)[0])
    dirichlet = boundary_cell_mask(mesh, list(WALLS))
    pattern = flow_pattern(mesh, dirichlet)
    lower = assemble_matrix(mesh, pattern, np.ones(mesh.n_facets), np.ones(mesh.n_cells))
    # The same matrix with the unknowns in Qhull's cell order.
    full = (lower + sp.tril(lower, -1).T).tocsr()
    by_cell = np.argsort(pattern.free_cells)
    unordered = sp.tril(full[by_cell][:, by_cell], format="csc")
    unordered.sort_indices()
    ordered = _factor_entries(lower, "natural")
    # The nested dissection order comes within a quarter of METIS's fill (1.16 times;
    # 1.27 with median cuts) and far below that of the cell order (12 times METIS).
    assert ordered < 1.25 * _factor_entries(lower, "metis")
    assert ordered < 0.5 * _factor_entries(unordered, "natural")


def test_locality_order_keeps_octants_together() -> None:
    """On a 4 x 4 x 4 grid the Z-order curve visits each 2 x 2 x 2 octant whole, the
    lower corner's first, and every node once."""
    axis = np.arange(4, dtype=np.float64)
    centres = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    order = locality_order(centres)
    np.testing.assert_array_equal(np.sort(order), np.arange(64))
    octants = (centres[order] >= 2).astype(int) @ [1, 2, 4]
    assert np.all(octants[:8] == 0)
    assert np.all(np.diff(octants.reshape(8, 8), axis=1) == 0)


@pytest.mark.parametrize("method", ["direct", "amg"])
def test_locality_ordered_system_gives_the_same_pressure(rng: np.random.Generator,
                                                         method: str) -> None:
    """A steady solve numbered along the Z-order curve returns the nested-dissection
    numbering's pressure, by the factor (which then orders itself) and by multigrid."""
    mesh = build_mesh(cube_points(10**3, rng, jitter=0.6)[0])
    dirichlet = boundary_cell_mask(mesh, [WALLS[4], WALLS[5]])
    conductance = rng.uniform(0.5, 2.0, mesh.n_facets) * 1e-20
    imposed = -1e6 * mesh.circumcentres[:, 2] / mesh.circumcentres[:, 2].max()
    pressures = [
        steady_pressure(mesh, flow_pattern(mesh, dirichlet, fill_reducing),
                        SPDSolver(residual_tolerance=1e-12, method=method), conductance, imposed)
        for fill_reducing in (True, False)
    ]
    np.testing.assert_allclose(pressures[1], pressures[0], rtol=0, atol=1e-8 * 1e6)
