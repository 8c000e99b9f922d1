"""The coupled pellet-powder model: its state, its set-up and one time step.

One step (Fig. 4.8): geometry of the cells for the current pellets (:mod:`macro.geometry`),
conductances, the time step and the mass update (:mod:`macro.hydraulics`), the local
pressure-volume problems (:mod:`macro.pressure_volume`), pellet radii r = (3 V / 4 pi)^(1/3)
and moduli E(s), the powder's push and the quasi-static DEM (:mod:`macro.mechanics`), and
the container's readings (:mod:`macro.readings`). Each part is a mixin of
:class:`MacroModel`, which holds the state they share.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from macro.extrusion import Extrusion
from macro.field import cell_porosity
from macro.geometry import VOID_FLOOR, Geometry, _cell_roles
from macro.hydraulics import Hydraulics
from macro.laws import MixtureParameters, saturation, swelling_strain
from macro.mechanics import Mechanics
from macro.mixture import cell_voids, container_points, solid_angles
from macro.packing import Packing
from macro.parts import CellGeometry, Contacts
from macro.pressure_volume import PressureVolume
from macro.readings import WallReadings
from macro.settings import MacroSettings, powder_porosity
from shared.mesh import build_mesh
from shared.upscaling import PermeabilityTable

__all__ = ["MacroModel"]

FloatArray = npt.NDArray[np.float64]

INITIAL_BALANCE = 10
"""Force evaluations of :meth:`MacroModel.balance`, in ``dem_substeps``."""


@dataclass
class MacroModel(Geometry, Hydraulics, Extrusion, PressureVolume, Mechanics, WallReadings):
    """The mixture (its state: :class:`macro.state.ModelState`) composed of its parts;
    :meth:`step` advances it."""

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
            container=container, on_plate=on_plate, cells=CellGeometry(omega, voids),
            contacts=Contacts(np.zeros((n_p, 3)), np.zeros((n_p, 3, 3))), packing=packing,
        )
        model.pellet_initial_solid = solid[:n_p].copy()
        model.powder_porosity = phi_powder
        model.stress = np.zeros(n_p + n_c)
        model.occupied_loss = np.zeros(n_p)
        model.spins = np.zeros_like(packing.positions)
        if settings.pellet_permeability == "tensor":
            frames = Rotation.random(n_p, random_state=np.random.default_rng(settings.seed + 2))
            model.pellet_frames = frames.as_matrix()
        model.hold_boundary()
        model.update_geometry()
        model.latest_readings = model.relax(0)
        model.initial_interior_water = model.interior_water()
        return model

    def balance(self) -> None:
        """Balance the packing before the hydration, as the thesis script's
        resolveUnbalanced does: the pellets as packed touch little and the dry powder
        pushes them. At most ``INITIAL_BALANCE`` times ``dem_substeps`` force evaluations;
        the water its motion moves to the held cells is not inflow (the hydration has
        not begun)."""
        if self.steps:
            raise RuntimeError("a model is balanced before its hydration, not after a step")
        self.latest_readings = self.relax(INITIAL_BALANCE * self.settings.dem_substeps)
        self._settle()
        self.boundary_inflow = 0.0
        self.initial_interior_water = self.interior_water()


    def step(self, max_dt: float = float("inf")) -> float:
        """Advance one coupled step; returns the time step used [s].

        Transport, extrusion and overflow, the local problems, then the relaxation under
        the new radii. The step ends at the pellets' new positions: their cells'
        geometry (a remesh where a cell inverted), the held cells at the boundary, and
        every cell within its void (the relaxation's motion squeezes cells; the squeezed
        water moves, the readings stay the balanced state's, whose push took squeezed
        cells as drained), so that a record's state is consistent with its geometry.
        """
        with self._phase("transport"):
            conductance = self.conductances()
            if self.settings.transport_scheme == "implicit":
                dt = self.implicit_transport(conductance, max_dt)
            else:
                dt = min(self.time_step(conductance), self.saturation_limited_step(conductance), max_dt)
                self.transport(dt, conductance)
        with self._phase("extrusion"):
            if self.settings.extrusion.enabled:
                self.extrude(dt)
                self.overflow()
        with self._phase("newton"):
            self.solve_local()
        with self._phase("dem"):
            n_p = self.n_pellets
            assert self.occupied_loss is not None
            self.radii = np.cbrt(3.0 * self.volume[:n_p] / (4.0 * np.pi * (1.0 - self.occupied_loss)))
            self.latest_readings = self.relax(self.settings.dem_substeps)
        self._settle()
        self.time += dt
        self.steps += 1
        return dt

    def _settle(self) -> None:
        """The state made consistent with the pellets' relaxed positions: their cells'
        geometry, the held cells at the boundary, every cell within its void."""
        with self._phase("remesh"):
            self.update_geometry()
            self.hold_boundary()
        with self._phase("extrusion"):
            if self.settings.extrusion.enabled:
                self.overflow()

    @contextmanager
    def _phase(self, name: str) -> Iterator[None]:
        """Add the block's wall time to ``phase_seconds[name]``."""
        clock = time.perf_counter()
        yield
        self.counters.phase_seconds[name] += time.perf_counter() - clock

