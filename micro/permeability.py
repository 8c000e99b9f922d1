"""Numerical permeability measurement of the frozen micro model (docs/design.md §3).

Thesis Sec. 3.5.3 and Appendix .2 (``emulatePermeability``), corrected as in
docs/yade.md §§4 and 10: saturation, porosity and mesh are frozen, a pressure drop of
``drop_fraction`` of the suction is imposed along one axis, the steady problem is solved:

* ``"wall_flux"``: Dirichlet cells on the two walls normal to the axis,
  k = mu Q L / (A dP), A = V / L the mean cross-section;
* ``"velocity"``: Dirichlet cells on all six walls, k = mu |<v>| / |grad p|, <v> the
  volume average of v_i = (1/V_i) sum_f q_f (x_f - x_i) over the central cells;
* the tensor (:func:`permeability_tensor`): velocity method for gradients along x, y and
  z, K[:, j] = -mu <v> / (grad p)_j; :func:`principal_permeability` its symmetric part.

Unbalanced or reversed wall fluxes are NaN; the rest: docs/micro.md, "micro.permeability".
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from functools import partial
from typing import Literal

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from micro.pool import gathered
from shared.errors import ConfigError
from shared.fv import (
    FlowPattern,
    assemble_matrix,
    facet_conductance,
    facet_divergence,
    facet_flux,
    solver_pattern,
)
from shared.materials import ClayParameters
from shared.mesh import WALLS, Mesh, boundary_cell_mask
from shared.permeability import Phase, phase_viscosity
from shared.solver import SolverError, SPDSolver

__all__ = [
    "AXES",
    "PHASES",
    "PrincipalPermeability",
    "measure_permeability",
    "measure_permeability_tensor",
    "measurement_pattern",
    "tensor_pattern",
    "permeability_tensor",
    "axis_permeabilities",
    "checkpoint_permeabilities",
    "principal_permeability",
]

FloatArray = npt.NDArray[np.float64]
log = logging.getLogger("micro.permeability")
Method = Literal["wall_flux", "velocity"]
AXES: tuple[str, ...] = ("x", "y", "z")
PHASES: tuple[Phase, ...] = ("water", "gas")
DROP_FRACTION = 0.1
"""Default pressure drop across the specimen, as a fraction of the suction [1]."""
INNER_FRACTION = 0.8
"""Default central fraction of the box whose velocities are averaged [1] (thesis: 0.8)."""


# Extended-precision refinement sweeps allowed for an unbalanced wall-flux solve.
_REFINEMENTS = 6


def _floored(conductance: FloatArray, floor: float) -> FloatArray | None:
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


def _measurement_solver() -> SPDSolver:
    """A fresh solver at round-off backward error for each measurement.

    A factor kept from another phase or axis would precondition conjugate gradients
    that meet a normwise backward error of 1e-16 on a crack network's conductances
    (twelve decades) and still miss the fluxes of the clay matrix by orders of
    magnitude; a direct solve with the matrix's own factor balances them to 1e-12.
    """
    return SPDSolver(residual_tolerance=1e-13, amg_unknowns=_MEASUREMENT_AMG_UNKNOWNS)


def _pattern(
    mesh: Mesh, dirichlet: npt.NDArray[np.bool_], solver: SPDSolver | None = None
) -> FlowPattern:
    """The pattern of these Dirichlet cells, ordered for the solver's path (default the
    measurements' solver): fill-reducing for a factor, by locality for multigrid."""
    return solver_pattern(mesh, dirichlet, _measurement_solver() if solver is None else solver)


def _imposed_profile(
    mesh: Mesh, axis: int, mean_pressure: float, pressure_drop: float, clip: bool
) -> tuple[FloatArray, float]:
    """Linear pressure at the (optionally box-clipped) circumcentres, and its gradient."""
    low, high = mesh.bounds[0, axis], mesh.bounds[1, axis]
    gradient = -pressure_drop / (high - low)
    centres = mesh.circumcentres[:, axis]
    position = (np.clip(centres, low, high) if clip else centres) - 0.5 * (low + high)
    return mean_pressure + gradient * position, gradient


def _cut_flux(mesh: Mesh, flux: FloatArray, region: npt.NDArray[np.bool_]) -> float:
    """Net flux leaving ``region`` through internal facets [m3/s]."""
    inside = region[mesh.facet_cells]
    leaving = inside[:, 0] & ~inside[:, 1]
    entering = ~inside[:, 0] & inside[:, 1]
    return float(flux[leaving].sum() - flux[entering].sum())


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


def _wall_rates(
    mesh: Mesh, flux: npt.NDArray, inlet: npt.NDArray[np.bool_], outlet: npt.NDArray[np.bool_]
) -> tuple[float, float]:
    """Rates leaving the inlet layer and entering the outlet layer [m3/s]."""
    return _cut_flux(mesh, flux, inlet), -_cut_flux(mesh, flux, outlet)


def _balanced(entering: float, leaving: float, tolerance: float) -> bool:
    rate = 0.5 * (entering + leaving)
    return bool(rate > 0.0 and abs(entering - leaving) <= tolerance * rate)


def _mean_velocity(
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


def _steady_solve(
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
    if not _balanced(entering, leaving, tolerance):
        entering, leaving, flux = _refined_rates(
            mesh, pattern, solver, conductance, pressure, rates, tolerance, matrix)
    return flux, entering, leaving


def _steady_matrix(mesh: Mesh, pattern: FlowPattern, conductance: FloatArray) -> sp.csc_matrix:
    """Lower triangle of the steady (storage-free) system of ``conductance``."""
    return assemble_matrix(mesh, pattern, conductance, np.zeros(mesh.n_cells))


def measure_permeability(
    mesh: Mesh,
    conductance: FloatArray,
    viscosity: float,
    axis: int,
    *,
    mean_pressure: float,
    pressure_drop: float,
    method: Method = "wall_flux",
    inner_fraction: float = INNER_FRACTION,
    conductance_floor: float = 1e-16,
    balance_tolerance: float = 1e-3,
    solver: SPDSolver | None = None,
    pattern: FlowPattern | None = None,
) -> float:
    """Permeability along one axis from a steady solve with frozen conductances.

    Parameters
    ----------
    mesh
        The mesh.
    conductance
        Facet conductances of the phase [m3/(Pa s)], shape (n_facets,), including any
        crack contributions.
    viscosity
        Dynamic viscosity of the phase used in ``conductance`` [Pa s].
    axis
        0, 1 or 2 for x, y, z.
    mean_pressure
        Pressure at the centre of the specimen [Pa] (minus the current suction).
    pressure_drop
        Pressure difference between the two wall planes [Pa], > 0.
    method
        ``"wall_flux"`` or ``"velocity"`` (see the module docstring).
    inner_fraction
        Central fraction of the box averaged by the velocity method [1].
    conductance_floor
        Conductances are raised to at least this fraction of the largest one [1].
    balance_tolerance
        Largest relative difference of the inlet and outlet rates of the wall-flux
        method [1]; beyond it the solve is deemed inaccurate and NaN is returned.
    solver
        Solver to use; default a fresh one. A solver that already factored other
        conductances would only precondition this solve (see ``_measurement_solver``).
    pattern
        System pattern of this method's Dirichlet cells for this axis
        (:func:`measurement_pattern`), e.g. shared by the two phases; default built here.

    Returns
    -------
    float
        Permeability [m2]; 0 if every conductance is 0; NaN (with a warning) if the
        wall fluxes are not balanced or run against the gradient.
    """
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2, got {axis}")
    if method not in ("wall_flux", "velocity"):
        raise ValueError(f"method must be 'wall_flux' or 'velocity', got {method!r}")
    if not pressure_drop > 0.0:
        raise ValueError(f"pressure_drop must be > 0, got {pressure_drop}")
    floored = _floored(conductance, conductance_floor)
    if floored is None:
        return 0.0
    departure, gradient = _imposed_profile(
        mesh, axis, 0.0, pressure_drop, clip=method == "wall_flux"
    )
    length = mesh.bounds[1, axis] - mesh.bounds[0, axis]
    solver = _measurement_solver() if solver is None else solver
    dirichlet, layers = _dirichlet_cells(mesh, axis, method)
    if pattern is None:
        pattern = _pattern(mesh, dirichlet, solver)
    elif not np.array_equal(pattern.dirichlet, dirichlet):
        raise ValueError(f"pattern: its Dirichlet cells are not those of the {method} "
                         f"method along axis {axis}")
    matrix = _steady_matrix(mesh, pattern, floored)
    if layers is not None:
        inlet, outlet = layers
        _, entering, leaving = _steady_solve(
            mesh, pattern, solver, floored, departure, matrix,
            lambda flux: _wall_rates(mesh, flux, inlet, outlet), balance_tolerance)
        if not _balanced(entering, leaving, balance_tolerance):
            log.warning(
                "axis %d at %.4g Pa: inlet and outlet rates %.4g and %.4g m3/s disagree "
                "even after extended-precision refinement; permeability set to NaN",
                axis, mean_pressure, entering, leaving,
            )
            return float("nan")
        area = mesh.volumes.sum() / length
        return viscosity * 0.5 * (entering + leaving) / (area * abs(gradient))
    flux, _, _ = _steady_solve(mesh, pattern, solver, floored, departure, matrix, None,
                               balance_tolerance)
    inner = _inner_cells(mesh, pattern.dirichlet, inner_fraction)
    if not np.any(inner):
        raise ConfigError("no free cell in the inner region: mesh too coarse")
    velocity = _mean_velocity(mesh, flux, inner)
    return viscosity * float(np.linalg.norm(velocity)) / abs(gradient)


def _wall_layers(mesh: Mesh, axis: int) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Cells of the inlet (lower) and outlet (upper) wall layers normal to ``axis``."""
    inlet = boundary_cell_mask(mesh, [WALLS[2 * axis]])
    return inlet, boundary_cell_mask(mesh, [WALLS[2 * axis + 1]]) & ~inlet


def _dirichlet_cells(
    mesh: Mesh, axis: int, method: Method
) -> tuple[npt.NDArray[np.bool_], tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]] | None]:
    """Dirichlet cells of a measurement, with the inlet and outlet wall layers whose rates
    ``wall_flux`` measures (None for ``velocity``, which imposes all six walls)."""
    if method == "wall_flux":
        inlet, outlet = _wall_layers(mesh, axis)
        return inlet | outlet, (inlet, outlet)
    return boundary_cell_mask(mesh, list(WALLS)), None


def measurement_pattern(mesh: Mesh, axis: int, method: Method = "wall_flux") -> FlowPattern:
    """System pattern of a measurement along ``axis`` (0, 1, 2) by ``method``: its
    Dirichlet cells are the two wall layers normal to the axis (``wall_flux``) or all
    six (``velocity``, the same for every axis)."""
    return _pattern(mesh, _dirichlet_cells(mesh, axis, method)[0])


def _refined_rates(
    mesh: Mesh,
    pattern: FlowPattern,
    solver: SPDSolver,
    conductance: FloatArray,
    pressure: FloatArray,
    rates: Callable[[npt.NDArray], tuple[float, float]],
    tolerance: float,
    matrix: sp.csc_matrix | None = None,
) -> tuple[float, float, npt.NDArray]:
    """Rates and fluxes after mixed-precision iterative refinement of a steady solve.

    The residual and the fluxes in ``numpy.longdouble``, the correction from the
    solver's double-precision factor of the same matrix; stops once the two ``rates``
    of the fluxes (in and out of a region) balance to ``tolerance`` or after
    ``_REFINEMENTS`` sweeps. Returns the two rates and the last fluxes [m3/s].
    """
    if matrix is None:
        matrix = assemble_matrix(mesh, pattern, conductance, np.zeros(mesh.n_cells))
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
        if _balanced(entering, leaving, tolerance):
            break
    return entering, leaving, flux


def axis_permeabilities(
    mesh: Mesh,
    saturation: FloatArray,
    porosity: FloatArray,
    suction: float,
    material: ClayParameters,
    *,
    conductances: Mapping[str, FloatArray] | None = None,
    method: Method = "wall_flux",
    drop_fraction: float = DROP_FRACTION,
    executor: Executor | None = None,
) -> dict[str, dict[str, float]]:
    """Water and gas permeability along x, y and z of a frozen state.

    Parameters
    ----------
    mesh
        The mesh.
    saturation
        Water saturation per cell [1], shape (n_cells,).
    porosity
        Porosity per cell [1], shape (n_cells,).
    suction
        Current (mean) suction of the specimen [Pa], > 0: the mean imposed pressure is
        -suction and the drop is ``drop_fraction * suction``.
    material
        Clay parameters (viscosities, k_0, b_k, S_r, S_s, n).
    conductances
        Optional facet conductances per phase [m3/(Pa s)] (e.g. with cracks);
        phases not given are computed with :func:`shared.fv.facet_conductance`.
    method
        ``"wall_flux"`` or ``"velocity"``.
    drop_fraction
        Pressure drop as a fraction of the suction [1].
    executor
        Makes half of the six independent solves while this thread makes the others
        (:func:`micro.run.measurement_executor`: a worker process, since pyamg's cycles
        and CHOLMOD hold the GIL); None makes them one after the other. The results do
        not depend on it.

    Returns
    -------
    dict
        ``{phase: {axis: permeability [m2]}}`` for phases ``water``, ``gas`` and axes
        ``x``, ``y``, ``z``.
    """
    phases = _phase_conductances(mesh, saturation, porosity, suction, material, conductances)
    return _axes_result(gathered(executor, _axes_calls(mesh, phases, suction, material,
                                                       method, drop_fraction)))


def _phase_conductances(
    mesh: Mesh, saturation: FloatArray, porosity: FloatArray, suction: float,
    material: ClayParameters, conductances: Mapping[str, FloatArray] | None,
) -> dict[str, FloatArray]:
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


def _axes_calls(
    mesh: Mesh, phases: Mapping[str, FloatArray], suction: float, material: ClayParameters,
    method: Method, drop_fraction: float,
) -> list[Callable[[], float]]:
    """The six solves of :func:`axis_permeabilities`, by axis then phase."""
    # one pattern per axis for both phases; the velocity method's serves every axis
    patterns = [measurement_pattern(mesh, 0, method)]
    if method == "wall_flux":
        patterns += [measurement_pattern(mesh, axis, method) for axis in (1, 2)]
    return [
        partial(measure_permeability, mesh, conductance, phase_viscosity(phase, material),
                axis, mean_pressure=-suction, pressure_drop=drop_fraction * suction,
                method=method, pattern=patterns[min(axis, len(patterns) - 1)])
        for axis in range(len(AXES)) for phase, conductance in phases.items()
    ]


def _axes_result(values: Sequence[float]) -> dict[str, dict[str, float]]:
    """``{phase: {axis: permeability}}`` from the results of :func:`_axes_calls`."""
    ordered = iter(values)
    result: dict[str, dict[str, float]] = {phase: {} for phase in PHASES}
    for name in AXES:
        for phase in PHASES:
            result[phase][name] = next(ordered)
    return result


def _inner_cells(
    mesh: Mesh, dirichlet: npt.NDArray[np.bool_], inner_fraction: float
) -> npt.NDArray[np.bool_]:
    """Free cells whose centroid lies in the central ``inner_fraction`` of the box."""
    centre = 0.5 * (mesh.bounds[0] + mesh.bounds[1])
    half = 0.5 * inner_fraction * (mesh.bounds[1] - mesh.bounds[0])
    return np.all(np.abs(mesh.centroids - centre) <= half, axis=1) & ~dirichlet


def _region_rates(
    mesh: Mesh, flux: npt.NDArray, region: npt.NDArray[np.bool_]
) -> tuple[float, float]:
    """Gross rates entering and leaving ``region`` through internal facets [m3/s].

    Facet by facet, so that their difference is the region's net imbalance (the sum of
    its cells' residuals) while their mean is the rate that crosses it.
    """
    inside = region[mesh.facet_cells]
    outward = np.where(inside[:, 0] & ~inside[:, 1], flux, 0.0) - np.where(
        ~inside[:, 0] & inside[:, 1], flux, 0.0
    )
    return float(np.clip(-outward, 0.0, None).sum()), float(np.clip(outward, 0.0, None).sum())


def measure_permeability_tensor(
    mesh: Mesh,
    conductance: FloatArray,
    viscosity: float,
    *,
    pressure_drop: float,
    inner_fraction: float = INNER_FRACTION,
    conductance_floor: float = 1e-16,
    balance_tolerance: float = 1e-3,
    sealed: npt.NDArray[np.bool_] | None = None,
    solver: SPDSolver | None = None,
    label: str = "permeability tensor",
    pattern: FlowPattern | None = None,
) -> FloatArray:
    """Full permeability tensor of one phase from three steady solves with one factor.

    Every cell of the six wall layers is Dirichlet. For each direction e_j the
    imposed pressure is the linear profile p = -(dP / L_j) (x_j - c_j) at the cells'
    circumcentres (L_j the box length along j, c_j its centre), so |grad p| =
    dP / L_j; the free cells solve the steady balance, the cell velocities
    v_i = (1/V_i) sum_f q_f (x_f - x_i) are volume-averaged over the free cells
    whose centroid lies in the central ``inner_fraction`` of the box along every
    axis (the thesis' inner 80 %, Eq. 3.40), and column j of the tensor is
    K[:, j] = -mu <v> / (grad p)_j (Eq. 3.41 read as a tensor: <v> = -K grad p / mu).
    The three solves share the conductance matrix: it is assembled and factored once
    and the factor serves the three right-hand sides (and any refinement sweep).

    A homogeneous isotropic medium returns k I to round-off: the Dirichlet cells
    hold the exact discrete solution of a linear field, and v_i is exact for uniform
    flow. As in :func:`measure_permeability`, conductances are floored at
    ``conductance_floor`` times the largest and the solve is for the departure from
    the mean pressure, which drops out of a steady problem. The gross rates entering
    and leaving the inner region must balance to ``balance_tolerance`` (their
    difference is the region's net imbalance, the sum of its cells' residuals in
    extended precision); if not, the pressure is refined in extended precision as the
    wall-flux method does, and the velocities are taken from the extended-precision
    fluxes.

    Parameters
    ----------
    mesh
        The mesh.
    conductance
        Facet conductances of the phase [m3/(Pa s)], shape (n_facets,), including any
        crack contributions.
    viscosity
        Dynamic viscosity of the phase used in ``conductance`` [Pa s].
    pressure_drop
        Pressure difference dP across the box along the imposed gradient [Pa], > 0
        (the result does not depend on it but for round-off).
    inner_fraction
        Central fraction of the box, along every axis, whose free cells are
        averaged [1], in (0, 1].
    conductance_floor
        Conductances are raised to at least this fraction of the largest one [1].
    balance_tolerance
        Largest relative difference of the rates entering and leaving the inner
        region [1]; beyond it after refinement the column is NaN.
    sealed
        Cells (n_cells,) bool that stay free even in a wall layer: the mouths of
        cracks. A crack joining two wall cells would otherwise carry, between their
        imposed pressures, a flux as large as its conductance (up to 1e16 times the
        clay's) through the averaged region: a short circuit of the boundary condition,
        not a property of the specimen.
    solver
        Solver to use; default a fresh one (a factor kept from other conductances
        would only precondition these solves, see ``_measurement_solver``).
    label
        Name of the measurement in warnings (e.g. the phase and suction).
    pattern
        System pattern of these Dirichlet cells (:func:`tensor_pattern` with the same
        ``sealed``), e.g. shared by the two phases; default built here.

    Returns
    -------
    ndarray, shape (3, 3)
        K[i, j] [m2]: component i of the Darcy velocity times mu per unit pressure
        gradient along -e_j. Zeros if every conductance is 0. A column is NaN (with a
        warning) if its solve stays unbalanced or its diagonal entry is not positive
        (flow against the gradient); the whole tensor is NaN (with a warning) if the
        factorisation fails, no free cell lies in the inner region, or the symmetric
        part of a complete tensor is not positive definite (flow against the gradient
        along some direction).
    """
    if not pressure_drop > 0.0:
        raise ValueError(f"pressure_drop must be > 0, got {pressure_drop}")
    if not 0.0 < inner_fraction <= 1.0:
        raise ValueError(f"inner_fraction must be in (0, 1], got {inner_fraction}")
    if np.shape(conductance) != (mesh.n_facets,):
        raise ValueError(f"conductance must have shape ({mesh.n_facets},)")
    tensor = np.full((3, 3), np.nan)
    floored = _floored(conductance, conductance_floor)
    if floored is None:
        return np.zeros((3, 3))
    dirichlet = _tensor_dirichlet(mesh, sealed)
    if pattern is not None and not np.array_equal(pattern.dirichlet, dirichlet):
        raise ValueError("pattern: its Dirichlet cells are not the wall layers less ``sealed``")
    inner = _inner_cells(mesh, dirichlet, inner_fraction)
    if not np.any(inner):
        log.warning("%s: no free cell in the inner region (mesh too coarse); tensor set to NaN",
                    label)
        return tensor
    solver = _measurement_solver() if solver is None else solver
    pattern = _pattern(mesh, dirichlet, solver) if pattern is None else pattern
    matrix = _steady_matrix(mesh, pattern, floored)
    centre = 0.5 * (mesh.bounds[0] + mesh.bounds[1])
    for j in range(3):
        gradient = -pressure_drop / (mesh.bounds[1, j] - mesh.bounds[0, j])
        try:
            # the first solve factors the matrix; the next ones reuse the factor
            flux, entering, leaving = _steady_solve(
                mesh, pattern, solver, floored,
                gradient * (mesh.circumcentres[:, j] - centre[j]), matrix,
                lambda f: _region_rates(mesh, f, inner), balance_tolerance)
        except SolverError as error:
            log.warning("%s: steady solve failed (%s); tensor set to NaN", label, error)
            return np.full((3, 3), np.nan)
        if not _balanced(entering, leaving, balance_tolerance):
            log.warning(
                "%s, gradient along %s: rates %.4g and %.4g m3/s into and out of the inner "
                "region disagree even after extended-precision refinement; column set to NaN",
                label, AXES[j], entering, leaving,
            )
            continue
        column = -viscosity * _mean_velocity(mesh, flux, inner) / gradient
        if not column[j] > 0.0:
            log.warning("%s, gradient along %s: mean flow runs against the gradient "
                        "(K_%s%s = %.4g m2); column set to NaN", label, AXES[j], AXES[j],
                        AXES[j], column[j])
            continue
        tensor[:, j] = column
    return _dissipative(tensor, label)


def _tensor_dirichlet(
    mesh: Mesh, sealed: npt.NDArray[np.bool_] | None
) -> npt.NDArray[np.bool_]:
    dirichlet = boundary_cell_mask(mesh, list(WALLS))
    if sealed is not None:
        dirichlet &= ~np.asarray(sealed, dtype=bool)
    return dirichlet


def tensor_pattern(mesh: Mesh, sealed: npt.NDArray[np.bool_] | None = None) -> FlowPattern:
    """System pattern of :func:`measure_permeability_tensor`: the six wall layers are
    Dirichlet but for the ``sealed`` cells."""
    return _pattern(mesh, _tensor_dirichlet(mesh, sealed))


def _dissipative(tensor: FloatArray, label: str) -> FloatArray:
    """The tensor, or NaN (with a warning) if its symmetric part is not positive definite.

    n . K n <= 0 for some unit n means a gradient along n drives a mean flow that does
    not run down it: the tensor analogue of the per-axis wall flux against the gradient.
    """
    if not np.all(np.isfinite(tensor)):
        return tensor
    smallest, largest = np.linalg.eigvalsh(0.5 * (tensor + tensor.T))[[0, -1]]
    if smallest > 0.0:
        return tensor
    log.warning("%s: symmetric part not positive definite (principal values %.4g to %.4g "
                "m2); tensor set to NaN", label, smallest, largest)
    return np.full((3, 3), np.nan)


def permeability_tensor(
    mesh: Mesh,
    saturation: FloatArray,
    porosity: FloatArray,
    suction: float,
    material: ClayParameters,
    *,
    conductances: Mapping[str, FloatArray] | None = None,
    drop_fraction: float = DROP_FRACTION,
    inner_fraction: float = INNER_FRACTION,
    sealed: npt.NDArray[np.bool_] | None = None,
    executor: Executor | None = None,
) -> FloatArray:
    """Water and gas permeability tensors of a frozen state (docs/design.md §2,
    ``permeability_tensor``).

    Three steady solves per phase with one factorisation
    (:func:`measure_permeability_tensor`).

    Parameters
    ----------
    mesh
        The mesh.
    saturation
        Water saturation per cell [1], shape (n_cells,).
    porosity
        Porosity per cell [1], shape (n_cells,).
    suction
        Current (mean) suction of the specimen [Pa], > 0: the pressure drop across the
        box is ``drop_fraction * suction``, as for :func:`axis_permeabilities`.
    material
        Clay parameters (viscosities, k_0, b_k, S_r, S_s, n).
    conductances
        Optional facet conductances per phase [m3/(Pa s)] (e.g. with cracks);
        phases not given are computed with :func:`shared.fv.facet_conductance`.
    drop_fraction
        Pressure drop as a fraction of the suction [1].
    inner_fraction
        Central fraction of the box averaged [1] (thesis: 0.8).
    sealed
        Cells that stay free in the wall layers (crack mouths), see
        :func:`measure_permeability_tensor`.
    executor
        Makes one phase's solves while this thread makes the other's, as in
        :func:`axis_permeabilities`.

    Returns
    -------
    ndarray, shape (2, 3, 3)
        K[phase, i, j] [m2] for phases (water, gas) and i, j over (x, y, z); NaN
        entries (with a warning) where a solve failed.
    """
    phases = _phase_conductances(mesh, saturation, porosity, suction, material, conductances)
    return np.stack(gathered(executor, _tensor_calls(mesh, phases, suction, material,
                                                     drop_fraction, inner_fraction, sealed)))


def _tensor_calls(
    mesh: Mesh, phases: Mapping[str, FloatArray], suction: float, material: ClayParameters,
    drop_fraction: float, inner_fraction: float, sealed: npt.NDArray[np.bool_] | None,
) -> list[Callable[[], FloatArray]]:
    """The two tensor measurements of :func:`permeability_tensor`, water then gas."""
    pattern = tensor_pattern(mesh, sealed)
    return [
        partial(measure_permeability_tensor, mesh, conductance, phase_viscosity(phase, material),
                pressure_drop=drop_fraction * suction, inner_fraction=inner_fraction,
                sealed=sealed, label=f"{phase} permeability tensor at {suction:.4g} Pa",
                pattern=pattern)
        for phase, conductance in phases.items()
    ]


def checkpoint_permeabilities(
    mesh: Mesh,
    saturation: FloatArray,
    porosity: FloatArray,
    suction: float,
    material: ClayParameters,
    *,
    conductances: Mapping[str, FloatArray] | None = None,
    sealed: npt.NDArray[np.bool_] | None = None,
    executor: Executor | None = None,
) -> tuple[dict[str, dict[str, float]], FloatArray]:
    """A checkpoint's eight solves: :func:`axis_permeabilities` (wall-flux method)
    and :func:`permeability_tensor` with their default fractions, in one gather.

    With ``executor``, the worker makes one phase's four solves and this thread the
    other's, and the mesh they share is sent to the worker once.

    Parameters
    ----------
    mesh, saturation, porosity, suction, material, conductances
        As for :func:`axis_permeabilities`: the frozen state [1, 1], the suction
        [Pa], the clay parameters, optional facet conductances per phase [m3/(Pa s)].
    sealed
        Cells that stay free in the tensor's wall layers (crack mouths), as for
        :func:`permeability_tensor`.
    executor
        A worker, as for :func:`axis_permeabilities`; the results do not depend on it.

    Returns
    -------
    axes : dict
        ``{phase: {axis: permeability [m2]}}``, as :func:`axis_permeabilities`.
    tensor : ndarray, shape (2, 3, 3)
        K[phase, i, j] [m2], as :func:`permeability_tensor`.
    """
    phases = _phase_conductances(mesh, saturation, porosity, suction, material, conductances)
    axes = _axes_calls(mesh, phases, suction, material, "wall_flux", DROP_FRACTION)
    values = gathered(executor, [*axes, *_tensor_calls(mesh, phases, suction, material,
                                                        DROP_FRACTION, INNER_FRACTION, sealed)])
    return _axes_result(values[:len(axes)]), np.stack(values[len(axes):])


@dataclass(frozen=True)
class PrincipalPermeability:
    """Derived quantities of permeability tensors (:func:`principal_permeability`).

    Attributes
    ----------
    symmetric : ndarray, shape (..., 3, 3)
        Symmetric part (K + K^T) / 2 [m2].
    values : ndarray, shape (..., 3)
        Eigenvalues of the symmetric part in ascending order [m2].
    directions : ndarray, shape (..., 3, 3)
        Unit eigenvectors of the symmetric part as columns: ``directions[..., :, k]``
        belongs to ``values[..., k]``; each has its largest-magnitude component
        positive (the first such component on a tie) [1].
    asymmetry : ndarray, shape (...)
        ||K - K^T||_F / ||K||_F [1] (0 for a zero tensor).
    """

    symmetric: FloatArray
    values: FloatArray
    directions: FloatArray
    asymmetry: FloatArray


def principal_permeability(tensor: npt.ArrayLike) -> PrincipalPermeability:
    """Symmetric part, principal values and directions, and asymmetry of tensors.

    Parameters
    ----------
    tensor
        Permeability tensors [m2], shape (..., 3, 3).

    Returns
    -------
    PrincipalPermeability
        All fields NaN for a tensor with a non-finite entry.
    """
    tensor = np.asarray(tensor, dtype=np.float64)
    if tensor.shape[-2:] != (3, 3):
        raise ValueError(f"tensors must have shape (..., 3, 3), got {tensor.shape}")
    finite = np.all(np.isfinite(tensor), axis=(-2, -1))
    clean = np.where(finite[..., None, None], tensor, 0.0)
    transposed = np.swapaxes(clean, -1, -2)
    symmetric = 0.5 * (clean + transposed)
    values, directions = np.linalg.eigh(symmetric)
    # sign convention: the largest-magnitude component of each direction is positive
    largest = np.argmax(np.abs(directions), axis=-2)[..., None, :]
    sign = np.where(np.take_along_axis(directions, largest, axis=-2) < 0.0, -1.0, 1.0)
    directions = directions * sign
    norm = np.linalg.norm(clean, axis=(-2, -1))
    skew = np.linalg.norm(clean - transposed, axis=(-2, -1))
    asymmetry = np.divide(skew, norm, out=np.zeros_like(norm), where=norm > 0.0)
    nan = ~finite
    symmetric[nan] = np.nan
    values[nan] = np.nan
    directions[nan] = np.nan
    asymmetry = np.where(nan, np.nan, asymmetry)
    return PrincipalPermeability(symmetric=symmetric, values=values, directions=directions,
                                 asymmetry=asymmetry)
