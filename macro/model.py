"""The coupled pellet-powder model: state, one time step, and the wall readings.

One step (Fig. 4.8): geometry of the cells for the current pellets (Delaunay mesh of the
pellet centres and of fixed points on the container, :func:`macro.mixture.container_points`; fixed
connectivity, :func:`macro.mixture.moved_mesh`; a new mesh when an active cell inverts), conductances, the stable time step
(Eq. 4.58), the explicit mass update (Eq. 4.23), the local pressure-volume problems
(Sec. 4.3), pellet radii r = (3 V / 4 pi)^(1/3) and moduli E(s) (Eqs. 4.3, 4.27-4.30),
the powder's swelling pressure and its forces on the pellets (Eqs. 4.31-4.38), and
quasi-static DEM substeps (Hertz between pellets and against the container).

The quasi-static DEM uses a fictitious mass per pellet equal to its contact stiffness
(time unit 1), so every substep is stable whatever the moduli (density scaling, as
the thesis's script scales the density by 1e10); it is a relaxation, not dynamics.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

from macro import _kernels
from macro.field import cell_porosity
from macro.laws import (
    MixtureParameters,
    confined_volume,
    consolidation_pressure,
    powder_permeability,
    saturation,
    suction_derivative,
    swelling_pressure,
    swelling_strain,
    yield_force,
    yield_pressure,
    young_modulus,
)
from macro.mixture import (
    Exchanges,
    cell_voids,
    container_points,
    end_cells,
    exchanges,
    facet_angles,
    mesh_edges,
    moved_mesh,
    solid_angles,
)
from macro.newton import NewtonSettings, PVProblem, solve_pressure_volume
from macro.packing import Packing
from macro.sensors import WallBands, equal_bands, named_sensors
from macro.transport import (
    conductances, harmonic_mean, implicit_pressures, limited_rates, mass_rates, stable_time_step,
)
from shared.dem import detect_contacts
from shared.mesh import Mesh, build_mesh, mesh_from_tetrahedra
from shared.upscaling import PermeabilityTable

__all__ = ["MacroSettings", "MacroModel", "macro_settings", "mixture_fractions", "Readings"]

FloatArray = npt.NDArray[np.float64]

VOID_FLOOR = 1e-3
"""Smallest cell void, fraction of the tetrahedron (the script's minVoidVolume ratio is 1e-4)."""
_REMESH_WEIGHTS = 0.05 + 0.8 * np.array(
    [(i, j, k, 3 - i - j - k) for i in range(4) for j in range(4 - i) for k in range(4 - i - j)]) / 3.0
"""Barycentric weights of the 20 points (a lattice of the tetrahedron, shrunk towards its
centroid) that carry equal shares of an old cell's powder in a remesh."""
PICARD_ITERATIONS = 3
"""Modified Picard iterations of an implicit step."""
IMPLICIT_LOSS = 0.99
"""Largest fraction of its water a system may lose in one implicit step (positivity)."""
POWDER_REFRESH = 50
"""DEM substeps between two updates of the powder's push to the pellets' positions."""
MAX_OVERLAP_LOSS = 0.3
"""Largest fraction of a pellet's sphere that its overlaps may cut off."""
MIN_AREA_FRACTION = 1e-2
"""Smallest powder path through a cell-cell triangle covered by pellets, fraction of it."""


@dataclass(frozen=True)
class MacroSettings:
    """The macro section of one case (see workflow/schemas/config.schema.yaml, ``macro``)."""

    height: float
    radius: float
    pellet_radius: float
    pellet_radius_spread: float
    packing_fraction: float
    dry_density: float
    pellet_porosity: float
    powder: Mapping[str, Any]
    table_condition: str
    pellet_permeability: str
    boundary_suction: float
    max_suction: float
    density: float
    viscosity: float
    conductivity_factor: float
    powder_pressure: bool
    retention_follows_porosity: bool
    powder_on_walls: bool
    sensors: WallBands
    bands: WallBands
    vtk_snapshots: int
    column_permeability_times: tuple[float, ...]
    seed: int
    chi: float
    max_saturation_change: float
    transport_scheme: str
    max_time_step: float
    max_time: float
    max_steps: int
    records: int
    snapshot_interval: float
    stop_window: float
    stop_tolerance: float
    stop_pressure_tolerance: float
    stop_after: float
    newton: NewtonSettings
    packing_sweeps: int
    min_cell_void_fraction: float
    container_spacing: float
    dem_substeps: int
    dem_damping: float
    dem_balance_tolerance: float
    stress_relaxation: float


def macro_settings(macro: Mapping[str, Any], case: str) -> MacroSettings:
    """Settings of one case: the ``macro`` section with ``macro.cases[case]`` applied.

    Raises
    ------
    KeyError
        Naming ``macro.cases`` when the case is not declared.
    ValueError
        Naming ``macro.sensors.<name>`` when a sensor's band reaches outside the container.
    """
    if case not in macro["cases"]:
        raise KeyError(f"macro.cases has no case {case!r} (has {sorted(macro['cases'])})")
    over = macro["cases"][case]
    num = macro["numerics"]
    powder = dict(macro["powder"])
    if "heterogeneity" in over:
        powder["heterogeneity"] = over["heterogeneity"]
    mixture = {**macro["mixture"], **over.get("mixture", {})}
    fraction, dry_density = mixture_fractions(mixture, float(macro["pellet_porosity"]),
                                              float(powder["grain_density_kg_m3"]))
    return MacroSettings(
        height=float(macro["cylinder_height_m"]),
        radius=float(macro["cylinder_radius_m"]),
        pellet_radius=float(over.get("pellet_radius_m", macro["pellet_radius_m"])),
        pellet_radius_spread=float(over.get("pellet_radius_spread", macro["pellet_radius_spread"])),
        packing_fraction=fraction,
        dry_density=dry_density,
        pellet_porosity=float(macro["pellet_porosity"]),
        powder=powder,
        table_condition=str(over.get("table_condition", macro["table_condition"])),
        pellet_permeability=str(over.get("pellet_permeability", macro["pellet_permeability"])),
        boundary_suction=float(macro["boundary_suction_pa"]),
        max_suction=float(macro["max_suction_pa"]),
        density=float(macro["water_density_kg_m3"]),
        viscosity=float(macro["water_viscosity_pa_s"]),
        conductivity_factor=float(over.get("conductivity_factor", macro["conductivity_factor"])),
        retention_follows_porosity=bool(macro["retention_follows_porosity"]),
        powder_pressure=bool(over.get("powder_swelling_pressure", macro["powder_swelling_pressure"])),
        powder_on_walls=bool(over.get("powder_pressure_on_walls", macro["powder_pressure_on_walls"])),
        sensors=named_sensors(macro["sensors"], float(macro["cylinder_height_m"])),
        bands=equal_bands(int(macro["sensor_bands"]), float(macro["cylinder_height_m"])),
        vtk_snapshots=int(macro["vtk_snapshots"]),
        column_permeability_times=tuple(sorted(float(t) for t in macro["column_permeability_times_s"])),
        seed=int(over.get("seed", macro["seed"])),
        chi=float(num["stability_factor"]),
        max_saturation_change=float(num["max_saturation_change"]),
        transport_scheme=str(num["transport_scheme"]),
        max_time_step=float(num["max_time_step_s"]),
        max_time=float(num["max_time_s"]),
        max_steps=int(num["max_steps"]),
        records=int(num["records"]),
        snapshot_interval=float(num["snapshot_interval_s"]),
        stop_window=float(num["stop_window_fraction"]),
        stop_tolerance=float(num["stop_tolerance"]),
        stop_pressure_tolerance=float(num["stop_pressure_tolerance"]),
        stop_after=float(num["stop_after_s"]),
        newton=NewtonSettings(
            tolerance=float(num["newton_tolerance"]),
            max_iterations=int(num["newton_max_iterations"]),
            barrier_start=float(num["newton_barrier_start"]),
            barrier_decay=float(num["newton_barrier_decay"]),
            relaxation_start=float(num["newton_relaxation_start"]),
            derivative_step=float(num["newton_derivative_step"]),
        ),
        packing_sweeps=int(num["packing_iterations"]),
        min_cell_void_fraction=float(num["min_cell_void_fraction"]),
        container_spacing=float(num["container_point_spacing"]),
        dem_substeps=int(num["dem_substeps"]),
        dem_damping=float(num["dem_damping"]),
        dem_balance_tolerance=float(num["dem_balance_tolerance"]),
        stress_relaxation=float(num["stress_relaxation"]),
    )


def mixture_fractions(mixture: Mapping[str, Any], pellet_porosity: float,
                      grain_density: float) -> tuple[float, float]:
    """Pellet packing fraction [1] and the mixture's dry density [kg/m3] from the
    validated ``macro.mixture`` section.

    The dry density is the target; the pellets' share of the dry mass is set by the
    pellet/powder dry-mass ratio when given (pellet fraction
    rho_d ratio / ((1 + ratio) rho_d,pellet)), else by ``packing_fraction``; the powder
    holds the rest of the dry mass.

    Raises
    ------
    ValueError
        Naming ``macro.mixture`` when the pellets alone are denser than the target or
        the fraction cannot be packed.
    """
    dry_density = float(mixture["dry_density_kg_m3"])
    pellet_density = grain_density * (1.0 - pellet_porosity)
    ratio = mixture.get("pellet_powder_dry_mass_ratio")
    if ratio is None:
        fraction = float(mixture["packing_fraction"])
    else:
        fraction = dry_density * float(ratio) / ((1.0 + float(ratio)) * pellet_density)
    if not 0.0 < fraction <= 0.6:
        raise ValueError(
            f"macro.mixture: a pellet packing fraction of {fraction:.3g} (dry density "
            f"{dry_density:g} kg/m3, pellet/powder dry-mass ratio {ratio}, pellet dry density "
            f"{pellet_density:.4g} kg/m3) cannot be packed at random (at most 0.6)")
    if fraction * pellet_density > dry_density:
        raise ValueError(
            f"macro.mixture: the pellets alone (packing fraction {fraction:.3g}, dry density "
            f"{pellet_density:.4g} kg/m3) are denser than macro.mixture.dry_density_kg_m3 = "
            f"{dry_density:g}")
    return fraction, dry_density


@dataclass
class Readings:
    """Wall readings of one instant: pressures of the named sensors (sensors,) and of the
    equal height bands (bands,) [Pa], axial pressures on the upper and lower plates [Pa],
    unbalanced force ratio [1]."""

    sensors: FloatArray
    bands: FloatArray
    axial_upper: float
    axial_lower: float
    unbalanced: float


@dataclass
class MacroModel:
    """State of the mixture; :meth:`step` advances it.

    Systems 0..n_p-1 are pellets, n_p..n_p+n_c-1 cells. Arrays over systems: water mass
    [kg], volume V [m3], pressure p [Pa], solid volume V_s [m3], reference volume V_0
    [m3], largest volume V_max [m3], held (Dirichlet end cells). The mesh's vertices are
    the pellet centres, then the fixed ``container`` points (``on_plate`` over all
    vertices: the container points on the plates).
    """

    settings: MacroSettings
    material: MixtureParameters
    table: PermeabilityTable
    mesh: Mesh
    positions: FloatArray
    velocities: FloatArray
    radii: FloatArray
    water_mass: FloatArray
    volume: FloatArray
    pressure: FloatArray
    solid_volume: FloatArray
    reference_volume: FloatArray
    max_volume: FloatArray
    held: npt.NDArray[np.bool_]
    inert: npt.NDArray[np.bool_]
    initial_void: FloatArray
    container: FloatArray
    on_plate: npt.NDArray[np.bool_]
    time: float = 0.0
    steps: int = 0
    boundary_inflow: float = 0.0
    fallbacks: int = 0
    remeshes: int = 0
    floored_cells: int = 0
    newton_iterations: int = 0
    dem_substeps_used: int = 0
    limited_systems: int = 0
    phase_seconds: dict[str, float] = field(default_factory=lambda: {
        "remesh": 0.0, "transport": 0.0, "newton": 0.0, "dem": 0.0})
    _omega: FloatArray | None = None
    _exchanges: Exchanges | None = None
    _cell_pressure: FloatArray | None = None
    _readings: Readings | None = None
    _next_dt: float = 0.0
    spins: FloatArray | None = None
    _contact_pairs: npt.NDArray[np.int64] | None = None
    _shear: FloatArray | None = None
    _plastic: FloatArray | None = None
    _wall_plastic: FloatArray | None = None
    _void: FloatArray | None = None
    _edges: npt.NDArray[np.int64] | None = None
    _edges_of: npt.NDArray[np.int64] | None = None
    pellet_frames: FloatArray | None = None
    stress: FloatArray | None = None
    powder_porosity: float = 0.0
    initial_interior_water: float = 0.0
    _occupied_loss: FloatArray | None = None

    @property
    def n_pellets(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_cells(self) -> int:
        return self.mesh.n_cells

    @property
    def n_vertices(self) -> int:
        """Mesh vertices: the pellets, then the container's points."""
        return self.n_pellets + int(self.container.shape[0])

    def vertex_positions(self) -> FloatArray:
        """(n_p + n_w, 3) the mesh's vertices now: pellet centres, container points [m]."""
        return np.concatenate([self.positions, self.container])

    def vertex_radii(self) -> FloatArray:
        """(n_p + n_w,) pellet radii, 0 on the container [m]."""
        return np.concatenate([self.radii, np.zeros(self.container.shape[0])])

    def clay_radii(self) -> FloatArray:
        """(n_p + n_w,) radii of spheres of the pellets' clay volumes, 0 on the container [m]:
        a cell's void is its tetrahedron less the pellets' clay volumes shared by solid
        angle, so that the voids and the pellets fill the container whatever the
        spheres' overlaps."""
        return np.concatenate([np.cbrt(3.0 * self.volume[:self.n_pellets] / (4.0 * np.pi)),
                               np.zeros(self.container.shape[0])])

    # ------------------------------------------------------------------ set-up
    @classmethod
    def create(cls, settings: MacroSettings, material: MixtureParameters,
               table: PermeabilityTable, packing: Packing) -> MacroModel:
        """Initial state on a packing: everything at the initial suction except the end
        cells, held at the boundary suction."""
        rng = np.random.default_rng(settings.seed + 1)
        spacing = 2.0 * settings.container_spacing * float(packing.radii.mean())
        container, on_plate = container_points(settings.height, settings.radius, spacing,
                                               np.random.default_rng(settings.seed + 3))
        mesh = build_mesh(np.concatenate([packing.positions, container]))
        n_p, n_c = packing.radii.size, mesh.n_cells
        on_plate = np.concatenate([np.zeros(n_p, dtype=np.bool_), on_plate])
        vertex_radii = np.concatenate([packing.radii, np.zeros(container.shape[0])])
        omega = solid_angles(mesh.points, mesh.tetrahedra)
        voids = cell_voids(mesh, vertex_radii, omega, VOID_FLOOR)
        n_cell = cell_porosity(mesh.centroids, settings.powder, rng, settings.seed)
        inert, held = _cell_roles(mesh, voids, on_plate, n_p, settings)
        pellet_v0 = 4.0 / 3.0 * np.pi * packing.radii**3
        pellet_dry_mass = material.grain_density * (1.0 - settings.pellet_porosity) * pellet_v0.sum()
        container_volume = np.pi * settings.radius**2 * settings.height
        powder_v0 = (1.0 - n_cell) * voids
        phi_powder = powder_porosity(settings.dry_density * container_volume - pellet_dry_mass,
                                     material.grain_density * powder_v0[~inert[n_p:]].sum())
        v0 = np.concatenate([pellet_v0, powder_v0])
        phi0 = np.concatenate([np.full(n_p, settings.pellet_porosity), np.full(n_c, phi_powder)])
        solid = (1.0 - phi0) * v0
        s0 = material.initial_suction
        retention = phi0 if settings.retention_follows_porosity else material.reference_porosity
        sat0 = saturation(s0, retention, material)
        water = settings.density * sat0 * (v0 - solid)
        # a pellet swells at most to its free swelling at zero suction
        v_max = np.concatenate([v0[:n_p] * (1.0 + swelling_strain(0.0, material)) * (1.0 + 1e-6), voids])
        model = cls(
            settings=settings, material=material, table=table, mesh=mesh,
            positions=packing.positions.copy(), velocities=np.zeros_like(packing.positions),
            radii=packing.radii.copy(), water_mass=water, volume=v0.copy(),
            pressure=np.full(n_p + n_c, -s0), solid_volume=solid, reference_volume=v0,
            max_volume=v_max, held=held, inert=inert, initial_void=voids,
            container=container, on_plate=on_plate,
        )
        model._omega = omega
        model.powder_porosity = phi_powder
        model.stress = np.zeros(n_p + n_c)
        model._occupied_loss = np.zeros(n_p)
        model.spins = np.zeros_like(packing.positions)
        model._wall_plastic = np.zeros((n_p, 3))
        if settings.pellet_permeability == "tensor":
            model.pellet_frames = Rotation.random(n_p, random_state=np.random.default_rng(settings.seed + 2)).as_matrix()
        model._hold_boundary()
        model._update_geometry()
        model._readings = model.relax(0)
        model.initial_interior_water = model.interior_water()
        return model

    def _hold_boundary(self) -> None:
        """Held cells at the boundary suction: S, V from the laws, V capped by their void
        (at least their solid at the smallest porosity). Called at every step: the held
        cells are the water supply's side, so the water a shrinking void squeezes out
        leaves through the boundary (it is not interior water)."""
        h = np.flatnonzero(self.held)
        s_b = self.settings.boundary_suction
        target = self.reference_volume[h] * (1.0 + swelling_strain(s_b, self.material))
        densest = self.solid_volume[h] / (1.0 - float(self.settings.powder["porosity_clamp"][0]))
        self.volume[h] = np.maximum(np.minimum(target, self.max_volume[h] * (1.0 - 1e-9)), densest)
        porosity = self.retention_porosity()[h]
        sat = saturation(s_b, porosity, self.material)
        self.water_mass[h] = self.settings.density * sat * (self.volume[h] - self.solid_volume[h])
        self.pressure[h] = -s_b

    # ------------------------------------------------------------------ geometry
    def _update_geometry(self) -> None:
        n_p = self.n_pellets
        if self.steps > 0:
            mesh, inverted = moved_mesh(self.mesh, self.vertex_positions())
            if np.any(inverted & ~self.inert[self.n_pellets:]):
                self._remesh()
            else:
                self.mesh = mesh
            self._omega = solid_angles(self.mesh.points, self.mesh.tetrahedra)
        assert self._omega is not None
        radii = self.vertex_radii()
        voids = cell_voids(self.mesh, self.clay_radii(), self._omega, VOID_FLOOR)
        cells = slice(n_p, None)
        self.max_volume[cells] = voids
        self._void = voids
        if self._edges is None or self._edges_of is not self.mesh.tetrahedra:
            self._edges, self._edges_of = mesh_edges(self.mesh), self.mesh.tetrahedra
        ex = exchanges(self.mesh, radii, n_p, self._omega, MIN_AREA_FRACTION, self._edges)
        keep = ~self.inert[ex.pairs].any(axis=1)
        self._exchanges = Exchanges(ex.pairs[keep], ex.area[keep], ex.length[keep], ex.kind[keep])

    def _remesh(self) -> None:
        """New Delaunay mesh when an active cell inverted; the powder moves with it.

        Conservative transfer: ``REMESH_SAMPLES`` points spread over each old cell (at the
        pellets' current positions) carry equal shares of its powder solid, water and
        volume into the new cells that contain them (Qhull point location); shares that
        land in a new cell without powder (a sliver) go to the nearest active one. The
        totals are conserved to round-off; what crosses between held and free cells is
        booked as boundary inflow. The initial void is carried the same way (for the
        neglected void fraction). Each new cell's reference volume follows from its solid
        (V_0 = V_s / (1 - phi_powder)), its suction is the water-weighted mean of its
        donors' (the next local solve corrects it); held cells are re-selected and reset.
        """
        from scipy.spatial import Delaunay, cKDTree

        n_p = self.n_pellets
        old = slice(n_p, None)
        interior_before = self.interior_water()
        vertices = self.vertex_positions()
        triangulation = Delaunay(vertices)
        mesh = mesh_from_tetrahedra(triangulation.points, triangulation.simplices, triangulation.neighbors)
        omega = solid_angles(mesh.points, mesh.tetrahedra)
        voids = cell_voids(mesh, self.clay_radii(), omega, VOID_FLOOR)
        inert, held = _cell_roles(mesh, voids, self.on_plate, n_p, self.settings)
        # sample points of every old cell and the new cell holding each
        corners = vertices[self.mesh.tetrahedra]  # (n_old, 4, 3)
        samples = np.einsum("ks,csx->ckx", _REMESH_WEIGHTS, corners).reshape(-1, 3)
        owner = np.repeat(np.arange(self.mesh.n_cells), _REMESH_WEIGHTS.shape[0])
        # Qhull's point location calls LAPACK once per cell: threaded BLAS on a loaded
        # machine made it 1000x slower (seconds instead of milliseconds)
        with threadpool_limits(limits=1, user_api="blas"):
            target = triangulation.find_simplex(samples)
        lost = target < 0
        if lost.any():
            target[lost] = cKDTree(mesh.centroids).query(samples[lost])[1]
        share = 1.0 / _REMESH_WEIGHTS.shape[0]
        n_new = mesh.n_cells
        initial_void = np.bincount(target, self.initial_void[owner] * share, minlength=n_new)
        # powder of the active old cells only; shares landing in new inert cells move on
        carries = ~self.inert[old][owner]
        dest = target[carries]
        stray = inert[n_p:][dest]
        if stray.any():
            active = np.flatnonzero(~inert[n_p:])
            dest[stray] = active[cKDTree(mesh.centroids[active]).query(samples[carries][stray])[1]]
        donor = owner[carries]

        def moved(values: FloatArray) -> FloatArray:
            return np.bincount(dest, values[old][donor] * share, minlength=n_new)

        solid, water, volume = moved(self.solid_volume), moved(self.water_mass), moved(self.volume)
        suction = moved(-self.pressure * self.water_mass) / np.maximum(water, 1e-300)
        empty = solid <= 0.0
        inert = inert | np.concatenate([np.zeros(n_p, dtype=np.bool_), empty])
        held &= ~inert
        phi_powder = self.powder_porosity
        v0 = np.where(empty, voids * (1.0 - phi_powder), solid / (1.0 - phi_powder))
        solid = np.where(empty, (1.0 - phi_powder) * v0, solid)
        low = solid + water / self.settings.density
        volume = np.clip(volume, low * (1.0 + 1e-6), np.maximum(voids, low * (1.0 + 1e-3)))
        self.mesh, self._omega = mesh, omega
        self.inert, self.held = inert, held
        self.initial_void = initial_void
        self.water_mass = np.concatenate([self.water_mass[:n_p], water])
        self.solid_volume = np.concatenate([self.solid_volume[:n_p], solid])
        self.reference_volume = np.concatenate([self.reference_volume[:n_p], v0])
        self.volume = np.concatenate([self.volume[:n_p], volume])
        self.max_volume = np.concatenate([self.max_volume[:n_p], np.maximum(voids, volume * (1.0 + 1e-6))])
        self.pressure = np.concatenate([self.pressure[:n_p],
                                        -np.where(empty, self.material.initial_suction, suction)])
        assert self.stress is not None
        self.stress = np.concatenate([self.stress[:n_p], np.zeros(n_new)])
        self._hold_boundary()
        self.boundary_inflow += self.interior_water() - interior_before
        self.remeshes += 1

    # ------------------------------------------------------------------ hydraulics
    def saturations(self) -> FloatArray:
        """(n,) water saturation m_w / (rho (V - V_s)) [1]."""
        return self.water_mass / (self.settings.density * (self.volume - self.solid_volume))

    def retention_porosity(self) -> FloatArray:
        """(n,) porosity of the retention curve: current (Eqs. 4.25-4.26, 4.42-4.43) or, with
        ``macro.retention_follows_porosity`` off, Table 4.2's reference porosity phi_0 (the
        curve as measured: pellets start at it; the loose powder would be much drier on the
        curve extrapolated to its porosity)."""
        if self.settings.retention_follows_porosity:
            return self.porosities()
        return np.full(self.volume.size, self.material.reference_porosity)

    def porosities(self) -> FloatArray:
        """(n,) porosity 1 - V_s / V [1]."""
        return 1.0 - self.solid_volume / self.volume

    def permeabilities(self) -> FloatArray:
        """(n,) permeability [m2]: the table's for pellets, the powder law for cells."""
        n_p = self.n_pellets
        k = np.empty(self.volume.size)
        k[:n_p] = self.table.permeability(-self.pressure[:n_p], "water")
        k[n_p:] = powder_permeability(self.saturations()[n_p:], self.porosities()[n_p:], self.material)
        return k

    def conductances(self) -> FloatArray:
        """Mass conductance of every exchange [kg/(Pa s)]."""
        ex = self._exchanges
        assert ex is not None
        k = self.permeabilities()
        i, j = ex.pairs[:, 0], ex.pairs[:, 1]
        k_i, k_j = k[i], k[j]
        if self.pellet_frames is not None:
            k_i, k_j = self._directional_permeabilities(k_i, k_j)
        k_edge = harmonic_mean(k_i, k_j)
        cc = ex.kind == 2
        sat, por = self.saturations(), self.porosities()
        k_edge[cc] = powder_permeability(0.5 * (sat[i[cc]] + sat[j[cc]]),
                                         0.5 * (por[i[cc]] + por[j[cc]]), self.material)
        s = self.settings
        return conductances(ex.area, ex.length, k_edge, s.density, s.viscosity, s.conductivity_factor)

    def _directional_permeabilities(self, k_i: FloatArray, k_j: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The pellet ends of the exchanges with the table's tensor (thesis Sec. 6.3): each
        pellet's tensor, rotated into the lab by its random frame (its compaction axis),
        read along the exchange, d^T R K R^T d (d the unit vector between the systems'
        centres); the cell ends keep the powder's."""
        assert self._exchanges is not None and self.pellet_frames is not None
        n_p = self.n_pellets
        frames = self.pellet_frames
        tensor = frames @ self.table.tensor(-self.pressure[:n_p], "water") @ np.swapaxes(frames, 1, 2)
        centres = np.concatenate([self.positions, self.mesh.centroids])
        i, j = self._exchanges.pairs[:, 0], self._exchanges.pairs[:, 1]
        d = centres[j] - centres[i]
        d /= np.maximum(np.linalg.norm(d, axis=1), 1e-300)[:, None]
        k_i, k_j = k_i.copy(), k_j.copy()
        for k_end, end in ((k_i, i), (k_j, j)):
            pellet = end < n_p
            k_end[pellet] = np.einsum("ea,eab,eb->e", d[pellet], tensor[end[pellet]], d[pellet])
        return k_i, k_j

    def time_step(self, conductance: FloatArray) -> float:
        """Stable explicit step of Eq. 4.58 [s]."""
        assert self._exchanges is not None
        # dp/dS grows without bound as S -> 1: no system is driven wetter than the
        # boundary, so the slope is taken no wetter than at half the boundary suction
        porosity = self.retention_porosity()
        wettest = saturation(0.5 * self.settings.boundary_suction, porosity, self.material)
        sat = np.clip(self.saturations(), 1e-12, wettest)
        slope = suction_derivative(sat, porosity, self.material)
        pore = self.volume - self.solid_volume
        return stable_time_step(self._exchanges.pairs, conductance, pore, slope, self.held | self.inert,
                                self.settings.density, self.settings.chi)

    def saturation_limited_step(self, conductance: FloatArray) -> float:
        """Largest step in which no free system's saturation changes by more than
        ``max_saturation_change`` and none loses more than that fraction of its water
        [s]: the explicit update follows a retention curve
        whose slope changes by orders of magnitude, which Eq. 4.58's local slope misses
        (a dry cell next to a wet one would otherwise be drained below zero water)."""
        assert self._exchanges is not None
        rate = mass_rates(self._exchanges.pairs, conductance, self.pressure, self.volume.size)
        free = ~self.held & ~self.inert
        pore = (self.volume - self.solid_volume)[free]
        change = np.abs(rate[free]) / (self.settings.density * pore)
        # and no system loses more than that fraction of its own water (dry systems)
        loss = np.maximum(-rate[free], 0.0) / np.maximum(self.water_mass[free], 1e-300)
        largest = max(change.max(initial=0.0), loss.max(initial=0.0))
        return float(self.settings.max_saturation_change / largest) if largest > 0.0 else float("inf")

    def transport(self, dt: float, conductance: FloatArray) -> None:
        """Explicit mass update (Eq. 4.23); held systems keep their mass, their loss is inflow."""
        assert self._exchanges is not None
        rate = mass_rates(self._exchanges.pairs, conductance, self.pressure, self.volume.size)
        self.boundary_inflow -= float(dt * rate[self.held].sum())
        free = ~self.held
        self.water_mass[free] += dt * rate[free]

    def solid_mass(self) -> FloatArray:
        """(n,) dry mass of every system [kg] (pellets and powder of one grain density)."""
        return self.material.grain_density * self.solid_volume

    def swelling_volume(self, suction: FloatArray) -> FloatArray:
        """(n,) volume each system swells to at ``suction`` [Pa] under its confining
        stress (:func:`macro.laws.confined_volume`), capped by V_max [m3]."""
        assert self.stress is not None
        volume = confined_volume(suction, self.stress, self.solid_mass(), self.reference_volume,
                                 self.retention_porosity(), self.material)
        return np.minimum(volume, self.max_volume)

    def capacities(self) -> FloatArray:
        """(n,) dm/dp of every system at its current state [kg/Pa]: the retention
        curve's storage rho (V - V_s) dS/dp plus, where the system is not at V_max, the
        swelling's rho S dV/dp of the confined swelling target (central differences)."""
        m = self.material
        sat = np.clip(self.saturations(), 1e-12, 1.0 - 1e-12)
        slope = suction_derivative(sat, self.retention_porosity(), m)
        pore = self.volume - self.solid_volume
        suction = np.maximum(-self.pressure, 1.0)
        swelling = (self.swelling_volume(0.99 * suction) - self.swelling_volume(1.01 * suction)) / (0.02 * suction)
        confined = self.volume >= self.max_volume * (1.0 - 1e-3)
        return self.settings.density * (pore / slope + np.where(confined, 0.0, sat * np.maximum(swelling, 0.0)))

    def water_at(self, pressure: FloatArray) -> FloatArray:
        """(n,) water each system would hold at ``pressure`` [kg]: the local problem with p
        given, rho S_ret(s) (V(s) - V_s), V(s) its swelling volume (:meth:`swelling_volume`)."""
        suction = np.clip(-pressure, 0.0, self.settings.max_suction)
        volume = self.swelling_volume(suction)
        sat = saturation(suction, self.retention_porosity(), self.material)
        return self.settings.density * sat * np.maximum(volume - self.solid_volume, 0.0)

    def implicit_transport(self, conductance: FloatArray, max_dt: float) -> float:
        """Linearised backward-Euler mass update (see :mod:`macro.transport`); returns dt [s].

        The trial step doubles the last accepted one (the first is Eq. 4.58's), capped by
        ``max_time_step_s``; it shrinks until no free system's water changes by more than
        ``max_saturation_change`` of its pore volume (at least the median system's); the
        outflows of a system that would lose more than ``IMPLICIT_LOSS`` of its water are
        limited (:func:`macro.transport.limited_rates`, counted in ``limited_systems``).
        """
        assert self._exchanges is not None
        s = self.settings
        pairs = self._exchanges.pairs
        free = ~self.held & ~self.inert
        capacity = self.capacities()
        # a system smaller than the median counts as the median: tiny cells may swing
        # further within a step (the step is stable; they hold little of the water)
        pore = (self.volume - self.solid_volume)[free]
        pore = np.maximum(pore, np.median(pore))
        limit = s.max_saturation_change
        if self._next_dt <= 0.0:
            self._next_dt = self.time_step(conductance)
        dt = min(self._next_dt, s.max_time_step, max_dt)
        start = self.water_at(self.pressure)
        for _ in range(20):
            # modified Picard (Celia et al. 1990): the storage of each iterate from the
            # retention and swelling laws themselves, with the secant capacity between
            # the step's start and the iterate (the tangent one at first)
            pressure = self.pressure
            for _ in range(PICARD_ITERATIONS):
                stored = self.water_at(pressure) - start
                moved = pressure - self.pressure
                big = np.abs(moved) > 1e-9 * np.abs(self.pressure)
                secant = np.where(big, stored / np.where(big, moved, 1.0), capacity)
                secant = np.where(secant > 0.0, secant, capacity)
                effective = pressure - stored / secant
                pressure = np.clip(implicit_pressures(pairs, conductance, effective, secant, dt, free),
                                   -s.max_suction, 0.0)
            # a tiny cell draining into a large dry neighbour would lose all its water
            # in a long step: its outflows are limited (conservatively) instead
            rate, limited = limited_rates(pairs, conductance, pressure, self.water_mass, dt, free,
                                          1.0 - IMPLICIT_LOSS)
            change = np.abs(dt * rate[free]) / (s.density * pore)
            largest = change.max(initial=0.0)
            if largest <= limit:
                break
            dt *= 0.9 * limit / largest
        self.limited_systems += limited
        self._next_dt = 2.0 * dt if largest <= 0.5 * limit else dt
        self.boundary_inflow -= float(dt * rate[self.held].sum())
        self.water_mass[~self.held] += dt * rate[~self.held]
        return dt

    def solve_local(self) -> None:
        """Pressure-volume problem of every system not held (Sec. 4.3)."""
        free = np.flatnonzero(~self.held & ~self.inert)
        n_p = self.n_pellets
        # a cell squeezed by swollen pellets keeps at least its solid at the smallest
        # porosity (the lower porosity clamp, minPoroClamp) and its water (counted)
        phi_min = float(self.settings.powder["porosity_clamp"][0])
        needed = np.maximum(self.solid_volume + self.water_mass / self.settings.density,
                            self.solid_volume / (1.0 - phi_min)) * (1.0 + 1e-6)
        floored = (self.max_volume < needed) & ~self.held & ~self.inert
        floored[:n_p] = False
        self.floored_cells += int(np.count_nonzero(floored))
        self.max_volume = np.where(floored, needed, self.max_volume)

        def names(k: int) -> str:
            i = int(free[k])
            return f"pellet {i}" if i < n_p else f"cell {i - n_p}"

        assert self.stress is not None
        problem = PVProblem(
            self.water_mass[free], self.solid_volume[free], self.reference_volume[free],
            self.max_volume[free], self.settings.density, self.settings.max_suction, names,
            None if self.settings.retention_follows_porosity else self.retention_porosity()[free],
            self.stress[free], self.solid_mass()[free],
        )
        volume, pressure, iterations, fallbacks = solve_pressure_volume(
            problem, self.material, self.settings.newton, self.volume[free], -self.pressure[free])
        self.volume[free], self.pressure[free] = volume, pressure
        self.newton_iterations += iterations
        self.fallbacks += fallbacks

    # ------------------------------------------------------------------ mechanics
    def powder_pressure(self) -> tuple[FloatArray, FloatArray]:
        """Effective pressure of the powder on its cell contour [Pa] (Eqs. 4.31-4.35) and
        its derivative with respect to the cell's void [Pa/m3], both (n_c,).

        The powder swells freely until it fills its cell's void V_c; held there, it
        presses with the swelling pressure of the confined clay
        (:func:`macro.laws.swelling_pressure`, zero at the moment of confinement), scaled
        by the powder's share of the tetrahedron V / V_t (Eq. 4.35). A cell squeezed below
        the powder's densest state (its solid at the smallest porosity, or solid and
        water) presses as at that state. With the pellets' yield (Eq. 4.4) on, at most
        the yield pressure of the cell's weakest pellet. Zero everywhere when
        ``macro.powder_swelling_pressure`` is off.
        """
        cells = slice(self.n_pellets, None)
        if not self.settings.powder_pressure:
            return np.zeros(self.n_cells), np.zeros(self.n_cells)
        assert self._void is not None
        solid, water = self.solid_volume[cells], self.water_mass[cells]
        phi_min = float(self.settings.powder["porosity_clamp"][0])
        densest = np.maximum(solid / (1.0 - phi_min), solid + water / self.settings.density)
        held = np.maximum(self._void, densest)
        suction = -self.pressure[cells]
        solid_mass = self.solid_mass()[cells]
        porosity = self.retention_porosity()[cells]
        free = self.reference_volume[cells] * (1.0 + swelling_strain(suction, self.material))
        share = np.minimum(free, held) / self.mesh.volumes
        active = ~self.inert[cells] & (free > held)
        pressure = np.where(active, swelling_pressure(held, suction, solid_mass, self.reference_volume[cells],
                                                      porosity, self.material) * share, 0.0)
        bound = self._pressure_bound()
        capped = pressure > bound
        pressure = np.where(capped, bound, pressure)
        # d/dV_c of S p'_vc(m_s / V_c) V_c / V_t
        line = saturation(suction, porosity, self.material) * consolidation_pressure(solid_mass / held, self.material)
        slope = line * self.material.alpha_v * solid_mass / held**2 * share
        return pressure, np.where(active & ~capped, slope, 0.0)

    def _pressure_bound(self) -> FloatArray:
        """(n_c,) the largest push of each cell's powder [Pa]: the yield pressure of its
        weakest pellet (:func:`macro.laws.yield_pressure`: the pellets' surface gives way
        first); a cell with only container points is bounded by its neighbours' bounds
        (the powder around it gives way), inf without yield."""
        tet, n_p = self.mesh.tetrahedra, self.n_pellets
        strength = np.append(yield_pressure(-self.pressure[:n_p], self.radii, self.material), np.inf)
        bound = strength[np.where(tet < n_p, tet, n_p)].min(axis=1)
        if not np.isfinite(strength[:n_p]).any():
            return bound
        neighbours = self.mesh.neighbours
        for _ in range(4):
            unbounded = np.isinf(bound)
            if not unbounded.any():
                break
            # a missing neighbour (-1) reads the appended -inf
            around = np.append(bound, -np.inf)[neighbours]
            bound = np.where(unbounded, np.where(np.isfinite(around), around, -np.inf).max(axis=1), bound)
            bound[np.isneginf(bound)] = np.inf
        return bound

    def hydro_forces(self, cell_pressure: FloatArray) -> FloatArray:
        """(n_p, 3) forces of the cell pressures on the pellets [N] (Eqs. 4.34-4.38).

        A pellet's sector A_k = theta r^2 / 2 of each triangle is pushed by the pressure
        difference across it, A_k (P_i - P_j) n_ij (n_ij from cell i to j). The mesh's hull
        is made of container points, which have no sectors: no pellet is pushed there.
        """
        mesh = self.mesh
        verts, cells = mesh.facet_vertices, mesh.facet_cells
        sector = 0.5 * facet_angles(mesh.points, verts) * self.vertex_radii()[verts] ** 2
        jump = cell_pressure[cells[:, 0]] - cell_pressure[cells[:, 1]]
        vec = (sector * jump[:, None])[:, :, None] * mesh.facet_normals[:, None, :]
        forces = np.empty((self.n_vertices, 3))
        for c in range(3):
            forces[:, c] = np.bincount(verts.ravel(), vec[:, :, c].ravel(), minlength=self.n_vertices)
        return forces[:self.n_pellets]

    def relax(self, substeps: int) -> Readings:
        """Quasi-static DEM under the current radii, moduli and powder: damped substeps
        until the unbalanced force ratio is below ``dem_balance_tolerance``, at most
        ``substeps`` (counted in ``dem_substeps_used``).

        The powder's push and its stiffness (dP/dV_c A^2 over a pellet's cells, added to
        the fictitious mass) are those of the step's geometry.
        """
        s = self.settings
        n_p = self.n_pellets
        young = young_modulus(-self.pressure[:n_p], self.material)
        strength = yield_force(-self.pressure[:n_p], self.material)
        assert self._wall_plastic is not None
        nu = self.material.poisson_ratio
        z_lo, z_hi = -0.5 * s.height, 0.5 * s.height
        skin = 0.2 * float(self.radii.mean())
        pairs, shear, plastic = self._contacts(detect_contacts(self.positions, self.radii, 1.0, skin))
        reference = self.positions.copy()
        # fictitious mass floor: the stiffness of a contact overlapping by 1e-3 r
        floor = 2.0 * young / (1.0 - nu * nu) * self.radii * np.sqrt(1e-3)
        cap = 1e-3 * self.radii
        external, powder_stiffness = self._powder_load()
        refresh = substeps > 0
        # displacement and rotation of the last substep (none before the first)
        moved, turned = np.zeros((n_p, 3)), np.zeros((n_p, 3))
        anchor = self.positions.copy()
        for k in range(substeps + 1):
            if refresh and k > 0 and k % POWDER_REFRESH == 0:
                # the powder's push follows the pellets: voids reopen as they move apart
                refresh = self._moved_geometry()
                if refresh:
                    external, powder_stiffness = self._powder_load()
                    anchor = self.positions.copy()
            if 2.0 * np.sqrt(((self.positions - reference) ** 2).sum(axis=1)).max() > skin:
                pairs, shear, plastic = self._contacts(detect_contacts(self.positions, self.radii, 1.0, skin),
                                                       pairs, shear, plastic)
                reference = self.positions.copy()
            # between two updates, the push linearised about them (isotropic mean of the
            # cells' stiffness: moving into a cell squeezes it and opens the opposite one)
            forces = external - powder_stiffness[:, None] / 3.0 * (self.positions - anchor)
            torques = np.zeros((n_p, 3))
            stiffness = powder_stiffness.copy()
            normal = _kernels.hertz_mindlin_pairs(self.positions, moved, turned, self.radii, young, nu,
                                                  self.material.friction, pairs, shear, forces, torques,
                                                  stiffness, strength, plastic)
            radial, lower, upper = _kernels.container_contacts(
                self.positions, self.radii, young, nu, s.radius, z_lo, z_hi, forces, stiffness, strength,
                self._wall_plastic)
            carried = np.concatenate([normal[normal > 0.0], radial[radial > 0.0],
                                      lower[lower > 0.0], upper[upper > 0.0]])
            resultant = np.sqrt((forces**2).sum(axis=1)).mean()
            unbalanced = float(resultant / carried.mean()) if carried.size else 0.0
            if k == substeps or unbalanced < s.dem_balance_tolerance:
                break
            mass = np.maximum(stiffness, floor)[:, None]
            self.velocities = _damped_update(self.velocities, forces, mass, s.dem_damping, cap)
            self.spins = _damped_update(self.spins, torques, mass * self.radii[:, None] ** 2, s.dem_damping,
                                        cap / self.radii)
            moved, turned = self.velocities, self.spins
            self.positions += self.velocities
        self._contact_pairs, self._shear, self._plastic = pairs, shear, plastic
        self.dem_substeps_used += k
        self._confine(pairs, normal, np.maximum(radial, 0.0) + np.maximum(lower, 0.0) + np.maximum(upper, 0.0))
        # radial loads on the curved wall at their contact's height above the lower plate
        heights, loads = self.positions[:, 2] + 0.5 * s.height, radial
        area = np.pi * s.radius**2
        upper_force, lower_force = float(upper.sum()), float(lower.sum())
        if s.powder_on_walls:
            wall_heights, wall_loads, extra_upper, extra_lower = self._powder_wall_loads()
            heights, loads = np.concatenate([heights, wall_heights]), np.concatenate([loads, wall_loads])
            upper_force += extra_upper
            lower_force += extra_lower
        return Readings(s.sensors.pressures(heights, loads, s.radius),
                        s.bands.pressures(heights, loads, s.radius),
                        upper_force / area, lower_force / area, unbalanced)

    def _powder_load(self) -> tuple[FloatArray, FloatArray]:
        """The powder's push on the pellets (n_p, 3) [N] (Eqs. 4.34-4.38) and its stiffness
        per pellet, dP/dV_c A^2 over the pellet's cells [N/m], at the current geometry."""
        assert self._omega is not None
        tet = self.mesh.tetrahedra
        self._cell_pressure, slope = self.powder_pressure()
        area = self._omega * self.vertex_radii()[tet] ** 2
        stiffness = np.bincount(tet.ravel(), (slope[:, None] * area**2).ravel(),
                                minlength=self.n_vertices)[:self.n_pellets]
        return self.hydro_forces(self._cell_pressure), stiffness

    def _moved_geometry(self) -> bool:
        """The cells' geometry and voids at the pellets' current positions (same
        connectivity); False, and nothing changed, when an active cell has inverted."""
        mesh, inverted = moved_mesh(self.mesh, self.vertex_positions())
        if np.any(inverted & ~self.inert[self.n_pellets:]):
            return False
        self.mesh = mesh
        self._omega = solid_angles(mesh.points, mesh.tetrahedra)
        self._void = cell_voids(mesh, self.clay_radii(), self._omega, VOID_FLOOR)
        return True

    def _confine(self, pairs: npt.NDArray[np.int64], normal: FloatArray, walls: FloatArray) -> None:
        """Confining stress of every pellet from the relaxed state, and the volume its
        sphere loses to overlaps.

        The mean stress on a sphere is the normal load over its surface,
        (sum of contact forces + sum_c P_c Omega_c r^2) / (4 pi r^2) (contacts, walls
        and the powder's push over the sphere's sectors in its cells); it enters the
        pellet's swelling target under-relaxed by ``stress_relaxation`` (the pellets'
        volumes and contacts are coupled explicitly, step by step). The overlaps' caps
        (with other pellets and the container) are the volume the sphere of a pellet
        loses, so that its radius keeps its clay volume (:meth:`step`).
        """
        assert self.stress is not None and self._omega is not None and self._cell_pressure is not None
        n_p, s = self.n_pellets, self.settings
        radii = self.radii
        load = walls + np.bincount(pairs[:, 0], normal, minlength=n_p) \
            + np.bincount(pairs[:, 1], normal, minlength=n_p)
        tet = self.mesh.tetrahedra
        surface = self._cell_pressure[:, None] * self._omega * self.vertex_radii()[tet] ** 2
        load += np.bincount(tet.ravel(), surface.ravel(), minlength=self.n_vertices)[:n_p]
        measured = load / (4.0 * np.pi * radii**2)
        self.stress[:n_p] += s.stress_relaxation * (measured - self.stress[:n_p])
        # caps cut off each sphere by its overlaps: pellets (plane of the lens) and container
        i, j = pairs[:, 0], pairs[:, 1]
        distance = np.linalg.norm(self.positions[j] - self.positions[i], axis=1)
        touching = radii[i] + radii[j] > distance
        i, j, distance = i[touching], j[touching], distance[touching]
        plane = (distance**2 + radii[i] ** 2 - radii[j] ** 2) / (2.0 * distance)
        lost = np.bincount(i, _cap_volume(radii[i], radii[i] - plane), minlength=n_p) \
            + np.bincount(j, _cap_volume(radii[j], radii[j] - (distance - plane)), minlength=n_p) + 0.0
        axis = np.hypot(self.positions[:, 0], self.positions[:, 1])
        for depth in (radii + axis - s.radius, radii - self.positions[:, 2] - 0.5 * s.height,
                      radii + self.positions[:, 2] - 0.5 * s.height):
            lost += _cap_volume(radii, np.maximum(depth, 0.0))
        self._occupied_loss = np.minimum(lost / (4.0 / 3.0 * np.pi * radii**3), MAX_OVERLAP_LOSS)

    def _contacts(self, pairs: npt.NDArray[np.int64], old_pairs: npt.NDArray[np.int64] | None = None,
                  old_shear: FloatArray | None = None, old_plastic: FloatArray | None = None,
                  ) -> tuple[npt.NDArray[np.int64], FloatArray, FloatArray]:
        """Detected pairs, their shear forces and plastic overlaps carried over from the
        same pairs before (by default the contacts at the end of the last relaxation); new
        pairs start at 0."""
        if old_pairs is None:
            old_pairs, old_shear, old_plastic = self._contact_pairs, self._shear, self._plastic
        shear = np.zeros((pairs.shape[0], 3))
        plastic = np.zeros(pairs.shape[0])
        if old_pairs is not None and old_shear is not None and old_plastic is not None \
                and old_pairs.size and pairs.size:
            n = self.n_pellets
            old_code = old_pairs.min(axis=1) * n + old_pairs.max(axis=1)
            code = pairs.min(axis=1) * n + pairs.max(axis=1)
            order = np.argsort(old_code)
            where = np.clip(np.searchsorted(old_code[order], code), 0, old_code.size - 1)
            found = old_code[order][where] == code
            source = order[where[found]]
            # the stored force acts on the pair's first pellet: flip where the order flipped
            sign = np.where(old_pairs[source, 0] == pairs[found, 0], 1.0, -1.0)
            shear[found] = old_shear[source] * sign[:, None]
            plastic[found] = old_plastic[source]
        return pairs, shear, plastic

    def _wall_cell_pressure(self) -> FloatArray:
        """(n_c,) the powder's pressure with the inert cells given their active neighbours'
        mean: the hull's slivers between container points hold no powder, and the powder
        beside them presses on the container through them."""
        assert self._cell_pressure is not None
        pressure = self._cell_pressure.copy()
        known = ~self.inert[self.n_pellets:]
        neighbours = self.mesh.neighbours
        for _ in range(4):
            if known.all():
                break
            inside = neighbours >= 0
            hits = np.where(inside, known[np.where(inside, neighbours, 0)], False)
            total = np.where(hits, pressure[np.where(inside, neighbours, 0)], 0.0).sum(axis=1)
            count = hits.sum(axis=1)
            fill = ~known & (count > 0)
            pressure[fill] = total[fill] / count[fill]
            known = known | fill
        return pressure

    def _powder_wall_loads(self) -> tuple[FloatArray, FloatArray, float, float]:
        """Sec. 4.10: confined powder of the cells on the container pushes on it through their
        triangles on the wall and plates (the mesh's hull).

        Returns the height above the lower plate [m] and the radial force [N] of each
        triangle on the curved wall (its centroid is its contact point), and the forces on
        the upper and lower plates [N]."""
        assert self._cell_pressure is not None
        mesh = self.mesh
        force = self._wall_cell_pressure()[mesh.boundary_cells] * mesh.boundary_areas
        normals, centroids = mesh.boundary_normals, mesh.boundary_centroids
        rho = np.maximum(np.hypot(centroids[:, 0], centroids[:, 1]), 1e-300)
        radial = (normals[:, 0] * centroids[:, 0] + normals[:, 1] * centroids[:, 1]) / rho
        side = np.abs(normals[:, 2]) <= np.sqrt(0.5)
        upper = float((force * np.maximum(normals[:, 2], 0.0))[~side].sum())
        lower = float((force * np.maximum(-normals[:, 2], 0.0))[~side].sum())
        return (centroids[side, 2] + 0.5 * self.settings.height, (force * np.maximum(radial, 0.0))[side],
                upper, lower)

    # ------------------------------------------------------------------ step
    def step(self, max_dt: float = float("inf")) -> float:
        """Advance one coupled step; returns the time step used [s]."""
        clock = time.perf_counter()
        if self.steps > 0:
            self._update_geometry()
            self._hold_boundary()
        now = time.perf_counter()
        self.phase_seconds["remesh"] += now - clock
        clock = now
        conductance = self.conductances()
        if self.settings.transport_scheme == "implicit":
            dt = self.implicit_transport(conductance, max_dt)
        else:
            dt = min(self.time_step(conductance), self.saturation_limited_step(conductance), max_dt)
            self.transport(dt, conductance)
        now = time.perf_counter()
        self.phase_seconds["transport"] += now - clock
        clock = now
        self.solve_local()
        now = time.perf_counter()
        self.phase_seconds["newton"] += now - clock
        clock = now
        n_p = self.n_pellets
        assert self._occupied_loss is not None
        self.radii = np.cbrt(3.0 * self.volume[:n_p] / (4.0 * np.pi * (1.0 - self._occupied_loss)))
        self._readings = self.relax(self.settings.dem_substeps)
        self.phase_seconds["dem"] += time.perf_counter() - clock
        self.time += dt
        self.steps += 1
        return dt

    @property
    def readings(self) -> Readings:
        assert self._readings is not None
        return self._readings

    def neglected_void_fraction(self) -> float:
        """Fraction of the cells' initial void in cells without powder [1]."""
        cells = slice(self.n_pellets, None)
        return float(self.initial_void[self.inert[cells]].sum() / self.initial_void.sum())

    def invariants(self) -> dict[str, float]:
        """What the model must conserve, now: water mass of the pellets, of the free
        powder and in the held end cells [kg]; the balance residual, interior water less
        the initial interior water and the boundary inflow [kg]; the solids and water of
        pellets and active cells over the container's volume, and the pellets' clay with
        the powder's solid and water over it [1]; the largest overfill of a cell, its
        powder's solid and water over its void less 1 [1]; the dry density of the
        pellets and active cells over the container [kg/m3]."""
        n_p, rho = self.n_pellets, self.settings.density
        cells = n_p + np.flatnonzero(~self.inert[n_p:])
        free_cells = cells[~self.held[cells]]
        container = np.pi * self.settings.radius**2 * self.settings.height
        solid = self.solid_volume[:n_p].sum() + self.solid_volume[cells].sum()
        water = self.water_mass[:n_p].sum() + self.water_mass[cells].sum()
        powder = self.solid_volume[cells] + self.water_mass[cells] / rho
        assert self._void is not None
        return {
            "water_pellets": float(self.water_mass[:n_p].sum()),
            "water_powder": float(self.water_mass[free_cells].sum()),
            "water_held": float(self.water_mass[self.held].sum()),
            "water_residual": self.interior_water() - self.initial_interior_water - self.boundary_inflow,
            "solid_water_fraction": float((solid + water / rho) / container),
            "occupied_fraction": float((self.volume[:n_p].sum() + powder.sum()) / container),
            "largest_overfill": float(np.max(powder / self._void[cells - n_p]) - 1.0),
            "dry_density": float(self.material.grain_density * solid / container),
        }

    def dry_mass_ratio(self) -> float:
        """Dry mass of the pellets over that of the powder in the active cells [1]."""
        n_p = self.n_pellets
        cells = n_p + np.flatnonzero(~self.inert[n_p:])
        return float(self.solid_volume[:n_p].sum() / self.solid_volume[cells].sum())

    def interior_water(self) -> float:
        """Water mass of the systems not held [kg]."""
        return float(self.water_mass[~self.held].sum())

    def mean_suction(self) -> tuple[float, float]:
        """Volume-weighted mean suction of the pellets and of the free powder cells [Pa]."""
        n_p = self.n_pellets
        s = -self.pressure
        cells = n_p + np.flatnonzero(~self.inert[n_p:])
        return (float(np.average(s[:n_p], weights=self.volume[:n_p])),
                float(np.average(s[cells], weights=self.volume[cells])))

    def mean_saturation(self) -> tuple[float, float]:
        """Pore-volume-weighted mean saturation of pellets and powder [1]."""
        n_p = self.n_pellets
        sat = self.saturations()
        pore = self.volume - self.solid_volume
        cells = n_p + np.flatnonzero(~self.inert[n_p:])
        return (float(np.average(sat[:n_p], weights=pore[:n_p])),
                float(np.average(sat[cells], weights=pore[cells])))

    def profiles(self, edges: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Along the axis (bins ``edges``): mean swelling strain V/V_0 - 1 of pellets and
        powder (volume-weighted) [1], and mean suction [Pa]."""
        n_p = self.n_pellets
        z = np.concatenate([self.positions[:, 2], self.mesh.centroids[:, 2]])
        bins = np.clip(np.searchsorted(edges, z) - 1, 0, edges.size - 2)
        n = edges.size - 1
        v0 = np.where(self.inert, 0.0, self.reference_volume)
        weight = np.bincount(bins, v0, minlength=n)
        swell = np.bincount(bins, self.volume - v0, minlength=n)
        suction = np.bincount(bins, -self.pressure * v0, minlength=n)
        del n_p
        with np.errstate(invalid="ignore", divide="ignore"):
            return swell / weight, suction / weight


def _cap_volume(radius: FloatArray, height: FloatArray) -> FloatArray:
    """Volume of spherical caps pi h^2 (3 r - h) / 3 [m3]."""
    return np.pi * height**2 * (3.0 * radius - height) / 3.0


def powder_porosity(dry_mass: float, grain_mass: float) -> float:
    """Initial porosity of the powder [1]: its ``dry_mass`` [kg] (the mixture's target
    minus the pellets') over ``grain_mass`` [kg], the mass of grains that would fill its
    volume (the cells' powder volumes, set by the heterogeneity field).

    Raises
    ------
    ValueError
        Naming ``macro.mixture`` when the powder's mass does not fit in its volume or is
        not positive.
    """
    porosity = 1.0 - dry_mass / grain_mass
    if not 0.0 < porosity < 1.0:
        raise ValueError(
            f"macro.mixture: the powder's dry mass ({dry_mass:.4g} kg: the target dry density "
            f"minus the pellets') gives a powder porosity of {porosity:.3g} in the volume the "
            "powder fills (macro.powder); change macro.mixture.dry_density_kg_m3 or the pellets' share")
    return float(porosity)


def _cell_roles(mesh: Mesh, voids: FloatArray, on_plate: npt.NDArray[np.bool_], n_pellets: int,
                settings: MacroSettings) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Inert (sliver) and held (hydrated end) flags over all systems (pellets never).

    Inert: cells whose void is below ``min_cell_void_fraction`` of the mean void (slivers
    between container points; after remeshes also cells squeezed by swollen pellets,
    whose powder the remesh hands to their neighbours). Held: active cells with a vertex
    on a plate (:func:`macro.mixture.end_cells`).
    """
    none = np.zeros(n_pellets, dtype=np.bool_)
    inert = voids < settings.min_cell_void_fraction * voids.mean()
    held = end_cells(mesh, on_plate) & ~inert
    return np.concatenate([none, inert]), np.concatenate([none, held])


def _damped_update(rate: FloatArray, drive: FloatArray, inertia: FloatArray, damping: float,
                   cap: FloatArray) -> FloatArray:
    """A damped substep of a velocity (or spin) per substep: Cundall's damping of the
    drive (force or torque) against the half-step rate, then the rate capped per pellet."""
    mid = rate + 0.5 * drive / inertia
    rate = rate + drive * (1.0 - damping * np.sign(drive * mid)) / inertia
    speed = np.sqrt((rate**2).sum(axis=1))
    return rate * np.minimum(1.0, cap / np.maximum(speed, 1e-300))[:, None]
