"""The typed parts of the macro model's state beside its arrays over systems: the cells'
geometry at the current positions, the contacts' history and the counted events.

:class:`macro.model.MacroModel` composes them; readers (the readings, the column's
permeability, benchmarks and tests) read them as public attributes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from macro.mixture import Exchanges

__all__ = ["CellGeometry", "Contacts", "Counters", "Readings"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass
class CellGeometry:
    """What the mesh gives the cells at the pellets' current positions.

    Attributes
    ----------
    solid_angles
        (n_c, 4) solid angle of each cell at its four vertices [sr].
    voids
        (n_c,) each cell's tetrahedron less the pellets' clay shares [m3].
    pressures
        (n_c,) the powder's swelling pressure in each cell at the last relaxation [Pa].
    exchanges
        The water paths between systems (:func:`macro.mixture.exchanges`), inert cells left out.
    edges
        (n_e, 2) the mesh's edges, and ``edges_of`` the tetrahedra they were computed
        for (recomputed when the mesh changes).
    """

    solid_angles: FloatArray
    voids: FloatArray
    pressures: FloatArray | None = None
    exchanges: Exchanges | None = None
    edges: IntArray | None = None
    edges_of: IntArray | None = None


@dataclass
class Contacts:
    """The contacts' history, carried from one relaxation to the next.

    Attributes
    ----------
    wall_plastic
        (n_p, 3) plastic overlap of each pellet on the curved wall and the lower and upper
        plates [m].
    wall_shear
        (n_p, 3, 3) tangential force of each pellet on those three surfaces [N].
    pairs
        (m, 2) pellet pairs detected at the last relaxation (None before the first).
    shear
        (m, 3) tangential force of each pair, acting on its first pellet [N].
    plastic
        (m,) plastic overlap of each pair [m].
    """

    wall_plastic: FloatArray
    wall_shear: FloatArray
    pairs: IntArray | None = None
    shear: FloatArray | None = None
    plastic: FloatArray | None = None


@dataclass
class Counters:
    """Events counted over a run; written as the result's attributes under these names."""

    newton_iterations: int = 0
    newton_fallbacks: int = 0
    capped_cell_steps: int = 0
    overflowed_cell_steps: int = 0
    extrusion_limited_steps: int = 0
    extruded_volume_m3: float = 0.0
    flux_limited_system_steps: int = 0
    remeshes: int = 0
    dem_substeps: int = 0
    phase_seconds: dict[str, float] = field(default_factory=lambda: dict.fromkeys(
        ("remesh", "transport", "extrusion", "newton", "dem"), 0.0))
    """Wall time of each phase of the step [s] (written as seconds_<phase>)."""

    def attributes(self) -> dict[str, int | float]:
        """The counters as the result's attributes: each by its name, the phases' wall
        times as ``seconds_<phase>``."""
        named = {name: getattr(self, name) for name in self.__dataclass_fields__ if name != "phase_seconds"}
        return named | {f"seconds_{phase}": value for phase, value in self.phase_seconds.items()}


@dataclass
class Readings:
    """Wall readings of one instant: pressures of the named sensors (sensors,) and of the
    equal height bands (bands,) [Pa], axial pressures on the upper and lower plates [Pa],
    the unbalanced force ratio (mean resultant over mean contact force) and the net one
    (the pellets' net resultant over the plates' mean load) [1]."""

    sensors: FloatArray
    bands: FloatArray
    axial_upper: float
    axial_lower: float
    unbalanced: float
    net_unbalanced: float
