"""The SPD solver's error and work counters."""

from __future__ import annotations

from dataclasses import dataclass

from shared.errors import SolverError

__all__ = ["Since", "SolverError", "SolverStats"]


@dataclass
class SolverStats:
    """Work counters of an :class:`shared.solver.SPDSolver`.

    Attributes
    ----------
    analyses
        Symbolic analyses (fill-reducing ordering), one per new sparsity pattern
        (factor path only).
    factorisations
        Numeric factorisations, or multigrid setups on the multigrid path.
    solves
        Calls of :meth:`shared.solver.SPDSolver.solve`.
    factor_applications
        Applications of the preconditioner: forward/backward substitutions with a
        factor, V-cycles, or diagonal scalings.
    iterations
        Preconditioned CG iterations.
    fallbacks
        Patterns on which ``method="auto"`` fell back from multigrid, or
        ``method="jacobi"`` from the diagonal, to the factor.
    """

    analyses: int = 0
    factorisations: int = 0
    solves: int = 0
    factor_applications: int = 0
    iterations: int = 0
    fallbacks: int = 0


@dataclass
class Since:
    """Work since the preconditioner was last bought (factored or set up): CG
    iterations, and solves that rented a stale factor."""

    iterations: int = 0
    solves: int = 0
