"""The SPD solver's reuse state: what decides its next refactorisations, saved in a
checkpoint and restored so that a resumed run continues bit for bit.

Neither a CHOLMOD factor nor a pyamg hierarchy can be saved, but each is a deterministic
function of its matrix (and the ordering): the state keeps the factored lower triangle,
and restoring builds the preconditioner again from it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from shared.solver.base import SolverStats

if TYPE_CHECKING:
    from shared.solver.spd import SPDSolver

__all__ = ["restore_reuse_state", "reuse_state"]


def reuse_state(solver: SPDSolver) -> tuple[dict[str, Any], dict[str, npt.NDArray[Any]]]:
    """What decides ``solver``'s next refactorisations, for a checkpoint file.

    Returns
    -------
    scalars : dict
        The preconditioner choice (``method``, ``amg_unknowns``, ``amg_strength``), the
        rent-or-buy counters (stale iterations and solves, last rent, solves left to buy
        at once, back-off; on the multigrid path the iterations of the first solve since
        the setup, and whether the factor took over the pattern), the diagnostics
        ``last_drift`` and ``last_residual``, the work counters of ``stats`` and the
        ordering of the current analysis (JSON-serialisable).
    arrays : dict
        ``indptr``, ``indices`` and ``data`` of the factored lower triangle, empty if
        there is no factor or hierarchy.
    """
    factor, multigrid, since = solver._cholmod, solver._multigrid, solver._since
    scalars: dict[str, Any] = {
        "stale_iterations": since.iterations, "last_rent": factor.last_rent,
        "stale_solves": since.solves, "buy_at_once": factor.buy_at_once,
        "backoff": factor.backoff, "last_drift": solver.last_drift,
        "last_residual": solver.last_residual, "ordering": factor.ordering,
        "method": solver.method, "amg_unknowns": solver.amg_unknowns,
        "amg_strength": solver.amg_strength, "setup_iterations": multigrid.setup_iterations,
        "fallback": solver._fallback,
        "stats": dataclasses.asdict(solver.stats),
    }
    arrays: dict[str, npt.NDArray[Any]] = {}
    if (factor.factor is not None or multigrid.cycle is not None) \
            and solver._factored_data is not None:
        assert solver._indptr is not None and solver._indices is not None
        arrays = {"indptr": solver._indptr, "indices": solver._indices,
                  "data": solver._factored_data}
    return scalars, arrays


def restore_reuse_state(
    solver: SPDSolver, scalars: Mapping[str, Any], arrays: Mapping[str, npt.NDArray[Any]]
) -> None:
    """Make ``solver`` continue as the one whose :func:`reuse_state` this was.

    With a saved factored matrix, it is analysed (same ordering) and factored, or its
    hierarchy built, again: CHOLMOD and the Ruge-Stueben setup are deterministic for a
    given matrix (and ordering), so the new preconditioner applies exactly as the lost
    one did.
    """
    # states saved before the multigrid path existed are factor states
    solver.method = scalars.get("method", "direct")
    solver.amg_unknowns = int(scalars.get("amg_unknowns", solver.amg_unknowns))
    # states saved before the threshold was a setting used pyamg's default
    solver.amg_strength = float(scalars.get("amg_strength", 0.25))
    solver._fallback = bool(scalars.get("fallback", False))
    if arrays:
        n = arrays["indptr"].shape[0] - 1
        matrix = sp.csc_matrix(
            (np.array(arrays["data"], dtype=np.float64),
             np.array(arrays["indices"], dtype=np.int32),
             np.array(arrays["indptr"], dtype=np.int32)), shape=(n, n))
        solver.ordering_method, saved_method = scalars["ordering"], solver.ordering_method
        try:
            solver.reset()
            solver._buy(matrix, ordered=False)
        finally:
            solver.ordering_method = saved_method
    else:
        solver.reset()
        solver._factored_data = None
    factor, since = solver._cholmod, solver._since
    factor.ordering = scalars["ordering"]
    since.iterations = int(scalars["stale_iterations"])
    factor.last_rent = int(scalars["last_rent"])
    since.solves = int(scalars["stale_solves"])
    factor.buy_at_once = int(scalars["buy_at_once"])
    factor.backoff = int(scalars["backoff"])
    solver._multigrid.setup_iterations = int(scalars.get("setup_iterations", 0))
    solver.last_drift = float(scalars["last_drift"])
    solver.last_residual = float(scalars["last_residual"])
    solver.stats = SolverStats(**{"fallbacks": 0, **scalars["stats"]})
