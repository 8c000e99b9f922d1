"""Saturated poroelastic coupling of DEM points and their Delaunay finite volumes (DEM-PFV).

Verification setup of ``test_terzaghi.py`` (Terzaghi consolidation, docs/design.md §5.1):
no stage runs it, so it lives beside its test, not in :mod:`micro`. The scheme of
Catalano, Chareyre & Barthelemy (2014) for an incompressible fluid and solid: in every
free cell i, sum_j g_ij (p_i - p_j) = -dV_i/dt; drained cells hold p_D. The fluid force
on the points is B^T (p - p_D), B = dV/dx, with equal vertex shares (the pressure work).
Each DEM step is a pressure projection, (L_ff + dt B_f M^-1 B_f^T) (p - p_D) =
-(B_f v* + owed / dt), factorised once; small strains (g and B of the mesh the coupling
was built on); with rigid walls the fluid fills the gap to the walls (``enclosed``).
Derivations: docs/validation.md, "tests.micro.terzaghi_setup".

Reference: Catalano, E., Chareyre, B., Barthelemy, E. (2014). Int. J. Numer. Anal.
Methods Geomech. 38, 51-71. doi:10.1002/nag.2198
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from shared.dem.contacts import update_contacts
from shared.dem.hertz import contact_forces
from shared.dem.integrator import StepReport, integrate
from shared.dem.parameters import DEMParameters
from shared.dem.state import DEMState
from shared.dem.walls import Walls, servo_walls, wall_forces
from shared.fv import FlowPattern, assemble_matrix, flow_pattern
from shared.mesh import Mesh, build_mesh
from shared.solver import SPDSolver

__all__ = ["SaturatedFlow", "drained_cells", "saturated_flow", "volume_gradient", "coupled_steps"]

FloatArray = npt.NDArray[np.float64]


@dataclass
class SaturatedFlow:
    """Pore fluid of a saturated DEM assembly, advanced by :func:`coupled_steps`.

    Attributes
    ----------
    mesh
        Delaunay mesh of the points when the coupling was built (the reference
        geometry).
    pattern
        Free and drained (Dirichlet) cells.
    solver
        CHOLMOD solver of the projection system (factorised once).
    conductance
        (n_facets,) facet conductances k A / (mu l) [m3/(Pa s)].
    laplacian
        Lower triangle of L_ff (free cells, CSC) [m3/(Pa s)]: outflow of each free
        cell per excess pressure.
    system
        Lower triangle of L_ff + dt B_f M^-1 B_f^T (CSC) [m3/(Pa s)].
    gradient
        B = dV/dx at the reference geometry, shape (n_cells, 3 n_points) [m2].
    time_step
        DEM time step the system was built for [s].
    enclosed
        Whether fixed rigid walls close the fluid domain (see :func:`saturated_flow`).
    drained_pressure
        Pressure of the drained cells (and outside the hull unless enclosed) [Pa].
    pressure
        (n_cells,) pore pressure of the last step [Pa].
    volumes
        (n_cells,) small-strain cell volumes V_0 + B (x - x_0) [m3].
    owed
        (n_cells,) accumulated actual minus balanced volume change [m3] (the last
        step's Cundall damping mismatch).
    drained_volume
        Fluid volume that has flowed from the free cells into the drained cells [m3].
    time
        Time covered by coupled steps [s].
    """

    mesh: Mesh
    pattern: FlowPattern
    solver: SPDSolver
    conductance: FloatArray
    laplacian: sp.csc_matrix
    system: sp.csc_matrix
    gradient: sp.csr_matrix
    time_step: float
    enclosed: bool
    drained_pressure: float
    pressure: FloatArray
    volumes: FloatArray
    owed: FloatArray
    drained_volume: float = 0.0
    time: float = 0.0

    def free_volume(self) -> float:
        """Volume of the free cells [m3]; the solid is incompressible, so its change is
        the change of their pore volume."""
        return float(self.volumes[self.pattern.free_cells].sum())

    def mean_excess_pressure(self) -> float:
        """Volume-weighted mean of p - p_D over the free cells [Pa]."""
        free = self.pattern.free_cells
        excess = self.pressure[free] - self.drained_pressure
        return float((excess * self.volumes[free]).sum() / self.volumes[free].sum())


def volume_gradient(points: npt.ArrayLike, tetrahedra: npt.ArrayLike) -> sp.csr_matrix:
    """Derivatives of the cell volumes with respect to the point coordinates.

    Parameters
    ----------
    points
        (n_points, 3) vertex coordinates [m].
    tetrahedra
        (n_cells, 4) positively oriented cells.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n_cells, 3 n_points)
        B[i, 3 k + d] = dV_i / dx_k,d [m2]: a third of the area vector of the face
        opposite vertex k, pointing towards k.
    """
    points = np.asarray(points, dtype=np.float64)
    tetrahedra = np.asarray(tetrahedra, dtype=np.int64)
    n_cells = tetrahedra.shape[0]
    values = np.empty((n_cells, 4, 3))
    for local in range(4):
        a, b, c = (tetrahedra[:, (local + offset) % 4] for offset in (1, 2, 3))
        area = 0.5 * np.cross(points[b] - points[a], points[c] - points[a])
        towards = np.einsum("ij,ij->i", area, points[tetrahedra[:, local]] - points[a])
        values[:, local] = np.sign(towards)[:, None] * area / 3.0
    columns = 3 * tetrahedra[:, :, None] + np.arange(3)
    rows = np.repeat(np.arange(n_cells), 12)
    return sp.csr_matrix(
        (values.ravel(), (rows, columns.ravel())), shape=(n_cells, 3 * points.shape[0])
    )


def _hull_gradient(mesh: Mesh, n_points: int) -> sp.csr_matrix:
    """Part of :func:`volume_gradient` due to the hull triangles, same shape.

    Vertex k of a cell's face f gets A_f n_f / 3 (outward normal) from that face; the
    hull faces' share is what a rigid wall beyond the hull takes over.
    """
    n_boundary = mesh.boundary_cells.shape[0]
    values = np.repeat(mesh.boundary_areas[:, None] * mesh.boundary_normals / 3.0, 3, axis=0)
    rows = np.repeat(mesh.boundary_cells, 9)
    columns = 3 * mesh.boundary_vertices[:, :, None] + np.arange(3)
    return sp.csr_matrix(
        (values.reshape(n_boundary, 3, 3).ravel(), (rows, columns.ravel())),
        shape=(mesh.n_cells, 3 * n_points),
    )


def drained_cells(mesh: Mesh, drained_points: npt.ArrayLike) -> npt.NDArray[np.bool_]:
    """Cells with a vertex among the drained points: those resting on the drain."""
    return np.any(np.asarray(drained_points, dtype=bool)[mesh.tetrahedra], axis=1)


def saturated_flow(
    state: DEMState,
    drained_points: npt.ArrayLike,
    permeability: float,
    viscosity: float,
    time_step: float,
    *,
    drained_pressure: float = 0.0,
    enclosed: bool = True,
    solver: SPDSolver | None = None,
) -> SaturatedFlow:
    """Mesh the points and set up the coupling, fluid at the drained pressure.

    Parameters
    ----------
    state
        Assembly (positions and masses; fixed points get no velocity).
    drained_points
        (n_points,) bool: the points at the drain (e.g. the top layer of a column);
        the cells with a vertex among them are drained, the other faces impervious.
    permeability
        Intrinsic permeability k of the medium [m2].
    viscosity
        Dynamic viscosity mu of the fluid [Pa s].
    time_step
        DEM time step of the coupled steps [s].
    drained_pressure
        Pressure of the drained cells (and outside the hull unless enclosed) [Pa].
    enclosed
        True if fixed rigid walls close the fluid domain (see the module docstring):
        the hull triangles then drop out of B. False for a specimen surrounded by
        fluid at the drained pressure.
    solver
        Solver to use; a new :class:`SPDSolver` if None.

    Returns
    -------
    SaturatedFlow
        With the pressure equal to ``drained_pressure`` everywhere.
    """
    if not (permeability > 0.0 and viscosity > 0.0 and time_step > 0.0):
        raise ValueError("permeability, viscosity and time_step must be > 0")
    mesh = build_mesh(state.positions)
    drained = drained_cells(mesh, drained_points)
    if not np.any(drained) or np.all(drained):
        raise ValueError("the drained points must touch some but not all cells")
    pattern = flow_pattern(mesh, drained)
    conductance = permeability * mesh.facet_areas / (viscosity * mesh.facet_lengths)
    laplacian = assemble_matrix(mesh, pattern, conductance, np.zeros(mesh.n_cells))
    gradient = volume_gradient(mesh.points, mesh.tetrahedra)
    if enclosed:
        gradient = (gradient - _hull_gradient(mesh, state.n_points)).tocsr()
    free_gradient = gradient[pattern.free_cells]
    mobility = np.where(state.fixed, 0.0, 1.0 / state.masses)
    # volume change per pressure within one step through the point masses
    inertia = time_step * free_gradient @ sp.diags(np.repeat(mobility, 3)) @ free_gradient.T
    system = sp.tril(laplacian + sp.tril(inertia, format="csc"), format="csc")
    system.sort_indices()
    return SaturatedFlow(
        mesh=mesh,
        pattern=pattern,
        solver=SPDSolver() if solver is None else solver,
        conductance=conductance,
        laplacian=laplacian,
        system=system,
        gradient=gradient,
        time_step=float(time_step),
        enclosed=enclosed,
        drained_pressure=float(drained_pressure),
        pressure=np.full(mesh.n_cells, float(drained_pressure)),
        volumes=mesh.volumes.copy(),
        owed=np.zeros(mesh.n_cells),
    )


def _symmetric_product(lower: sp.csc_matrix, vector: FloatArray) -> FloatArray:
    """Product of the symmetric matrix given by its lower triangle with a vector."""
    return lower @ vector + lower.T @ vector - lower.diagonal() * vector


def coupled_steps(
    state: DEMState,
    flow: SaturatedFlow,
    n_steps: int,
    parameters: DEMParameters,
    walls: Walls | None = None,
    external_forces: FloatArray | None = None,
) -> StepReport:
    """Advance the DEM by ``n_steps`` steps of ``flow.time_step``, each with its pressure.

    Parameters
    ----------
    state
        Assembly, advanced in place.
    flow
        The coupling, advanced in place.
    n_steps
        Number of DEM steps, >= 1.
    parameters
        DEM parameters (Cundall damping included); keep ``flow.time_step`` below
        :func:`shared.dem.stable_time_step`.
    walls
        Wall box, or None; fixed (no servo) if the coupling is enclosed, since the
        fluid volume between hull and walls is taken as constant.
    external_forces
        (n_points, 3) other forces, e.g. a load [N], or None.

    Returns
    -------
    StepReport
        Of the last step; its forces include the fluid forces.
    """
    if n_steps < 1:
        raise ValueError(f"n_steps must be >= 1, got {n_steps}")
    if flow.enclosed and walls is not None and walls.servo and np.any(walls.active):
        raise ValueError("an enclosed coupling needs fixed walls: set walls.servo = False")
    dt = flow.time_step
    free = flow.pattern.free_cells
    free_gradient = flow.gradient[free]
    for _ in range(n_steps):
        # contact, wall and external forces as in shared.dem.step; the fluid force
        # joins them before the leapfrog, since it answers this step's velocities
        rebuilt = update_contacts(state, parameters)
        forces = np.zeros((state.n_points, 3))
        if external_forces is not None:
            forces += external_forces
        forces, torques, normal_forces = contact_forces(state, dt, parameters, forces)
        loads = None if walls is None else wall_forces(state, walls, forces, parameters)
        predicted = state.velocities + dt * forces / state.masses[:, None]
        predicted[state.fixed] = 0.0
        excess = flow.solver.solve(
            flow.system, -(free_gradient @ predicted.ravel() + flow.owed[free] / dt)
        )
        flow.pressure[free] = flow.drained_pressure + excess
        forces += (free_gradient.T @ excess).reshape(-1, 3)
        before = state.positions.copy()
        integrate(state, forces, torques, dt, parameters.damping)
        if walls is not None and loads is not None:
            servo_walls(walls, loads, dt, parameters)
        change = flow.gradient @ (state.positions - before).ravel()
        outflow = dt * _symmetric_product(flow.laplacian, excess)
        flow.owed[free] += change[free] + outflow
        flow.volumes += change
        flow.drained_volume += float(outflow.sum())
        flow.time += dt
    return StepReport(forces, torques, normal_forces, loads, rebuilt)
