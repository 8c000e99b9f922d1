"""The local pressure-volume problem of every pellet and powder cell (Sec. 4.3): the
suction and volume that hold a system's water under its confining stress."""

from __future__ import annotations

from typing import cast

import numpy as np
import numpy.typing as npt

from macro.laws import confined_volume
from macro.newton import PVProblem, solve_pressure_volume
from macro.state import ModelState

FloatArray = npt.NDArray[np.float64]


class PressureVolume(ModelState):
    """Pressure-volume part of :class:`macro.model.MacroModel`."""

    READS: tuple[str, ...] = ("cells", "counters", "held", "inert", "material", "max_volume", "mesh", "n_pellets",
             "pressure", "reference_volume", "retention_porosity", "settings", "solid_volume",
             "stress", "volume", "water_mass")
    """What this part reads of the model's state and of its other parts."""

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


    def densest_volume(self, systems: slice | npt.NDArray[np.int64], with_water: bool = True) -> FloatArray:
        """Smallest volume of the clay of ``systems`` [m3]: its solid at the smallest
        porosity (the lower bound of ``macro.powder.porosity_clamp``) and, ``with_water``,
        no less than its solid and water."""
        solid = self.solid_volume[systems]
        densest = solid / (1.0 - float(self.settings.powder["porosity_clamp"][0]))
        if with_water:
            densest = np.maximum(densest, solid + self.water_mass[systems] / self.settings.density)
        return densest

    def growth_room(self) -> FloatArray:
        """(n_p,) largest growth of each pellet's clay volume in this step [m3]: its share of
        the room of the active cells around it (their void less their powder's densest
        state), each cell's room shared among its pellets by solid angle. A cell's void is
        its tetrahedron less Omega / (4 pi) of each pellet's clay volume, so pellets that
        take their shares leave every cell its densest state on the whole; a cell that
        one pellet squeezes more than its share hands the excess on (:meth:`overflow`)."""
        n_p = self.n_pellets
        tet = self.mesh.tetrahedra
        # a held cell's water leaves through the boundary as it is squeezed: its solid alone counts
        densest = np.where(self.held[n_p:], self.densest_volume(slice(n_p, None), with_water=False),
                           self.densest_volume(slice(n_p, None)))
        room = np.where(self.inert[n_p:], 0.0, np.maximum(self.cells.voids - densest, 0.0))
        share = np.where(tet < n_p, self.cells.solid_angles, 0.0)
        total = share.sum(axis=1)
        parts = room[:, None] * share / np.where(total > 0.0, total, 1.0)[:, None]
        pellet = tet < n_p
        # weighted: floats (numpy's stub types every bincount as integers)
        return cast(FloatArray, np.bincount(tet[pellet], parts[pellet], minlength=n_p))

    def solve_local(self) -> None:
        """Pressure-volume problem of every system not held (Sec. 4.3).

        A pellet grows at most by its :meth:`growth_room`, so that no cell is squeezed
        below its powder's densest state by the swelling; a cell whose void is still
        below it (squeezed by the pellets' motion) is capped there, holding more than
        its void (counted in ``capped_cells``: an event, not a state the model relies on).
        """
        free = np.flatnonzero(~self.held & ~self.inert)
        n_p = self.n_pellets
        needed = self.densest_volume(slice(None)) * (1.0 + 1e-6)
        capped = (self.max_volume < needed) & ~self.inert
        capped[:n_p] = False
        self.counters.capped_cell_steps += int(np.count_nonzero(capped))
        self.max_volume = np.where(capped, needed, self.max_volume)
        limit = self.max_volume.copy()
        limit[:n_p] = np.minimum(limit[:n_p], np.maximum(self.volume[:n_p] + self.growth_room(), needed[:n_p]))

        def names(k: int) -> str:
            i = int(free[k])
            return f"pellet {i}" if i < n_p else f"cell {i - n_p}"

        assert self.stress is not None
        problem = PVProblem(
            self.water_mass[free], self.solid_volume[free], self.reference_volume[free],
            limit[free], self.settings.density, self.settings.max_suction, names,
            None if self.settings.retention_follows_porosity else self.retention_porosity()[free],
            self.stress[free], self.solid_mass()[free],
        )
        volume, pressure, iterations, fallbacks = solve_pressure_volume(
            problem, self.material, self.settings.newton, self.volume[free], -self.pressure[free])
        self.volume[free], self.pressure[free] = volume, pressure
        self.counters.newton_iterations += iterations
        self.counters.newton_fallbacks += fallbacks
