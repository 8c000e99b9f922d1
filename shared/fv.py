"""Partially saturated finite volumes on a tetrahedral mesh: conductances and systems.

docs/design.md §3. Per free cell i, implicit in the water pressure p:

    n_i V_i (dS/dp)_i (p_i - p_i^old) / dt = sum_j g_ij (p_j - p_i),

with g_ij = k_M(phi_ij) k_r(S_ij) A_ij / (mu l_ij), phi_ij and S_ij the arithmetic means
of the two cells' porosities and saturations. Dirichlet cells are eliminated and the
system is solved for the increment delta = p - p* (p* the old pressures with the imposed
values), (C + L_ff) delta_f = sum_j g_ij (p*_j - p*_i), C = diag(n V dS/dp / dt), SPD
when every connected set of free cells has storage or touches a Dirichlet cell.
Saturation follows explicitly, S += dS/dp delta (thesis Eq. 3.19), clamped to
[S_r, S_s]. :class:`FlowPattern` holds the sparsity and assembly positions, computed
once per mesh and Dirichlet set. Details: docs/micro.md, "shared.fv".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from numba import njit
from scipy.spatial import cKDTree

from shared.delaunay import same_cells
from shared.materials import ClayParameters
from shared.mesh import Mesh
from shared.ordering import locality_order, nested_dissection
from shared.permeability import (
    Phase,
    intrinsic_permeability,
    phase_viscosity,
    relative_permeability,
)
from shared.retention import saturation as retention_saturation
from shared.retention import saturation_derivative
from shared.solver import SPDSolver

__all__ = [
    "FlowPattern",
    "StepResult",
    "facet_conductance",
    "flow_pattern",
    "solver_pattern",
    "assemble_matrix",
    "facet_divergence",
    "transient_step",
    "steady_pressure",
    "facet_flux",
    "water_volume",
    "porosity_from_solid_volume",
    "TransferredState",
    "transfer_cell_state",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def _require_cell_arrays(mesh: Mesh, **arrays: FloatArray) -> None:
    for name, array in arrays.items():
        if np.shape(array) != (mesh.n_cells,):
            raise ValueError(f"{name} must have shape ({mesh.n_cells},), got {np.shape(array)}")
        if not np.all(np.isfinite(array)):
            raise ValueError(f"{name} contains NaN or inf")


@dataclass(frozen=True)
class FlowPattern:
    """Sparsity and scatter positions of the free-free system for one mesh.

    Attributes
    ----------
    dirichlet : ndarray of bool, shape (n_cells,)
        Cells holding an imposed pressure.
    free_cells : ndarray of int64, shape (n_free,)
        Global indices of the unknowns, in matrix order.
    free_index : ndarray of int64, shape (n_cells,)
        Matrix row of each cell, -1 for Dirichlet cells.
    indptr, indices : ndarray of int32
        CSC structure of the lower triangle (sorted, diagonal first in each column).
    diagonal_position : ndarray of int64, shape (n_free,)
        Data position of each diagonal entry.
    facet_position : ndarray of int64, shape (n_facets,)
        Data position of each facet's off-diagonal entry, -1 unless both cells are free.
    fill_reducing : bool
        The unknowns are in a fill-reducing order (nested dissection) that a factor can
        use as it is; else in a locality order, for multigrid (a factor orders itself).
    """

    dirichlet: npt.NDArray[np.bool_]
    free_cells: IntArray
    free_index: IntArray
    indptr: npt.NDArray[np.int32]
    indices: npt.NDArray[np.int32]
    diagonal_position: IntArray
    facet_position: IntArray
    fill_reducing: bool = True

    @property
    def n_free(self) -> int:
        """Number of unknowns."""
        return int(self.free_cells.shape[0])


@njit(cache=True)
def _lower_pattern(
    free_index: IntArray, facet_cells: IntArray, n_free: int
) -> tuple[IntArray, npt.NDArray[np.int32], IntArray]:
    """CSC lower-triangle structure (diagonal first, rows sorted) and facet positions."""
    indptr = np.ones(n_free + 1, dtype=np.int64)
    indptr[0] = 0
    for f in range(facet_cells.shape[0]):
        a, b = free_index[facet_cells[f, 0]], free_index[facet_cells[f, 1]]
        if a >= 0 and b >= 0:
            indptr[min(a, b) + 1] += 1
    for k in range(n_free):
        indptr[k + 1] += indptr[k]
    indices = np.empty(indptr[n_free], dtype=np.int32)
    slot_facet = np.empty(indptr[n_free], dtype=np.int64)
    fill = indptr[:-1] + 1
    for k in range(n_free):
        indices[indptr[k]] = k
    for f in range(facet_cells.shape[0]):
        a, b = free_index[facet_cells[f, 0]], free_index[facet_cells[f, 1]]
        if a >= 0 and b >= 0:
            column = min(a, b)
            indices[fill[column]] = max(a, b)
            slot_facet[fill[column]] = f
            fill[column] += 1
    facet_position = np.full(facet_cells.shape[0], -1, dtype=np.int64)
    for column in range(n_free):
        # Insertion sort of the few off-diagonal rows of the column.
        for p in range(indptr[column] + 2, indptr[column + 1]):
            row, facet, q = indices[p], slot_facet[p], p
            while q > indptr[column] + 1 and indices[q - 1] > row:
                indices[q], slot_facet[q] = indices[q - 1], slot_facet[q - 1]
                q -= 1
            indices[q], slot_facet[q] = row, facet
        for p in range(indptr[column] + 1, indptr[column + 1]):
            facet_position[slot_facet[p]] = p
    return indptr, indices, facet_position


def flow_pattern(mesh: Mesh, dirichlet: npt.ArrayLike, fill_reducing: bool = True) -> FlowPattern:
    """Build the system's sparsity pattern for a mesh and a set of Dirichlet cells.

    The unknowns are numbered in a fill-reducing order of the free cells' centroids
    (:func:`shared.ordering.nested_dissection`), so that the solver needs no ordering of
    its own (:meth:`shared.solver.SPDSolver.solve` with ``ordered=True``), or, for a
    system that multigrid will solve, along a space-filling curve
    (:func:`shared.ordering.locality_order`).

    Parameters
    ----------
    mesh
        The mesh.
    dirichlet
        Boolean mask, shape (n_cells,): cells with an imposed pressure.
    fill_reducing
        Nested dissection (True) or the locality order (False).

    Returns
    -------
    FlowPattern
    """
    dirichlet = np.asarray(dirichlet, dtype=bool)
    if dirichlet.shape != (mesh.n_cells,):
        raise ValueError(f"dirichlet mask must have shape ({mesh.n_cells},)")
    free = np.flatnonzero(~dirichlet).astype(np.int64)
    n_free = free.shape[0]
    local = np.full(mesh.n_cells, -1, dtype=np.int64)
    local[free] = np.arange(n_free, dtype=np.int64)
    if fill_reducing:
        ends = local[mesh.facet_cells]
        free_cells = free[nested_dissection(mesh.centroids[free], ends[np.all(ends >= 0, axis=1)])]
    else:
        free_cells = free[locality_order(mesh.centroids[free])]
    free_index = np.full(mesh.n_cells, -1, dtype=np.int64)
    free_index[free_cells] = np.arange(n_free, dtype=np.int64)
    indptr, indices, facet_position = _lower_pattern(free_index, mesh.facet_cells, n_free)
    return FlowPattern(
        dirichlet=dirichlet,
        free_cells=free_cells,
        free_index=free_index,
        indptr=indptr.astype(np.int32),
        indices=indices,
        diagonal_position=indptr[:-1].copy(),
        facet_position=facet_position,
        fill_reducing=fill_reducing,
    )


def facet_conductance(
    mesh: Mesh,
    saturation: FloatArray,
    porosity: FloatArray,
    phase: Phase,
    material: ClayParameters,
) -> FloatArray:
    """Darcy conductance of each internal facet, g_ij = k_M k_r A_ij / (mu l_ij).

    Parameters
    ----------
    mesh
        The mesh.
    saturation
        Water saturation per cell [1], shape (n_cells,).
    porosity
        Porosity per cell [1], shape (n_cells,).
    phase
        ``"water"`` (k_r from Se, water viscosity) or ``"gas"`` (1 - Se, gas viscosity).
    material
        Clay parameters.

    Returns
    -------
    ndarray, shape (n_facets,)
        Conductance [m3/(Pa s)] (flux per pressure difference).
    """
    _require_cell_arrays(mesh, saturation=saturation, porosity=porosity)
    i, j = mesh.facet_cells[:, 0], mesh.facet_cells[:, 1]
    mean_saturation = 0.5 * (saturation[i] + saturation[j])
    mean_porosity = 0.5 * (porosity[i] + porosity[j])
    permeability = intrinsic_permeability(mean_porosity, material) * relative_permeability(
        mean_saturation, phase, material
    )
    return permeability * mesh.facet_areas / (phase_viscosity(phase, material) * mesh.facet_lengths)


@njit(cache=True)
def _assemble_lower(
    facet_cells: IntArray,
    conductance: FloatArray,
    free_index: IntArray,
    diagonal_position: IntArray,
    facet_position: IntArray,
    storage_free: FloatArray,
    n_data: int,
) -> FloatArray:
    data = np.zeros(n_data)
    for k in range(storage_free.shape[0]):
        data[diagonal_position[k]] = storage_free[k]
    for f in range(facet_cells.shape[0]):
        g = conductance[f]
        a = free_index[facet_cells[f, 0]]
        b = free_index[facet_cells[f, 1]]
        if a >= 0:
            data[diagonal_position[a]] += g
        if b >= 0:
            data[diagonal_position[b]] += g
        if facet_position[f] >= 0:
            data[facet_position[f]] -= g
    return data


def assemble_matrix(
    mesh: Mesh, pattern: FlowPattern, conductance: FloatArray, storage: FloatArray
) -> sp.csc_matrix:
    """Lower triangle of C + L_ff in CSC, on the pattern's fixed sparsity.

    Parameters
    ----------
    mesh
        The mesh.
    pattern
        Pattern from :func:`flow_pattern`.
    conductance
        Facet conductances [m3/(Pa s)], shape (n_facets,).
    storage
        Storage coefficients n V dS/dp / dt per cell [m3/(Pa s)], shape (n_cells,)
        (zeros for a steady problem).

    Returns
    -------
    scipy.sparse.csc_matrix, shape (n_free, n_free)
        Lower triangle (with diagonal) of the symmetric positive semi-definite matrix.
    """
    data = _assemble_lower(
        mesh.facet_cells,
        np.ascontiguousarray(conductance, dtype=np.float64),
        pattern.free_index,
        pattern.diagonal_position,
        pattern.facet_position,
        np.ascontiguousarray(storage[pattern.free_cells], dtype=np.float64),
        pattern.indices.shape[0],
    )
    n = pattern.n_free
    return sp.csc_matrix((data, pattern.indices, pattern.indptr), shape=(n, n))


@njit(cache=True)
def _divergence(facet_cells: IntArray, conductance: FloatArray, pressure: FloatArray) -> FloatArray:
    result = np.zeros(pressure.shape[0])
    for f in range(facet_cells.shape[0]):
        i = facet_cells[f, 0]
        j = facet_cells[f, 1]
        flux = conductance[f] * (pressure[j] - pressure[i])
        result[i] += flux
        result[j] -= flux
    return result


def facet_divergence(mesh: Mesh, conductance: FloatArray, pressure: FloatArray) -> FloatArray:
    """Net inflow of each cell, sum_j g_ij (p_j - p_i) [m3/s], shape (n_cells,)."""
    return _divergence(
        mesh.facet_cells,
        np.ascontiguousarray(conductance, dtype=np.float64),
        np.ascontiguousarray(pressure, dtype=np.float64),
    )


def facet_flux(mesh: Mesh, conductance: FloatArray, pressure: npt.NDArray[np.floating]) -> npt.NDArray[np.floating]:
    """Flux from cell i to cell j of each facet, g_ij (p_i - p_j) [m3/s], shape (n_facets,)."""
    i, j = mesh.facet_cells[:, 0], mesh.facet_cells[:, 1]
    return conductance * (pressure[i] - pressure[j])


def _solve_increment(
    mesh: Mesh,
    pattern: FlowPattern,
    solver: SPDSolver,
    conductance: FloatArray,
    storage: FloatArray,
    pressure: FloatArray,
    imposed_pressure: FloatArray,
    force_refactor: bool,
    judge_whole: bool,
) -> FloatArray:
    """Pressure after solving for its increment from ``pressure``.

    ``judge_whole``: the solver's tolerance applies to the system of the whole pressure
    (a time step, whose increment is small next to the pressure); otherwise to the
    increment's own (a steady solve from a guess: the flux a permeability measurement
    takes is made of the departure from the guessed linear profile, so that departure
    is what must be accurate).
    """
    if np.shape(imposed_pressure) != (mesh.n_cells,):
        raise ValueError(f"imposed_pressure must have shape ({mesh.n_cells},)")
    start = np.array(pressure, dtype=np.float64)
    start[pattern.dirichlet] = imposed_pressure[pattern.dirichlet]
    if not np.all(np.isfinite(start)):
        raise ValueError("pressure or imposed pressure on Dirichlet cells is not finite")
    rhs = facet_divergence(mesh, conductance, start)[pattern.free_cells]
    matrix = assemble_matrix(mesh, pattern, conductance, storage)
    increment = solver.solve(
        matrix, rhs, force_refactor=force_refactor, ordered=pattern.fill_reducing,
        offset=start[pattern.free_cells] if judge_whole else None,
    )
    start[pattern.free_cells] += increment
    return start


@dataclass(frozen=True)
class StepResult:
    """Outcome of one transient flow step.

    Attributes
    ----------
    pressure : ndarray, shape (n_cells,)
        New water pressure [Pa] (imposed values on Dirichlet cells).
    saturation : ndarray, shape (n_cells,)
        New water saturation [1].
    boundary_inflow : float
        Water volume rate from Dirichlet cells into free cells at the new pressure
        [m3/s]; dt times it is the volume the boundary supplied.
    clamped_volume : float
        Water volume added (> 0) or removed by clamping S to [S_r, S_s] in free cells
        [m3]; zero when the step conserved mass exactly.
    """

    pressure: FloatArray
    saturation: FloatArray
    boundary_inflow: float
    clamped_volume: float


def transient_step(
    mesh: Mesh,
    pattern: FlowPattern,
    solver: SPDSolver,
    pressure: FloatArray,
    saturation: FloatArray,
    porosity: FloatArray,
    conductance: FloatArray,
    imposed_pressure: FloatArray,
    time_step: float,
    material: ClayParameters,
    *,
    force_refactor: bool = False,
) -> StepResult:
    """Advance pressure implicitly and saturation explicitly by one time step.

    dS/dp is evaluated once, at the start-of-step pressure (as Yade does), for the
    storage term. Free-cell saturation is then advanced incrementally (Eq. 3.19), not
    reset to the retention curve, by dt times the cell's net inflow at the new pressure
    (n V dS/dp dp for an exact solve): the water volume change of the free cells equals
    dt times the boundary inflow (plus any clamp) to round-off, whatever the solver's
    residual. Dirichlet cells take S(imposed suction).

    Parameters
    ----------
    mesh, pattern, solver
        Mesh, its :class:`FlowPattern` and the factor-reusing solver.
    pressure
        Water pressure per cell at the start of the step [Pa].
    saturation
        Water saturation per cell at the start of the step [1].
    porosity
        Porosity per cell (frozen during the step) [1].
    conductance
        Facet conductances [m3/(Pa s)] (from :func:`facet_conductance`, possibly
        modified by the crack model).
    imposed_pressure
        Pressure per cell [Pa]; read on Dirichlet cells only.
    time_step
        dt [s].
    material
        Clay parameters.
    force_refactor
        Refactor the matrix even if the coefficients did not drift (e.g. after remesh).

    Returns
    -------
    StepResult
    """
    if not time_step > 0.0:
        raise ValueError(f"time_step must be > 0, got {time_step}")
    _require_cell_arrays(mesh, pressure=pressure, saturation=saturation, porosity=porosity)
    if np.shape(conductance) != (mesh.n_facets,):
        raise ValueError(f"conductance must have shape ({mesh.n_facets},)")
    derivative = saturation_derivative(-pressure, porosity, material)
    storage = porosity * mesh.volumes * derivative / time_step
    new_pressure = _solve_increment(
        mesh, pattern, solver, conductance, storage, pressure, imposed_pressure, force_refactor,
        judge_whole=True,
    )
    free = pattern.free_cells
    dirichlet = pattern.dirichlet
    pore = porosity[free] * mesh.volumes[free]
    inflow = facet_divergence(mesh, conductance, new_pressure)
    # the water of a free cell changes by dt times its net inflow, not by dS/dp dp:
    # equal for an exact solve, but the fluxes cancel pair by pair whatever the
    # solver's residual, which with crack conductances 1e10 times the clay's is not
    # small next to the clay's storage
    raw = saturation[free] + time_step * inflow[free] / pore
    clipped = np.clip(raw, material.residual_saturation, material.saturated_saturation)
    new_saturation = np.array(saturation, dtype=np.float64)
    new_saturation[free] = clipped
    new_saturation[dirichlet] = retention_saturation(
        -imposed_pressure[dirichlet], porosity[dirichlet], material
    )
    return StepResult(
        pressure=new_pressure,
        saturation=new_saturation,
        boundary_inflow=float(-inflow[dirichlet].sum()),
        clamped_volume=float(np.sum(pore * (clipped - raw))),
    )


def solver_pattern(mesh: Mesh, dirichlet: npt.ArrayLike, solver: SPDSolver) -> FlowPattern:
    """:func:`flow_pattern` ordered for the path ``solver`` takes on it: fill-reducing
    for a factor, by locality for multigrid (a factor that takes over orders itself)."""
    dirichlet = np.asarray(dirichlet, dtype=bool)
    return flow_pattern(mesh, dirichlet, not solver.uses_multigrid(int((~dirichlet).sum())))


def steady_pressure(
    mesh: Mesh,
    pattern: FlowPattern,
    solver: SPDSolver,
    conductance: FloatArray,
    imposed_pressure: FloatArray,
    initial_pressure: FloatArray | None = None,
) -> FloatArray:
    """Steady pressure field sum_j g_ij (p_j - p_i) = 0 in free cells.

    Parameters
    ----------
    mesh, pattern, solver
        Mesh, pattern (with at least one Dirichlet cell per connected component of
        positive conductance) and solver.
    conductance
        Facet conductances [m3/(Pa s)].
    imposed_pressure
        Pressure per cell [Pa]; read on Dirichlet cells only.
    initial_pressure
        Starting pressure [Pa] (only improves round-off); defaults to zero.

    Returns
    -------
    ndarray, shape (n_cells,)
        Pressure [Pa].
    """
    start = np.zeros(mesh.n_cells) if initial_pressure is None else initial_pressure
    return _solve_increment(
        mesh, pattern, solver, conductance, np.zeros(mesh.n_cells), start, imposed_pressure, False,
        judge_whole=False,
    )


def water_volume(
    mesh: Mesh,
    porosity: FloatArray,
    saturation: FloatArray,
    cells: npt.NDArray[np.integer] | npt.NDArray[np.bool_] | None = None,
) -> float:
    """Water volume sum n_i V_i S_i [m3] (times the water density gives the mass).

    Parameters
    ----------
    mesh
        The mesh.
    porosity, saturation
        Per-cell porosity and saturation [1].
    cells
        Optional index or mask of the cells to sum (default: all).
    """
    content = porosity * mesh.volumes * saturation
    return float(np.sum(content if cells is None else content[cells]))


def porosity_from_solid_volume(
    solid_volume: FloatArray,
    volumes: FloatArray,
    minimum: float = 0.0,
    maximum: float = 1.0,
) -> FloatArray:
    """Porosity phi = 1 - V_s / V (thesis Eqs. 3.24-3.25), clipped to [minimum, maximum].

    Parameters
    ----------
    solid_volume
        Solid volume per cell V_s = (1 - phi_0) V_0, fixed between remeshes [m3].
    volumes
        Current cell volumes V [m3].
    minimum, maximum
        Clip bounds [1] (Yade's minPoroClamp / maxPoroClamp: 0.1 and 0.8 in the
        thesis script).

    Returns
    -------
    ndarray
        Porosity [1].
    """
    return np.clip(1.0 - solid_volume / volumes, minimum, maximum)


@dataclass(frozen=True)
class TransferredState:
    """Cell state carried from an old mesh to a new one (see :func:`transfer_cell_state`).

    Attributes
    ----------
    pressure, saturation, porosity, solid_volume : ndarray, shape (n_new_cells,)
        Water pressure [Pa], saturation [1], porosity [1], solid volume
        (1 - phi) V [m3] on the new mesh.
    water_defect : float
        Water volume of the old mesh minus that of the transferred state before the
        correction [m3].
    """

    pressure: FloatArray
    saturation: FloatArray
    porosity: FloatArray
    solid_volume: FloatArray
    water_defect: float


def transfer_cell_state(
    old_mesh: Mesh,
    new_mesh: Mesh,
    pressure: FloatArray,
    saturation: FloatArray,
    porosity: FloatArray,
    material: ClayParameters,
    *,
    conserve_water: bool = True,
) -> TransferredState:
    """Carry the cell state across a remesh (docs/yade.md §§8.3 and 8.4).

    A remesh of moved points keeps most cells: a new cell with the same four vertices
    as an old one keeps that cell's state (its material moved with its vertices); the
    others fill the region that the removed old cells leave, and each takes the state
    of the removed cell whose centroid, at the moved positions, is nearest. The solid
    volume is recomputed from that porosity and the new volume, so porosity does not
    jump. The water volume sum n V S generally changes; with ``conserve_water`` the
    defect is spread as a uniform saturation shift over the cells, clipped to
    [S_r, S_s] (a clip leaves part of the defect, visible by comparing volumes).

    Parameters
    ----------
    old_mesh, new_mesh
        Meshes of the same points before and after the remesh (``new_mesh.points`` are
        the moved positions).
    pressure, saturation, porosity
        Old state per old cell: water pressure [Pa], saturation [1], porosity [1].
    material
        Clay parameters (S_r, S_s).
    conserve_water
        Restore the old total water volume by a uniform saturation shift.

    Returns
    -------
    TransferredState
    """
    if old_mesh.points.shape != new_mesh.points.shape:
        raise ValueError("the meshes must be of the same points: "
                         f"{old_mesh.points.shape} and {new_mesh.points.shape}")
    nearest = same_cells(old_mesh.tetrahedra, new_mesh.tetrahedra, new_mesh.points.shape[0])
    others = np.flatnonzero(nearest < 0)
    if others.size:
        # the new cells fill the region the removed ones leave: take their state
        removed = np.ones(old_mesh.n_cells, dtype=bool)
        removed[nearest[nearest >= 0]] = False
        candidates = np.flatnonzero(removed)
        if candidates.size == 0:  # new cells where there were none (dropped flat ones)
            candidates = np.arange(old_mesh.n_cells)
        moved = new_mesh.points[old_mesh.tetrahedra[candidates]].mean(axis=1)
        nearest[others] = candidates[cKDTree(moved).query(new_mesh.centroids[others])[1]]
    new_porosity = porosity[nearest]
    new_saturation = saturation[nearest]
    pore = new_porosity * new_mesh.volumes
    defect = water_volume(old_mesh, porosity, saturation) - float(np.sum(pore * new_saturation))
    if conserve_water:
        new_saturation = np.clip(
            new_saturation + defect / pore.sum(),
            material.residual_saturation,
            material.saturated_saturation,
        )
    return TransferredState(
        pressure=pressure[nearest],
        saturation=new_saturation,
        porosity=new_porosity,
        solid_volume=(1.0 - new_porosity) * new_mesh.volumes,
        water_defect=defect,
    )
