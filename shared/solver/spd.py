"""The SPD solver's dispatcher: a CHOLMOD factor, a multigrid hierarchy or the diagonal
preconditions conjugate gradients on the current matrix, judged by a row-wise backward
error.

:class:`SPDSolver` keeps the sparsity pattern and the matrix its preconditioner was
bought for, chooses the path (:mod:`shared.solver.factor`,
:mod:`shared.solver.multigrid`, :mod:`shared.solver.jacobi`), hands a system the
hierarchy or the diagonal cannot solve to the factor (``method="auto"``,
``method="jacobi"``), and runs the CG iterations the paths share. Its reuse state (what
decides its next refactorisations) is saved in a checkpoint and restored by its own
methods (:meth:`SPDSolver.reuse_state`, :meth:`SPDSolver.restore_reuse_state`), so that a
resumed run continues bit for bit.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from sksparse.cholmod import Factor

from shared.solver._kernels import _cg_update, _check_lower, _scaled_drift, _symmetric_product
from shared.solver.base import Since, SolverError, SolverStats
from shared.solver.factor import FactorReuse, set_cholmod_blas_threads
from shared.solver.jacobi import DiagonalScaling
from shared.solver.multigrid import AMG_STRENGTH, AMG_UNKNOWNS, MultigridReuse

__all__ = ["SPDSolver"]

FloatArray = npt.NDArray[np.float64]
log = logging.getLogger("shared.solver")


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
        differently, so a run's results would depend on its thread count.
    method
        ``"direct"`` (CHOLMOD factor), ``"amg"`` (multigrid hierarchy), ``"auto"``:
        multigrid from ``amg_unknowns`` unknowns on, or ``"jacobi"``: CG preconditioned
        by the current diagonal, the factor for a system it does not solve within
        ``jacobi_max_iterations`` (and for the rest of that pattern).
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
    jacobi_max_iterations
        CG iterations allowed in one solve on the diagonal path [1].

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
        jacobi_max_iterations: int = 500,
    ) -> None:
        if method not in ("auto", "direct", "amg", "jacobi"):
            raise ValueError(f"method must be 'auto', 'direct', 'amg' or 'jacobi', got {method!r}")
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
        self.jacobi_max_iterations = jacobi_max_iterations
        self.blas_threads = blas_threads
        self.blas_threads_set = blas_threads is not None and set_cholmod_blas_threads(blas_threads)
        self.factor_blas_threads = factor_blas_threads if self.blas_threads_set else None
        self.stats = SolverStats()
        # drift of the last solve's matrix, computed only for the optional trigger
        self.last_drift = float("nan")
        self.last_residual = 0.0
        self._cholmod = FactorReuse()
        self._multigrid = MultigridReuse()
        self._diagonal = DiagonalScaling()
        self._since = Since()
        # the pattern and values of the matrix the preconditioner was bought for
        self._indptr: npt.NDArray[np.int32] | None = None
        self._indices: npt.NDArray[np.int32] | None = None
        self._factored_data: FloatArray | None = None
        # whether the factor path took over the current pattern from multigrid or Jacobi
        self._fallback = False

    @property
    def _factor(self) -> Factor | None:
        """The current CHOLMOD factor (None on the multigrid path)."""
        return self._cholmod.factor

    def uses_multigrid(self, unknowns: int) -> bool:
        """Whether a system of ``unknowns`` unknowns is preconditioned by multigrid."""
        return self.method == "amg" or (self.method == "auto" and unknowns >= self.amg_unknowns)

    def reset(self) -> None:
        """Forget the analysis, factor and hierarchy (the next solve starts afresh)."""
        self._cholmod.factor = None
        self._multigrid.cycle = None
        self._indptr = None

    def reuse_state(self) -> tuple[dict[str, Any], dict[str, npt.NDArray[Any]]]:
        """What decides this solver's next refactorisations, for a checkpoint file.

        Neither a CHOLMOD factor nor a pyamg hierarchy can be saved, but each is a
        deterministic function of its matrix (and the ordering): the state keeps the
        factored lower triangle, and :meth:`restore_reuse_state` builds the
        preconditioner again from it.

        Returns
        -------
        scalars : dict
            The preconditioner choice (``method``, ``amg_unknowns``, ``amg_strength``),
            the rent-or-buy counters (stale iterations and solves, last rent, solves left
            to buy at once, back-off; on the multigrid path the iterations of the first
            solve since the setup, and whether the factor took over the pattern), the
            diagnostics ``last_drift`` and ``last_residual``, the work counters of
            ``stats`` and the ordering of the current analysis (JSON-serialisable).
        arrays : dict
            ``indptr``, ``indices`` and ``data`` of the factored lower triangle, empty if
            there is no factor or hierarchy.
        """
        factor, multigrid, since = self._cholmod, self._multigrid, self._since
        scalars: dict[str, Any] = {
            "stale_iterations": since.iterations, "last_rent": factor.last_rent,
            "stale_solves": since.solves, "buy_at_once": factor.buy_at_once,
            "backoff": factor.backoff, "last_drift": self.last_drift,
            "last_residual": self.last_residual, "ordering": factor.ordering,
            "method": self.method, "amg_unknowns": self.amg_unknowns,
            "amg_strength": self.amg_strength, "setup_iterations": multigrid.setup_iterations,
            "fallback": self._fallback,
            "stats": dataclasses.asdict(self.stats),
        }
        arrays: dict[str, npt.NDArray[Any]] = {}
        if (factor.factor is not None or multigrid.cycle is not None) \
                and self._factored_data is not None:
            assert self._indptr is not None and self._indices is not None
            arrays = {"indptr": self._indptr, "indices": self._indices,
                      "data": self._factored_data}
        return scalars, arrays

    def restore_reuse_state(
        self, scalars: Mapping[str, Any], arrays: Mapping[str, npt.NDArray[Any]]
    ) -> None:
        """Continue as the solver whose :meth:`reuse_state` this was, bit for bit.

        With a saved factored matrix, it is analysed (same ordering) and factored, or its
        hierarchy built, again: CHOLMOD and the Ruge-Stueben setup are deterministic for
        a given matrix (and ordering), so the new preconditioner applies exactly as the
        lost one did.
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
                self._buy(matrix, ordered=False)
            finally:
                self.ordering_method = saved_method
        else:
            self.reset()
            self._factored_data = None
        factor, since = self._cholmod, self._since
        factor.ordering = scalars["ordering"]
        since.iterations = int(scalars["stale_iterations"])
        factor.last_rent = int(scalars["last_rent"])
        since.solves = int(scalars["stale_solves"])
        factor.buy_at_once = int(scalars["buy_at_once"])
        factor.backoff = int(scalars["backoff"])
        self._multigrid.setup_iterations = int(scalars.get("setup_iterations", 0))
        self.last_drift = float(scalars["last_drift"])
        self.last_residual = float(scalars["last_residual"])
        self.stats = SolverStats(**{"fallbacks": 0, **scalars["stats"]})

    def _same_pattern(self, matrix: sp.csc_matrix) -> bool:
        return (
            self._indptr is not None
            and self._indices is not None
            and matrix.shape[0] == self._indptr.shape[0] - 1
            and np.array_equal(matrix.indptr, self._indptr)
            and np.array_equal(matrix.indices, self._indices)
        )

    def _buy(self, matrix: sp.csc_matrix, ordered: bool) -> None:
        """Buy a preconditioner of ``matrix``: a CHOLMOD factor or a multigrid hierarchy."""
        same = self._same_pattern(matrix)
        if not same:
            _check_lower(matrix)
        if self.uses_multigrid(matrix.shape[0]) and not self._fallback:
            self._cholmod.factor = None
            self._multigrid.build(matrix, self.amg_strength)
        else:
            self._multigrid.cycle = None
            ordering = self.ordering_method or ("natural" if ordered else "metis")
            try:
                self._cholmod.build(matrix, ordering, same and self._cholmod.factor is not None,
                                    self.blas_threads, self.factor_blas_threads, self.stats)
            except SolverError:
                self.reset()
                raise
        if not same:
            self._indptr = matrix.indptr.copy()
            self._indices = matrix.indices.copy()
        self._factored_data = matrix.data.copy()
        self._since.iterations = 0
        self._since.solves = 0
        self.stats.factorisations += 1

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
        if self._diagonal.inverse is not None:
            return self._diagonal.apply(vector)
        if self._multigrid.cycle is not None:
            return self._multigrid.apply(vector)
        return self._cholmod.apply(vector)

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
            self._cholmod.factor is None and self._multigrid.cycle is None)
        diagonal = np.abs(lower.data[lower.indptr[:-1]])
        if fresh:
            self._fallback = False

        def iterate(budget: int, start: FloatArray | None = None) -> tuple[FloatArray, bool]:
            return self._iterate(lower, rhs, diagonal, budget, offset, start)

        if self.method == "jacobi" and not self._fallback:
            solution, converged = self._jacobi_solve(lower, ordered, iterate)
        elif self.uses_multigrid(lower.shape[0]) and not self._fallback:
            solution, converged = self._multigrid.solve(
                self.stats, fresh=fresh, max_iterations=self.amg_max_iterations,
                rebuild_ratio=self.amg_rebuild_ratio,
                buy=lambda: self._buy(lower, ordered=True), iterate=iterate)
            if not converged and self.method == "auto":
                # a system the hierarchy cannot solve (extreme conductance contrasts):
                # the factor solves it, and the next solves of this pattern too
                log.info("multigrid missed the tolerance (%.1e) on %d unknowns: factor path "
                         "until the next pattern", self.last_residual, lower.shape[0])
                self._fallback = True
                self.stats.fallbacks += 1
                solution, converged = self._factor_solve(lower, True, ordered, iterate)
        else:
            solution, converged = self._factor_solve(lower, fresh, ordered, iterate)
        if not converged:
            raise SolverError(
                f"residual {self.last_residual:.3e} above tolerance "
                f"{self.residual_tolerance:.1e} even with a fresh preconditioner "
                "(ill-conditioned or not positive definite?)"
            )
        return solution

    def _jacobi_solve(self, lower: sp.csc_matrix, ordered: bool,
                      iterate: Any) -> tuple[FloatArray, bool]:
        """The diagonal path (:mod:`shared.solver.jacobi`); a system it does not solve
        goes to a fresh factor, which keeps its pattern (as the multigrid fallback)."""
        _check_lower(lower)
        self._diagonal.build(lower)
        try:
            solution, converged = iterate(self.jacobi_max_iterations)
        finally:
            self._diagonal.inverse = None
        if converged:
            return solution, converged
        log.info("Jacobi CG missed the tolerance (%.1e) on %d unknowns in %d iterations: factor "
                 "path until the next pattern", self.last_residual, lower.shape[0],
                 self.jacobi_max_iterations)
        self._fallback = True
        self.stats.fallbacks += 1
        return self._factor_solve(lower, True, ordered, iterate)

    def _factor_solve(self, lower: sp.csc_matrix, fresh: bool, ordered: bool,
                      iterate: Any) -> tuple[FloatArray, bool]:
        """The factor path (:meth:`shared.solver.factor.FactorReuse.solve`)."""
        drifted = None if self.refactor_tolerance is None else (lambda: self._drifted(lower))
        return self._cholmod.solve(
            self._since, fresh=fresh, refactor_iterations=self.refactor_iterations,
            max_iterations=self.max_iterations, drifted=drifted,
            buy=lambda: self._buy(lower, ordered), iterate=iterate)

    def _drifted(self, lower: sp.csc_matrix) -> bool:
        """Whether the drift since the factorisation exceeds ``refactor_tolerance``."""
        self.last_drift = self.drift(lower)
        assert self.refactor_tolerance is not None
        return self.last_drift > self.refactor_tolerance

    def _iterate(
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
            self._since.iterations += 1
        return solution, False

    @staticmethod
    def _check_finite(solution: FloatArray) -> None:
        if not np.all(np.isfinite(solution)):
            raise SolverError("solution contains NaN or inf (solver divergence)")
