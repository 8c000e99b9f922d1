"""Permeability of the whole mixture column along its axis (Appendix .1 ``emulatePermeability``).

The state is frozen; the active systems of the network of :mod:`macro.transport` whose
centre lies within one mean pellet radius of a plate get a pressure linear along the
axis around the current suction s (a drop dp of 10 % of s between the plates); the
steady flow is solved with the current mass conductances divided by
``macro.conductivity_factor`` (the material's k), no flux through the curved wall, and
k = mu Q / (rho A dp / L) [m2], Q the mass flux through the column [kg/s], A = pi R^2
and L the container's cross-section and height: with a no-flux wall Q / (rho A) is the
mean axial Darcy velocity over any slab, the thesis's estimator. Systems linked to no
end are NaN. The problem is linear: k depends on neither s nor dp. The system is that of
the implicit transport step without storage (:func:`macro.transport.network_pressures`),
solved by a CHOLMOD factor of :class:`shared.solver.SPDSolver` to a row-wise backward
error of ``STEADY_TOLERANCE``. The Dirichlet layer's thickness and the network's bias
(14-19 % above a uniform k): docs/macro.md, "macro.column_permeability".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from macro.model import MacroModel
from macro.transport import network_pressures
from shared.solver import SPDSolver

__all__ = ["DROP_FRACTION", "ORDERING", "STEADY_TOLERANCE", "ColumnFlow", "column_permeability", "network_permeability"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

DROP_FRACTION = 0.1
"""Pressure drop between the plates, as a fraction of the mean suction [1] (Appendix .1)."""
ORDERING = "amd"
"""Fill-reducing ordering of the one factorisation: on the default case's 9 000 unknowns
METIS's costs more than it saves (the whole measurement 81 ms against 48 ms with AMD)."""
STEADY_TOLERANCE = 1e-13
"""Row-wise backward error of the steady solve (that of micro's permeability measurement):
the flux is made of the departure from the linear profile, so the departure itself must
be accurate."""


@dataclass(frozen=True)
class ColumnFlow:
    """Steady flow along the column's axis.

    Attributes
    ----------
    permeability
        k = mu Q L / (rho A dp) [m2].
    inflow
        Mass flux from the upper layer into the column [kg/s].
    outflow
        Mass flux from the column into the lower layer [kg/s].
    drop
        Pressure drop dp between the plates [Pa].
    pressure
        (n,) steady pressure of every system [Pa], NaN where left out (inert, or
        linked to no end).
    """

    permeability: float
    inflow: float
    outflow: float
    drop: float
    pressure: FloatArray


def network_permeability(
    pairs: IntArray, conductance: FloatArray, position: FloatArray, active: BoolArray,
    height: float, area: float, layer: float, mean_pressure: float, drop: float,
    density: float, viscosity: float,
) -> ColumnFlow:
    """Steady flow through a network between two Dirichlet layers, and its permeability.

    Parameters
    ----------
    pairs
        (m, 2) exchanges between systems.
    conductance
        (m,) their mass conductances G [kg/(Pa s)].
    position
        (n,) coordinate of each system's centre along the axis, 0 at mid-height [m].
    active
        (n,) systems that take part (the others are left out).
    height, area
        Length L of the column between the plates and its cross-section A [m], [m2].
    layer
        Systems within this distance of a plate are Dirichlet [m].
    mean_pressure
        Pressure at mid-height [Pa].
    drop
        Pressure drop dp between the plates, lower pressure at the lower plate [Pa].
    density, viscosity
        rho [kg/m3] and mu [Pa s] of the water.

    Returns
    -------
    ColumnFlow
        With the mean of the inflow and the outflow as Q.
    """
    n = position.size
    keep = (conductance > 0.0) & active[pairs].all(axis=1)
    pairs, conductance = pairs[keep], conductance[keep]
    upper = active & (position > 0.5 * height - layer)
    lower = active & (position < -0.5 * height + layer)
    fixed = upper | lower
    # systems linked to no end have no steady pressure (and carry no flux)
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    anchored = np.bincount(label, fixed, minlength=count) > 0
    free = active & ~fixed & anchored[label]
    # solved for the departure from the mean pressure (from 0 on the free systems): the
    # fluxes are differences of it
    start = np.where(fixed, drop * position / height, 0.0)
    solver = SPDSolver(residual_tolerance=STEADY_TOLERANCE, method="direct", ordering_method=ORDERING)
    steady = network_pressures(pairs, conductance, np.zeros(n), start, free, solver, whole=False)
    departure = np.where(fixed | free, steady, np.nan)
    first, second = pairs[:, 0], pairs[:, 1]
    flux = conductance * (departure[first] - departure[second])  # from first to second
    inflow = float(flux[upper[first] & free[second]].sum() - flux[free[first] & upper[second]].sum())
    outflow = float(flux[free[first] & lower[second]].sum() - flux[lower[first] & free[second]].sum())
    mean_flux = 0.5 * (inflow + outflow)
    permeability = viscosity * mean_flux * height / (density * area * drop)
    return ColumnFlow(permeability, inflow, outflow, drop, mean_pressure + departure)


def column_permeability(model: MacroModel) -> ColumnFlow:
    """The mixture column's permeability along its axis in the model's current state.

    The model is left as it was: its state is only read, and the look-up counters of
    its permeability table, which the conductances advance, are set back.

    The pressures are imposed around the volume-weighted mean suction s of the active
    systems, with a drop of ``DROP_FRACTION`` s between the plates (k depends on neither).

    Parameters
    ----------
    model
        The mixture (read only).
    """
    s = model.settings
    table = model.table
    looked_up, clamped = table.looked_up, table.clamped
    try:
        conductance = model.conductances() / s.conductivity_factor
    finally:
        table.looked_up, table.clamped = looked_up, clamped
    assert model.cells.exchanges is not None
    active = ~model.inert
    suction = float(np.average(-model.pressure[active], weights=model.volume[active]))
    # the exchanges' geometry: the mesh's pellet centres and cell centroids
    position = np.concatenate([model.mesh.points[:model.n_pellets, 2], model.mesh.centroids[:, 2]])
    return network_permeability(
        model.cells.exchanges.pairs, conductance, position, active, s.height, np.pi * s.radius**2,
        float(model.radii.mean()), -suction, DROP_FRACTION * suction, s.density, s.viscosity)
