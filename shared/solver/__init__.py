"""SPD solver of the flow systems: CG preconditioned by a CHOLMOD factor or by multigrid.

Factorising dominates the flow solve (thesis Chap. 5.3.1), so the preconditioner is
reused while the matrix drifts. Yade then silently solves a stale system (docs/yade.md
§8.2); here every answer solves the current matrix A to a row-wise backward error
max_i |b - A x|_i / (|a_ii| ||x||_inf + |b_i|) <= ``residual_tolerance``.

``method="auto"`` preconditions with a sparse Cholesky factor (CHOLMOD) below
``amg_unknowns`` unknowns and with a classical Ruge-Stueben hierarchy (pyamg) above:
on a 3D mesh the factor costs O(n^2) to compute and O(n^(4/3)) to apply, the hierarchy
O(n). A stale factor is refreshed by a rent-or-buy rule on the CG iterations spent
since the last factorisation (``refactor_iterations``), a stale hierarchy after
``amg_rebuild_ratio`` times its first solve's iterations; both rules count iterations,
not time, so they are deterministic. The rules in full: docs/performance.md,
"shared.solver". Parts: :mod:`.spd` (the dispatcher and CG), :mod:`.factor`,
:mod:`.multigrid`, :mod:`.state` (checkpoints).
"""

from shared.solver._kernels import _scaled_drift, _symmetric_product
from shared.solver.base import SolverError, SolverStats
from shared.solver.factor import set_cholmod_blas_threads
from shared.solver.multigrid import AMG_STRENGTH, AMG_UNKNOWNS
from shared.solver.spd import SPDSolver

__all__ = ["SolverError", "SolverStats", "SPDSolver", "set_cholmod_blas_threads",
           "AMG_UNKNOWNS", "AMG_STRENGTH", "_scaled_drift", "_symmetric_product"]
