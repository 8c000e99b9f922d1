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
"shared.solver".
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pyamg
import scipy.sparse as sp
from numba import njit
from sksparse.cholmod import CholmodNotPositiveDefiniteError, Factor, analyze
from threadpoolctl import ThreadpoolController

__all__ = ["SolverError", "SolverStats", "SPDSolver", "set_cholmod_blas_threads",
           "AMG_UNKNOWNS"]

FloatArray = npt.NDArray[np.float64]
log = logging.getLogger("shared.solver")

# Most solves that buy a factor at once between two probes of the stale factor.
_MAX_BACKOFF = 32

# Iterations a stale hierarchy may rent at least (times the rebuild ratio), however fast
# its first solve was.
_MIN_SETUP_ITERATIONS = 4

# Unknowns from which ``method="auto"`` preconditions with multigrid instead of a factor
# (measured crossover of a whole run, benchmarks/reference/README.md).
AMG_UNKNOWNS = 100_000

# Strength threshold of the classical coarsening: 0.5 instead of pyamg's 0.25 halves the
# hierarchy's operator complexity on the micro model's steady systems (5.7 -> 3.5) and
# takes a solve to 1e-13 in fewer iterations (benchmarks/reference/README.md).
AMG_STRENGTH = 0.5

# One forward Gauss-Seidel sweep before the coarse correction and one backward after it:
# the V-cycle stays symmetric (the post-smoother is the pre-smoother's adjoint) at half
# the sweeps of pyamg's symmetric sweeps on both sides, for one or two more CG
# iterations (README, "Flow solver").
_PRESMOOTHER = ("gauss_seidel", {"sweep": "forward"})
_POSTSMOOTHER = ("gauss_seidel", {"sweep": "backward"})


class SolverError(RuntimeError):
    """The linear solve failed: singular/indefinite matrix or non-finite values."""


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


@njit(cache=True)
def _symmetric_product(
    indptr: npt.NDArray[np.int32], indices: npt.NDArray[np.int32], data: FloatArray,
    vector: FloatArray,
) -> FloatArray:
    """A x for the symmetric A given by its CSC lower triangle (diagonal first)."""
    result = np.zeros(vector.shape[0])
    for column in range(vector.shape[0]):
        x_column = vector[column]
        total = data[indptr[column]] * x_column
        for p in range(indptr[column] + 1, indptr[column + 1]):
            row = indices[p]
            result[row] += data[p] * x_column
            total += data[p] * vector[row]
        result[column] += total
    return result


@njit(cache=True)
def _scaled_drift(
    indptr: npt.NDArray[np.int32], indices: npt.NDArray[np.int32], data: FloatArray,
    old: FloatArray,
) -> float:
    """max |a_ij - a0_ij| / sqrt(|a0_ii a0_jj|); 0 where both vanish, inf for a new entry."""
    largest = 0.0
    for column in range(indptr.shape[0] - 1):
        diagonal = abs(old[indptr[column]])
        for p in range(indptr[column], indptr[column + 1]):
            change = abs(data[p] - old[p])
            if change == 0.0:
                continue
            scale = np.sqrt(diagonal * abs(old[indptr[indices[p]]]))
            largest = max(largest, change / scale if scale > 0.0 else np.inf)
    return largest


@njit(cache=True)
def _cg_update(
    indptr: npt.NDArray[np.int32], indices: npt.NDArray[np.int32], data: FloatArray,
    preconditioned: FloatArray, solution: FloatArray, residual: FloatArray,
    direction: FloatArray, rho: float,
) -> tuple[float, bool]:
    """One preconditioned CG update of solution, residual and direction (in place).

    Returns the new rho = r . z and whether the step was possible (rho and the
    curvature d . A d positive).
    """
    rho_new = 0.0
    for k in range(residual.shape[0]):
        rho_new += residual[k] * preconditioned[k]
    if not rho_new > 0.0:
        return rho_new, False
    beta = rho_new / rho
    for k in range(residual.shape[0]):
        direction[k] = preconditioned[k] + beta * direction[k]
    image = _symmetric_product(indptr, indices, data, direction)
    curvature = 0.0
    for k in range(residual.shape[0]):
        curvature += direction[k] * image[k]
    if not curvature > 0.0:
        return rho_new, False
    step = rho_new / curvature
    for k in range(residual.shape[0]):
        solution[k] += step * direction[k]
        residual[k] -= step * image[k]
    return rho_new, True


def _check_lower(matrix: sp.csc_matrix) -> None:
    """Raise unless ``matrix`` is a square CSC lower triangle with a leading diagonal."""
    if not (sp.issparse(matrix) and matrix.format == "csc"):
        raise ValueError("pass the lower triangle as a scipy.sparse CSC matrix")
    if matrix.shape[0] != matrix.shape[1]:
        raise ValueError(f"matrix must be square, got shape {matrix.shape}")
    counts = np.diff(matrix.indptr)
    columns = np.repeat(np.arange(matrix.shape[1]), counts)
    if np.any(matrix.indices < columns):
        raise ValueError("matrix has entries above the diagonal: pass its lower triangle")
    leading = matrix.indices[matrix.indptr[:-1]]
    if np.any(counts == 0) or np.any(leading != np.arange(matrix.shape[1])):
        raise ValueError("every column must start with its diagonal entry (sorted indices)")


@dataclass
class SolverStats:
    """Work counters of an :class:`SPDSolver`.

    Attributes
    ----------
    analyses
        Symbolic analyses (fill-reducing ordering), one per new sparsity pattern
        (factor path only).
    factorisations
        Numeric factorisations, or multigrid setups on the multigrid path.
    solves
        Calls of :meth:`SPDSolver.solve`.
    factor_applications
        Applications of the preconditioner: forward/backward substitutions with a
        factor, or V-cycles.
    iterations
        Preconditioned CG iterations.
    fallbacks
        Patterns on which ``method="auto"`` fell back from multigrid to the factor.
    """

    analyses: int = 0
    factorisations: int = 0
    solves: int = 0
    factor_applications: int = 0
    iterations: int = 0
    fallbacks: int = 0


def _full_matrix(lower: sp.csc_matrix) -> sp.csr_matrix:
    """The symmetric matrix of a lower triangle, CSR (what pyamg takes)."""
    full = (lower + sp.tril(lower, k=-1, format="csc").T).tocsr()
    full.sort_indices()
    return full


class SPDSolver:
    """Solve SPD systems given by their lower triangle, reusing a factor or a hierarchy.

    Parameters
    ----------
    refactor_tolerance
        Largest scaled coefficient drift tolerated before refactoring [1]; None
        (default) disables this trigger and leaves the decision to the rent-or-buy rule.
    residual_tolerance
        Target row-wise backward error max_i |b - A x|_i / (|a_ii| ||x||_inf + |b_i|)
        of every solve [1] (with ``offset``, of the system the whole unknown solves).
        For the transient steps of :mod:`shared.fv` it bounds each cell's volume-rate
        imbalance by this fraction of its own diagonal times the largest pressure
        (water is conserved to round-off anyway: the update is in flux form); 1e-7
        already lets the clay rows next to open cracks push saturations past their
        bounds (``tests/shared/test_fv.py``).
    max_iterations
        CG iterations allowed in one solve with a fresh factor (with a stale one the
        rent-or-buy budget also applies).
    refactor_iterations
        CG iterations since the last factorisation after which the solve refactors [1]:
        about the price of a factorisation in substitutions.
    ordering_method
        CHOLMOD fill-reducing ordering (``"metis"``, ``"amd"``, ``"natural"``, ...);
        ``None`` (default) uses ``"natural"`` for matrices passed with ``ordered=True``
        (their unknowns are already in a fill-reducing order) and ``"metis"`` otherwise.
    blas_threads
        If given, the OpenBLAS thread count set at construction
        (:func:`set_cholmod_blas_threads`, process-wide); ``None`` leaves it alone.
    factor_blas_threads
        If given (and ``blas_threads`` too), the OpenBLAS thread count during numeric
        factorisations only, ``blas_threads`` being restored after: the large dense
        supernodes of a factorisation may gain from threads that the small blocks of the
        substitutions lose to. Off by default: a threaded factorisation rounds
        differently, so a run's results would depend on its thread count (README,
        "Benchmarks"), and on a shared 2-core machine the gain was not reproducible.
    method
        ``"direct"`` (CHOLMOD factor), ``"amg"`` (multigrid hierarchy) or ``"auto"``:
        multigrid from ``amg_unknowns`` unknowns on.
    amg_unknowns
        Crossover of ``method="auto"`` [1].
    amg_max_iterations
        CG iterations allowed in one solve on the multigrid path [1].
    amg_rebuild_ratio
        A stale hierarchy may spend this many times the iterations of the first solve
        after its setup (at least 4) before it is rebuilt in the middle of the solve [1].
    amg_strength
        Classical strength threshold theta of the coarsening [1]: a connection is strong
        if -a_ij >= theta max_k -a_ik.

    Notes
    -----
    The factorisation is forced to supernodal LL^T so that an indefinite or singular
    matrix raises instead of being factored as LDL^T with negative or zero pivots; on
    the multigrid path such a matrix stops CG (non-positive curvature) short of the
    tolerance, which raises or, with ``method="auto"``, hands it to the factor.
    The CG vector work runs in numba kernels rather than numpy: numpy's dot products
    wake its own BLAS threads, which then compete with the CHOLMOD substitutions on a
    loaded machine.
    """

    def __init__(
        self,
        refactor_tolerance: float | None = None,
        residual_tolerance: float = 1e-8,
        max_iterations: int = 20,
        refactor_iterations: int = 20,
        ordering_method: str | None = None,
        blas_threads: int | None = 1,
        factor_blas_threads: int | None = None,
        method: str = "auto",
        amg_unknowns: int = AMG_UNKNOWNS,
        amg_max_iterations: int = 100,
        amg_rebuild_ratio: float = 1.5,
        amg_strength: float = AMG_STRENGTH,
    ) -> None:
        if method not in ("auto", "direct", "amg"):
            raise ValueError(f"method must be 'auto', 'direct' or 'amg', got {method!r}")
        self.refactor_tolerance = refactor_tolerance
        self.residual_tolerance = residual_tolerance
        self.max_iterations = max_iterations
        self.refactor_iterations = refactor_iterations
        self.ordering_method = ordering_method
        self.method = method
        self.amg_unknowns = amg_unknowns
        self.amg_max_iterations = amg_max_iterations
        self.amg_rebuild_ratio = amg_rebuild_ratio
        self.amg_strength = amg_strength
        self.blas_threads = blas_threads
        self.blas_threads_set = blas_threads is not None and set_cholmod_blas_threads(blas_threads)
        self.factor_blas_threads = factor_blas_threads if self.blas_threads_set else None
        self.stats = SolverStats()
        # drift of the last solve's matrix, computed only for the optional trigger
        self.last_drift = float("nan")
        self.last_residual = 0.0
        self._factor: Factor | None = None
        self._cycle: Any = None
        self._indptr: npt.NDArray[np.int32] | None = None
        self._indices: npt.NDArray[np.int32] | None = None
        self._factored_data: FloatArray | None = None
        self._ordering: str | None = None
        self._stale_iterations = 0
        self._last_rent = 0
        self._stale_solves = 0
        self._buy_at_once = 0
        self._backoff = 1
        # multigrid path: iterations of the first solve after the setup; whether the
        # factor path took over for the current pattern
        self._setup_iterations = 0
        self._fallback = False

    def uses_multigrid(self, unknowns: int) -> bool:
        """Whether a system of ``unknowns`` unknowns is preconditioned by multigrid."""
        return self.method == "amg" or (self.method == "auto" and unknowns >= self.amg_unknowns)

    def reset(self) -> None:
        """Forget the analysis, factor and hierarchy (the next solve starts afresh)."""
        self._factor = None
        self._cycle = None
        self._indptr = None

    def _same_pattern(self, matrix: sp.csc_matrix) -> bool:
        return (
            self._indptr is not None
            and self._indices is not None
            and matrix.shape[0] == self._indptr.shape[0] - 1
            and np.array_equal(matrix.indptr, self._indptr)
            and np.array_equal(matrix.indices, self._indices)
        )

    def _factorise(self, matrix: sp.csc_matrix, ordered: bool) -> None:
        """Buy a preconditioner of ``matrix``: a CHOLMOD factor or a multigrid hierarchy."""
        same = self._same_pattern(matrix)
        if not same:
            _check_lower(matrix)
        if self.uses_multigrid(matrix.shape[0]) and not self._fallback:
            self._factor = None
            # the coarsest level (at most 500 unknowns, SPD) by sparse LU: pyamg's default
            # pseudo-inverse takes an SVD at the first cycle of every new hierarchy
            hierarchy = pyamg.ruge_stuben_solver(
                _full_matrix(matrix), strength=("classical", {"theta": self.amg_strength}),
                CF=("RS", {"second_pass": True}), max_coarse=500, coarse_solver="splu",
                presmoother=_PRESMOOTHER, postsmoother=_POSTSMOOTHER)
            self._cycle = hierarchy.aspreconditioner(cycle="V")
            self._setup_iterations = -1
        else:
            self._cycle = None
            self._cholesky(matrix, ordered, same and self._factor is not None)
        if not same:
            self._indptr = matrix.indptr.copy()
            self._indices = matrix.indices.copy()
        self._factored_data = matrix.data.copy()
        self._stale_iterations = 0
        self._stale_solves = 0
        self.stats.factorisations += 1

    def _cholesky(self, matrix: sp.csc_matrix, ordered: bool, analysed: bool) -> None:
        threaded = self.factor_blas_threads is not None
        try:
            if not analysed:
                method = self.ordering_method or ("natural" if ordered else "metis")
                self._factor = analyze(matrix, mode="supernodal", ordering_method=method)
                self._ordering = method
                self.stats.analyses += 1
            assert self._factor is not None
            if threaded:
                set_cholmod_blas_threads(self.factor_blas_threads)
            self._factor.cholesky_inplace(matrix)
        except CholmodNotPositiveDefiniteError as error:
            self.reset()
            raise SolverError(
                "matrix not positive definite: a set of free cells without storage is "
                "not connected to any imposed pressure, or a coefficient is negative"
            ) from error
        finally:
            if threaded:
                set_cholmod_blas_threads(self.blas_threads)

    def reuse_state(self) -> tuple[dict[str, Any], dict[str, npt.NDArray[Any]]]:
        """What decides this solver's next refactorisations, for a checkpoint file.

        Returns
        -------
        scalars : dict
            The preconditioner choice (``method``, ``amg_unknowns``, ``amg_strength``), the rent-or-buy
            counters (stale iterations and solves, last rent, solves left to buy at
            once, back-off; on the multigrid path the iterations of the first solve
            since the setup, and whether the factor took over the pattern), the
            diagnostics ``last_drift`` and ``last_residual``, the work counters of :attr:`stats` and the ordering
            of the current analysis (JSON-serialisable).
        arrays : dict
            ``indptr``, ``indices`` and ``data`` of the factored lower triangle, empty
            if there is no factor or hierarchy. Neither can be saved: each is a
            deterministic function of this matrix (and the ordering), and
            :meth:`restore_reuse_state` builds it again.
        """
        scalars: dict[str, Any] = {
            "stale_iterations": self._stale_iterations, "last_rent": self._last_rent,
            "stale_solves": self._stale_solves, "buy_at_once": self._buy_at_once,
            "backoff": self._backoff, "last_drift": self.last_drift,
            "last_residual": self.last_residual, "ordering": self._ordering,
            "method": self.method, "amg_unknowns": self.amg_unknowns,
            "amg_strength": self.amg_strength, "setup_iterations": self._setup_iterations, "fallback": self._fallback,
            "stats": dataclasses.asdict(self.stats),
        }
        arrays: dict[str, npt.NDArray[Any]] = {}
        if (self._factor is not None or self._cycle is not None) \
                and self._factored_data is not None:
            assert self._indptr is not None and self._indices is not None
            arrays = {"indptr": self._indptr, "indices": self._indices,
                      "data": self._factored_data}
        return scalars, arrays

    def restore_reuse_state(
        self, scalars: Mapping[str, Any], arrays: Mapping[str, npt.NDArray[Any]]
    ) -> None:
        """Continue as the solver whose :meth:`reuse_state` this was, bit for bit.

        With a saved factored matrix, it is analysed (same ordering) and factored, or
        its hierarchy built, again: CHOLMOD and the Ruge-Stueben setup are
        deterministic for a given matrix (and ordering), so the new preconditioner
        applies exactly as the lost one did.
        """
        # states saved before the multigrid path existed are factor states
        self.method = scalars.get("method", "direct")
        self.amg_unknowns = int(scalars.get("amg_unknowns", self.amg_unknowns))
        # states saved before the threshold was a setting used pyamg's default
        self.amg_strength = float(scalars.get("amg_strength", 0.25))
        self._fallback = bool(scalars.get("fallback", False))
        if arrays:
            n = arrays["indptr"].shape[0] - 1
            matrix = sp.csc_matrix(
                (np.array(arrays["data"], dtype=np.float64),
                 np.array(arrays["indices"], dtype=np.int32),
                 np.array(arrays["indptr"], dtype=np.int32)), shape=(n, n))
            self.ordering_method, saved_method = scalars["ordering"], self.ordering_method
            try:
                self.reset()
                self._factorise(matrix, ordered=False)
            finally:
                self.ordering_method = saved_method
        else:
            self.reset()
            self._factored_data = None
        self._ordering = scalars["ordering"]
        self._stale_iterations = int(scalars["stale_iterations"])
        self._last_rent = int(scalars["last_rent"])
        self._stale_solves = int(scalars["stale_solves"])
        self._buy_at_once = int(scalars["buy_at_once"])
        self._backoff = int(scalars["backoff"])
        self._setup_iterations = int(scalars.get("setup_iterations", 0))
        self.last_drift = float(scalars["last_drift"])
        self.last_residual = float(scalars["last_residual"])
        self.stats = SolverStats(**{"fallbacks": 0, **scalars["stats"]})

    def drift(self, lower: sp.csc_matrix) -> float:
        """Largest scaled entry change of ``lower`` since the last factorisation [1].

        max |a_ij - a0_ij| / sqrt(|a0_ii a0_jj|) over the lower triangle (same pattern
        as the factored matrix); a diagnostic, and the optional refactor trigger.
        """
        if self._factored_data is None or not self._same_pattern(lower):
            raise ValueError("no factor of a matrix with this sparsity pattern")
        return _scaled_drift(lower.indptr, lower.indices, lower.data, self._factored_data)

    def _apply(self, vector: FloatArray) -> FloatArray:
        self.stats.factor_applications += 1
        if self._cycle is not None:
            return np.ascontiguousarray(self._cycle.matvec(vector), dtype=np.float64)
        assert self._factor is not None
        return np.ascontiguousarray(self._factor(vector), dtype=np.float64)

    def solve(
        self,
        lower: sp.csc_matrix,
        rhs: npt.ArrayLike,
        *,
        force_refactor: bool = False,
        ordered: bool = False,
        offset: FloatArray | None = None,
    ) -> FloatArray:
        """Solve A x = b for the SPD matrix A given by its lower triangle.

        Parameters
        ----------
        lower
            Lower triangle with diagonal of A, CSC with sorted indices (the diagonal is
            the first entry of each column, as :func:`shared.fv.assemble_matrix` builds).
        rhs
            Right-hand side b, shape (n,).
        force_refactor
            Refactor (or rebuild the hierarchy) even if the reuse rules would not
            (e.g. at remesh).
        ordered
            The unknowns are already numbered in a fill-reducing order (as
            :func:`shared.fv.flow_pattern` numbers them): with the default
            ``ordering_method`` the analysis then skips METIS.
        offset
            If given, x is the increment of an unknown y = offset + x, and the
            tolerance applies to the system A y = b + A offset that y solves: x is
            then needed only as accurately as y is (a time step's pressure
            increment from the start-of-step pressure, say).

        Returns
        -------
        ndarray, shape (n,)
            x with |b - A x|_i <= residual_tolerance (|a_ii| ||y||_inf + |f_i|) for
            every row i of the current A, where y = x and f = b, or y = offset + x and
            f = b + A offset.

        Raises
        ------
        SolverError
            If A is not positive definite, b or x is not finite, or CG with a fresh
            factor or hierarchy still misses the tolerance.
        """
        rhs = np.ascontiguousarray(rhs, dtype=np.float64)
        if not np.all(np.isfinite(rhs)):
            raise SolverError("right-hand side contains NaN or inf")
        if not np.all(np.isfinite(lower.data)):
            raise SolverError("matrix contains NaN or inf")
        self.stats.solves += 1
        fresh = force_refactor or not self._same_pattern(lower) or (
            self._factor is None and self._cycle is None)
        diagonal = np.abs(lower.data[lower.indptr[:-1]])
        if fresh:
            self._fallback = False
        if self.uses_multigrid(lower.shape[0]) and not self._fallback:
            solution, converged = self._multigrid_solve(lower, rhs, diagonal, fresh, offset)
            if not converged and self.method == "auto":
                # a system the hierarchy cannot solve (extreme conductance contrasts):
                # the factor solves it, and the next solves of this pattern too
                log.info("multigrid missed the tolerance (%.1e) on %d unknowns: factor path "
                         "until the next pattern", self.last_residual, lower.shape[0])
                self._fallback = True
                self.stats.fallbacks += 1
                solution, converged = self._factor_solve(lower, rhs, diagonal, True, ordered,
                                                         offset)
        else:
            solution, converged = self._factor_solve(lower, rhs, diagonal, fresh, ordered,
                                                     offset)
        if not converged:
            raise SolverError(
                f"residual {self.last_residual:.3e} above tolerance "
                f"{self.residual_tolerance:.1e} even with a fresh preconditioner "
                "(ill-conditioned or not positive definite?)"
            )
        return solution

    def _factor_solve(
        self, lower: sp.csc_matrix, rhs: FloatArray, diagonal: FloatArray, fresh: bool,
        ordered: bool, offset: FloatArray | None,
    ) -> tuple[FloatArray, bool]:
        """The factor path: rent the stale factor or buy a new one (module docstring)."""
        remaining = self.refactor_iterations - self._stale_iterations
        refactor = fresh or self._last_rent >= remaining or self._buy_at_once > 0
        self._buy_at_once = max(self._buy_at_once - 1, 0)
        if self.refactor_tolerance is not None and not fresh:
            self.last_drift = self.drift(lower)
            refactor = refactor or self.last_drift > self.refactor_tolerance
        if refactor:
            self._factorise(lower, ordered)
        # A stale factor may only rent the iterations left before buying a new one.
        budget = self.max_iterations if refactor else min(self.max_iterations, remaining)
        rented = self._stale_iterations
        probe = not refactor and self._stale_solves == 0
        self._stale_solves += 0 if refactor else 1
        solution, converged = self._corrected_solve(lower, rhs, diagonal, budget, offset)
        self._last_rent = 0 if refactor else self._stale_iterations - rented
        if probe:
            # A first stale solve that exhausts its budget shows one step of drift to
            # cost more than a factorisation: buy at once for the next solves, twice
            # as many after each failed probe (exponential back-off).
            self._buy_at_once = 0 if converged else self._backoff
            self._backoff = 1 if converged else min(2 * self._backoff, _MAX_BACKOFF)
        if not converged and not refactor:
            # Buy: refactor and finish from the iterate reached with the old factor.
            self._factorise(lower, ordered)
            solution, converged = self._corrected_solve(
                lower, rhs, diagonal, self.max_iterations, offset, solution
            )
        return solution, converged

    def _multigrid_solve(
        self, lower: sp.csc_matrix, rhs: FloatArray, diagonal: FloatArray, fresh: bool,
        offset: FloatArray | None,
    ) -> tuple[FloatArray, bool]:
        """The multigrid path: reuse the hierarchy while it converges about as fast as it
        did on its own matrix (module docstring)."""
        rebuild = fresh or self._cycle is None
        if rebuild:
            self._factorise(lower, ordered=True)
        # a stale hierarchy may rent what a solve with a fresh one would need; a crack
        # that opened can make it useless, and then that bound is all it wastes
        budget = self.amg_max_iterations if rebuild else min(self.amg_max_iterations, math.ceil(
            self.amg_rebuild_ratio * max(self._setup_iterations, _MIN_SETUP_ITERATIONS)))
        before = self.stats.iterations
        solution, converged = self._corrected_solve(lower, rhs, diagonal, budget, offset)
        if not converged and not rebuild:
            self._factorise(lower, ordered=True)
            before = self.stats.iterations
            solution, converged = self._corrected_solve(
                lower, rhs, diagonal, self.amg_max_iterations, offset, solution)
        if self._setup_iterations < 0:
            self._setup_iterations = self.stats.iterations - before
        return solution, converged

    def _corrected_solve(
        self,
        lower: sp.csc_matrix,
        rhs: FloatArray,
        diagonal: FloatArray,
        iterations: int,
        offset: FloatArray | None,
        start: FloatArray | None = None,
    ) -> tuple[FloatArray, bool]:
        """Preconditioned CG on the current matrix, from the preconditioned rhs or ``start``.

        Convergence is judged row by row: max_i |r_i| / (|a_ii| ||x||_inf + |b_i|),
        ``diagonal`` = |a_ii| of the current matrix. For the diagonally dominant flow
        matrices a backward-stable direct solve reaches it at round-off level whatever
        the conditioning, and, unlike the normwise ||r|| / (||A|| ||x|| + ||b||), it
        does not let the largest rows (open cracks, 1e10 times the clay's
        conductance) excuse residuals as large as the storage terms of the others.
        At most ``iterations`` CG iterations.
        """
        if not np.any(rhs):
            self.last_residual = 0.0
            return np.zeros_like(rhs), True
        indptr, indices, data = lower.indptr, lower.indices, lower.data
        solution = self._apply(rhs) if start is None else start.copy()
        residual = rhs - _symmetric_product(indptr, indices, data, solution)
        direction = np.zeros_like(rhs)
        if offset is None:
            magnitude = np.abs(rhs)
            offset = np.zeros_like(rhs)
        else:
            magnitude = np.abs(rhs + _symmetric_product(indptr, indices, data, offset))
        rho = 1.0
        for iteration in range(iterations + 1):
            self._check_finite(solution)
            scale = diagonal * float(np.max(np.abs(offset + solution))) + magnitude
            self.last_residual = float(np.max(np.abs(residual) / scale))
            if self.last_residual <= self.residual_tolerance:
                return solution, True
            if iteration == iterations:
                break
            rho, advanced = _cg_update(
                indptr, indices, data, self._apply(residual), solution, residual, direction, rho
            )
            if not advanced:
                break
            self.stats.iterations += 1
            self._stale_iterations += 1
        return solution, False

    @staticmethod
    def _check_finite(solution: FloatArray) -> None:
        if not np.all(np.isfinite(solution)):
            raise SolverError("solution contains NaN or inf (solver divergence)")
