"""SPD solver of the flow systems: CG preconditioned by a CHOLMOD factor or by multigrid.

Factorising dominates the flow solve (thesis Chap. 5.3.1), so the preconditioner is
reused while the matrix drifts; every answer still solves the current matrix A to a
row-wise backward error max_i |b - A x|_i / (|a_ii| ||x||_inf + |b_i|) <=
``residual_tolerance`` (Yade solves a stale system: docs/yade.md §8.2).

``method="auto"`` preconditions with a sparse Cholesky factor (CHOLMOD) below
``amg_unknowns`` unknowns and with a classical Ruge-Stueben hierarchy (pyamg) above.
A stale factor or hierarchy is refreshed by rules that count CG iterations, not time,
so they are deterministic. ``method="jacobi"`` preconditions with the current diagonal
and buys nothing unless CG misses, for systems whose storage dominates the diagonal.
The rules in full: docs/performance.md, "shared.solver". Parts: :mod:`.spd` (the
dispatcher and CG, and its reuse state for checkpoints), :mod:`.factor`,
:mod:`.multigrid`, :mod:`.jacobi`.
"""

from shared.solver.base import SolverError, SolverStats
from shared.solver.factor import set_cholmod_blas_threads
from shared.solver.multigrid import AMG_STRENGTH, AMG_UNKNOWNS
from shared.solver.spd import SPDSolver

__all__ = ["SolverError", "SolverStats", "SPDSolver", "set_cholmod_blas_threads",
           "AMG_UNKNOWNS", "AMG_STRENGTH"]
