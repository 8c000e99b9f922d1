"""Mass transport between systems (Caulk 2022, Eqs. 4.13-4.23, 4.52-4.58).

Mass conductance of an exchange e = (i, j): G_e = f rho k_e A_e / (mu L_e) [kg/(Pa s)]
(Eq. 4.15; f the configured conductivity factor), so that in one explicit step
(Eq. 4.23) m_i += dt sum_j G_ij (p_j - p_i). Permeabilities: a pellet's from the
upscaling table at its suction, a cell's from the powder law (Eqs. 4.16-4.19);
pellet-pellet and pellet-cell exchanges take the harmonic mean of their two systems,
cell-cell exchanges the powder law at the two cells' mean state. Held systems
(Dirichlet) keep their state; the water they give is the boundary inflow.

Stable explicit step (Eq. 4.58, dp/dS in the denominator: our reading):
dt = chi min_i 2 / (alpha_i |dp/dS|_i), alpha_i = sum_j G_ij / (rho n_i V_i). The
implicit step (our addition) takes the fluxes at the end-of-step pressures,
linearised through each system's capacity dm/dp; its linear system, and the steady one
of :mod:`macro.column_permeability`, are solved by :class:`shared.solver.SPDSolver`
(:func:`network_pressures`). In full: docs/macro.md, "macro.transport".
"""

from __future__ import annotations

from typing import cast

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from shared.solver import SPDSolver

__all__ = ["conductances", "edge_rates", "harmonic_mean", "implicit_pressures", "limited_fluxes", "limited_rates",
           "mass_rates", "network_matrix", "network_pressures", "stable_time_step"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

CG_TOLERANCE = 1e-10
"""Row-wise backward error of the implicit step's solve (:class:`shared.solver.SPDSolver`'s
``residual_tolerance``): each system's mass imbalance within this fraction of its
diagonal times the largest pressure."""
CG_ITERATIONS = 500
"""Jacobi-preconditioned CG iterations before the implicit step falls back to a CHOLMOD
factorisation."""


def harmonic_mean(a: FloatArray, b: FloatArray) -> FloatArray:
    """2 a b / (a + b), elementwise (0 where both are 0)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(a + b > 0.0, 2.0 * a * b / (a + b), 0.0)


def conductances(
    area: FloatArray, length: FloatArray, permeability: FloatArray,
    density: float, viscosity: float, factor: float,
) -> FloatArray:
    """Mass conductances G = factor rho k A / (mu L) [kg/(Pa s)] (Eqs. 4.15, 4.21)."""
    return factor * density * permeability * area / (viscosity * length)


def mass_rates(pairs: IntArray, conductance: FloatArray, pressure: FloatArray,
               n_systems: int) -> FloatArray:
    """dm_i/dt = sum_j G_ij (p_j - p_i) [kg/s] (Eq. 4.22), antisymmetric by construction."""
    return edge_rates(pairs, conductance * (pressure[pairs[:, 1]] - pressure[pairs[:, 0]]), n_systems)


def stable_time_step(
    pairs: IntArray, conductance: FloatArray, pore_volume: FloatArray,
    slope: FloatArray, held: npt.NDArray[np.bool_], density: float, chi: float,
) -> float:
    """Eq. 4.58: chi min_i 2 / (alpha_i |dp/dS|_i) over the systems not held [s].

    Parameters
    ----------
    pairs, conductance
        Exchanges and their mass conductances [kg/(Pa s)].
    pore_volume
        (n,) n_i V_i [m3].
    slope
        (n,) |dp/dS| [Pa].
    held
        (n,) Dirichlet systems (left out).
    density
        rho_w [kg/m3].
    chi
        Safety factor of Eq. 4.58 [1].
    """
    n = pore_volume.size
    total = (np.bincount(pairs[:, 0], conductance, minlength=n)
             + np.bincount(pairs[:, 1], conductance, minlength=n))
    alpha = total / (density * pore_volume)
    rate = (alpha * slope)[~held]
    largest = rate.max(initial=0.0)
    if not largest > 0.0:
        return float("inf")
    return float(chi * 2.0 / largest)


def network_matrix(pairs: IntArray, conductance: FloatArray, storage: FloatArray,
                   free: npt.NDArray[np.bool_]) -> tuple[sp.csc_matrix, IntArray]:
    """The system of the ``free`` systems, diag(S) + L_ff, L the network's Laplacian.

    Parameters
    ----------
    pairs, conductance
        (m, 2) exchanges and their conductances G [kg/(Pa s)].
    storage
        (n,) storage coefficient S of each system [kg/(Pa s)] (0 for a steady problem).
    free
        (n,) systems whose pressure is unknown.

    Returns
    -------
    lower : scipy.sparse.csc_matrix
        Lower triangle of the matrix (diagonal first in each column, rows sorted), what
        :meth:`shared.solver.SPDSolver.solve` takes.
    unknown : ndarray of int64
        The system of each unknown.
    """
    unknown = np.flatnonzero(free)
    m = unknown.size
    index = np.full(free.size, -1, dtype=np.int64)
    index[unknown] = np.arange(m)
    a, b = index[pairs[:, 0]], index[pairs[:, 1]]
    diagonal = (storage[unknown] + np.bincount(a[a >= 0], conductance[a >= 0], minlength=m)
                + np.bincount(b[b >= 0], conductance[b >= 0], minlength=m))
    both = (a >= 0) & (b >= 0)
    rows = np.concatenate([np.arange(m), np.maximum(a[both], b[both])])
    columns = np.concatenate([np.arange(m), np.minimum(a[both], b[both])])
    lower = sp.csc_matrix((np.concatenate([diagonal, -conductance[both]]), (rows, columns)), shape=(m, m))
    lower.sort_indices()
    return lower, unknown


def network_pressures(pairs: IntArray, conductance: FloatArray, storage: FloatArray, start: FloatArray,
                      free: npt.NDArray[np.bool_], solver: SPDSolver, whole: bool) -> FloatArray:
    """Pressures p = start + d [Pa], the ``free`` systems' d solving
    (diag(S) + L_ff) d = sum_j G_ij (start_j - start_i), the others keeping ``start``:
    S (p - start) = sum_j G_ij (p_j - p_i) on the free systems.

    Parameters
    ----------
    pairs, conductance, storage, free
        As for :func:`network_matrix`.
    start
        (n,) pressures the increment d starts from [Pa]; the held values on the systems
        that are not free.
    solver
        Solves the system.
    whole
        The solver's tolerance applies to the system of the whole pressure p (a time
        step, whose increment is small next to p); otherwise to d's own (a steady
        solve, whose fluxes are differences of d).
    """
    lower, unknown = network_matrix(pairs, conductance, storage, free)
    rhs = mass_rates(pairs, conductance, start, start.size)[unknown]
    out = start.copy()
    out[unknown] += solver.solve(lower, rhs, offset=start[unknown] if whole else None)
    return out


def implicit_pressures(
    pairs: IntArray, conductance: FloatArray, pressure: FloatArray, capacity: FloatArray,
    dt: float, free: npt.NDArray[np.bool_],
) -> FloatArray:
    """Pressures at the end of a linearised backward-Euler step [Pa].

    C_i (p_i' - p_i) / dt = sum_j G_ij (p_j' - p_i') over the ``free`` systems, the
    others keeping their pressure (held: Dirichlet): the SPD system
    (C/dt + L) p' = C/dt p + G_boundary p_boundary, solved for p' - p
    (:func:`network_pressures`) by CG preconditioned by its diagonal to a row-wise
    backward error of ``CG_TOLERANCE``, by a CHOLMOD factor where CG does not converge
    within ``CG_ITERATIONS`` (:class:`shared.solver.SPDSolver`, ``method="jacobi"``):
    the storage term C/dt weighs on the diagonal, so CG converges in tens of
    iterations where a factorisation of ten thousand systems costs 10-20 times more.
    Nothing is kept from one solve to the next: the answer is a function of the system.

    Parameters
    ----------
    pairs, conductance
        Exchanges and their mass conductances G [kg/(Pa s)].
    pressure
        (n,) pressures at the start of the step [Pa].
    capacity
        (n,) dm/dp of each system [kg/Pa] (> 0 where free).
    dt
        Time step [s].
    free
        (n,) systems whose pressure is unknown.
    """
    solver = SPDSolver(residual_tolerance=CG_TOLERANCE, method="jacobi", jacobi_max_iterations=CG_ITERATIONS)
    return network_pressures(pairs, conductance, capacity / dt, pressure, free, solver, whole=True)


def limited_fluxes(pairs: IntArray, conductance: FloatArray, pressure: FloatArray, amount: FloatArray,
                   dt: float, free: npt.NDArray[np.bool_], keep: float) -> tuple[FloatArray, int]:
    """Fluxes G_ij (p_j - p_i) into ``pairs[:, 0]`` with the outflows of a free system
    scaled down so that it keeps at least ``keep`` of its ``amount`` over ``dt`` (a
    positivity-preserving flux limiter: each exchange's flux scaled by the factor of the
    system it leaves, so the update stays antisymmetric and conserves the amount exactly).
    Returns the fluxes and the number of systems limited.
    """
    n = pressure.size
    flux = conductance * (pressure[pairs[:, 1]] - pressure[pairs[:, 0]])
    source = np.where(flux < 0.0, pairs[:, 0], pairs[:, 1])
    outflow = np.bincount(source, np.abs(flux), minlength=n)
    allowed = (1.0 - keep) * amount
    limited = free & (dt * outflow > allowed)
    factor = np.ones(n)
    factor[limited] = allowed[limited] / (dt * outflow[limited])
    return flux * factor[source], int(np.count_nonzero(limited))


def edge_rates(pairs: IntArray, flux: FloatArray, n_systems: int) -> FloatArray:
    """(n,) net inflow of every system from the fluxes into ``pairs[:, 0]``."""
    return cast(FloatArray, np.bincount(pairs[:, 0], flux, n_systems) - np.bincount(pairs[:, 1], flux, n_systems))


def limited_rates(pairs: IntArray, conductance: FloatArray, pressure: FloatArray, water: FloatArray,
                  dt: float, free: npt.NDArray[np.bool_], keep: float) -> tuple[FloatArray, int]:
    """dm_i/dt of Eq. 4.22 [kg/s] with the outflows of a free system limited so that it
    keeps at least ``keep`` of its water over ``dt`` (:func:`limited_fluxes`); also the
    number of systems limited."""
    flux, limited = limited_fluxes(pairs, conductance, pressure, water, dt, free, keep)
    return edge_rates(pairs, flux, pressure.size), limited
