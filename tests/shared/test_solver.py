"""CHOLMOD wrapper: dense agreement, factor reuse with correction, refactor triggers."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from shared.solver import CholeskySolver, SolverError, _scaled_drift, _symmetric_product


def laplacian_system(n: int, rng: np.random.Generator) -> sp.csc_matrix:
    """SPD graph Laplacian of a random sparse graph plus a positive diagonal."""
    rows = rng.integers(0, n, 4 * n)
    cols = rng.integers(0, n, 4 * n)
    keep = rows != cols
    weights = rng.uniform(0.5, 2.0, keep.sum())
    adjacency = sp.coo_matrix((weights, (rows[keep], cols[keep])), shape=(n, n)).tocsr()
    adjacency = adjacency + adjacency.T
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    return (sp.diags(degree + rng.uniform(0.01, 0.1, n)) - adjacency).tocsc()


def lower_of(matrix: sp.spmatrix) -> sp.csc_matrix:
    lower = sp.tril(matrix, format="csc")
    lower.sort_indices()
    return lower


def test_solver_matches_dense_solve(rng: np.random.Generator) -> None:
    matrix = laplacian_system(80, rng)
    rhs = rng.standard_normal(80)
    solver = CholeskySolver()
    solution = solver.solve(lower_of(matrix), rhs)
    np.testing.assert_allclose(solution, np.linalg.solve(matrix.toarray(), rhs), rtol=1e-10)
    assert (solver.stats.analyses, solver.stats.factorizations) == (1, 1)


def test_solver_reuses_factor_and_solves_the_current_matrix(rng: np.random.Generator) -> None:
    matrix = laplacian_system(120, rng)
    rhs = rng.standard_normal(120)
    solver = CholeskySolver(refactor_tolerance=0.05, residual_tolerance=1e-13)
    solver.solve(lower_of(matrix), rhs)
    drifted = matrix.copy()
    drifted.data *= 1.0 + 0.01 * rng.uniform(-1.0, 1.0, drifted.nnz)
    drifted = (drifted + drifted.T) / 2.0
    expected = np.linalg.solve(drifted.toarray(), rhs)
    solution = solver.solve(lower_of(drifted), rhs)
    assert solver.stats.factorizations == 1
    assert solver.stats.iterations > 0
    assert 0.0 < solver.last_drift < 0.05
    np.testing.assert_allclose(solution, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    # Without the correction the stale factor would be visibly wrong.
    stale = np.linalg.solve(matrix.toarray(), rhs)
    assert np.abs(stale - expected).max() > 1e-4 * np.abs(expected).max()


def test_solver_refactors_beyond_drift_tolerance(rng: np.random.Generator) -> None:
    matrix = laplacian_system(60, rng)
    rhs = rng.standard_normal(60)
    solver = CholeskySolver(refactor_tolerance=0.05)
    solver.solve(lower_of(matrix), rhs)
    solver.solve(lower_of(matrix * 1.2), rhs)
    assert (solver.stats.analyses, solver.stats.factorizations) == (1, 2)
    solver.solve(lower_of(matrix * 1.2), rhs, force_refactor=True)
    assert solver.stats.factorizations == 3
    other = laplacian_system(60, np.random.default_rng(7))
    solution = solver.solve(lower_of(other), rhs)
    assert solver.stats.analyses == 2
    np.testing.assert_allclose(solution, np.linalg.solve(other.toarray(), rhs), rtol=1e-10)


def test_solver_reports_failures(rng: np.random.Generator) -> None:
    matrix = laplacian_system(30, rng)
    solver = CholeskySolver()
    with pytest.raises(SolverError, match="NaN"):
        solver.solve(lower_of(matrix), np.full(30, np.nan))
    indefinite = matrix - sp.eye(30, format="csc") * 1e3
    with pytest.raises(SolverError, match="positive definite"):
        solver.solve(lower_of(indefinite), np.ones(30))


def test_solver_rejects_a_full_or_unsorted_matrix(rng: np.random.Generator) -> None:
    matrix = laplacian_system(20, rng)
    with pytest.raises(ValueError, match="lower triangle"):
        CholeskySolver().solve(matrix.tocsc(), np.ones(20))
    with pytest.raises(ValueError, match="CSC"):
        CholeskySolver().solve(sp.tril(matrix, format="csr"), np.ones(20))


def test_solver_kernels_match_numpy(rng: np.random.Generator) -> None:
    matrix = laplacian_system(50, rng)
    lower = lower_of(matrix)
    vector = rng.standard_normal(50)
    np.testing.assert_allclose(
        _symmetric_product(lower.indptr, lower.indices, lower.data, vector), matrix @ vector,
        rtol=1e-12, atol=1e-12 * np.abs(matrix @ vector).max(),
    )
    old = lower.data.copy()
    new = lower.data * (1.0 + 0.01 * rng.uniform(-1.0, 1.0, lower.nnz))
    diagonal = np.abs(old[lower.indptr[:-1]])
    columns = np.repeat(np.arange(50), np.diff(lower.indptr))
    expected = np.max(np.abs(new - old) / np.sqrt(diagonal[lower.indices] * diagonal[columns]))
    drift = _scaled_drift(lower.indptr, lower.indices, new, old)
    assert drift == pytest.approx(expected, rel=1e-14)


def test_solver_ordered_matrix_skips_the_ordering(rng: np.random.Generator) -> None:
    matrix = laplacian_system(90, rng)
    rhs = rng.standard_normal(90)
    solver = CholeskySolver()
    solution = solver.solve(lower_of(matrix), rhs, ordered=True)
    np.testing.assert_allclose(solution, np.linalg.solve(matrix.toarray(), rhs), rtol=1e-10)
    # CHOLMOD's natural ordering keeps the given order up to its postordering: the
    # factor's permutation differs from METIS's.
    metis = CholeskySolver(ordering_method="metis")
    metis.solve(lower_of(matrix), rhs, ordered=True)
    assert solver._factor is not None and metis._factor is not None
    assert not np.array_equal(solver._factor.P(), metis._factor.P())


def test_solver_refactors_after_enough_stale_iterations(rng: np.random.Generator) -> None:
    matrix = laplacian_system(100, rng)
    rhs = rng.standard_normal(100)
    solver = CholeskySolver(refactor_tolerance=0.05, refactor_iterations=4)
    solver.solve(lower_of(matrix), rhs)
    drifted = matrix.copy()
    drifted.data *= 1.0 + 0.02 * rng.uniform(-1.0, 1.0, drifted.nnz)
    drifted = lower_of((drifted + drifted.T) / 2.0)
    solver.solve(drifted, rhs)
    assert solver.stats.factorizations == 1
    assert solver.stats.iterations >= 4
    # The next solve buys a factor instead of renting more iterations.
    solver.solve(drifted, rhs)
    assert solver.stats.factorizations == 2
    iterations = solver.stats.iterations
    solver.solve(drifted, rhs)
    assert solver.stats.iterations == iterations
