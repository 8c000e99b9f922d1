"""The local pressure-volume problem of every pellet and powder cell (Sec. 4.3): the
suction and volume that hold a system's water under its confining stress."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from macro.laws import confined_volume
from macro.newton import PVProblem, solve_pressure_volume

FloatArray = npt.NDArray[np.float64]


class PressureVolume:
    """Pressure-volume part of :class:`macro.model.MacroModel`."""

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

    def solve_local(self) -> None:
        """Pressure-volume problem of every system not held (Sec. 4.3)."""
        free = np.flatnonzero(~self.held & ~self.inert)
        n_p = self.n_pellets
        # a cell squeezed by swollen pellets keeps at least its solid at the smallest
        # porosity (the lower porosity clamp, minPoroClamp) and its water (counted)
        needed = self.densest_volume(slice(None)) * (1.0 + 1e-6)
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

