"""shared.solver.factor: the CHOLMOD factor path, reused on drifted matrices by the
rent-or-buy rule, and the thread count of CHOLMOD's BLAS."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from shared.solver import SPDSolver
from tests.shared.solver._systems import drift_conductances, drifting_start, laplacian_system, lower_of


def test_solver_reuses_factor_and_solves_the_current_matrix(rng: np.random.Generator) -> None:
    matrix = laplacian_system(120, rng)
    rhs = rng.standard_normal(120)
    solver = SPDSolver(refactor_tolerance=0.05, residual_tolerance=1e-13)
    solver.solve(lower_of(matrix), rhs)
    drifted = matrix.copy()
    drifted.data *= 1.0 + 0.01 * rng.uniform(-1.0, 1.0, drifted.nnz)
    drifted = (drifted + drifted.T) / 2.0
    expected = np.linalg.solve(drifted.toarray(), rhs)
    solution = solver.solve(lower_of(drifted), rhs)
    assert solver.stats.factorisations == 1
    assert solver.stats.iterations > 0
    assert 0.0 < solver.last_drift < 0.05
    np.testing.assert_allclose(solution, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    # Without the correction the stale factor would be visibly wrong.
    stale = np.linalg.solve(matrix.toarray(), rhs)
    assert np.abs(stale - expected).max() > 1e-4 * np.abs(expected).max()


def test_solver_ordered_matrix_skips_the_ordering(rng: np.random.Generator) -> None:
    matrix = laplacian_system(90, rng)
    rhs = rng.standard_normal(90)
    solver = SPDSolver()
    solution = solver.solve(lower_of(matrix), rhs, ordered=True)
    np.testing.assert_allclose(solution, np.linalg.solve(matrix.toarray(), rhs), rtol=1e-10)
    # CHOLMOD's natural ordering keeps the given order up to its postordering: the
    # factor's permutation differs from METIS's.
    metis = SPDSolver(ordering_method="metis")
    metis.solve(lower_of(matrix), rhs, ordered=True)
    assert solver._factor is not None and metis._factor is not None
    assert not np.array_equal(solver._factor.P(), metis._factor.P())


def test_solver_buys_a_factor_once_the_rented_iterations_reach_its_price(
    rng: np.random.Generator,
) -> None:
    matrix, rhs, solver = drifting_start(rng, refactor_iterations=4, residual_tolerance=1e-14)
    solver.solve(lower_of(matrix), rhs)
    drifted = drift_conductances(matrix, 0.3, rng)
    solution = solver.solve(lower_of(drifted), rhs)
    # The stale factor rents its 4 iterations, then the solve refactors and finishes.
    assert solver.stats.factorisations == 2
    assert solver.stats.iterations >= 4
    np.testing.assert_allclose(solution, np.linalg.solve(drifted.toarray(), rhs), rtol=1e-9)
    # The last solve rented its whole budget: the next one buys at once, without
    # renting, since the drift only accumulates.
    iterations = solver.stats.iterations
    solver.solve(lower_of(drifted), rhs)
    assert (solver.stats.factorisations, solver.stats.iterations) == (3, iterations)
    # That one rented nothing: the next solve rents again, and this factor solves the
    # same matrix without any iteration.
    solver.solve(lower_of(drifted), rhs)
    assert (solver.stats.factorisations, solver.stats.iterations) == (3, iterations)


def test_solver_rents_while_the_budget_lasts(rng: np.random.Generator) -> None:
    matrix, rhs, solver = drifting_start(rng, refactor_iterations=20)
    solver.solve(lower_of(matrix), rhs)
    drifted = lower_of(drift_conductances(matrix, 0.01, rng))
    rents = []
    for _ in range(12):
        before = solver.stats.iterations
        solver.solve(drifted, rhs)
        rents.append(solver.stats.iterations - before)
    # The same small drift costs r iterations per solve: the factor is reused while
    # the rented total stays within 20, then bought at once when r more would exceed it.
    rent = rents[0]
    assert 0 < rent < 10
    reused = 20 // rent - (20 % rent == 0)
    assert rents[:reused] == [rent] * reused
    assert solver.stats.factorisations == 2
    assert rents[reused] == 0


@pytest.mark.parametrize("tolerance", [1e-10, 1e-13])
def test_solver_honours_its_tolerance_on_a_strongly_drifted_matrix(
    rng: np.random.Generator, tolerance: float
) -> None:
    matrix = laplacian_system(150, rng)
    rhs = rng.standard_normal(150)
    solver = SPDSolver(residual_tolerance=tolerance)
    solver.solve(lower_of(matrix), rhs)
    # A few conductances grow a thousandfold, as near-cospherical cell pairs do when
    # points move; everything else drifts by 1 %. No drift trigger: the stale factor
    # is reused and CG must still reach the tolerance on the current matrix.
    drifted = matrix.copy().tolil()
    rows, columns = sp.tril(matrix, k=-1).nonzero()
    for edge in rng.choice(rows.size, 5, replace=False):
        a, b = rows[edge], columns[edge]
        weight = 1e3 * rng.uniform(0.5, 2.0)
        drifted[a, b] -= weight
        drifted[b, a] -= weight
        drifted[a, a] += weight
        drifted[b, b] += weight
    drifted = drift_conductances(drifted.tocsc(), 0.01, rng)
    solution = solver.solve(lower_of(drifted), rhs)
    assert solver.stats.factorisations == 1
    assert solver.stats.iterations > 0
    assert solver.drift(lower_of(drifted)) > 100.0
    dense = drifted.toarray()
    backward = np.abs(rhs - dense @ solution).max() / (
        np.abs(dense).sum(axis=1).max() * np.abs(solution).max() + np.abs(rhs).max()
    )
    assert backward <= tolerance
    np.testing.assert_allclose(
        solution, np.linalg.solve(dense, rhs), rtol=0, atol=1e3 * tolerance * np.abs(solution).max()
    )


def test_solver_buys_at_once_while_one_step_of_drift_costs_more_than_a_factor(
    rng: np.random.Generator,
) -> None:
    matrix, rhs, solver = drifting_start(rng, refactor_iterations=3, residual_tolerance=1e-14)
    rents, bought = [], []
    for _ in range(16):
        # Every matrix differs from the last by up to 60 % in every conductance.
        lower = lower_of(drift_conductances(matrix, 0.6, rng))
        before = dataclasses.replace(solver.stats)
        solution = solver.solve(lower, rhs)
        rents.append(solver.stats.iterations - before.iterations)
        bought.append(solver.stats.factorisations - before.factorisations)
        dense = (lower + sp.tril(lower, -1).T).toarray()
        np.testing.assert_allclose(solution, np.linalg.solve(dense, rhs), rtol=1e-9)
    # Each probe of the stale factor rents its 3 iterations in vain and buys; then
    # 1, 2, 4, ... solves buy at once without renting.
    probes = [k for k, rent in enumerate(rents) if rent >= 3]
    assert probes == [1, 3, 6, 11]
    assert all(count == 1 for count in bought)


def test_the_cholmod_blas_thread_count_is_set_on_cholmods_library_alone() -> None:
    """The OpenBLAS that CHOLMOD links reports the count set (it is process-wide); the
    one numpy's wheel brings keeps its own."""
    import threadpoolctl

    from shared.solver import set_cholmod_blas_threads

    def counts() -> dict[str, int]:
        return {lib["prefix"]: lib["num_threads"] for lib in threadpoolctl.threadpool_info()
                if lib["user_api"] == "blas"}

    numpy_blas = {prefix: n for prefix, n in counts().items() if prefix != "libopenblas"}
    try:
        for threads in (2, 1):
            assert set_cholmod_blas_threads(threads)
            assert counts() == {**numpy_blas, "libopenblas": threads}
    finally:
        set_cholmod_blas_threads(1)
