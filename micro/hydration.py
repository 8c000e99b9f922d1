"""Coupled hydration of a compacted bentonite pellet (Caulk 2022, Chap. 3), quasi-statically.

The specimen is a cube of DEM points whose Delaunay tetrahedra are partially saturated
finite volumes. Boundary suction is lowered through a list of checkpoints; at each the
model advances in staggered steps until hydraulic balance: (1) one implicit flow step;
(2) point suction from the incident cells, swelling strain and radii
r = r0 (1 + eps_v)^(1/3); (3) hydro-mechanical forces (:mod:`micro.forces`) and DEM
relaxation to mechanical balance; (4) cell geometry and porosity from the moved points,
a conservative Delaunay remesh when a cell inverts; (5) the crack model. Flow time steps
grow geometrically from ``initial_time_step`` after each checkpoint. Yade instead lowers
the boundary suction by 10 Pa per 1e-9 s DEM step and stays far from balance
(docs/yade.md §10). The steps in full: docs/micro.md, "micro.hydration".
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from micro.cracks import (
    CrackNetwork,
    capillary_release_forces,
    centroid_distances,
    crack_conductivity,
    crack_network,
)
from micro.forces import hull_face_loads, hydromechanical_forces, membrane_forces, point_suction
from shared.delaunay import delaunay_tetrahedra, update_delaunay
from shared.dem.contacts import held_points
from shared.dem.integrator import limit_speed, stable_time_step, step, unbalanced_force
from shared.dem.parameters import DEMParameters
from shared.dem.state import DEMState
from shared.dem.walls import Walls
from shared.errors import DivergenceError
from shared.fv import (
    FlowPattern,
    facet_conductance,
    porosity_from_solid_volume,
    solver_pattern,
    transfer_cell_state,
    transient_step,
)
from shared.materials import ClayParameters
from shared.mesh import (
    WALLS,
    Mesh,
    boundary_cell_mask,
    cell_volumes,
    mesh_from_tetrahedra,
    update_mesh,
)
from shared.permeability import Phase
from shared.progress import ConvergenceProgress, PhaseClock
from shared.retention import saturation as retention_saturation
from shared.solver import AMG_UNKNOWNS, SolverError, SPDSolver
from shared.swelling import swollen_radius, volumetric_strain

__all__ = [
    "HydrationSettings",
    "PelletState",
    "DivergenceError",
    "BalanceProgress",
    "relax",
    "advance_to_balance",
]

FloatArray = npt.NDArray[np.float64]
log = logging.getLogger("micro.hydration")

# Strength threshold of the flow steps' multigrid coarsening: on their transient
# systems 0.75 builds a hierarchy in 40 % of the time that pyamg's 0.25 takes, for 20 %
# more iterations per solve; a remesh, hence a setup, comes with most flow steps
# (benchmarks/reference/README.md).
FLOW_AMG_STRENGTH = 0.75


@dataclass(frozen=True)
class HydrationSettings:
    """Numerical settings of the staggered scheme.

    Attributes
    ----------
    initial_time_step
        First flow time step after a change of boundary suction [s].
    time_step_growth
        Factor between consecutive flow time steps [1].
    max_flow_steps
        Flow steps allowed per checkpoint before giving up on balance [1].
    hydraulic_tolerance
        Balance when every cell's suction is within this fraction of the boundary's [1].
    unbalanced_force_tolerance
        Mechanical balance when the unbalanced-force ratio falls below this [1].
    max_relaxation_steps
        DEM steps allowed per relaxation [1].
    final_relaxations
        Further relaxations (each up to ``max_relaxation_steps``) allowed at hydraulic
        balance, under the last loads, while the unbalanced force is above tolerance [1].
    check_interval
        DEM steps between two evaluations of the unbalanced force [1].
    ramp_steps
        DEM steps over which a change of hydro-mechanical load is applied [1].
    damping
        Cundall damping of the relaxation [1]: only the balanced state matters, so it
        is higher than the 0.4 of the thesis's dynamic runs.
    max_step_fraction
        Largest displacement of a point per DEM step during relaxation, as a fraction of
        the smallest reference radius [1].
    porosity_bounds
        Porosity is clamped to this range (Yade's minPoroClamp, maxPoroClamp): the DEM
        does not know that the solid is incompressible [1].
    cracks
        Whether the crack model modifies conductances.
    solver
        Preconditioner of the flow solves, ``"auto"``, ``"direct"`` or ``"amg"``
        (:class:`shared.solver.SPDSolver`).
    amg_unknowns
        Unknowns from which ``solver="auto"`` uses multigrid [1].
    """

    initial_time_step: float
    time_step_growth: float
    max_flow_steps: int
    hydraulic_tolerance: float
    unbalanced_force_tolerance: float
    max_relaxation_steps: int
    final_relaxations: int
    check_interval: int
    ramp_steps: int
    damping: float
    max_step_fraction: float
    porosity_bounds: tuple[float, float]
    cracks: bool
    solver: str = "auto"
    amg_unknowns: int = AMG_UNKNOWNS


@dataclass
class PelletState:
    """Everything the coupled model advances (arrays per cell unless stated).

    Attributes
    ----------
    dem
        The point assembly (positions, radii, bonds, ...).
    mesh
        Current finite-volume mesh.
    pressure
        Water pressure [Pa] (negative: suction).
    saturation
        Water saturation [1].
    solid_volume
        Solid volume of each cell, conserved [m3].
    porosity
        Current porosity, 1 - solid_volume / volume [1].
    reference_extent
        Extent of the point cloud at set-up [m] (divergence check).
    walls
        Wall box (confined runs) or None (free swelling).
    time
        Simulated hydration time [s].
    n_remesh
        Number of Delaunay remeshes so far.
    """

    dem: DEMState
    mesh: Mesh
    pressure: FloatArray
    saturation: FloatArray
    solid_volume: FloatArray
    porosity: FloatArray
    reference_extent: FloatArray = field(default_factory=lambda: np.full(3, np.inf))
    walls: Walls | None = None
    time: float = 0.0
    n_remesh: int = 0
    cracks: CrackNetwork | None = field(default=None, repr=False)
    hydraulic_forces: FloatArray | None = field(default=None, repr=False)

    def water_volume(self) -> float:
        """Water volume sum n V S [m3]."""
        return float((self.porosity * self.mesh.volumes * self.saturation).sum())

    def mean_saturation(self) -> float:
        """Pore-volume weighted saturation [1]."""
        pores = self.porosity * self.mesh.volumes
        return float((pores * self.saturation).sum() / pores.sum())


def _check_finite(state: PelletState, where: str) -> None:
    for name in ("pressure", "saturation", "porosity"):
        values = getattr(state, name)
        if not np.all(np.isfinite(values)):
            raise DivergenceError(f"non-finite {name} after {where}")
    if not np.all(np.isfinite(state.dem.positions)):
        raise DivergenceError(f"non-finite point positions after {where}")


def loaded_time_step(
    state: DEMState, forces: FloatArray, parameters: DEMParameters
) -> float:
    """Stable time step of a contact carrying the largest point force [s].

    Hertz contacts have no stiffness at zero overlap, so the time step of an assembly
    whose bonds barely touch is unbounded until the load has compressed them; this
    bound uses the tangent stiffness k = 3/2 F / delta of a contact carrying the
    largest force F, delta = (F / (4/3 E* sqrt(R*)))^(2/3), R* = r / 2, for twelve
    such contacts on the lightest point.
    """
    largest = float(np.sqrt((forces**2).sum(axis=1)).max(initial=0.0))
    if largest == 0.0:
        return float("inf")
    radius = float(state.reference_radii.min())
    overlap = (largest / (4.0 / 3.0 * parameters.effective_modulus * np.sqrt(0.5 * radius))) ** (2 / 3)
    stiffness = 1.5 * largest / overlap
    mass = float(state.masses.min())
    return float(parameters.time_step_safety * 2.0 / np.sqrt(12.0 * stiffness / mass))


def _holding_pairs(dem: DEMState, normal_forces: FloatArray) -> npt.NDArray[np.int64]:
    """Point pairs held together: compressive contacts and intact bonds."""
    return np.vstack([dem.contacts.pairs[normal_forces > 0.0], dem.bonds[~dem.bond_broken]])


def _main_body(dem: DEMState, normal_forces: FloatArray) -> npt.NDArray[np.bool_]:
    """Points of the largest group held together by contacts and bonds."""
    pairs = _holding_pairs(dem, normal_forces)
    graph = sp.coo_matrix((np.ones(pairs.shape[0], dtype=np.int8), (pairs[:, 0], pairs[:, 1])),
                          shape=(dem.n_points, dem.n_points))
    _, labels = connected_components(graph, directed=False)
    return labels == np.argmax(np.bincount(labels))


def relax(
    dem: DEMState,
    walls: Walls | None,
    external_forces: FloatArray,
    settings: HydrationSettings,
    parameters: DEMParameters,
    previous_forces: FloatArray | None = None,
    target_radii: FloatArray | None = None,
) -> tuple[int, float]:
    """Run damped DEM steps until the unbalanced-force ratio is below tolerance.

    The external forces move from ``previous_forces`` to ``external_forces``, and the
    radii from their current values to ``target_radii``, over the first
    ``settings.ramp_steps`` steps: a swelling increment applied at once stores elastic
    energy that the explicit dynamics releases as a burst that can scatter the points.
    A point that has lost every contact and every intact bond, or whose group of
    points held together no longer touches the main body (the largest group), is a
    detached fragment: the pore-fluid and membrane loads, computed for the cells it
    closed at the start, no longer act on it (held, they would push it away without
    bound, even a hull point that still touches a neighbour but no longer the
    specimen), and it is stopped, since damping proportional to force does not slow a
    point that no force acts on. Single points are checked every ``check_interval``
    steps, groups every ten times that (a connected-components pass costs more than a
    DEM step). A relaxation longer than a minute (hundreds of thousands of points) logs
    its step, unbalanced-force ratio and ETA once a minute.

    Returns
    -------
    steps : int
        DEM steps taken.
    unbalanced : float
        Final unbalanced-force ratio [1].
    """
    start = external_forces if previous_forces is None else previous_forces
    first_radii = dem.radii.copy()
    final_radii = first_radii if target_radii is None else target_radii
    cap = loaded_time_step(dem, np.maximum(np.abs(external_forces), np.abs(start)), parameters)
    time_step = min(stable_time_step(dem, parameters, walls), cap)
    unbalanced = float("inf")
    attached: npt.NDArray[np.bool_] = np.ones(dem.n_points, dtype=bool)
    body = attached
    progress = ConvergenceProgress(settings.unbalanced_force_tolerance,
                                   "relaxation: unbalanced force ratio", log)
    load_change = external_forces - start
    growth = final_radii - first_radii
    load = np.empty_like(load_change)
    smallest = float(dem.reference_radii.min())
    attachment_changed = True
    for count in range(1, settings.max_relaxation_steps + 1):
        weight = min(count / settings.ramp_steps, 1.0)
        ramping = weight < 1.0 or count == settings.ramp_steps
        # the load changes only along the ramp and where points detach or reattach
        if ramping or attachment_changed:
            np.multiply(load_change, weight, out=load)
            load += start
            load[~attached] = 0.0
            attachment_changed = False
        if ramping:
            np.multiply(growth, weight, out=dem.radii)
            dem.radii += first_radii
        report = step(dem, time_step, parameters, load, walls, settings.damping)
        limit_speed(dem, settings.max_step_fraction * smallest / time_step)
        if count % settings.check_interval == 0:
            if count % (10 * settings.check_interval) == settings.check_interval:
                body = _main_body(dem, report.normal_forces)
            now_attached = held_points(dem, report.normal_forces) & body
            attachment_changed = not np.array_equal(now_attached, attached)
            attached = now_attached
            # Cundall damping acts on forces: a detached point would coast at its last
            # speed for ever and carry the specimen's extent away with it
            dem.velocities[~attached] = 0.0
            unbalanced = unbalanced_force(report.forces, report.normal_forces, dem.fixed)
            progress.update(count, unbalanced)
            if weight == 1.0 and unbalanced < settings.unbalanced_force_tolerance:
                return count, unbalanced
            time_step = min(stable_time_step(dem, parameters, walls), cap)
    return settings.max_relaxation_steps, unbalanced


def triangulate(
    positions: FloatArray, previous: Mesh | None = None, flat_ratio: float = 1e-9
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """Delaunay connectivity of the points without its flat tetrahedra.

    Faces of a loaded specimen flatten, and four nearly coplanar hull points give
    slivers of no volume (at most ``flat_ratio`` times the mean cell volume); they are
    dropped (their neighbours see a boundary there). With the ``previous`` mesh of the
    same points, the cells still Delaunay are kept and only the others retriangulated
    (:func:`shared.delaunay.update_delaunay`, the same cells as from scratch); from
    scratch (Qhull) when that cannot be certified.

    Returns
    -------
    tetrahedra, neighbours : ndarray of int64, shape (n_cells, 4)
        As :func:`shared.delaunay.delaunay_tetrahedra`, with -1 for no neighbour.
    """
    if previous is not None:
        repaired = update_delaunay(positions, previous.tetrahedra, previous.neighbours,
                                   flat_ratio * float(previous.volumes.mean()))
        if repaired is not None:
            return repaired
        log.debug("Delaunay repair not certified: full triangulation")
    _, tetrahedra, neighbours = delaunay_tetrahedra(positions)
    volumes = np.abs(cell_volumes(positions, tetrahedra))
    keep = volumes > flat_ratio * volumes.mean()
    renumber = np.full(tetrahedra.shape[0] + 1, -1, dtype=np.int64)
    renumber[:-1][keep] = np.arange(int(keep.sum()))
    return tetrahedra[keep], renumber[neighbours[keep]]


def update_geometry(
    state: PelletState,
    porosity_bounds: tuple[float, float],
    material: ClayParameters,
) -> bool:
    """Recompute cell geometry and porosity from the moved points; remesh if needed.

    With fixed connectivity the solid volume of each cell is conserved exactly (the
    porosity is clamped to ``porosity_bounds``). A cell that inverts triggers a
    Delaunay remesh (:func:`triangulate`); :func:`shared.fv.transfer_cell_state` carries porosity and
    saturation over (a cell the remesh kept keeps its own) and conserves the water
    volume, and the solid volumes are then scaled so that their total is conserved too:
    otherwise every remesh would reset the porosity that swelling has built up. The
    solid of inverted cells, counted twice where they overlap, cannot stay where it
    was: the scaling spreads it over the specimen.

    Returns
    -------
    bool
        Whether a full remesh happened (the flow pattern must then be rebuilt).
    """
    positions = state.dem.positions
    try:
        state.mesh = update_mesh(state.mesh, positions)
        state.porosity = porosity_from_solid_volume(
            state.solid_volume, state.mesh.volumes, *porosity_bounds
        )
        return False
    except ValueError:
        pass
    # the water of the moved cells, as the fixed-connectivity path would count it, so
    # that a remesh neither adds nor removes water of its own
    moved_volumes = np.abs(cell_volumes(positions, state.mesh.tetrahedra))
    moved_porosity = porosity_from_solid_volume(state.solid_volume, moved_volumes, *porosity_bounds)
    water = float((moved_porosity * moved_volumes * state.saturation).sum())
    new = mesh_from_tetrahedra(positions, *triangulate(positions, state.mesh))
    moved = transfer_cell_state(state.mesh, new, state.pressure, state.saturation,
                                state.porosity, material, conserve_water=False)
    state.mesh = new
    state.pressure = moved.pressure
    state.solid_volume = moved.solid_volume * (state.solid_volume.sum() / moved.solid_volume.sum())
    state.porosity = porosity_from_solid_volume(state.solid_volume, new.volumes, *porosity_bounds)
    pores = state.porosity * new.volumes
    defect = water - float((pores * moved.saturation).sum())
    state.saturation = np.clip(moved.saturation + defect / pores.sum(),
                               material.residual_saturation, material.saturated_saturation)
    state.n_remesh += 1
    return True


@dataclass
class FlowSystem:
    """Boundary cells, sparsity pattern and factor-reusing solver of the current mesh."""

    dirichlet: npt.NDArray[np.bool_]
    pattern: FlowPattern
    solver: SPDSolver

    @classmethod
    def for_mesh(
        cls, mesh: Mesh, dirichlet: npt.NDArray[np.bool_] | None = None,
        settings: HydrationSettings | None = None,
    ) -> FlowSystem:
        """All six walls impose the boundary suction (thesis Sec. 3.5.1).

        The boundary layer is found from the geometry at a (re)mesh and kept until the
        next one; pass the saved mask to rebuild the same system when resuming. The
        solver's preconditioner follows ``settings`` (default: ``"auto"``).
        """
        if dirichlet is None:
            dirichlet = boundary_cell_mask(mesh, WALLS)
        choice: dict[str, Any] = {} if settings is None else {"method": settings.solver,
                                              "amg_unknowns": settings.amg_unknowns}
        solver = SPDSolver(amg_strength=FLOW_AMG_STRENGTH, **choice)
        return cls(dirichlet, solver_pattern(mesh, dirichlet, solver), solver)


def conductances(
    state: PelletState, phase: Phase, material: ClayParameters, cracks: bool
) -> FloatArray:
    """Facet conductances of a phase, with the crack model's changes when enabled."""
    base = facet_conductance(state.mesh, state.saturation, state.porosity, phase, material)
    if not cracks or state.cracks is None or state.cracks.bonds.size == 0:
        return base
    lengths = centroid_distances(state.mesh.facet_cells, state.mesh.centroids)
    change = crack_conductivity(state.cracks, lengths, material)
    if phase == "water":
        return change.water_scale * base + change.water_added
    return change.gas_scale * base + change.gas_added


def update_cracks(state: PelletState, material: ClayParameters) -> None:
    """Find the open broken bonds on mesh edges and their imbibed or gas-filled state."""
    dem = state.dem
    state.cracks = crack_network(
        dem.bonds, dem.positions, dem.radii, state.mesh.facet_vertices,
        state.mesh.facet_cells, state.mesh.centroids, np.maximum(-state.pressure, 0.0),
        material, reference_overlaps=dem.bond_overlaps, reference_radii=dem.reference_radii,
        broken=dem.bond_broken,
    )


def swell(
    state: PelletState, material: ClayParameters, cracks: bool = False
) -> tuple[FloatArray, FloatArray]:
    """Swollen point radii from the suction of their cells, and the hydro-mechanical forces.

    The exterior chi p on each hull triangle is taken equal to that of the boundary
    cell it closes, so the facet forces carry only the jumps of S p between cells; the
    pull of the pore fluid on the hull (Yade's hull forces with air outside) is applied
    instead face by face, each face's resultant shared by its outer layer of points
    (:func:`micro.forces.hull_face_loads`, :func:`micro.forces.membrane_forces`). On a jittered cloud the hull
    has few large triangles, and hull forces would concentrate the whole face load on a
    handful of points; a uniform stress on every face would leave the specimen with a
    net force wherever S p varies over the hull, so that it never comes to rest. With
    ``cracks``, the capillary pull across the gas-filled cracks of ``state.cracks`` is
    removed (Eq. 3.35, :func:`micro.cracks.capillary_release_forces`).
    """
    mesh = state.mesh
    suction = point_suction(mesh.tetrahedra, mesh.volumes, np.maximum(-state.pressure, 0.0),
                            state.dem.n_points)
    radii = swollen_radius(state.dem.reference_radii, volumetric_strain(suction, material))
    bishop = state.saturation * state.pressure
    facets = hydromechanical_forces(mesh, state.dem.positions, radii, state.pressure,
                                    state.saturation, exterior_pressure=bishop[mesh.boundary_cells])
    layer = float(state.dem.reference_radii.mean())
    forces = facets + membrane_forces(state.dem.positions, hull_face_loads(mesh, bishop), layer)
    if cracks and state.cracks is not None:
        forces += capillary_release_forces(state.cracks, state.pressure, state.saturation,
                                           mesh.facet_cells, radii)
    return radii, forces


def _flow_step(
    state: PelletState,
    system: FlowSystem,
    boundary_suction: float,
    time_step: float,
    settings: HydrationSettings,
    material: ClayParameters,
) -> float:
    """One accepted implicit flow step, halving the time step while it overshoots.

    dS/dp is frozen at the start of a step, and it grows by orders of magnitude as
    suction falls: a long step then drives cells past the boundary suction, which the
    maximum principle forbids. Such a step is rejected and retried with half the time
    step.

    Returns
    -------
    float
        The time step taken [s].
    """
    _check_finite(state, "the last update")
    imposed = np.full(state.mesh.n_cells, -boundary_suction)
    state.saturation[system.dirichlet] = retention_saturation(
        boundary_suction, state.porosity[system.dirichlet], material
    )
    conductance = conductances(state, "water", material, settings.cracks)
    old_suction = -state.pressure
    slack = settings.hydraulic_tolerance * boundary_suction
    low = min(boundary_suction, float(old_suction.min())) - slack
    high = max(boundary_suction, float(old_suction.max())) + slack
    while time_step >= settings.initial_time_step * 1e-6:
        try:
            result = transient_step(state.mesh, system.pattern, system.solver, state.pressure,
                                    state.saturation, state.porosity, conductance, imposed,
                                    time_step, material)
        except SolverError as err:
            raise DivergenceError(f"flow solve failed at t = {state.time:.3g} s: {err}") from err
        new_suction = -result.pressure
        if not np.all(np.isfinite(new_suction)):
            raise DivergenceError(f"non-finite pressure at t = {state.time:.3g} s")
        if new_suction.min() >= low and new_suction.max() <= high:
            state.pressure, state.saturation = result.pressure, result.saturation
            state.time += time_step
            return time_step
        time_step *= 0.5
    raise DivergenceError(
        f"the flow step overshoots the boundary suction even at dt = {time_step:.3g} s "
        f"(t = {state.time:.3g} s)"
    )


@dataclass(frozen=True)
class BalanceProgress:
    """Where :func:`advance_to_balance` stands between two flow steps: enough, with the
    state and its flow system, to continue bit for bit after a restart.

    Attributes
    ----------
    flow_steps
        Flow steps done at this boundary suction [1].
    time_step
        Time step of the next flow step [s].
    dem_steps
        DEM steps done at this boundary suction [1].
    unbalanced, misfit
        Last unbalanced-force ratio and suction misfit [1].
    """

    flow_steps: int
    time_step: float
    dem_steps: int
    unbalanced: float
    misfit: float


def advance_to_balance(
    state: PelletState,
    system: FlowSystem,
    boundary_suction: float,
    settings: HydrationSettings,
    material: ClayParameters,
    parameters: DEMParameters,
    start: BalanceProgress | None = None,
    snapshot: Callable[[FlowSystem, BalanceProgress], None] | None = None,
    clock: PhaseClock | None = None,
) -> tuple[FlowSystem, dict[str, float]]:
    """Impose a boundary suction and advance the coupled model to hydraulic balance.

    At hydraulic balance, a last relaxation that ran out of steps is continued (at most
    ``settings.final_relaxations`` more) until the unbalanced force is below tolerance,
    so that the checkpoint is measured at mechanical balance too.

    ``start`` continues a balance interrupted after a flow step (its state and flow
    system as saved then); ``snapshot(system, progress)`` is called after every flow
    step that does not reach balance (the caller decides whether to save), and changes
    nothing. ``clock`` adds the wall time of the flow steps, swelling, relaxations,
    geometry updates, remeshes (the updates that remeshed, with the new flow system)
    and crack updates to its phases ``flow``, ``swelling``, ``relaxation``,
    ``geometry``, ``remesh`` and ``cracks``.

    Returns
    -------
    system : FlowSystem
        The flow system, rebuilt if the mesh was remeshed.
    diagnostics : dict
        ``flow_steps``, ``dem_steps``, ``unbalanced_force``, ``suction_misfit`` (largest
        relative departure of a cell's suction from the boundary's), ``balanced`` (1 if
        both hydraulic and mechanical balance were reached, else 0).

    Raises
    ------
    DivergenceError
        If the pressure or the points become non-finite, or the specimen flies apart
        (its extent more than doubles).
    """
    if start is None:
        # a fresh factor at each checkpoint makes a run resumed from its checkpoint file
        # follow the same arithmetic as an uninterrupted one
        system.solver.reset()
        start = BalanceProgress(0, settings.initial_time_step, 0, float("nan"), float("inf"))
    time_step, dem_steps = start.time_step, start.dem_steps
    unbalanced, misfit = start.unbalanced, start.misfit
    flow_steps = start.flow_steps
    clock = PhaseClock() if clock is None else clock
    for flow_steps in range(start.flow_steps + 1, settings.max_flow_steps + 1):
        with clock.phase("flow"):
            time_step = _flow_step(state, system, boundary_suction, time_step, settings,
                                   material)
        with clock.phase("swelling"):
            radii, forces = swell(state, material, settings.cracks)
        with clock.phase("relaxation"):
            taken, unbalanced = relax(state.dem, state.walls, forces, settings, parameters,
                                      state.hydraulic_forces, radii)
        state.hydraulic_forces = forces
        dem_steps += taken
        system = _settle_geometry(state, system, settings, material, clock)
        misfit = float(np.abs(-state.pressure / boundary_suction - 1.0).max())
        if misfit < settings.hydraulic_tolerance:
            break
        time_step *= settings.time_step_growth
        if snapshot is not None:
            snapshot(system, BalanceProgress(flow_steps, time_step, dem_steps, unbalanced,
                                             misfit))
    hydraulic = misfit < settings.hydraulic_tolerance
    # optionally relax on under the last loads if the last relaxation ran out of steps
    for _ in range(settings.final_relaxations if hydraulic else 0):
        if unbalanced < settings.unbalanced_force_tolerance:
            break
        assert state.hydraulic_forces is not None  # the flow steps computed them
        with clock.phase("relaxation"):
            taken, unbalanced = relax(state.dem, state.walls, state.hydraulic_forces,
                                      settings, parameters)
        dem_steps += taken
        system = _settle_geometry(state, system, settings, material, clock)
    mechanical = unbalanced < settings.unbalanced_force_tolerance
    return system, {
        "flow_steps": float(flow_steps),
        "dem_steps": float(dem_steps),
        "unbalanced_force": unbalanced,
        "suction_misfit": misfit,
        "balanced": float(hydraulic and mechanical),
    }


def _settle_geometry(
    state: PelletState, system: FlowSystem, settings: HydrationSettings,
    material: ClayParameters, clock: PhaseClock,
) -> FlowSystem:
    """After a relaxation: check the points, update geometry and cracks; the flow system
    (rebuilt after a remesh). The update counts to ``clock``'s phase ``remesh`` if it
    remeshed, else to ``geometry``."""
    _check_finite(state, "mechanical relaxation")
    extent = np.ptp(state.dem.positions, axis=0)
    if np.any(extent > 2.0 * state.reference_extent):
        raise DivergenceError(
            f"the specimen flies apart (extent {extent.max():.3g} m) at t = {state.time:.3g} s"
        )
    start = time.perf_counter()
    remeshed = update_geometry(state, settings.porosity_bounds, material)
    if remeshed:
        system = FlowSystem.for_mesh(state.mesh, settings=settings)
    clock.add("remesh" if remeshed else "geometry", time.perf_counter() - start)
    with clock.phase("cracks"):
        update_cracks(state, material)
    return system
