"""What the parts of the macro model read of each other, declared for the type checker.

Each part of :class:`macro.model.MacroModel` (a mixin: :mod:`macro.geometry`,
:mod:`macro.hydraulics`, ...) reads the model's state and the other parts' methods
through ``self``; it lists those names in ``READS`` (checked by tests/macro/test_parts.py).
:class:`ModelState` declares them with their types, so that mypy checks each part's code
against them and the model against the parts (a field of another type, a method of
another signature is an error). The parts derive from it only for the type checker: at
run time it is :class:`object`, and the parts stay plain mixins.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

__all__ = ["ModelState"]

if TYPE_CHECKING:
    from abc import abstractmethod

    import numpy as np
    import numpy.typing as npt

    from macro.laws import MixtureParameters
    from macro.parts import CellGeometry, Contacts, Counters
    from macro.readings import Readings
    from macro.settings import MacroSettings
    from shared.mesh import Mesh
    from shared.upscaling import PermeabilityTable

    FloatArray = npt.NDArray[np.float64]
    BoolArray = npt.NDArray[np.bool_]

    class ModelState:
        """The model's fields (:class:`macro.model.MacroModel` documents them) and the
        parts' methods that another part calls (abstract here: a part defines each)."""

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
        steps: int
        boundary_inflow: float
        counters: Counters
        latest_readings: Readings | None
        trial_time_step: float
        spins: FloatArray | None
        pellet_frames: FloatArray | None
        stress: FloatArray | None
        powder_porosity: float
        initial_interior_water: float
        occupied_loss: FloatArray | None
        pellet_initial_solid: FloatArray | None

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
else:
    ModelState = object
