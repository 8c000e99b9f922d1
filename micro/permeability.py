"""Numerical permeability measurement of the frozen micro model (DESIGN.md section 3).

Thesis Sec. 3.5.3 and Appendix .2 (``emulatePermeability``), with the corrections of
REFERENCE_NOTES sections 4 and 10: saturation, porosity and the mesh are frozen, a
pressure drop of ``drop_fraction`` (10 %) of the current suction is imposed along one
axis, the steady problem is solved (no transient term), and the permeability follows
from either

* ``"wall_flux"``: Dirichlet cells on the two walls normal to the axis only, no flux
  elsewhere; k = mu Q L / (A dP), Q the mean of the flux leaving the inlet layer and
  entering the outlet layer, A = V / L the mean cross-section of the meshed volume V
  over the length L between the wall planes; or
* ``"velocity"``: Dirichlet cells on all six walls, as in the thesis script; cell
  velocities v_i = (1/V_i) sum_f q_f (x_f - x_i) (exact for uniform flow); k =
  mu |<v>| / |grad p| with <v> the volume average over the cells whose centroid lies in
  the central ``inner_fraction`` of the box along every axis.

The imposed pressure is the linear profile evaluated at each Dirichlet cell's
circumcentre (its dual point). With the velocity method every boundary cell is
Dirichlet and this linear field is the exact discrete solution of a homogeneous
medium (the scheme reproduces linear fields), so the input permeability comes back to
round-off. With the wall-flux method the jagged no-flux side walls break linearity
anyway, an O(h/L) excess; there the circumcentres are clipped to the box, so that hull
slivers, whose circumcentres lie far out, keep pressures between the two wall values,
which reduces that excess.

Zero conductances (e.g. the gas phase of a saturated region) would make isolated free
cells singular: conductances are floored at ``conductance_floor`` times the largest
one, a floor low enough to leave the clay's gas conductances alone although gas cracks
reach 1e11 times them.

A steady solve without storage does not depend on the mean pressure, so it is solved
for the departure from ``mean_pressure``: with open gas cracks the conductances span
twelve decades, and carrying a mean ten times the drop through that ill-conditioned
system loses the digits the flux is made of. Near saturation a few gas-filled cracks
conduct 1e16 times the clay's gas conductance: the flux across such a facet, computed
in double precision, carries a round-off as large as a few per cent of the whole
specimen's rate, whatever the solver's tolerance, and the clay's fluxes can be off as
much. Inlet and outlet rates that differ by more than ``balance_tolerance`` (0.1 %) are
then refined: the residual and the fluxes are computed in extended precision
(``numpy.longdouble``) and the double-precision factor solves for the correction
(mixed-precision iterative refinement). A wall flux that runs against the gradient, or that stays unbalanced
after ``_REFINEMENTS`` sweeps, is a failed solve: it is reported as NaN with a warning
rather than as a permeability. The measurements behind these choices are in
``benchmarks/reference/README.md``.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Literal

import numpy as np
import numpy.typing as npt

from shared.fv import (
    FlowPattern,
    assemble_matrix,
    facet_conductance,
    facet_flux,
    flow_pattern,
    steady_pressure,
)
from shared.materials import ClayParameters
from shared.mesh import WALLS, Mesh, boundary_cell_mask
from shared.permeability import Phase, phase_viscosity
from shared.solver import CholeskySolver

__all__ = ["AXES", "PHASES", "measure_permeability", "permeability_tensor_axes"]

FloatArray = npt.NDArray[np.float64]
log = logging.getLogger("micro.permeability")
Method = Literal["wall_flux", "velocity"]
AXES: tuple[str, ...] = ("x", "y", "z")
PHASES: tuple[Phase, ...] = ("water", "gas")


# Extended-precision refinement sweeps allowed for an unbalanced wall-flux solve.
_REFINEMENTS = 6


def _measurement_solver() -> CholeskySolver:
    """A fresh solver at round-off backward error for each measurement.

    A factor kept from another phase or axis would precondition conjugate gradients
    that meet a normwise backward error of 1e-16 on a crack network's conductances
    (twelve decades) and still miss the fluxes of the clay matrix by orders of
    magnitude; a direct solve with the matrix's own factor balances them to 1e-12.
    """
    return CholeskySolver(residual_tolerance=1e-13)


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
    """Volume-averaged velocity over ``cells`` [m/s], shape (3,)."""
    i, j = mesh.facet_cells[:, 0], mesh.facet_cells[:, 1]
    moment = np.zeros((mesh.n_cells, 3))
    for component in range(3):
        x = mesh.facet_centroids[:, component]
        moment[:, component] = np.bincount(
            i, flux * (x - mesh.centroids[i, component]), minlength=mesh.n_cells
        ) - np.bincount(j, flux * (x - mesh.centroids[j, component]), minlength=mesh.n_cells)
    return moment[cells].sum(axis=0) / mesh.volumes[cells].sum()


def measure_permeability(
    mesh: Mesh,
    conductance: FloatArray,
    viscosity: float,
    axis: int,
    *,
    mean_pressure: float,
    pressure_drop: float,
    method: Method = "wall_flux",
    inner_fraction: float = 0.8,
    conductance_floor: float = 1e-16,
    balance_tolerance: float = 1e-3,
    solver: CholeskySolver | None = None,
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

    Returns
    -------
    float
        Permeability [m2]; 0 if every conductance is 0; NaN (with a warning) if the
        wall fluxes are not balanced or run against the gradient.
    """
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2, got {axis}")
    if not pressure_drop > 0.0:
        raise ValueError(f"pressure_drop must be > 0, got {pressure_drop}")
    largest = float(np.max(conductance, initial=0.0))
    if largest == 0.0:
        return 0.0
    floored = np.maximum(conductance, conductance_floor * largest)
    departure, gradient = _imposed_profile(
        mesh, axis, 0.0, pressure_drop, clip=method == "wall_flux"
    )
    length = mesh.bounds[1, axis] - mesh.bounds[0, axis]
    solver = _measurement_solver() if solver is None else solver
    if method == "wall_flux":
        lower_wall, upper_wall = WALLS[2 * axis], WALLS[2 * axis + 1]
        inlet = boundary_cell_mask(mesh, [lower_wall])
        outlet = boundary_cell_mask(mesh, [upper_wall]) & ~inlet
        pattern = flow_pattern(mesh, inlet | outlet)
        pressure = steady_pressure(mesh, pattern, solver, floored, departure, departure)
        entering, leaving = _wall_rates(mesh, facet_flux(mesh, floored, pressure), inlet, outlet)
        if not _balanced(entering, leaving, balance_tolerance):
            entering, leaving = _refined_rates(
                mesh, pattern, solver, floored, pressure, inlet, outlet, balance_tolerance
            )
        if not _balanced(entering, leaving, balance_tolerance):
            log.warning(
                "axis %d at %.4g Pa: inlet and outlet rates %.4g and %.4g m3/s disagree "
                "even after extended-precision refinement; permeability set to NaN",
                axis, mean_pressure, entering, leaving,
            )
            return float("nan")
        area = mesh.volumes.sum() / length
        return viscosity * 0.5 * (entering + leaving) / (area * abs(gradient))
    if method == "velocity":
        dirichlet = boundary_cell_mask(mesh, list(WALLS))
        pattern = flow_pattern(mesh, dirichlet)
        pressure = steady_pressure(mesh, pattern, solver, floored, departure, departure)
        flux = facet_flux(mesh, floored, pressure)
        centre = 0.5 * (mesh.bounds[0] + mesh.bounds[1])
        half = 0.5 * inner_fraction * (mesh.bounds[1] - mesh.bounds[0])
        inner = np.all(np.abs(mesh.centroids - centre) <= half, axis=1) & ~dirichlet
        if not np.any(inner):
            raise ValueError("no free cell in the inner region: mesh too coarse")
        velocity = _mean_velocity(mesh, flux, inner)
        return viscosity * float(np.linalg.norm(velocity)) / abs(gradient)
    raise ValueError(f"method must be 'wall_flux' or 'velocity', got {method!r}")


def _refined_rates(
    mesh: Mesh,
    pattern: FlowPattern,
    solver: CholeskySolver,
    conductance: FloatArray,
    pressure: FloatArray,
    inlet: npt.NDArray[np.bool_],
    outlet: npt.NDArray[np.bool_],
    tolerance: float,
) -> tuple[float, float]:
    """Wall rates after mixed-precision iterative refinement of a steady solve.

    The residual and the fluxes in ``numpy.longdouble``, the correction from the
    solver's double-precision factor of the same matrix; stops once the rates balance
    to ``tolerance`` or after ``_REFINEMENTS`` sweeps.
    """
    matrix = assemble_matrix(mesh, pattern, conductance, np.zeros(mesh.n_cells))
    free = pattern.free_cells
    extended = pressure.astype(np.longdouble)
    entering = leaving = float("nan")
    inflow, _ = _extended_divergence(mesh, conductance, extended)
    for _ in range(_REFINEMENTS):
        correction = solver.solve(matrix, np.asarray(inflow[free], dtype=np.float64), ordered=True)
        extended[free] += correction.astype(np.longdouble)
        inflow, flux = _extended_divergence(mesh, conductance, extended)
        entering, leaving = _wall_rates(mesh, flux, inlet, outlet)
        if _balanced(entering, leaving, tolerance):
            break
    return entering, leaving


def permeability_tensor_axes(
    mesh: Mesh,
    saturation: FloatArray,
    porosity: FloatArray,
    suction: float,
    material: ClayParameters,
    *,
    conductances: Mapping[str, FloatArray] | None = None,
    method: Method = "wall_flux",
    drop_fraction: float = 0.1,
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

    Returns
    -------
    dict
        ``{phase: {axis: permeability [m2]}}`` for phases ``water``, ``gas`` and axes
        ``x``, ``y``, ``z``.
    """
    if not suction > 0.0:
        raise ValueError(f"suction must be > 0, got {suction}")
    given = {} if conductances is None else dict(conductances)
    result: dict[str, dict[str, float]] = {}
    # The velocity method imposes pressure on all walls: one pattern for every axis.
    for phase in PHASES:
        conductance = given.get(phase)
        if conductance is None:
            conductance = facet_conductance(mesh, saturation, porosity, phase, material)
        result[phase] = {
            name: measure_permeability(
                mesh,
                conductance,
                phase_viscosity(phase, material),
                axis,
                mean_pressure=-suction,
                pressure_drop=drop_fraction * suction,
                method=method,
            )
            for axis, name in enumerate(AXES)
        }
    return result
