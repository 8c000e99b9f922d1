"""The multigrid path of the SPD solver: a Ruge-Stueben hierarchy (pyamg) reused while
it converges about as fast as on its own matrix.

Every solve iterates; the hierarchy is built for a new pattern or on demand and reused
on drifted matrices (the coarsening of a conductance graph survives a step of drift) for
at most ``amg_rebuild_ratio`` times the iterations of the first solve after its setup.
A stale hierarchy that misses the tolerance within them is rebuilt and the solve
finishes from its iterate. The coarsening is classical with Ruge and Stueben's second
pass, strength threshold ``amg_strength``; the V-cycle smooths by a forward
Gauss-Seidel sweep before the coarse correction and a backward one after it (a
symmetric positive definite preconditioner, as CG needs); the coarsest level is solved
by sparse LU. Details: docs/performance.md, "shared.solver".
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt
import pyamg
import scipy.sparse as sp

from shared.solver._kernels import _full_matrix
from shared.solver.base import SolverStats

__all__ = ["AMG_STRENGTH", "AMG_UNKNOWNS", "MultigridReuse"]

FloatArray = npt.NDArray[np.float64]

# Iterations a stale hierarchy may rent at least (times the rebuild ratio), however fast
# its first solve was.
_MIN_SETUP_ITERATIONS = 4

# Unknowns from which ``method="auto"`` preconditions with multigrid instead of a factor
# (measured crossover of a whole run, benchmarks/reference/README.md).
AMG_UNKNOWNS = 100_000

# Strength threshold of the classical coarsening, instead of pyamg's 0.25 (the
# measurements: benchmarks/reference/README.md).
AMG_STRENGTH = 0.5

# One forward Gauss-Seidel sweep before the coarse correction and one backward after it:
# the V-cycle stays symmetric (the post-smoother is the pre-smoother's adjoint).
_PRESMOOTHER = ("gauss_seidel", {"sweep": "forward"})
_POSTSMOOTHER = ("gauss_seidel", {"sweep": "backward"})


class MultigridReuse:
    """A V-cycle preconditioner and the iterations of its first solve.

    Attributes
    ----------
    cycle
        The hierarchy as a preconditioner, None before the first setup.
    setup_iterations
        CG iterations of the first solve after the setup (-1 until it is made).
    """

    def __init__(self) -> None:
        self.cycle: Any = None
        self.setup_iterations = 0

    def build(self, matrix: sp.csc_matrix, strength: float) -> None:
        """Set a hierarchy up for the SPD matrix of the lower triangle ``matrix``."""
        # the coarsest level (at most 500 unknowns, SPD) by sparse LU: pyamg's default
        # pseudo-inverse takes an SVD at the first cycle of every new hierarchy
        hierarchy = pyamg.ruge_stuben_solver(
            _full_matrix(matrix), strength=("classical", {"theta": strength}),
            CF=("RS", {"second_pass": True}), max_coarse=500, coarse_solver="splu",
            presmoother=_PRESMOOTHER, postsmoother=_POSTSMOOTHER)
        self.cycle = hierarchy.aspreconditioner(cycle="V")
        self.setup_iterations = -1

    def apply(self, vector: FloatArray) -> FloatArray:
        """One V-cycle on ``vector``."""
        return np.ascontiguousarray(self.cycle.matvec(vector), dtype=np.float64)

    def solve(
        self, stats: SolverStats, *, fresh: bool, max_iterations: int, rebuild_ratio: float,
        buy: Callable[[], None], iterate: Callable[..., tuple[FloatArray, bool]],
    ) -> tuple[FloatArray, bool]:
        """Reuse or rebuild the hierarchy (``buy()``) and solve (``iterate(budget,
        start=None)``)."""
        rebuild = fresh or self.cycle is None
        if rebuild:
            buy()
        # a stale hierarchy may rent what a solve with a fresh one would need; a crack
        # that opened can make it useless, and then that bound is all it wastes
        budget = max_iterations if rebuild else min(max_iterations, math.ceil(
            rebuild_ratio * max(self.setup_iterations, _MIN_SETUP_ITERATIONS)))
        before = stats.iterations
        solution, converged = iterate(budget)
        if not converged and not rebuild:
            buy()
            before = stats.iterations
            solution, converged = iterate(max_iterations, start=solution)
        if self.setup_iterations < 0:
            self.setup_iterations = stats.iterations - before
        return solution, converged
