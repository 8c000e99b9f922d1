"""Set-up of the pellet specimen and the measurements taken at each suction checkpoint."""

from __future__ import annotations

import copy
from concurrent.futures import Executor, Future
from dataclasses import dataclass
from functools import partial
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
import xarray as xr
from scipy import ndimage

from micro.fabric import crack_fabric
from micro.hydration import (
    FlowSystem,
    HydrationSettings,
    PelletState,
    advance_to_balance,
    conductances,
    triangulate,
    update_cracks,
)
from micro.permeability import FrozenState, checkpoint_permeabilities
from micro.permeability.steady import PHASES
from shared.dem.parameters import DEMParameters
from shared.dem.points import cube_points
from shared.dem.state import new_state
from shared.dem.walls import walls_around
from shared.errors import InputError
from shared.materials import ClayParameters
from shared.mesh import mesh_from_tetrahedra, porosity_at_points
from shared.retention import saturation as retention_saturation

__all__ = ["SpecimenSpec", "CheckpointMeasurement", "centred_grid", "initial_state", "settle",
           "measure_checkpoint", "POROSITY_BINS"]

FloatArray = npt.NDArray[np.float64]
POROSITY_BINS = np.linspace(0.0, 1.0, 51)


@dataclass(frozen=True)
class SpecimenSpec:
    """The cube specimen.

    Attributes
    ----------
    edge_length
        Cube edge [m] (thesis: 7 mm).
    n_points
        Requested number of DEM points.
    layout
        ``"grid"`` (jittered cubic grid) or ``"random"`` (random sequential packing).
    jitter
        Grid jitter as a fraction of the spacing [1].
    confinement
        Confining stress on the three axes [Pa]; 0 for free swelling.
    rotations
        Whether points rotate. The points discretise a continuum rather than stand for
        grains: on a jittered cubic lattice, free rotations let the points roll, a
        shear mechanism that buckles under the suction's confinement, so they are
        locked by default.
    seed
        Seed of the point layout.
    offset
        Shift (x, y, z) of the cube's centre from the centre of the scanned specimen
        [m], to cut sub-regions for a scale study (thesis Sec. 3.5.9).
    """

    edge_length: float = 7e-3
    n_points: int = 1500
    layout: Literal["grid", "random"] = "grid"
    jitter: float = 0.1
    confinement: float = 0.0
    rotations: bool = False
    seed: int = 0
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)


def _grid_name(porosity: xr.DataArray) -> str:
    """The grid's file (``encoding['source']`` of a grid read from disk), for messages."""
    source = porosity.encoding.get("source")
    return f"porosity grid {source}" if source else "porosity grid (micro.sample)"


def _outside_specimen(nan: np.ndarray, blocks: tuple[np.ndarray, ...]) -> np.ndarray:
    """Which of the given NaN blocks belong to a NaN region reaching the grid's border
    (the air around the specimen), rather than to a hole inside the specimen."""
    labels, _ = ndimage.label(nan)
    border = np.zeros_like(nan)
    for axis in range(nan.ndim):
        border[(slice(None),) * axis + (0,)] = True
        border[(slice(None),) * axis + (-1,)] = True
    return np.isin(labels[blocks], labels[border & nan])


def centred_grid(
    porosity: xr.DataArray,
    edge_length: float,
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> xr.DataArray:
    """The part of a porosity grid around a cube [0, edge_length]^3 at its specimen's centre.

    The centre is the mean position of the grid's finite (specimen) values, moved by
    ``offset`` (x, y, z) [m]; the grid is shifted there and cropped to the cube plus
    one grid spacing on each side, the nodes that trilinear interpolation inside the
    cube needs.

    Raises
    ------
    shared.errors.InputError
        If the grid is not ``(z, y, x)``, holds no finite value, is coarser than half the
        cube (coordinates in mm read as m), does not span the cube, or holds NaN around it
        (the cube reaches outside the specimen, or the grid has a hole inside it); the
        message names the grid file and the config key to change.
    """
    name = _grid_name(porosity)
    if porosity.ndim != 3 or set(porosity.dims) != {"z", "y", "x"}:
        raise InputError(
            f"{name}: dims {tuple(porosity.dims)}; expected ('z', 'y', 'x') in m, as "
            "rule imaging_porosity writes them (micro.sample names the grid)"
        )
    finite = np.isfinite(porosity.values)
    if not finite.any():
        raise InputError(f"{name}: no finite value (no block inside the specimen; see "
                         "imaging.mask and imaging.min_specimen_fraction)")
    keys = "micro.specimen_size_m (or the case's specimen_size_m and offset_m)"
    for axis in porosity.dims:
        spacing = float(np.median(np.abs(np.diff(porosity[axis].values)))) if porosity[axis].size > 1 else np.inf
        if not spacing <= 0.5 * edge_length:
            raise InputError(
                f"{name}: its spacing along {axis} ({spacing:.4g} m) exceeds half the "
                f"{edge_length * 1e3:g} mm cube ({keys}): fewer than two grid blocks across "
                "it; are the grid's coordinates in metres?"
            )
    shifted = {}
    for axis_index, axis in enumerate(porosity.dims):
        coordinate = porosity[axis].values
        counts = finite.sum(axis=tuple(i for i in range(3) if i != axis_index))
        centre = float((coordinate * counts).sum() / counts.sum()) + offset["xyz".index(str(axis))]
        shifted[axis] = coordinate - (centre - 0.5 * edge_length)
    moved = porosity.assign_coords(shifted)
    crop = {}
    for axis in porosity.dims:
        coordinate = moved[axis].values
        # a grid that spans exactly the cube must not be refused by a rounding unit
        slack = 1e-9 * max(edge_length, float(np.ptp(coordinate)))
        if coordinate.min() > slack or coordinate.max() < edge_length - slack:
            raise InputError(
                f"{name}: does not span the {edge_length * 1e3:g} mm cube along {axis} (grid "
                f"from {coordinate.min() * 1e3:.4g} to {coordinate.max() * 1e3:.4g} mm, cube "
                f"from 0 to {edge_length * 1e3:g} mm, centred in the specimen): use a "
                f"smaller {keys}"
            )
        low = coordinate[coordinate <= slack].max()
        high = coordinate[coordinate >= edge_length - slack].min()
        crop[axis] = (coordinate >= low) & (coordinate <= high)
    cropped = moved.isel(crop)
    missing = ~np.isfinite(cropped.values)
    if missing.any():
        local = np.nonzero(missing)
        blocks = tuple(np.flatnonzero(crop[axis])[k] for axis, k in zip(cropped.dims, local, strict=True))
        outside = _outside_specimen(~finite, blocks)
        first = int(np.argmax(outside)) if outside.any() else 0
        position = ", ".join(f"{axis} = {float(cropped[axis][k[first]]) * 1e3:.4g} mm"
                             for axis, k in zip(cropped.dims, local, strict=True))
        if outside.any():
            raise InputError(
                f"{name}: the {edge_length * 1e3:g} mm cube reaches outside the scanned "
                f"pellet (NaN at {position} of the cube, {int(missing.sum())} block(s)): "
                f"use a smaller {keys}"
            )
        raise InputError(
            f"{name}: NaN at {position} of the {edge_length * 1e3:g} mm cube, inside the "
            f"specimen ({int(missing.sum())} block(s)): a hole in the grid, e.g. blocks below "
            "imaging.min_specimen_fraction; check imaging.mask and imaging.min_specimen_fraction"
        )
    return cropped


def initial_state(
    spec: SpecimenSpec,
    porosity_grid: xr.DataArray | None,
    homogeneous_porosity: float | None,
    material: ClayParameters,
    parameters: DEMParameters,
) -> PelletState:
    """Points, mesh, porosity (CT grid or homogeneous) and retention state at s0.

    Parameters
    ----------
    spec
        Specimen geometry and layout.
    porosity_grid
        ``porosity(z, y, x)`` with coordinates in m, or None for a homogeneous specimen.
    homogeneous_porosity
        Porosity of a homogeneous specimen [1]; default: the grid's mean over the
        specimen's cells if a grid is given, else the material's reference porosity.
    material, parameters
        Clay and DEM parameters.
    """
    rng = np.random.default_rng(spec.seed)
    positions, radii = cube_points(spec.n_points, rng, spec.edge_length, spec.layout, spec.jitter)
    # the as-built cloud is at rest: its overlaps store no stress (see settle)
    dem = new_state(positions, radii, parameters, stress_free_bonds=True)
    if not spec.rotations:
        dem.inertia[:] = np.inf
    mesh = mesh_from_tetrahedra(dem.positions, *triangulate(dem.positions))
    field = _porosity_field(spec, mesh.centroids, porosity_grid, homogeneous_porosity, material)
    suction = material.initial_suction
    walls = None
    if spec.confinement > 0.0:
        walls = walls_around(dem.positions, dem.radii, spec.confinement)
    return PelletState(
        dem=dem,
        mesh=mesh,
        pressure=np.full(mesh.n_cells, -suction),
        saturation=retention_saturation(suction, field, material),
        solid_volume=(1.0 - field) * mesh.volumes,
        porosity=field.copy(),
        reference_extent=np.ptp(dem.positions, axis=0),
        walls=walls,
    )


def _porosity_field(
    spec: SpecimenSpec,
    points: FloatArray,
    porosity_grid: xr.DataArray | None,
    homogeneous_porosity: float | None,
    material: ClayParameters,
) -> FloatArray:
    """Porosity at points of the as-built cube (see :func:`initial_state`)."""
    if homogeneous_porosity is not None:
        return np.full(points.shape[0], homogeneous_porosity)
    if porosity_grid is not None:
        return porosity_at_points(points, centred_grid(porosity_grid, spec.edge_length, spec.offset))
    return np.full(points.shape[0], material.reference_porosity)


def settle(
    state: PelletState,
    system: FlowSystem,
    spec: SpecimenSpec,
    porosity_grid: xr.DataArray | None,
    homogeneous_porosity: float | None,
    settings: HydrationSettings,
    material: ClayParameters,
    parameters: DEMParameters,
) -> tuple[FlowSystem, dict[str, float]]:
    """Settle the as-built cloud under the initial suction, then give it the CT porosity.

    The scanned pellet is the pellet at the initial suction s0, loaded by its own
    Bishop stress S s0 (about 50 MPa at 132 MPa), not the stress-free cloud of
    :func:`initial_state`, which that stress compacts (by 11-19 % in volume at 125 to
    8 000 points). So the cloud first reaches balance at s0, and then every cell takes
    the porosity of the grid (or the homogeneous value) at the point where its material
    was built, the mean of its vertices' as-built positions, with solid volume
    (1 - porosity) V and saturation S(s0) of its new porosity: the specimen at s0 has the
    measured porosity, and volumetric strains count from this state.

    Parameters
    ----------
    state, system
        The state of :func:`initial_state` and its flow system (updated in place).
    spec, porosity_grid, homogeneous_porosity, material, parameters
        As for :func:`initial_state`.
    settings
        Hydration settings of the balance.

    Returns
    -------
    system : FlowSystem
        The flow system, rebuilt if the mesh was remeshed.
    diagnostics : dict
        Those of :func:`micro.hydration.advance_to_balance` for the settling.
    """
    built = state.dem.positions.copy()
    suction = material.initial_suction
    system, diagnostics = advance_to_balance(state, system, suction, settings, material, parameters)
    mesh = mesh_from_tetrahedra(state.dem.positions, state.mesh.tetrahedra,
                                state.mesh.neighbours, reorient=False)
    field = _porosity_field(spec, built[mesh.tetrahedra].mean(axis=1), porosity_grid,
                            homogeneous_porosity, material)
    state.mesh = mesh
    state.porosity = field
    state.solid_volume = (1.0 - field) * mesh.volumes
    state.pressure = np.full(mesh.n_cells, -suction)
    state.saturation = retention_saturation(suction, field, material)
    state.reference_extent = np.ptp(state.dem.positions, axis=0)
    update_cracks(state, material)
    return system, diagnostics


@dataclass
class CheckpointMeasurement:
    """A checkpoint's record whose permeabilities a worker process may still be solving.

    Attributes
    ----------
    record
        Everything but ``permeability`` and ``permeability_tensor``.
    permeabilities
        The axes' permeabilities and the tensors, or the worker's future of them.
    """

    record: dict[str, object]
    permeabilities: Future | tuple[dict[str, dict[str, float]], FloatArray]

    @property
    def in_background(self) -> bool:
        """Whether the permeabilities come from a worker process."""
        return isinstance(self.permeabilities, Future)

    def done(self) -> bool:
        """Whether the permeabilities are there (:meth:`result` would not wait)."""
        permeabilities = self.permeabilities
        return not isinstance(permeabilities, Future) or permeabilities.done()

    def result(self) -> dict[str, Any]:
        """The whole record (waits for the worker)."""
        done = self.permeabilities
        axes, tensor = done.result() if isinstance(done, Future) else done
        return {**self.record, "permeability_tensor": tensor,
                "permeability": np.array([[axes[p][a] for a in "xyz"] for p in ("water", "gas")])}


def measure_checkpoint(
    state: PelletState,
    suction: float,
    reference_volume: float,
    material: ClayParameters,
    cracks: bool = True,
    executor: Executor | None = None,
    background: bool = False,
) -> CheckpointMeasurement:
    """Everything recorded at a checkpoint (docs/design.md §2, ``results/micro``).

    The crack network is updated here (the hydration goes on with it). ``executor`` (a
    worker process, :func:`micro.pool.measurement_executor`) makes the eight independent
    permeability solves: with ``background``, all of them as one task on copies of the
    cell state while the caller goes on (the next checkpoint's hydration), else half of
    them while this process makes the others. The results do not depend on it.

    Returns
    -------
    CheckpointMeasurement
        Its record: ``saturation``, ``eps_v``, ``porosity_mean``, ``permeability`` (2, 3)
        [m2] (water, gas x x, y, z; wall-flux method), ``permeability_tensor`` (2, 3, 3)
        [m2] (water, gas; linear pressure on all six walls, velocity averaged over the
        inner 80 %: :func:`micro.permeability.permeability_tensor`), crack counts, areas
        [m2], volumes [m3], fabric tensors (3, 3) for all, imbibed and gas-filled cracks,
        and the porosity histogram.
    """
    update_cracks(state, material)
    phases = {phase: conductances(state, phase, material, cracks) for phase in PHASES}
    # the tensor's wall layers leave the crack mouths free (no boundary short circuit)
    mouths = np.zeros(state.mesh.n_cells, dtype=bool)
    if cracks and state.cracks is not None:
        mouths[state.mesh.facet_cells[state.cracks.patch_facets].ravel()] = True
    permeabilities: Future | tuple
    if executor is not None and background:
        # the executor pickles the arguments later, in its own thread, while the hydration
        # goes on in place (the mesh's points are the DEM's positions): copied now
        mesh, saturation, porosity = copy.deepcopy((state.mesh, state.saturation, state.porosity))
        permeabilities = executor.submit(partial(
            checkpoint_permeabilities, FrozenState(mesh, saturation, porosity, suction, material, phases),
            sealed=mouths))
    else:
        permeabilities = checkpoint_permeabilities(
            FrozenState(state.mesh, state.saturation, state.porosity, suction, material, phases),
            sealed=mouths, executor=executor)
    volumes = state.mesh.volumes
    assert state.cracks is not None  # update_cracks built the network
    fabric = crack_fabric(state.cracks.normals, state.cracks.areas, state.cracks.apertures,
                          state.cracks.imbibed)
    histogram, _ = np.histogram(state.porosity, bins=POROSITY_BINS, weights=volumes)
    return CheckpointMeasurement({
        "saturation": state.mean_saturation(),
        "eps_v": float(volumes.sum() / reference_volume - 1.0),
        "porosity_mean": float((state.porosity * volumes).sum() / volumes.sum()),
        "porosity_hist": histogram / volumes.sum(),
        "crack_count": fabric.count,
        "crack_count_imbibed": fabric.count_imbibed,
        "crack_count_gas": fabric.count_gas,
        "crack_area": fabric.area,
        "crack_area_imbibed": fabric.area_imbibed,
        "crack_area_gas": fabric.area_gas,
        "crack_volume": fabric.volume,
        "crack_fabric": fabric.tensor,
        "crack_fabric_imbibed": fabric.tensor_imbibed,
        "crack_fabric_gas": fabric.tensor_gas,
        "time": state.time,
        "n_remesh": state.n_remesh,
    }, permeabilities)
