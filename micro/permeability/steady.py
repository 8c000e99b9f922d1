"""The steady solve every permeability measurement makes, and its balance checks.

Saturation, porosity and mesh are frozen; a linear pressure profile is imposed on the
Dirichlet cells of a measurement and the free cells solve the storage-free balance for
the departure from the mean pressure (which drops out of a steady problem). A solve
whose two rates (into and out of a region) do not balance is refined in extended
precision with the same factor (:func:`solve`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from typing import Literal, NamedTuple

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from shared.fv import FlowPattern, assemble_matrix, facet_conductance, facet_divergence, facet_flux, solver_pattern
from shared.materials import ClayParameters
from shared.mesh import Mesh
from shared.permeability import Phase
from shared.solver import SPDSolver

__all__ = [
    "AXES",
    "DROP_FRACTION",
    "FrozenState",
    "INNER_FRACTION",
    "PHASES",
    "balanced",
    "floored",
    "inner_cells",
    "mean_velocity",
    "measurement_solver",
    "phase_conductances",
    "solve",
    "system_matrix",
    "system_pattern",
]

FloatArray = npt.NDArray[np.float64]
log = logging.getLogger(__name__)
Method = Literal["wall_flux", "velocity"]
AXES: tuple[str, ...] = ("x", "y", "z")
PHASES: tuple[Phase, ...] = ("water", "gas")
DROP_FRACTION = 0.1
"""Default pressure drop across the specimen, as a fraction of the suction [1]."""
INNER_FRACTION = 0.8
"""Default central fraction of the box whose velocities are averaged [1] (thesis: 0.8)."""


# Extended-precision refinement sweeps allowed for an unbalanced wall-flux solve.
_REFINEMENTS = 6


def floored(conductance: FloatArray, floor: float) -> FloatArray | None:
    """Conductances raised to ``floor`` times the largest (isolated free cells would make
    the steady system singular); None if every conductance is 0."""
    largest = float(np.max(conductance, initial=0.0))
    if largest == 0.0:
        return None
    return np.maximum(conductance, floor * largest)


# Unknowns from which a measurement's solves use multigrid: at 1e-13 the hierarchy needs
# about 18 iterations and hands some crack networks to the factor, so it pays off later
# than for the flow steps (the measurements: benchmarks/reference/README.md).
_MEASUREMENT_AMG_UNKNOWNS = 400_000


def measurement_solver() -> SPDSolver:
    """A fresh solver at round-off backward error for each measurement.

    A factor kept from another phase or axis would precondition conjugate gradients
    that meet a normwise backward error of 1e-16 on a crack network's conductances
    (twelve decades) and still miss the fluxes of the clay matrix by orders of
    magnitude; a direct solve with the matrix's own factor balances them to 1e-12.
    """
    return SPDSolver(residual_tolerance=1e-13, amg_unknowns=_MEASUREMENT_AMG_UNKNOWNS)


def system_pattern(
    mesh: Mesh, dirichlet: npt.NDArray[np.bool_], solver: SPDSolver | None = None
) -> FlowPattern:
    """The pattern of these Dirichlet cells, ordered for the solver's path (default the
    measurements' solver): fill-reducing for a factor, by locality for multigrid."""
    return solver_pattern(mesh, dirichlet, measurement_solver() if solver is None else solver)


def _extended_divergence(
    mesh: Mesh, conductance: FloatArray, pressure: npt.NDArray[np.longdouble]
) -> tuple[npt.NDArray, npt.NDArray]:
    """Net inflow per cell and flux i -> j per facet, in extended precision [m3/s].

    :func:`shared.fv.facet_flux` keeps the ``longdouble`` of the pressure;
    :func:`shared.fv.facet_divergence` is a float64 kernel, hence ``np.add.at`` here.
    """
    flux = facet_flux(mesh, conductance, pressure)
    inflow = np.zeros(pressure.shape[0], dtype=np.longdouble)
    np.add.at(inflow, mesh.facet_cells[:, 0], -flux)
    np.add.at(inflow, mesh.facet_cells[:, 1], flux)
    return inflow, flux


def balanced(entering: float, leaving: float, tolerance: float) -> bool:
    """Whether the two rates of a region [m3/s] are positive and agree to ``tolerance`` [1]."""
    rate = 0.5 * (entering + leaving)
    return bool(rate > 0.0 and abs(entering - leaving) <= tolerance * rate)


def mean_velocity(
    mesh: Mesh, flux: FloatArray, cells: npt.NDArray[np.bool_]
) -> FloatArray:
    """Volume-averaged velocity over ``cells`` [m/s], shape (3,).

    ``flux`` may be extended precision (a refined solve): the per-facet moments are
    rounded to double once the pressure differences they are made of are exact.
    """
    i, j = mesh.facet_cells[:, 0], mesh.facet_cells[:, 1]
    moment = np.zeros((mesh.n_cells, 3))
    for component in range(3):
        x = mesh.facet_centroids[:, component]
        outgoing = np.asarray(flux * (x - mesh.centroids[i, component]), dtype=np.float64)
        incoming = np.asarray(flux * (x - mesh.centroids[j, component]), dtype=np.float64)
        moment[:, component] = np.bincount(i, outgoing, minlength=mesh.n_cells) - np.bincount(
            j, incoming, minlength=mesh.n_cells
        )
    return moment[cells].sum(axis=0) / mesh.volumes[cells].sum()


def solve(
    mesh: Mesh, pattern: FlowPattern, solver: SPDSolver, conductance: FloatArray,
    profile: FloatArray, matrix: sp.csc_matrix,
    rates: Callable[[npt.NDArray], tuple[float, float]] | None, tolerance: float,
) -> tuple[npt.NDArray, float, float]:
    """The steady solve every measurement makes: the departure from the mean pressure
    with the linear ``profile`` imposed on the Dirichlet cells (and as the start of the
    free ones), its facet fluxes [m3/s], and with ``rates`` the two rates of a region
    (in and out), refined in extended precision (:func:`_refined_rates`) when they do not
    balance to ``tolerance``. ``matrix`` is the steady matrix of ``conductance``; the
    solver's factor of it serves every solve and refinement sweep."""
    pressure = np.array(profile, dtype=np.float64)
    free = pattern.free_cells
    rhs = facet_divergence(mesh, conductance, pressure)[free]
    pressure[free] += solver.solve(matrix, rhs, ordered=pattern.fill_reducing)
    flux: npt.NDArray = facet_flux(mesh, conductance, pressure)
    if rates is None:
        return flux, float("nan"), float("nan")
    entering, leaving = rates(flux)
    if not balanced(entering, leaving, tolerance):
        entering, leaving, flux = _refined_rates(
            mesh, pattern, solver, conductance, pressure, rates, tolerance, matrix)
    return flux, entering, leaving


def system_matrix(mesh: Mesh, pattern: FlowPattern, conductance: FloatArray) -> sp.csc_matrix:
    """Lower triangle of the steady (storage-free) system of ``conductance``."""
    return assemble_matrix(mesh, pattern, conductance, np.zeros(mesh.n_cells))


def _refined_rates(
    mesh: Mesh,
    pattern: FlowPattern,
    solver: SPDSolver,
    conductance: FloatArray,
    pressure: FloatArray,
    rates: Callable[[npt.NDArray], tuple[float, float]],
    tolerance: float,
    matrix: sp.csc_matrix,
) -> tuple[float, float, npt.NDArray]:
    """Rates and fluxes after mixed-precision iterative refinement of a steady solve.

    The residual and the fluxes in ``numpy.longdouble``, the correction from the
    solver's double-precision factor of the same ``matrix``; stops once the two ``rates``
    of the fluxes (in and out of a region) balance to ``tolerance`` or after
    ``_REFINEMENTS`` sweeps. Returns the two rates and the last fluxes [m3/s].
    """
    free = pattern.free_cells
    extended = pressure.astype(np.longdouble)
    entering = leaving = float("nan")
    inflow, flux = _extended_divergence(mesh, conductance, extended)
    for _ in range(_REFINEMENTS):
        correction = solver.solve(matrix, np.asarray(inflow[free], dtype=np.float64),
                                  ordered=pattern.fill_reducing)
        extended[free] += correction.astype(np.longdouble)
        inflow, flux = _extended_divergence(mesh, conductance, extended)
        entering, leaving = rates(flux)
        if balanced(entering, leaving, tolerance):
            break
    return entering, leaving, flux


def inner_cells(
    mesh: Mesh, dirichlet: npt.NDArray[np.bool_], inner_fraction: float, label: str
) -> npt.NDArray[np.bool_] | None:
    """Free cells whose centroid lies in the central ``inner_fraction`` of the box [1].

    None, with a warning naming the measurement ``label``, if there is none (a mesh of a
    few tens of points, the smallest specimen the configuration allows): the measurement
    is then NaN rather than an error, since it is one diagnostic of a checkpoint and the
    run's other results stand (the one failure policy of :mod:`micro.permeability`).
    """
    centre = 0.5 * (mesh.bounds[0] + mesh.bounds[1])
    half = 0.5 * inner_fraction * (mesh.bounds[1] - mesh.bounds[0])
    inner = np.all(np.abs(mesh.centroids - centre) <= half, axis=1) & ~dirichlet
    if np.any(inner):
        return inner
    log.warning("%s: no free cell in the inner region (mesh too coarse); set to NaN", label)
    return None


class FrozenState(NamedTuple):
    """A frozen state to measure.

    Attributes
    ----------
    mesh
        The specimen's mesh.
    saturation, porosity
        Water saturation [1] and porosity [1] per cell, shape (n_cells,).
    suction
        Current (mean) suction of the specimen [Pa], > 0: the mean imposed pressure is
        -suction and the drop a fraction of it.
    material
        Clay parameters (viscosities, k_0, b_k, S_r, S_s, n).
    conductances
        Optional facet conductances per phase [m3/(Pa s)] (e.g. with cracks); phases not
        given are computed with :func:`shared.fv.facet_conductance`.
    """

    mesh: Mesh
    saturation: FloatArray
    porosity: FloatArray
    suction: float
    material: ClayParameters
    conductances: Mapping[Phase, FloatArray] | None = None

    def phases(self) -> dict[Phase, FloatArray]:
        """Each phase's facet conductances (:func:`phase_conductances`)."""
        return phase_conductances(self.mesh, self.saturation, self.porosity, self.suction, self.material,
                                  self.conductances)


def phase_conductances(
    mesh: Mesh, saturation: FloatArray, porosity: FloatArray, suction: float,
    material: ClayParameters, conductances: Mapping[Phase, FloatArray] | None,
) -> dict[Phase, FloatArray]:
    """Each phase's facet conductances: the given ones, the others computed.

    Raises
    ------
    ValueError
        If ``suction`` is not > 0 (every measurement's drop is a fraction of it).
    """
    if not suction > 0.0:
        raise ValueError(f"suction must be > 0, got {suction}")
    given = {} if conductances is None else dict(conductances)
    return {
        phase: given[phase] if given.get(phase) is not None
        else facet_conductance(mesh, saturation, porosity, phase, material)
        for phase in PHASES
    }
