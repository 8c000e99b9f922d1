"""Saturated poroelastic coupling of DEM points and their Delaunay finite volumes (DEM-PFV).

The scheme of Catalano, Chareyre & Barthelemy (2014) for an incompressible pore fluid
and an incompressible solid: the fluid a tetrahedron expels is its volume decrease, so
in every free cell i

    sum_j g_ij (p_i - p_j) = -dV_i/dt,

a steady Darcy problem with the volume rates as sources, implicit in p; the pressures
then push on the points (:func:`micro.forces.hydromechanical_forces` with S = 1).
Drained cells (Dirichlet) hold the drainage pressure p_D; a saturated medium has no
retention storage, so this volume balance is what delays the settlement (Terzaghi
consolidation, REFERENCE_NOTES section 9).

Time discretisation (staggered): the DEM runs ``steps_per_solve`` steps with the
pressure forces held, then dV/dt comes from the volume change of every cell over those
steps (moved points, fixed connectivity) and the pressure is solved. The volume rates
are exact differences, so the fluid that leaves the free cells equals their volume
loss to the solver tolerance over any number of steps (the differences telescope).

Stability: the pressure answers the velocities of the previous interval and acts as a
Darcy drag. For a compression mode of any wavelength the drag is -(mu / k) v per unit
volume, i.e. c = mu V_p / k on a point with volume share V_p; applied explicitly over an
interval dt it scales the velocity by 1 - c dt / m per interval: stable for
c dt / m < 2, without overshoot below 1 (:func:`drag_time_step`).

Small strains: the conductances g_ij = k A_ij / (mu l_ij) are those of the mesh the
coupling was built on, so the matrix and its CHOLMOD factor stay constant. To follow
large deformations, assign new ``conductance`` values (e.g. from a refreshed mesh): the
solver then reuses its factor while the coefficients drift less than its tolerance.

References
----------
Catalano, E., Chareyre, B., Barthelemy, E. (2014). Pore-scale modeling of fluid-particles
interaction and emerging poromechanical effects. Int. J. Numer. Anal. Methods Geomech.
38, 51-71. doi:10.1002/nag.2198
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from micro.forces import SectorWeights, hydromechanical_forces, sector_weights
from shared.dem.integrator import StepReport, step
from shared.dem.parameters import DEFAULT_DEM, DEMParameters
from shared.dem.state import DEMState
from shared.dem.walls import Walls
from shared.fv import FlowPattern, facet_divergence, flow_pattern, steady_pressure
from shared.mesh import Mesh, boundary_cell_mask, build_mesh, cell_volumes
from shared.solver import CholeskySolver

__all__ = [
    "SaturatedFlow",
    "saturated_flow",
    "fluid_forces",
    "update_pressure",
    "drag_time_step",
    "coupled_steps",
]

FloatArray = npt.NDArray[np.float64]


@dataclass
class SaturatedFlow:
    """Pore fluid of a saturated DEM assembly, advanced by :func:`update_pressure`.

    Attributes
    ----------
    mesh
        Delaunay mesh of the points when the coupling was built: connectivity, facet
        conductance geometry and the orientation of the force triangles.
    pattern
        Sparsity of the free-cell system; Dirichlet cells are the drained ones.
    solver
        CHOLMOD solver; keeps its factor while the conductances do not drift.
    conductance
        (n_facets,) facet conductances k A / (mu l) [m3/(Pa s)].
    mobility
        k / mu of the medium [m2/(Pa s)] (drag estimate of :func:`drag_time_step`).
    drained_pressure
        Pressure of the drained cells and of the medium outside the hull [Pa].
    pressure
        (n_cells,) pore pressure [Pa].
    volumes
        (n_cells,) cell volumes at the last pressure solve [m3].
    weights
        Vertex shares of the triangles' forces (kept: the triangles barely change).
    drained_volume
        Fluid volume that has flowed from the free cells into the drained cells since
        the coupling was built [m3].
    time
        Time covered by the pressure solves [s].
    """

    mesh: Mesh
    pattern: FlowPattern
    solver: CholeskySolver
    conductance: FloatArray
    mobility: float
    drained_pressure: float
    pressure: FloatArray
    volumes: FloatArray
    weights: SectorWeights
    drained_volume: float = 0.0
    time: float = 0.0

    def free_volume(self) -> float:
        """Volume of the free (undrained) cells at the last solve [m3].

        The solid is incompressible, so its change is the change of their pore volume.
        """
        return float(self.volumes[self.pattern.free_cells].sum())

    def mean_excess_pressure(self) -> float:
        """Volume-weighted mean of p - p_D over the free cells [Pa]."""
        free = self.pattern.free_cells
        excess = self.pressure[free] - self.drained_pressure
        return float((excess * self.volumes[free]).sum() / self.volumes[free].sum())


def saturated_flow(
    positions: npt.ArrayLike,
    radii: npt.ArrayLike,
    drained_walls: Sequence[str],
    permeability: float,
    viscosity: float,
    *,
    drained_pressure: float = 0.0,
    solver: CholeskySolver | None = None,
) -> SaturatedFlow:
    """Mesh the points and set up the saturated coupling, fluid at the drained pressure.

    Parameters
    ----------
    positions
        (n_points, 3) point centres [m].
    radii
        (n_points,) interaction radii [m] (vertex shares of the fluid forces).
    drained_walls
        Walls (names of :data:`shared.mesh.WALLS`) whose boundary layer of cells
        (:func:`shared.mesh.boundary_cell_mask`) is drained; the other faces are
        impervious.
    permeability
        Intrinsic permeability k of the medium [m2].
    viscosity
        Dynamic viscosity mu of the fluid [Pa s].
    drained_pressure
        Pressure of the drained cells and outside the hull [Pa].
    solver
        Solver to use; a new :class:`CholeskySolver` if None.

    Returns
    -------
    SaturatedFlow
        With the pressure equal to ``drained_pressure`` everywhere.
    """
    if not (permeability > 0.0 and viscosity > 0.0):
        raise ValueError("permeability and viscosity must be > 0")
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    mesh = build_mesh(positions)
    drained = boundary_cell_mask(mesh, list(drained_walls))
    if not np.any(drained) or np.all(drained):
        raise ValueError("the drained walls must hold some but not all cells")
    return SaturatedFlow(
        mesh=mesh,
        pattern=flow_pattern(mesh, drained),
        solver=CholeskySolver() if solver is None else solver,
        conductance=permeability * mesh.facet_areas / (viscosity * mesh.facet_lengths),
        mobility=permeability / viscosity,
        drained_pressure=float(drained_pressure),
        pressure=np.full(mesh.n_cells, float(drained_pressure)),
        volumes=mesh.volumes.copy(),
        weights=sector_weights(mesh, positions, radii),
    )


def fluid_forces(flow: SaturatedFlow, state: DEMState) -> FloatArray:
    """Force of the excess pore pressure on each point [N], shape (n_points, 3).

    The drained pressure also acts outside the hull, so only p - p_D loads the
    skeleton, as in a cell with a back-pressure.
    """
    return hydromechanical_forces(
        flow.mesh, state.positions, state.radii, flow.pressure, np.ones(flow.mesh.n_cells),
        exterior_pressure=flow.drained_pressure, weights=flow.weights,
    )


def update_pressure(flow: SaturatedFlow, positions: npt.ArrayLike, elapsed: float) -> float:
    """Solve the pressure for the volume change since the last solve (in place).

    Parameters
    ----------
    flow
        The coupling; ``pressure``, ``volumes``, ``drained_volume`` and ``time`` are
        updated.
    positions
        (n_points, 3) current point centres [m].
    elapsed
        Time since the last solve [s], > 0.

    Returns
    -------
    float
        Volume rate from the free into the drained cells [m3/s].

    Raises
    ------
    ValueError
        If a cell has inverted (remesh, or smaller steps).
    """
    if not elapsed > 0.0:
        raise ValueError(f"elapsed must be > 0, got {elapsed}")
    volumes = cell_volumes(positions, flow.mesh.tetrahedra)
    if np.any(volumes <= -1.0):
        raise ValueError(f"{int(np.sum(volumes <= 0.0))} cells inverted: remesh")
    imposed = np.full(flow.mesh.n_cells, flow.drained_pressure)
    flow.pressure = steady_pressure(
        flow.mesh, flow.pattern, flow.solver, flow.conductance, imposed,
        initial_pressure=flow.pressure, source=-(volumes - flow.volumes) / elapsed,
    )
    inflow = facet_divergence(flow.mesh, flow.conductance, flow.pressure)
    rate = float(inflow[flow.pattern.dirichlet].sum())
    flow.volumes = volumes
    flow.drained_volume += rate * elapsed
    flow.time += elapsed
    return rate


def drag_time_step(flow: SaturatedFlow, state: DEMState, safety: float = 0.5) -> float:
    """Largest interval between pressure solves for which the drag does not overshoot [s].

    Parameters
    ----------
    flow
        The coupling (mesh volumes, mobility k / mu).
    state
        Assembly (point masses).
    safety
        Fraction of the overshoot limit m / c [1]; 2 is the stability limit.

    Returns
    -------
    float
        safety min_p m_p k / (mu V_p) [s], V_p a quarter of the volume of the cells
        around point p.
    """
    n_points = state.n_points
    share = np.bincount(
        flow.mesh.tetrahedra.ravel(), np.repeat(0.25 * flow.volumes, 4), minlength=n_points
    )
    meshed = share > 0.0
    return float(safety * np.min(state.masses[meshed] * flow.mobility / share[meshed]))


def coupled_steps(
    state: DEMState,
    flow: SaturatedFlow,
    time_step: float,
    n_steps: int,
    parameters: DEMParameters = DEFAULT_DEM,
    walls: Walls | None = None,
    external_forces: FloatArray | None = None,
    steps_per_solve: int = 1,
) -> StepReport:
    """Advance the DEM by ``n_steps`` steps, solving the pressure every few steps.

    Parameters
    ----------
    state
        Assembly, advanced in place.
    flow
        The coupling, advanced in place.
    time_step
        DEM time step [s]; keep it below :func:`shared.dem.stable_time_step` and
        ``steps_per_solve`` times it below :func:`drag_time_step`.
    n_steps
        Number of DEM steps, >= 1.
    parameters
        DEM parameters (damping included).
    walls
        Wall box, or None.
    external_forces
        (n_points, 3) other forces, e.g. a load [N], or None.
    steps_per_solve
        DEM steps with the same pressure forces between two pressure solves, >= 1.

    Returns
    -------
    StepReport
        Of the last DEM step.
    """
    if n_steps < 1 or steps_per_solve < 1:
        raise ValueError("n_steps and steps_per_solve must be >= 1")
    for start in range(0, n_steps, steps_per_solve):
        forces = fluid_forces(flow, state)
        if external_forces is not None:
            forces += external_forces
        count = min(steps_per_solve, n_steps - start)
        for _ in range(count):
            report = step(state, time_step, parameters, forces, walls)
        update_pressure(flow, state.positions, count * time_step)
    return report
