"""shared.solver.spd: the dispatcher against dense solves: the backward-error criterion on
both paths, the drift trigger, refused inputs, the automatic choice of the path and its
fallback."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from shared.solver import SolverError, SPDSolver
from shared.solver._kernels import _scaled_drift, _symmetric_product
from tests.shared.solver._systems import drift_conductances, flow_system, laplacian_system, lower_of


def test_solver_matches_dense_solve(rng: np.random.Generator) -> None:
    matrix = laplacian_system(80, rng)
    rhs = rng.standard_normal(80)
    solver = SPDSolver()
    solution = solver.solve(lower_of(matrix), rhs)
    np.testing.assert_allclose(solution, np.linalg.solve(matrix.toarray(), rhs), rtol=1e-10)
    assert (solver.stats.analyses, solver.stats.factorisations) == (1, 1)


def test_solver_refactors_beyond_drift_tolerance(rng: np.random.Generator) -> None:
    matrix = laplacian_system(60, rng)
    rhs = rng.standard_normal(60)
    solver = SPDSolver(refactor_tolerance=0.05)
    solver.solve(lower_of(matrix), rhs)
    solver.solve(lower_of(matrix * 1.2), rhs)
    assert (solver.stats.analyses, solver.stats.factorisations) == (1, 2)
    solver.solve(lower_of(matrix * 1.2), rhs, force_refactor=True)
    assert solver.stats.factorisations == 3
    other = laplacian_system(60, np.random.default_rng(7))
    solution = solver.solve(lower_of(other), rhs)
    assert solver.stats.analyses == 2
    np.testing.assert_allclose(solution, np.linalg.solve(other.toarray(), rhs), rtol=1e-10)


def test_solver_reports_failures(rng: np.random.Generator) -> None:
    matrix = laplacian_system(30, rng)
    solver = SPDSolver()
    with pytest.raises(SolverError, match="NaN"):
        solver.solve(lower_of(matrix), np.full(30, np.nan))
    indefinite = matrix - sp.eye(30, format="csc") * 1e3
    with pytest.raises(SolverError, match="positive definite"):
        solver.solve(lower_of(indefinite), np.ones(30))


def test_solver_rejects_a_full_or_unsorted_matrix(rng: np.random.Generator) -> None:
    matrix = laplacian_system(20, rng)
    with pytest.raises(ValueError, match="lower triangle"):
        SPDSolver().solve(matrix.tocsc(), np.ones(20))
    with pytest.raises(ValueError, match="CSC"):
        SPDSolver().solve(sp.tril(matrix, format="csr"), np.ones(20))


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


def test_solver_judges_an_increment_by_the_system_of_the_whole_unknown(
    rng: np.random.Generator,
) -> None:
    """An increment x of a known y0 meets the backward error of A (y0 + x) = b + A y0.

    The bound is checked here with scipy on the full system, independently of the
    solver's own bookkeeping; judged against the increment alone, the same solve needs
    more CG iterations (the bound then scales with ||x||, 1e3 times smaller).
    """
    n = 150
    matrix = laplacian_system(n, rng)
    drifted = drift_conductances(matrix, 0.3, rng)
    offset = rng.uniform(-5e7, -4e7, n)
    increment_rhs = 1e-3 * drifted @ rng.uniform(-5e4, 5e4, n)
    iterations = {}
    for judged in ("whole", "increment"):
        solver = SPDSolver(residual_tolerance=1e-8, max_iterations=50)
        solver.solve(lower_of(matrix), np.ones(n))
        before = solver.stats.iterations
        solution = solver.solve(
            lower_of(drifted), increment_rhs, offset=offset if judged == "whole" else None
        )
        iterations[judged] = solver.stats.iterations - before
        if judged == "whole":
            whole = offset + solution
            full_rhs = increment_rhs + drifted @ offset
            residual = np.abs(full_rhs - drifted @ whole)
            scale = np.abs(drifted.diagonal()) * np.abs(whole).max() + np.abs(full_rhs)
            assert np.max(residual / scale) <= 1e-8
    assert 0 < iterations["whole"] < iterations["increment"]


@pytest.mark.parametrize(("case", "contrast"), [("transient", 1.0), ("steady", 1.0),
                                              ("cracked", 1e6), ("cracked", 1e15)])
def test_multigrid_and_factor_paths_meet_the_same_criterion(
    rng: np.random.Generator, case: str, contrast: float
) -> None:
    """Both preconditioners return solutions whose row-wise backward error, computed here
    with the dense matrix, is within the tolerance, and that agree with the dense solve
    to what that backward error allows. At a crack contrast of 1e15 the cracked cells'
    common pressure is ill-determined by any backward-stable solve (the dense LU and
    CHOLMOD differ there by percents), so only the backward error is compared."""
    lower, rhs = flow_system(9, case, rng, contrast)
    dense = (lower + sp.tril(lower, -1).T).toarray()
    exact = np.linalg.solve(dense, rhs)
    for method in ("direct", "amg"):
        # the 1e15 contrast takes the hierarchy about 120 iterations
        solver = SPDSolver(residual_tolerance=1e-10, method=method, amg_max_iterations=300)
        solution = solver.solve(lower, rhs)
        residual = np.abs(rhs - dense @ solution)
        scale = np.abs(np.diag(dense)) * np.abs(solution).max() + np.abs(rhs)
        assert np.max(residual / scale) <= 1e-10
        assert solver.stats.factorisations == 1
        if contrast < 1e15:
            np.testing.assert_allclose(solution, exact, rtol=0,
                                       atol=1e-7 * np.abs(exact).max())
    # the hierarchy is a real multigrid and needs iterations; the factor needs none
    assert solver.stats.iterations > 2


def test_auto_method_switches_to_multigrid_at_the_crossover(rng: np.random.Generator) -> None:
    lower, rhs = flow_system(6, "transient", rng)
    n = lower.shape[0]
    below, above = SPDSolver(amg_unknowns=n + 1), SPDSolver(amg_unknowns=n)
    assert not below.uses_multigrid(n) and above.uses_multigrid(n)
    below.solve(lower, rhs)
    above.solve(lower, rhs)
    assert below.stats.analyses == 1 and below.stats.iterations == 0
    assert above.stats.analyses == 0 and above.stats.iterations > 0
    with pytest.raises(ValueError, match="method"):
        SPDSolver(method="gmres")


def test_auto_method_falls_back_to_the_factor_for_the_rest_of_the_pattern(
    rng: np.random.Generator,
) -> None:
    """A hierarchy allowed 3 iterations cannot reach 1e-13 on the cracked system: with
    ``auto`` the factor solves it (and the next solve of that pattern), with ``amg`` the
    solve fails."""
    lower, rhs = flow_system(7, "cracked", rng)
    with pytest.raises(SolverError, match="fresh preconditioner"):
        SPDSolver(method="amg", residual_tolerance=1e-13, amg_max_iterations=3).solve(lower, rhs)
    solver = SPDSolver(amg_unknowns=1, residual_tolerance=1e-13, amg_max_iterations=3)
    solution = solver.solve(lower, rhs)
    dense = (lower + sp.tril(lower, -1).T).toarray()
    residual = np.abs(rhs - dense @ solution)
    assert np.max(residual / (np.abs(np.diag(dense)) * np.abs(solution).max() + np.abs(rhs))) \
        <= 1e-13
    assert (solver.stats.fallbacks, solver.stats.analyses) == (1, 1)
    before = dataclasses.replace(solver.stats)
    solver.solve(lower, 2.0 * rhs)
    assert solver.stats.factor_applications == before.factor_applications + 1
    assert solver.stats.factorisations == before.factorisations
    # a new pattern tries the hierarchy again (one it can solve in its budget)
    solver.residual_tolerance, solver.amg_max_iterations = 1e-8, 50
    other, other_rhs = flow_system(6, "transient", rng)
    solver.solve(other, other_rhs)
    assert solver.stats.factorisations == before.factorisations + 1
    assert solver.stats.analyses == 1 and solver.stats.iterations > before.iterations
