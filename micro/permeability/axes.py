"""Permeability along one axis at a time: the wall-flux and the velocity methods.

Thesis Sec. 3.5.3 and Appendix .2 (``emulatePermeability``), corrected as in
docs/yade.md §§4 and 10: a pressure drop of ``drop_fraction`` of the suction is imposed
along one axis and the steady problem solved (:mod:`micro.permeability.steady`):

* ``"wall_flux"``: Dirichlet cells on the two walls normal to the axis,
  k = mu Q L / (A dP), A = V / L the mean cross-section;
* ``"velocity"``: Dirichlet cells on all six walls, k = mu |<v>| / |grad p|, <v> the
  volume average of v_i = (1/V_i) sum_f q_f (x_f - x_i) over the central cells.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from functools import partial

import numpy as np
import numpy.typing as npt

from micro.permeability import steady
from micro.permeability.steady import AXES, DROP_FRACTION, INNER_FRACTION, PHASES, FloatArray, Method
from micro.pool import gathered
from shared.fv import FlowPattern
from shared.materials import ClayParameters
from shared.mesh import WALLS, Mesh, boundary_cell_mask
from shared.permeability import Phase, phase_viscosity
from shared.solver import SPDSolver

__all__ = ["axes_calls", "axes_result", "axis_permeabilities", "measure_permeability",
           "measurement_pattern"]

log = logging.getLogger(__name__)


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


def _wall_rates(
    mesh: Mesh, flux: npt.NDArray, inlet: npt.NDArray[np.bool_], outlet: npt.NDArray[np.bool_]
) -> tuple[float, float]:
    """Rates leaving the inlet layer and entering the outlet layer [m3/s]."""
    return _cut_flux(mesh, flux, inlet), -_cut_flux(mesh, flux, outlet)


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
        conductances would only precondition this solve (see
        :func:`micro.permeability.steady.measurement_solver`).
    pattern
        System pattern of this method's Dirichlet cells for this axis
        (:func:`measurement_pattern`), e.g. shared by the two phases; default built here.

    Returns
    -------
    float
        Permeability [m2]; 0 if every conductance is 0; NaN (with a warning) if the
        wall fluxes are not balanced or run against the gradient, or if no free cell lies
        in the velocity method's inner region.
    """
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2, got {axis}")
    if method not in ("wall_flux", "velocity"):
        raise ValueError(f"method must be 'wall_flux' or 'velocity', got {method!r}")
    if not pressure_drop > 0.0:
        raise ValueError(f"pressure_drop must be > 0, got {pressure_drop}")
    raised = steady.floored(conductance, conductance_floor)
    if raised is None:
        return 0.0
    departure, gradient = _imposed_profile(
        mesh, axis, 0.0, pressure_drop, clip=method == "wall_flux"
    )
    length = mesh.bounds[1, axis] - mesh.bounds[0, axis]
    solver = steady.measurement_solver() if solver is None else solver
    dirichlet, layers = _dirichlet_cells(mesh, axis, method)
    if pattern is None:
        pattern = steady.system_pattern(mesh, dirichlet, solver)
    elif not np.array_equal(pattern.dirichlet, dirichlet):
        raise ValueError(f"pattern: its Dirichlet cells are not those of the {method} "
                         f"method along axis {axis}")
    matrix = steady.system_matrix(mesh, pattern, raised)
    if layers is not None:
        inlet, outlet = layers
        _, entering, leaving = steady.solve(
            mesh, pattern, solver, raised, departure, matrix,
            lambda flux: _wall_rates(mesh, flux, inlet, outlet), balance_tolerance)
        if not steady.balanced(entering, leaving, balance_tolerance):
            log.warning(
                "axis %d at %.4g Pa: inlet and outlet rates %.4g and %.4g m3/s disagree "
                "even after extended-precision refinement; permeability set to NaN",
                axis, mean_pressure, entering, leaving,
            )
            return float("nan")
        area = mesh.volumes.sum() / length
        return viscosity * 0.5 * (entering + leaving) / (area * abs(gradient))
    inner = steady.inner_cells(mesh, pattern.dirichlet, inner_fraction,
                        f"axis {axis} at {mean_pressure:.4g} Pa, velocity method")
    if inner is None:
        return float("nan")
    flux, _, _ = steady.solve(mesh, pattern, solver, raised, departure, matrix, None,
                              balance_tolerance)
    velocity = steady.mean_velocity(mesh, flux, inner)
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
    return steady.system_pattern(mesh, _dirichlet_cells(mesh, axis, method)[0])


def axis_permeabilities(
    state: steady.FrozenState,
    *,
    method: Method = "wall_flux",
    drop_fraction: float = DROP_FRACTION,
    executor: Executor | None = None,
) -> dict[str, dict[str, float]]:
    """Water and gas permeability along x, y and z of a frozen state.

    Parameters
    ----------
    state
        The frozen state (:class:`micro.permeability.steady.FrozenState`); the drop is
        ``drop_fraction * state.suction``.
    method
        ``"wall_flux"`` or ``"velocity"``.
    drop_fraction
        Pressure drop as a fraction of the suction [1].
    executor
        Makes half of the six independent solves while this thread makes the others
        (:func:`micro.pool.measurement_executor`: a worker process, since pyamg's cycles
        and CHOLMOD hold the GIL); None makes them one after the other. The results do
        not depend on it.

    Returns
    -------
    dict
        ``{phase: {axis: permeability [m2]}}`` for phases ``water``, ``gas`` and axes
        ``x``, ``y``, ``z``.
    """
    return axes_result(gathered(executor, axes_calls(state.mesh, state.phases(), state.suction, state.material,
                                                       method, drop_fraction)))


def axes_calls(
    mesh: Mesh, phases: Mapping[Phase, FloatArray], suction: float, material: ClayParameters,
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


def axes_result(values: Sequence[float]) -> dict[str, dict[str, float]]:
    """``{phase: {axis: permeability}}`` from the results of :func:`_axes_calls`."""
    ordered = iter(values)
    result: dict[str, dict[str, float]] = {phase: {} for phase in PHASES}
    for name in AXES:
        for phase in PHASES:
            result[phase][name] = next(ordered)
    return result
