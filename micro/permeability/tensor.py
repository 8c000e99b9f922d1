"""The full permeability tensor of a frozen state: three steady solves with one factor.

The velocity method for gradients along x, y and z in turn, K[:, j] = -mu <v> / (grad p)_j
(:func:`measure_permeability_tensor`); :func:`permeability_tensor` for both phases.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from concurrent.futures import Executor
from functools import partial

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from micro.permeability import steady
from micro.permeability.steady import AXES, DROP_FRACTION, INNER_FRACTION, FloatArray
from micro.pool import gathered
from shared.fv import FlowPattern
from shared.materials import ClayParameters
from shared.mesh import WALLS, Mesh, boundary_cell_mask
from shared.permeability import Phase, phase_viscosity
from shared.solver import SolverError, SPDSolver

__all__ = ["measure_permeability_tensor", "permeability_tensor", "tensor_calls", "tensor_pattern"]

log = logging.getLogger(__name__)


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
    flow. As in :func:`micro.permeability.axes.measure_permeability`, conductances are floored at
    ``conductance_floor`` times the largest and the solve is for the departure from
    the mean pressure, which drops out of a steady problem. The gross rates entering
    and leaving the inner region must balance to ``balance_tolerance`` (their
    difference is the region's net imbalance, the sum of its cells' residuals in
    extended precision); if not, the pressure is refined in extended precision as the
    wall-flux method does, and the velocities are taken from the extended-precision
    fluxes.

    Parameters
    ----------
    mesh, conductance, viscosity
        As for :func:`micro.permeability.axes.measure_permeability`: the mesh, the
        phase's facet conductances [m3/(Pa s)] (n_facets,) and its viscosity [Pa s].
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
        would only precondition these solves, see
        :func:`micro.permeability.steady.measurement_solver`).
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
    _check_tensor_arguments(mesh, conductance, pressure_drop, inner_fraction)
    raised = steady.floored(conductance, conductance_floor)
    if raised is None:
        return np.zeros((3, 3))
    dirichlet = _tensor_dirichlet(mesh, sealed)
    if pattern is not None and not np.array_equal(pattern.dirichlet, dirichlet):
        raise ValueError("pattern: its Dirichlet cells are not the wall layers less ``sealed``")
    inner = steady.inner_cells(mesh, dirichlet, inner_fraction, label)
    if inner is None:
        return np.full((3, 3), np.nan)
    solver = steady.measurement_solver() if solver is None else solver
    pattern = steady.system_pattern(mesh, dirichlet, solver) if pattern is None else pattern
    matrix = steady.system_matrix(mesh, pattern, raised)
    tensor = np.full((3, 3), np.nan)
    for j in range(3):
        try:
            # the first solve factors the matrix; the next ones reuse the factor
            tensor[:, j] = _tensor_column(mesh, pattern, solver, raised, matrix, inner, j,
                                          viscosity, pressure_drop, balance_tolerance, label)
        except SolverError as error:
            log.warning("%s: steady solve failed (%s); tensor set to NaN", label, error)
            return np.full((3, 3), np.nan)
    return _dissipative(tensor, label)


def _check_tensor_arguments(mesh: Mesh, conductance: FloatArray, pressure_drop: float,
                            inner_fraction: float) -> None:
    """Raise ValueError for a drop [Pa] not > 0, a fraction [1] outside (0, 1] or
    conductances not one per facet."""
    if not pressure_drop > 0.0:
        raise ValueError(f"pressure_drop must be > 0, got {pressure_drop}")
    if not 0.0 < inner_fraction <= 1.0:
        raise ValueError(f"inner_fraction must be in (0, 1], got {inner_fraction}")
    if np.shape(conductance) != (mesh.n_facets,):
        raise ValueError(f"conductance must have shape ({mesh.n_facets},)")


def _tensor_column(
    mesh: Mesh, pattern: FlowPattern, solver: SPDSolver, conductance: FloatArray,
    matrix: sp.csc_matrix, inner: npt.NDArray[np.bool_], j: int, viscosity: float,
    pressure_drop: float, tolerance: float, label: str,
) -> FloatArray:
    """Column ``j`` of the tensor [m2]: the steady solve with the gradient along e_j
    (linear profile at the circumcentres, zero at the box's centre), -mu <v> / (grad p)_j
    over the ``inner`` cells. NaN (with a warning) if the inner region's rates stay
    unbalanced after refinement or the mean flow runs against the gradient."""
    centre = 0.5 * (mesh.bounds[0, j] + mesh.bounds[1, j])
    gradient = -pressure_drop / (mesh.bounds[1, j] - mesh.bounds[0, j])
    flux, entering, leaving = steady.solve(
        mesh, pattern, solver, conductance, gradient * (mesh.circumcentres[:, j] - centre),
        matrix, lambda f: _region_rates(mesh, f, inner), tolerance)
    if not steady.balanced(entering, leaving, tolerance):
        log.warning(
            "%s, gradient along %s: rates %.4g and %.4g m3/s into and out of the inner "
            "region disagree even after extended-precision refinement; column set to NaN",
            label, AXES[j], entering, leaving,
        )
        return np.full(3, np.nan)
    column = -viscosity * steady.mean_velocity(mesh, flux, inner) / gradient
    if not column[j] > 0.0:
        log.warning("%s, gradient along %s: mean flow runs against the gradient "
                    "(K_%s%s = %.4g m2); column set to NaN", label, AXES[j], AXES[j],
                    AXES[j], column[j])
        return np.full(3, np.nan)
    return column


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
    return steady.system_pattern(mesh, _tensor_dirichlet(mesh, sealed))


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
    state: steady.FrozenState,
    *,
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
    state
        The frozen state (:class:`micro.permeability.steady.FrozenState`); the drop
        across the box is ``drop_fraction * state.suction``.
    drop_fraction
        Pressure drop as a fraction of the suction [1].
    inner_fraction
        Central fraction of the box averaged [1] (thesis: 0.8).
    sealed
        Cells that stay free in the wall layers (crack mouths), see
        :func:`measure_permeability_tensor`.
    executor
        Makes one phase's solves while this thread makes the other's, as in
        :func:`micro.permeability.axes.axis_permeabilities`.

    Returns
    -------
    ndarray, shape (2, 3, 3)
        K[phase, i, j] [m2] for phases (water, gas) and i, j over (x, y, z); NaN
        entries (with a warning) where a solve failed.
    """
    return np.stack(gathered(executor, tensor_calls(state.mesh, state.phases(), state.suction, state.material,
                                                     drop_fraction, inner_fraction, sealed)))


def tensor_calls(
    mesh: Mesh, phases: Mapping[Phase, FloatArray], suction: float, material: ClayParameters,
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
