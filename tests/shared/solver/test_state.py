"""SPDSolver.reuse_state and restore_reuse_state: the solver's reuse state, saved and
restored, continues bit for bit."""

from __future__ import annotations

import json

import numpy as np
import scipy.sparse as sp

from shared.solver import SPDSolver
from tests.shared.solver._systems import drift_conductances, drifting_start, flow_system, laplacian_system, lower_of


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


def test_factor_state_mid_rent_restores_bit_for_bit(rng: np.random.Generator) -> None:
    """Saved while the stale factor is being rented (through JSON, as a checkpoint keeps
    it), the restored solver takes the same rent-or-buy decisions on the solves that
    follow, with the same answers bit for bit and the same counters."""
    matrix, rhs, solver = drifting_start(rng, refactor_iterations=20)
    solver.solve(lower_of(matrix), rhs)
    drifts = [lower_of(drift_conductances(matrix, 0.02 * k, rng)) for k in range(1, 9)]
    for lower in drifts[:3]:
        solver.solve(lower, rhs)
    assert solver.stats.factorisations == 1 and solver.stats.iterations > 0
    scalars, arrays = solver.reuse_state()
    restored = SPDSolver(refactor_iterations=20)
    restored.restore_reuse_state(json.loads(json.dumps(scalars)), {k: v.copy() for k, v in arrays.items()})
    for lower in drifts[3:]:
        np.testing.assert_array_equal(restored.solve(lower, rhs), solver.solve(lower, rhs))
    assert restored.stats == solver.stats and solver.stats.factorisations > 1


def test_a_fresh_solvers_state_restores_a_fresh_solver(rng: np.random.Generator) -> None:
    scalars, arrays = SPDSolver().reuse_state()
    assert arrays == {}
    restored = SPDSolver()
    restored.restore_reuse_state(scalars, arrays)
    lower = lower_of(laplacian_system(30, rng))
    restored.solve(lower, np.ones(30))
    assert (restored.stats.analyses, restored.stats.factorisations, restored.stats.iterations) == (1, 1, 0)


def test_the_solver_package_exports_no_private_name() -> None:
    """The reuse state is the solver's own methods (no module reads another object's
    private attribute: tests/shared/test_private_access.py), and the package exports no
    private name."""
    import shared.solver

    assert [name for name in shared.solver.__all__ if name.startswith("_")] == []
