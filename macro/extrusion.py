"""The powder as a conserved, mobile solid: wet clay extruded down swelling-pressure
differences, between neighbouring cells and from the pellets' surface into looser cells.

Beyond the thesis (whose powder stays in its cell, Sec. 4.8): the mock-up homogenises
by the extrusion of the swelling clay into the looser zones (Molinero-Guerra et al.
2020). The solid volume flux across an exchange is q_ij = M A_ij / L_ij (P_i - P_j)
[m3/s], P the clay's swelling pressure (:func:`macro.laws.swelling_pressure`), M =
M_0 f(S) the mobility of the donor's clay [m2/(Pa s)]: dry clay is granular and does
not flow, wet clay is a gel (Darde et al. 2020's switch from a granular to a continuous
state, here on the donor's saturation: f = clip((S - S_c) / (1 - S_c), 0, 1)).
Pellets only give clay, while confined and while they hold half their initial solid
(the DEM's sphere stays a pellet). Water and the reference volume travel with the
solid at the donor's ratios, so solid, water and V_0 are conserved to round-off. The
step is linearised backward Euler in the cells' pressures (the SPD system of
:func:`macro.transport.implicit_pressures`), with each cell's capacity dV_s/dP.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from macro.laws import confined_pressure, free_volume, swelling_pressure
from macro.settings import ExtrusionSettings
from macro.state import ModelState
from macro.transport import edge_rates, implicit_pressures, limited_fluxes

__all__ = ["Extrusion", "mobility"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
PELLET_KEEPS = 0.5
"""Fraction of its initial solid below which a pellet gives no more clay."""
OVERFLOW_PASSES = 4
"""Rounds of :meth:`Extrusion.overflow`'s spills to the face neighbours (what a cell
received may spill on)."""
ROUTED_PASSES = 16
"""Rounds of its spills to the nearest cells with room, each filling them (the nearest
may have only a sliver of room: the next round goes further)."""
ROUTED_ROOM = 1e-6
"""Room, relative to its void, below which a cell is passed over by the routed spills
(round-off leaves slivers of 1e-14 of a void that would take a round each)."""
OVERFLOW_MARGIN = 1e-4
"""Contents left below the void after an overflow, relative to it (the local problem
needs room: V_s + m_w / rho < V_max)."""


def mobility(saturation: npt.ArrayLike, settings: ExtrusionSettings) -> FloatArray:
    """M(S) = M_0 clip((S - S_c) / (1 - S_c), 0, 1) [m2/(Pa s)]."""
    ramp = (np.asarray(saturation, dtype=np.float64) - settings.mobile_saturation) / (1.0 - settings.mobile_saturation)
    return settings.mobility * np.clip(ramp, 0.0, 1.0)


class Extrusion(ModelState):
    """Extrusion part of :class:`macro.model.MacroModel`."""

    READS: tuple[str, ...] = ("boundary_inflow", "cells", "counters", "densest_volume", "held", "inert", "material",
             "max_volume", "mesh", "n_pellets", "pellet_initial_solid", "powder_pressure",
             "pressure", "reference_volume", "retention_porosity", "saturations", "settings",
             "solid_mass", "solid_volume", "stress", "volume", "water_mass")
    """What this part reads of the model's state and of its other parts."""

    def extrusion_pressure(self) -> FloatArray:
        """(n,) the pressure that drives the clay [Pa]: a pellet's swelling pressure where it is
        confined (0 at its free volume: a free pellet is not squeezed), at most its
        confining stress (what its surface carries, from the DEM), a cell's powder at
        its swelling pressure where it fills its void (0 where it does not),
        as it pushes on the pellets (:meth:`macro.mechanics.Mechanics.powder_pressure`, at
        the current cells)."""
        n_p = self.n_pellets
        pellets = confined_pressure(self.volume[:n_p], -self.pressure[:n_p], self.solid_mass()[:n_p],
                                    self.reference_volume[:n_p], self.retention_porosity()[:n_p], self.material)
        assert self.stress is not None
        return np.concatenate([np.minimum(pellets, self.stress[:n_p]), self.powder_pressure()[0]])

    def extrude(self, dt: float) -> None:
        """Move clay for ``dt`` [s] down the swelling-pressure differences (module docstring).

        Counts the systems whose outflow was limited to ``max_solid_change`` of their
        solid in ``extrusion_limited``; the water crossing between held and free systems
        is booked as boundary inflow (the held cells are the water supply's side).
        """
        settings = self.settings.extrusion
        ex = self.cells.exchanges
        assert ex is not None
        n_p, n = self.n_pellets, self.volume.size
        pressure = self.extrusion_pressure()
        pairs = ex.pairs[ex.kind > 0]
        i, j = pairs[:, 0], pairs[:, 1]
        donor = np.where(pressure[i] >= pressure[j], i, j)
        moving = mobility(self.saturations(), settings)
        # pellets give clay, never take it, and keep at least PELLET_KEEPS of their own
        # (the DEM's sphere stays a pellet): a pellet-cell exchange flows only outwards
        assert self.pellet_initial_solid is not None
        keeps = self.solid_volume[:n_p] > PELLET_KEEPS * self.pellet_initial_solid
        outwards = (i >= n_p) | ((pressure[i] > pressure[j]) & keeps[np.minimum(i, n_p - 1)])
        geometry = ex.area[ex.kind > 0] / ex.length[ex.kind > 0]
        conductance = np.where(outwards, moving[donor] * geometry, 0.0)
        if not conductance.any():
            return
        cells = np.arange(n) >= n_p
        free = cells & ~self.inert
        # dV_s/dP of confined clay, V / (alpha_v rho_s P), at least at the onset of confinement
        rho_s, m = self.material.grain_density, self.material
        onset = swelling_pressure(self.solid_mass() / free_volume(-self.pressure, self.reference_volume, m),
                                  -self.pressure, self.retention_porosity(), m)
        capacity = self.volume / (m.alpha_v * rho_s * np.maximum(np.maximum(pressure, onset), 1.0))
        new = implicit_pressures(pairs, conductance, pressure, capacity, dt, free)
        new[~free] = pressure[~free]
        flux, limited = limited_fluxes(pairs, conductance, new, self.solid_volume, dt, free | ~cells,
                                       1.0 - settings.max_solid_change)
        self.counters.extrusion_limited_steps += limited
        # each exchange carries the donor's clay: solid, water, V_0 and (pellets) volume
        source = np.where(flux < 0.0, i, j)
        moved = dt * flux
        reference = self.reference_volume[:n_p].copy()
        per_solid = {name: getattr(self, name) / self.solid_volume
                     for name in ("water_mass", "reference_volume", "volume")}
        with self._held_water_booked():
            self.solid_volume = self.solid_volume + edge_rates(pairs, moved, n)
            for name, ratio in per_solid.items():
                setattr(self, name, getattr(self, name) + edge_rates(pairs, moved * ratio[source], n))
        # a pellet's largest volume (its free swelling at zero suction) follows its V_0
        self.max_volume[:n_p] *= self.reference_volume[:n_p] / reference
        self.counters.extruded_volume_m3 += float(np.abs(moved).sum())

    def overflow(self) -> None:
        """Hand what no longer fits in a squeezed cell to cells with room.

        The pellets' motion and the clay received by extrusion can leave a cell's void
        below its contents. Its clay beyond the powder's densest state (solid at the
        smallest porosity: solid, water, V_0 and volume at the cell's own ratios) goes to
        the cells with room; then water beyond its pore space goes to the cells with air
        (a saturated cell squeezed drains at once: its consolidation time, L^2 mu m_v / k,
        is seconds at the cells' size). First to the face neighbours, in proportion to
        their room; what they cannot take, to the nearest active cells with room (in
        face-to-face steps: the squeezed clay extrudes through the full cells between).
        A held cell's water beyond its pore space leaves through the boundary (the held
        cells are the water supply's side). Counted in ``overflowed_cells``; conservative
        to round-off; what no cell can take stays (then capped in the local problem,
        counted)."""
        n_p = self.n_pellets
        cells = slice(n_p, None)
        active = ~self.inert[cells]
        void = self.cells.voids / (1.0 + OVERFLOW_MARGIN)
        with self._held_water_booked():
            for route, passes in ((False, OVERFLOW_PASSES), (True, ROUTED_PASSES)):
                for _ in range(passes):
                    if not self._overflow_pass(cells, active, void, route):
                        break
        held = self.held[cells]
        pore = self.settings.density * np.maximum(void - self.solid_volume[cells], 0.0)
        self.water_mass[cells] = np.where(held, np.minimum(self.water_mass[cells], pore), self.water_mass[cells])

    def _overflow_pass(self, cells: slice, active: npt.NDArray[np.bool_], void: FloatArray, route: bool) -> int:
        """One pass of :meth:`overflow`'s two spills, to the face neighbours or (``route``)
        to the nearest cells with room; returns the number of cells that gave."""
        held = self.held[cells]
        solid = self.densest_volume(cells, with_water=False)
        # a held cell's water drains through the boundary: its solid alone takes room
        filled = np.where(held, solid, self.densest_volume(cells))
        room = np.where(active, np.maximum(void - filled, 0.0), 0.0)
        excess = np.where(active, solid - void, 0.0)
        moved = self._spill(excess / solid, room, filled, ("solid_volume", "water_mass", "reference_volume", "volume"),
                            self._targets(room, void, active, route))
        wet = self.densest_volume(cells)
        air = np.where(active, np.maximum(void - wet, 0.0), 0.0)
        squeezed = np.where(active & ~held, (wet - void) / np.maximum(wet - self.solid_volume[cells], 1e-300), 0.0)
        moved += self._spill(squeezed, air, self.water_mass[cells] / self.settings.density, ("water_mass",),
                             self._targets(air, void, active, route))
        return moved

    def _targets(self, room: FloatArray, void: FloatArray, active: npt.NDArray[np.bool_], route: bool) -> IntArray:
        """(n_c, k) the cells each cell gives to (-1: none): its face neighbours, or
        (``route``) the nearest active cell with ``room`` [m3] of at least
        ``ROUTED_ROOM`` of its ``void`` [m3], in face-to-face steps through active cells."""
        neighbours = self.mesh.neighbours
        if not route:
            return neighbours
        a = np.repeat(np.arange(neighbours.shape[0]), neighbours.shape[1])
        b = neighbours.ravel()
        keep = (b >= 0) & active[a] & active[np.maximum(b, 0)]
        graph = sp.csr_matrix((np.ones(np.count_nonzero(keep)), (a[keep], b[keep])), shape=(room.size,) * 2)
        sources = np.flatnonzero(room > ROUTED_ROOM * void)
        if sources.size == 0:
            return np.full((room.size, 1), -1)
        nearest = dijkstra(graph, directed=False, indices=sources, unweighted=True, min_only=True,
                           return_predecessors=True)[2]
        return np.where(nearest >= 0, nearest, -1)[:, None]

    @contextmanager
    def _held_water_booked(self) -> Iterator[None]:
        """What the held cells lose within the block entered the interior: booked as
        boundary inflow."""
        before = self.water_mass[self.held].sum()
        yield
        self.boundary_inflow += float(before - self.water_mass[self.held].sum())

    def _spill(self, fraction: FloatArray, room: FloatArray, freed: FloatArray, names: tuple[str, ...],
               targets_of: IntArray) -> int:
        """Move ``fraction`` (n_c,) of the named quantities of each cell (those with a
        positive fraction) to its ``targets_of`` (n_c, k; -1: none) in proportion to their
        ``room`` [m3] (n_c,); a target asked by several cells takes at most its room,
        each served in proportion. ``freed`` (n_c,) is the volume the whole of the
        quantities takes [m3] (the clay's densest volume, or the water's own); returns
        the number of cells that gave."""
        n_p = self.n_pellets
        giving = np.flatnonzero(fraction > 0.0)
        if giving.size == 0:
            return 0
        targets = targets_of[giving]
        hit = targets >= 0
        room_of = np.where(hit, room[targets], 0.0)
        capacity = room_of.sum(axis=1)
        wanted = fraction[giving] * freed[giving]
        asked = room_of * np.where(capacity > 0.0, np.minimum(wanted / np.where(capacity > 0.0, capacity, 1.0), 1.0),
                                   0.0)[:, None]
        total = np.bincount(targets[hit], asked[hit], minlength=room.size)
        served = np.where(total > room, room / np.where(total > 0.0, total, 1.0), 1.0)
        share = np.where(hit, asked * served[targets], 0.0) / freed[giving][:, None]
        for name in names:
            values = getattr(self, name)
            given = values[n_p + giving][:, None] * share
            values[n_p + giving] -= given.sum(axis=1)
            np.add.at(values, n_p + targets[hit], given[hit])
        count = int(np.count_nonzero(share.sum(axis=1) > 0.0))
        self.counters.overflowed_cell_steps += count
        return count
