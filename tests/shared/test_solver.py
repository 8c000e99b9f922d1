"""CHOLMOD wrapper: dense agreement, factor reuse with correction, refactor triggers."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from shared.solver import SolverError, SPDSolver, _scaled_drift, _symmetric_product


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


def drift_conductances(
    matrix: sp.csc_matrix, amplitude: float, rng: np.random.Generator
) -> sp.csc_matrix:
    """The system with every conductance (off-diagonal) scaled by 1 +- amplitude.

    Storage (row sums) is kept, so the result is again a Laplacian plus a positive
    diagonal, hence SPD.
    """
    storage = np.asarray(matrix.sum(axis=1)).ravel()
    adjacency = sp.diags(matrix.diagonal()) - matrix
    adjacency.data *= 1.0 + amplitude * rng.uniform(-1.0, 1.0, adjacency.nnz)
    adjacency = (adjacency + adjacency.T) / 2.0
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    return (sp.diags(degree + storage) - adjacency).tocsc()


def lower_of(matrix: sp.spmatrix) -> sp.csc_matrix:
    lower = sp.tril(matrix, format="csc")
    lower.sort_indices()
    return lower


def test_solver_matches_dense_solve(rng: np.random.Generator) -> None:
    matrix = laplacian_system(80, rng)
    rhs = rng.standard_normal(80)
    solver = SPDSolver()
    solution = solver.solve(lower_of(matrix), rhs)
    np.testing.assert_allclose(solution, np.linalg.solve(matrix.toarray(), rhs), rtol=1e-10)
    assert (solver.stats.analyses, solver.stats.factorisations) == (1, 1)


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
    matrix = laplacian_system(100, rng)
    rhs = rng.standard_normal(100)
    solver = SPDSolver(refactor_iterations=4, residual_tolerance=1e-14)
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
    matrix = laplacian_system(100, rng)
    rhs = rng.standard_normal(100)
    solver = SPDSolver(refactor_iterations=20)
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
    matrix = laplacian_system(100, rng)
    rhs = rng.standard_normal(100)
    solver = SPDSolver(refactor_iterations=3, residual_tolerance=1e-14)
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


def flow_system(
    per_side: int, case: str, rng: np.random.Generator, contrast: float = 1e15
) -> tuple[sp.csc_matrix, np.ndarray]:
    """Lower triangle and rhs of a flow system of the micro model on a jittered mesh.

    ``transient``: every cell free, storage of a 1000 s step; ``steady``: two opposite
    walls imposed, no storage; ``cracked``: the steady system with rings of facets
    around 25 edges conducting ``contrast`` times the clay (1e15: the permeability
    test's contrast).
    """
    from shared.fv import assemble_matrix, facet_divergence, flow_pattern
    from shared.mesh import WALLS, boundary_cell_mask, build_mesh

    spacing = 7e-3 / per_side
    axis = (np.arange(per_side) + 0.5) * spacing
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    mesh = build_mesh(grid + rng.uniform(-0.3, 0.3, grid.shape) * spacing)
    conductance = rng.uniform(0.5, 2.0, mesh.n_facets) * 1e-22
    storage = np.zeros(mesh.n_cells)
    if case == "transient":
        dirichlet = np.zeros(mesh.n_cells, dtype=bool)
        storage = mesh.volumes * 0.3 * 1e-9 / 1e3
    else:
        dirichlet = boundary_cell_mask(mesh, [WALLS[4], WALLS[5]])
    if case == "cracked":
        edges = np.sort(mesh.facet_vertices, axis=1)
        ring = np.zeros(mesh.n_facets, dtype=bool)
        for a, b in edges[rng.choice(mesh.n_facets, 25, replace=False)][:, :2]:
            ring |= (edges == a).any(axis=1) & (edges == b).any(axis=1)
        conductance = np.where(ring, conductance * contrast, conductance)
    pattern = flow_pattern(mesh, dirichlet)
    pressure = np.where(mesh.circumcentres[:, 2] < 3.5e-3, -1e8, -2e7)
    rhs = facet_divergence(mesh, conductance, pressure)[pattern.free_cells]
    return assemble_matrix(mesh, pattern, conductance, storage), rhs


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


def test_multigrid_state_restores_bit_for_bit(rng: np.random.Generator) -> None:
    lower, rhs = flow_system(8, "steady", rng)
    matrix = (lower + sp.tril(lower, -1).T).tocsc()
    solver = SPDSolver(method="amg")
    solver.solve(lower, rhs)
    drifted = lower_of(drift_conductances(matrix, 0.05, rng))
    scalars, arrays = solver.reuse_state()
    restored = SPDSolver(method="amg")
    restored.restore_reuse_state(scalars, arrays)
    np.testing.assert_array_equal(restored.solve(drifted, rhs), solver.solve(drifted, rhs))
    assert restored.stats == solver.stats


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
