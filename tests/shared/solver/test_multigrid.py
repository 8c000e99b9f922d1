"""shared.solver.multigrid: the multigrid path, an SPD V-cycle whose hierarchy is reused
on drifted matrices and rebuilt when it stops converging."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from shared.solver import SPDSolver
from tests.shared.solver._systems import drift_conductances, flow_system, lower_of


def test_the_multigrid_cycle_is_a_symmetric_positive_definite_preconditioner(
    rng: np.random.Generator,
) -> None:
    """CG needs an SPD preconditioner: the V-cycle's matrix, built column by column on a
    steady flow system of several levels, is symmetric to round-off and its
    eigenvalues are positive (a forward sweep on both sides of the coarse correction
    would break the symmetry by far more)."""
    lower, rhs = flow_system(8, "steady", rng)
    solver = SPDSolver(method="amg")
    solver.solve(lower, rhs)
    n = lower.shape[0]
    cycle = np.column_stack([solver._apply(column) for column in np.eye(n)])
    assert n > 500  # more unknowns than the coarsest level: a real V-cycle
    asymmetry = np.abs(cycle - cycle.T).max() / np.abs(cycle).max()
    assert asymmetry <= 1e-12
    assert np.linalg.eigvalsh(0.5 * (cycle + cycle.T)).min() > 0.0


def test_multigrid_reuses_its_hierarchy_on_drifted_matrices(rng: np.random.Generator) -> None:
    lower, rhs = flow_system(8, "transient", rng)
    matrix = lower + sp.tril(lower, -1).T
    solver = SPDSolver(method="amg", residual_tolerance=1e-10)
    solver.solve(lower, rhs)
    first = solver.stats.iterations
    for amplitude in (0.01, 0.02):
        drifted = lower_of(drift_conductances(matrix.tocsc(), amplitude, rng))
        solution = solver.solve(drifted, rhs)
        dense = drifted + sp.tril(drifted, -1).T
        np.testing.assert_allclose(dense @ solution, rhs, rtol=0,
                                   atol=1e-8 * np.abs(rhs).max())
    assert solver.stats.factorisations == 1 and solver.stats.iterations > first
    # conductances changed by ten decades on 3 % of the facets (cracks opening): the
    # stale hierarchy rents at most 1.5 times its first solve's iterations (at least 4),
    # then the solve rebuilds it and finishes
    storage = np.asarray(matrix.sum(axis=1)).ravel()
    adjacency = sp.triu(sp.diags(matrix.diagonal()) - matrix, k=1, format="csr")
    adjacency.data *= np.where(rng.random(adjacency.nnz) < 0.03, 1e10, 1.0)
    adjacency = adjacency + adjacency.T
    cracked = lower_of(sp.diags(np.asarray(adjacency.sum(axis=1)).ravel() + storage)
                       - adjacency)
    before = solver.stats.iterations
    solution = solver.solve(cracked, rhs)
    assert solver.stats.factorisations == 2
    dense = (cracked + sp.tril(cracked, -1).T).toarray()
    residual = np.abs(rhs - dense @ solution)
    assert np.max(residual / (np.abs(np.diag(dense)) * np.abs(solution).max() + np.abs(rhs))) \
        <= 1e-10
    assert solver.stats.iterations - before >= 1.5 * max(first, 4)
