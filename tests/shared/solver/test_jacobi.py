"""shared.solver.jacobi: the diagonal path against dense solves, its hand-over to the
factor, and its refusals."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from shared.solver import SolverError, SPDSolver
from tests.shared.solver._systems import flow_system, laplacian_system, lower_of


def _backward_error(dense: np.ndarray, solution: np.ndarray, rhs: np.ndarray) -> float:
    """max_i |b - A x|_i / (|a_ii| ||x||_inf + |b_i|), with the dense matrix."""
    residual = np.abs(rhs - dense @ solution)
    return float(np.max(residual / (np.abs(np.diag(dense)) * np.abs(solution).max() + np.abs(rhs))))


def test_jacobi_path_meets_the_criterion_without_a_factor(rng: np.random.Generator) -> None:
    """A transient flow system: CG scaled by the diagonal reaches 1e-10 with no analysis
    and no factorisation, one diagonal scaling per iteration and one for the start, and
    agrees with the dense solve to what that backward error allows."""
    lower, rhs = flow_system(7, "transient", rng)
    dense = (lower + sp.tril(lower, -1).T).toarray()
    solver = SPDSolver(residual_tolerance=1e-10, method="jacobi")
    solution = solver.solve(lower, rhs)
    assert _backward_error(dense, solution, rhs) <= 1e-10
    exact = np.linalg.solve(dense, rhs)
    np.testing.assert_allclose(solution, exact, rtol=0, atol=1e-8 * np.abs(exact).max())
    stats = solver.stats
    assert (stats.analyses, stats.factorisations, stats.fallbacks) == (0, 0, 0)
    assert stats.iterations > 2 and stats.factor_applications == stats.iterations + 1


def test_jacobi_path_hands_what_it_cannot_solve_to_the_factor(rng: np.random.Generator) -> None:
    """The cracked steady system (contrast 1e15) at 1e-13 is beyond 50 Jacobi-CG
    iterations: a fresh factor solves it (to the criterion, checked densely) and the
    next solve of that pattern, with no new factorisation; a new pattern goes back to
    the diagonal."""
    lower, rhs = flow_system(7, "cracked", rng)
    solver = SPDSolver(residual_tolerance=1e-13, method="jacobi", jacobi_max_iterations=50)
    solution = solver.solve(lower, rhs)
    dense = (lower + sp.tril(lower, -1).T).toarray()
    assert _backward_error(dense, solution, rhs) <= 1e-13
    assert (solver.stats.fallbacks, solver.stats.analyses, solver.stats.factorisations) == (1, 1, 1)
    assert solver.stats.iterations >= 50
    before = dataclasses.replace(solver.stats)
    solver.solve(lower, 2.0 * rhs)
    assert solver.stats.factorisations == before.factorisations
    assert solver.stats.factor_applications == before.factor_applications + 1
    matrix = laplacian_system(60, rng)
    other_rhs = rng.standard_normal(60)
    solver.residual_tolerance = 1e-10
    other = solver.solve(lower_of(matrix), other_rhs)
    np.testing.assert_allclose(other, np.linalg.solve(matrix.toarray(), other_rhs), rtol=1e-8)
    assert (solver.stats.fallbacks, solver.stats.factorisations) == (1, before.factorisations)


def test_jacobi_path_refuses_what_the_factor_refuses(rng: np.random.Generator) -> None:
    """An indefinite matrix stops CG and then fails the factorisation; a full matrix or
    an upper entry is refused before any iteration."""
    matrix = laplacian_system(30, rng)
    indefinite = matrix - sp.eye(30, format="csc") * 1e3
    with pytest.raises(SolverError, match="positive definite"):
        SPDSolver(method="jacobi").solve(lower_of(indefinite), np.ones(30))
    with pytest.raises(ValueError, match="lower triangle"):
        SPDSolver(method="jacobi").solve(matrix.tocsc(), np.ones(30))
