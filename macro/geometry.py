"""The cells of the mixture: the Delaunay mesh of the pellet centres and the container's
points, the cells' voids, which cells are slivers (inert) or hydrated ends (held), and a
new mesh with a conservative transfer of the powder when a cell inverts (Sec. 4.5)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from threadpoolctl import threadpool_limits

from macro.mixture import (
    Exchanges,
    cell_voids,
    end_cells,
    exchanges,
    matching_keys,
    mesh_edges,
    moved_mesh,
    solid_angles,
)
from macro.settings import MacroSettings
from macro.state import ModelState
from shared.delaunay import qhull_delaunay
from shared.mesh import Mesh, mesh_from_tetrahedra

FloatArray = npt.NDArray[np.float64]

VOID_FLOOR = 1e-3
"""Smallest cell void, fraction of the tetrahedron (the script's minVoidVolume ratio is 1e-4)."""
_REMESH_WEIGHTS = 0.05 + 0.8 * np.array(
    [(i, j, k, 3 - i - j - k) for i in range(4) for j in range(4 - i) for k in range(4 - i - j)]) / 3.0
"""Barycentric weights of the 20 points (a lattice of the tetrahedron, shrunk towards its
centroid) that carry equal shares of an old cell's powder in a remesh."""
MIN_AREA_FRACTION = 1e-2
"""Smallest powder path through a cell-cell triangle covered by pellets, fraction of it."""


class Geometry(ModelState):
    """Mesh part of :class:`macro.model.MacroModel`: vertices, voids, moves and remeshes."""

    READS: tuple[str, ...] = ("boundary_inflow", "cells", "container", "counters", "held", "hold_boundary", "inert",
             "initial_void", "interior_water", "material", "max_volume", "mesh", "on_plate",
             "positions", "powder_porosity", "pressure", "radii", "reference_volume", "settings",
             "solid_volume", "steps", "stress", "volume", "water_mass")
    """What this part reads of the model's state and of its other parts."""

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

    def update_geometry(self) -> None:
        n_p = self.n_pellets
        if self.steps == 0:
            self.cells.voids = cell_voids(self.mesh, self.clay_radii(), self.cells.solid_angles, VOID_FLOOR)
        elif not np.array_equal(self.mesh.points, self.vertex_positions()) and not self.move_geometry():
            # (where the points are the pellets', the relaxation left the mesh, its solid
            # angles and voids at them)
            self.remesh()
        radii = self.vertex_radii()
        cells = slice(n_p, None)
        self.max_volume[cells] = self.cells.voids
        if self.cells.edges is None or self.cells.edges_of is not self.mesh.tetrahedra:
            self.cells.edges, self.cells.edges_of = mesh_edges(self.mesh), self.mesh.tetrahedra
        ex = exchanges(self.mesh, radii, n_p, self.cells.solid_angles, MIN_AREA_FRACTION, self.cells.edges)
        keep = ~self.inert[ex.pairs].any(axis=1)
        self.cells.exchanges = Exchanges(ex.pairs[keep], ex.area[keep], ex.length[keep], ex.kind[keep])

    def remesh(self) -> None:
        """New Delaunay mesh when an active cell inverted; the powder moves with it.

        The new mesh keeps most cells: a cell with the same four vertices before and
        after keeps its whole state (powder, water, volume, V_0, suction, stress and role).
        Only the cells that changed exchange powder, conservatively: 20 points
        (``_REMESH_WEIGHTS``) spread over each old cell that went (at the pellets' current
        positions), each standing for its share of the cell's void, find the new cells
        that contain them (Qhull point location; a point landing elsewhere than in a new
        active cell goes to the nearest one). Each new cell takes, per unit of its void,
        the mean solid, water, volume and V_0 per unit void of the old cells it covers,
        weighted by the points, all scaled so that the cells that went give exactly what
        they held: the new cells' dry densities are means of the old ones' (counting
        20 points into each new cell made them as noisy as the points, and the push,
        exponential in dry density, jolted the pellets). The initial void is carried by
        the points alone. The totals are conserved to round-off; what crosses between
        held and free cells is booked as boundary inflow. A new cell's suction is the
        water-weighted mean of its donors' (the next local solve corrects it); held cells
        are re-selected among new cells.
        """
        from scipy.spatial import cKDTree

        n_p = self.n_pellets
        old = slice(n_p, None)
        interior_before = self.interior_water()
        vertices = self.vertex_positions()
        triangulation = qhull_delaunay(vertices)
        mesh = mesh_from_tetrahedra(triangulation.points, triangulation.simplices, triangulation.neighbors)
        omega = solid_angles(mesh.points, mesh.tetrahedra)
        voids = cell_voids(mesh, self.clay_radii(), omega, VOID_FLOOR)
        inert, held = _cell_roles(mesh, voids, self.on_plate, n_p, self.settings)
        n_new = mesh.n_cells
        source = _same_cells(self.mesh.tetrahedra, mesh.tetrahedra, vertices.shape[0])
        kept = source >= 0
        gone = np.ones(self.mesh.n_cells, dtype=np.bool_)
        gone[source[kept]] = False
        inert[n_p:][kept] = self.inert[old][source[kept]]
        held[n_p:][kept] = self.held[old][source[kept]]
        # sample points of every old cell that went and the new cell holding each
        corners = vertices[self.mesh.tetrahedra[gone]]  # (n_gone, 4, 3)
        samples = np.einsum("ks,csx->ckx", _REMESH_WEIGHTS, corners).reshape(-1, 3)
        owner = np.repeat(np.flatnonzero(gone), _REMESH_WEIGHTS.shape[0])
        # Qhull's point location calls LAPACK once per cell: threaded BLAS on a loaded
        # machine made it 1000x slower (seconds instead of milliseconds)
        with threadpool_limits(limits=1, user_api="blas"):
            target = triangulation.find_simplex(samples)
        share = 1.0 / _REMESH_WEIGHTS.shape[0]
        # new cells that take a share: the changed ones, and of them the active ones for powder
        open_cells = ~kept
        stray = (target < 0) | kept[np.maximum(target, 0)]
        if stray.any():
            candidates = np.flatnonzero(open_cells)
            target[stray] = candidates[cKDTree(mesh.centroids[candidates]).query(samples[stray])[1]]
        initial_void = np.zeros(n_new)
        initial_void[kept] = self.initial_void[source[kept]]
        initial_void += np.bincount(target, self.initial_void[owner] * share, minlength=n_new)
        # powder of the active old cells only; shares landing in new inert cells move on
        carries = ~self.inert[old][owner]
        dest = target[carries]
        receiving = open_cells & ~inert[n_p:]
        stray = ~receiving[dest]
        if stray.any():
            active = np.flatnonzero(receiving)
            dest[stray] = active[cKDTree(mesh.centroids[active]).query(samples[carries][stray])[1]]
        donor = owner[carries]
        # each sample stands for its share of its old cell's void at the current positions
        old_mesh = moved_mesh(self.mesh, vertices)[0]
        old_void = cell_voids(old_mesh, self.clay_radii(), solid_angles(vertices, old_mesh.tetrahedra), VOID_FLOOR)
        weight = old_void[donor] * share
        covered = np.bincount(dest, weight, minlength=n_new)
        giving = gone & ~self.inert[old]
        taking = receiving & (covered > 0.0)

        def moved(values: FloatArray) -> FloatArray:
            # per unit void, the overlap-weighted mean of the old cells a new cell covers,
            # times its void; scaled so that the cells that went give exactly their total
            density = np.bincount(dest, weight * values[old][donor] / old_void[donor], minlength=n_new)
            out = np.where(taking, density / np.where(taking, covered, 1.0) * voids, 0.0)
            total = out.sum()
            out *= values[old][giving].sum() / total if total > 0.0 else 0.0
            out[kept] = values[old][source[kept]]
            return out

        solid, water, volume = moved(self.solid_volume), moved(self.water_mass), moved(self.volume)
        reference = moved(self.reference_volume)
        suction = moved(-self.pressure * self.water_mass) / np.maximum(water, 1e-300)
        suction[kept] = -self.pressure[old][source[kept]]
        assert self.stress is not None
        stress = np.zeros(n_new)
        stress[kept] = self.stress[old][source[kept]]
        empty = (solid <= 0.0) & open_cells
        inert = inert | np.concatenate([np.zeros(n_p, dtype=np.bool_), empty])
        held &= ~inert
        phi_powder = self.powder_porosity
        reference = np.where(empty, voids * (1.0 - phi_powder), reference)
        solid = np.where(empty, (1.0 - phi_powder) * reference, solid)
        low = solid + water / self.settings.density
        fitted = np.clip(volume, low * (1.0 + 1e-6), np.maximum(voids, low * (1.0 + 1e-3)))
        volume = np.where(kept, volume, fitted)
        self.mesh, self.cells.solid_angles, self.cells.voids = mesh, omega, voids
        self.inert, self.held = inert, held
        self.initial_void = initial_void
        self.water_mass = np.concatenate([self.water_mass[:n_p], water])
        self.solid_volume = np.concatenate([self.solid_volume[:n_p], solid])
        self.reference_volume = np.concatenate([self.reference_volume[:n_p], reference])
        self.volume = np.concatenate([self.volume[:n_p], volume])
        self.max_volume = np.concatenate([self.max_volume[:n_p], np.maximum(voids, volume * (1.0 + 1e-6))])
        self.pressure = np.concatenate([self.pressure[:n_p],
                                        -np.where(empty, self.material.initial_suction, suction)])
        self.stress = np.concatenate([self.stress[:n_p], stress])
        self.hold_boundary()
        self.boundary_inflow += self.interior_water() - interior_before
        self.counters.remeshes += 1

    def move_geometry(self) -> bool:
        """The cells' geometry and voids at the pellets' current positions (same
        connectivity); False, and nothing changed, when an active cell has inverted."""
        mesh, inverted = moved_mesh(self.mesh, self.vertex_positions())
        if np.any(inverted & ~self.inert[self.n_pellets:]):
            return False
        self.mesh = mesh
        self.cells.solid_angles = solid_angles(mesh.points, mesh.tetrahedra)
        self.cells.voids = cell_voids(mesh, self.clay_radii(), self.cells.solid_angles, VOID_FLOOR)
        return True



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


def _same_cells(old: npt.NDArray[np.int64], new: npt.NDArray[np.int64], n_vertices: int) -> npt.NDArray[np.int64]:
    """(n_new,) index of the old cell with the same four vertices as each new cell, -1 if none."""
    def keys(tetrahedra: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
        ordered = np.sort(tetrahedra, axis=1).astype(np.int64)
        return ((ordered[:, 0] * n_vertices + ordered[:, 1]) * n_vertices + ordered[:, 2]) * n_vertices + ordered[:, 3]

    return matching_keys(keys(old), keys(new))
