"""The macro model's state, and what its parts read of each other.

Each part of :class:`macro.model.MacroModel` (a mixin: :mod:`macro.geometry`,
:mod:`macro.hydraulics`, ...) reads the model's state and the other parts' methods
through ``self``; it lists those names in ``READS`` (checked by tests/macro/test_parts.py).
:class:`ModelState` holds the state's fields, once, and declares for the type checker the
parts' methods that another part calls, so that mypy checks each part's code against
them and the model against the parts (a field of another type, a method of another
signature is an error).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from macro.laws import MixtureParameters
from macro.packing import Packing
from macro.parts import CellGeometry, Contacts, Counters, Readings
from macro.settings import MacroSettings
from shared.mesh import Mesh
from shared.upscaling import PermeabilityTable

__all__ = ["ModelState"]

if TYPE_CHECKING:
    from abc import abstractmethod

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


@dataclass
class ModelState:
    """State of the mixture.

    Systems 0..n_p-1 are pellets, n_p..n_p+n_c-1 cells. Arrays over systems: water mass
    [kg], volume V [m3], pressure p [Pa], solid volume V_s [m3], reference volume V_0
    [m3], largest volume V_max [m3], held (Dirichlet end cells). The mesh's vertices are
    the pellet centres, then the fixed ``container`` points (``on_plate`` over all
    vertices: the container points on the plates). ``packing`` is the packing the model
    was built on.
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
    held: BoolArray
    inert: BoolArray
    initial_void: FloatArray
    container: FloatArray
    on_plate: BoolArray
    cells: CellGeometry
    contacts: Contacts
    packing: Packing
    time: float = 0.0
    steps: int = 0
    boundary_inflow: float = 0.0
    counters: Counters = field(default_factory=Counters)
    latest_readings: Readings | None = None
    trial_time_step: float = 0.0
    spins: FloatArray | None = None
    pellet_frames: FloatArray | None = None
    stress: FloatArray | None = None
    powder_porosity: float = 0.0
    initial_interior_water: float = 0.0
    occupied_loss: FloatArray | None = None
    pellet_initial_solid: FloatArray | None = None

    if TYPE_CHECKING:
        # the parts' methods that another part calls (abstract here: a part defines each)
            @property
            @abstractmethod
            def n_pellets(self) -> int: ...
            @property
            @abstractmethod
            def n_cells(self) -> int: ...
            @property
            @abstractmethod
            def n_vertices(self) -> int: ...
            @abstractmethod
            def vertex_radii(self) -> FloatArray: ...
            @abstractmethod
            def clay_radii(self) -> FloatArray: ...
            @abstractmethod
            def remesh(self) -> None: ...
            @abstractmethod
            def move_geometry(self) -> bool: ...
            @abstractmethod
            def hold_boundary(self) -> None: ...
            @abstractmethod
            def saturations(self) -> FloatArray: ...
            @abstractmethod
            def retention_porosity(self) -> FloatArray: ...
            @abstractmethod
            def overflow(self) -> None: ...
            @abstractmethod
            def solid_mass(self) -> FloatArray: ...
            @abstractmethod
            def swelling_volume(self, suction: FloatArray) -> FloatArray: ...
            @abstractmethod
            def densest_volume(self, systems: slice | npt.NDArray[np.int64], with_water: bool = True) -> FloatArray: ...
            @abstractmethod
            def powder_pressure(self) -> tuple[FloatArray, FloatArray]: ...
            @abstractmethod
            def powder_wall_loads(self) -> tuple[FloatArray, FloatArray, float, float]: ...
            @abstractmethod
            def interior_water(self) -> float: ...
