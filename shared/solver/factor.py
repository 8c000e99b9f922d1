"""The factor path of the SPD solver: a CHOLMOD factor reused by a rent-or-buy rule.

The symbolic analysis (fill-reducing ordering) is kept while the sparsity pattern is
unchanged. The old numeric factor preconditions conjugate gradients on the current
matrix until the CG iterations spent since the factorisation reach
``refactor_iterations`` (about one factorisation's price in substitutions); then the
solve refactors, mid-solve if need be, and finishes from its iterate. A solve also
buys at once when the previous solve's rent would exhaust the rest of the budget, and
when a first stale solve exhausts its budget the next 1, 2, 4, ... (at most
``_MAX_BACKOFF``) solves buy at once (exponential back-off): the total work stays within
about twice that of the better of always and never refactoring. Details:
docs/performance.md, "shared.solver".
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from sksparse.cholmod import CholmodNotPositiveDefiniteError, Factor, analyze
from threadpoolctl import ThreadpoolController

from shared.solver.base import Since, SolverError, SolverStats

__all__ = ["FactorReuse", "set_cholmod_blas_threads"]

FloatArray = npt.NDArray[np.float64]

# Most solves that buy a factor at once between two probes of the stale factor.
_MAX_BACKOFF = 32


def set_cholmod_blas_threads(threads: int) -> bool:
    """Set the thread count of the OpenBLAS library CHOLMOD links (process-wide).

    Multithreaded BLAS slows the small dense blocks of the triangular solves down,
    several-fold on an oversubscribed machine.

    Parameters
    ----------
    threads
        Number of BLAS threads, >= 1.

    Returns
    -------
    bool
        True if an OpenBLAS library was found and set; False otherwise (then the BLAS
        is left alone, e.g. with MKL or a reference BLAS).
    """
    libraries = _cholmod_blas()
    if not libraries.lib_controllers:
        return False
    libraries.limit(limits=int(threads))
    return True


@functools.cache
def _cholmod_blas() -> ThreadpoolController:
    """The OpenBLAS that CHOLMOD links (``libopenblas``; numpy's wheels bring their own,
    ``libscipy_openblas``, left alone), loaded when this module imports CHOLMOD."""
    return ThreadpoolController().select(prefix="libopenblas")


class FactorReuse:
    """A CHOLMOD factor (supernodal LL^T, so that an indefinite or singular matrix raises
    instead of being factored with negative or zero pivots) and its rent-or-buy state.

    Attributes
    ----------
    factor
        The current factor, None before the first factorisation.
    ordering
        The fill-reducing ordering of the current analysis.
    last_rent, buy_at_once, backoff
        CG iterations of the last stale solve, solves left to buy at once, and the
        back-off of the next failed probe.
    """

    def __init__(self) -> None:
        self.factor: Factor | None = None
        self.ordering: str | None = None
        self.last_rent = 0
        self.buy_at_once = 0
        self.backoff = 1

    def build(
        self, matrix: sp.csc_matrix, ordering_method: str, analysed: bool,
        blas_threads: int | None, factor_blas_threads: int | None, stats: SolverStats,
    ) -> None:
        """Factor ``matrix``, analysing it first unless ``analysed`` (same pattern).

        Raises
        ------
        SolverError
            If the matrix is not positive definite.
        """
        threaded = factor_blas_threads is not None
        try:
            if not analysed:
                self.factor = analyze(matrix, mode="supernodal", ordering_method=ordering_method)
                self.ordering = ordering_method
                stats.analyses += 1
            assert self.factor is not None
            if factor_blas_threads is not None:
                set_cholmod_blas_threads(factor_blas_threads)
            self.factor.cholesky_inplace(matrix)
        except CholmodNotPositiveDefiniteError as error:
            raise SolverError(
                "matrix not positive definite: a set of free cells without storage is "
                "not connected to any imposed pressure, or a coefficient is negative"
            ) from error
        finally:
            if threaded and blas_threads is not None:  # SPDSolver threads the factor only then
                set_cholmod_blas_threads(blas_threads)

    def apply(self, vector: FloatArray) -> FloatArray:
        """The factor's solve of ``vector`` (forward and backward substitution)."""
        assert self.factor is not None
        return np.ascontiguousarray(self.factor(vector), dtype=np.float64)

    def solve(
        self, since: Since, *, fresh: bool, refactor_iterations: int, max_iterations: int,
        drifted: Callable[[], bool] | None, buy: Callable[[], None],
        iterate: Callable[..., tuple[FloatArray, bool]],
    ) -> tuple[FloatArray, bool]:
        """Rent the stale factor or buy a new one, and solve.

        ``since`` counts the work since the last factorisation (``buy()`` resets it,
        ``iterate`` adds its iterations); ``drifted()`` is the optional drift trigger;
        ``buy()`` refactors the current matrix; ``iterate(budget, start=None)`` runs CG.
        """
        remaining = refactor_iterations - since.iterations
        refactor = fresh or self.last_rent >= remaining or self.buy_at_once > 0
        self.buy_at_once = max(self.buy_at_once - 1, 0)
        if drifted is not None and not fresh:
            refactor = drifted() or refactor
        if refactor:
            buy()
        # A stale factor may only rent the iterations left before buying a new one.
        budget = max_iterations if refactor else min(max_iterations, remaining)
        rented = since.iterations
        probe = not refactor and since.solves == 0
        since.solves += 0 if refactor else 1
        solution, converged = iterate(budget)
        self.last_rent = 0 if refactor else since.iterations - rented
        if probe:
            # A first stale solve that exhausts its budget shows one step of drift to
            # cost more than a factorisation: buy at once for the next solves, twice
            # as many after each failed probe (exponential back-off).
            self.buy_at_once = 0 if converged else self.backoff
            self.backoff = 1 if converged else min(2 * self.backoff, _MAX_BACKOFF)
        if not converged and not refactor:
            # Buy: refactor and finish from the iterate reached with the old factor.
            buy()
            solution, converged = iterate(max_iterations, start=solution)
        return solution, converged
