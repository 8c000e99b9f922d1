"""What the model reports: the container's readings (sensor bands, plates, the powder's
push through the hull), water and volume invariants, means and axial profiles."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from macro.parts import Readings
from macro.state import ModelState

FloatArray = npt.NDArray[np.float64]


class WallReadings(ModelState):
    """Readings part of :class:`macro.model.MacroModel`."""

    READS: tuple[str, ...] = ("boundary_inflow", "cells", "held", "inert", "initial_interior_water", "initial_void",
             "latest_readings", "material", "mesh", "n_pellets", "n_vertices", "positions",
             "pressure", "reference_volume", "saturations", "settings", "solid_mass",
             "solid_volume", "volume", "water_mass")
    """What this part reads of the model's state and of its other parts."""

    def wall_point_pressure(self) -> FloatArray:
        """(n_w,) the powder's pressure at each container point [Pa]: the mean over the
        active cells around the point, weighted by their solid angle at it. The hull's
        slivers (cells between container points only, inert) hold no powder and do not
        count: the powder around a point presses on the container there, whatever the
        slivers the triangulation puts between the points."""
        assert self.cells.pressures is not None
        n_p, tet = self.n_pellets, self.mesh.tetrahedra
        weight = np.where((tet >= n_p) & ~self.inert[n_p:, None], self.cells.solid_angles, 0.0)
        total = np.bincount(tet.ravel(), (weight * self.cells.pressures[:, None]).ravel(),
                            minlength=self.n_vertices)[n_p:]
        covered = np.bincount(tet.ravel(), weight.ravel(), minlength=self.n_vertices)[n_p:]
        return np.where(covered > 0.0, total / np.where(covered > 0.0, covered, 1.0), 0.0)

    def powder_wall_loads(self) -> tuple[FloatArray, FloatArray, float, float]:
        """Sec. 4.10: the powder pushes on the container through the mesh's hull, each
        triangle at the mean of its three points' :meth:`wall_point_pressure`.

        Returns the heights of the vertices above the lower plate (n, 3) [m] and the radial
        force [N] of each triangle on the curved wall, and the forces on the upper and
        lower plates [N]."""
        mesh = self.mesh
        point = np.concatenate([np.zeros(self.n_pellets), self.wall_point_pressure()])
        force = point[mesh.boundary_vertices].mean(axis=1) * mesh.boundary_areas
        normals, centroids = mesh.boundary_normals, mesh.boundary_centroids
        rho = np.maximum(np.hypot(centroids[:, 0], centroids[:, 1]), 1e-300)
        radial = (normals[:, 0] * centroids[:, 0] + normals[:, 1] * centroids[:, 1]) / rho
        side = np.abs(normals[:, 2]) <= np.sqrt(0.5)
        upper = float((force * np.maximum(normals[:, 2], 0.0))[~side].sum())
        lower = float((force * np.maximum(-normals[:, 2], 0.0))[~side].sum())
        heights = mesh.points[mesh.boundary_vertices[side], 2] + 0.5 * self.settings.height
        return heights, (force * np.maximum(radial, 0.0))[side], upper, lower


    @property
    def readings(self) -> Readings:
        assert self.latest_readings is not None
        return self.latest_readings

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
        pellets and active cells over the container [kg/m3]; the spread of the dry density
        (:meth:`dry_density_spread`) [kg/m3]."""
        n_p, rho = self.n_pellets, self.settings.density
        cells = n_p + np.flatnonzero(~self.inert[n_p:])
        free_cells = cells[~self.held[cells]]
        container = np.pi * self.settings.radius**2 * self.settings.height
        solid = self.solid_volume[:n_p].sum() + self.solid_volume[cells].sum()
        water = self.water_mass[:n_p].sum() + self.water_mass[cells].sum()
        powder = self.solid_volume[cells] + self.water_mass[cells] / rho
        return {
            "water_pellets": float(self.water_mass[:n_p].sum()),
            "water_powder": float(self.water_mass[free_cells].sum()),
            "water_held": float(self.water_mass[self.held].sum()),
            "water_residual": self.interior_water() - self.initial_interior_water - self.boundary_inflow,
            "solid_water_fraction": float((solid + water / rho) / container),
            "occupied_fraction": float((self.volume[:n_p].sum() + powder.sum()) / container),
            "largest_overfill": float(np.max(powder / self.cells.voids[cells - n_p]) - 1.0),
            "dry_density": float(self.material.grain_density * solid / container),
            "dry_density_spread": self.dry_density_spread(),
        }

    def dry_density_spread(self) -> float:
        """Volume-weighted standard deviation of the dry density m_s / V over the pellets
        and the active cells [kg/m3]: 0 for a homogeneous mixture."""
        n_p = self.n_pellets
        systems = np.concatenate([np.arange(n_p), n_p + np.flatnonzero(~self.inert[n_p:])])
        density = self.solid_mass()[systems] / self.volume[systems]
        mean = np.average(density, weights=self.volume[systems])
        return float(np.sqrt(np.average((density - mean) ** 2, weights=self.volume[systems])))

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
        z = np.concatenate([self.positions[:, 2], self.mesh.centroids[:, 2]])
        bins = np.clip(np.searchsorted(edges, z) - 1, 0, edges.size - 2)
        n = edges.size - 1
        v0 = np.where(self.inert, 0.0, self.reference_volume)
        weight = np.bincount(bins, v0, minlength=n)
        swell = np.bincount(bins, self.volume - v0, minlength=n)
        suction = np.bincount(bins, -self.pressure * v0, minlength=n)
        with np.errstate(invalid="ignore", divide="ignore"):
            return swell / weight, suction / weight

