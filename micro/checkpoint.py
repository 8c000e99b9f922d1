"""Checkpoint files of a micro run: the whole coupled state after a suction checkpoint.

A run killed between checkpoints resumes from the last file with the same configuration
hash and continues bit for bit as if it had not stopped (the contact list and its shear
history are saved too). Files are written to a temporary name and renamed.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from micro.hydration import FlowSystem, PelletState, update_cracks
from shared.dem.state import ContactList, DEMState
from shared.dem.walls import Walls
from shared.materials import ClayParameters
from shared.io import atomic_write
from shared.mesh import mesh_from_tetrahedra

__all__ = ["save_checkpoint", "load_checkpoint"]

_DEM_ARRAYS = ("positions", "velocities", "spins", "radii", "reference_radii", "masses",
               "inertia", "bonds", "bond_overlaps", "bond_broken", "fixed")
_CONTACT_ARRAYS = ("pairs", "shear_forces", "detection_positions", "detection_radii",
                   "reference_overlaps")
_CELL_ARRAYS = ("pressure", "saturation", "solid_volume", "porosity", "reference_extent")


def _jsonable(record: dict[str, Any]) -> dict[str, Any]:
    return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in record.items()}


def save_checkpoint(
    path: Path, digest: str, state: PelletState, system: FlowSystem,
    records: list[dict[str, Any]], reference_volume: float,
) -> None:
    """Write the state, its flow system's boundary cells and the records so far, atomically."""
    arrays: dict[str, Any] = {f"dem_{k}": getattr(state.dem, k) for k in _DEM_ARRAYS}
    arrays.update({f"contacts_{k}": getattr(state.dem.contacts, k) for k in _CONTACT_ARRAYS})
    arrays.update({f"cell_{k}": getattr(state, k) for k in _CELL_ARRAYS})
    arrays.update(mesh_tetrahedra=state.mesh.tetrahedra, mesh_neighbours=state.mesh.neighbours,
                  dirichlet=system.dirichlet)
    if state.hydraulic_forces is not None:
        arrays["hydraulic_forces"] = state.hydraulic_forces
    if state.walls is not None:
        arrays.update(walls_lower=state.walls.lower, walls_upper=state.walls.upper,
                      walls_active=state.walls.active, walls_target=state.walls.target_stress)
    scalars = {"digest": digest, "time": state.time, "dem_time": state.dem.time,
               "n_remesh": state.n_remesh, "skin": state.dem.contacts.skin,
               "reference_volume": reference_volume,
               "walls_servo": None if state.walls is None else bool(state.walls.servo),
               "records": [_jsonable(r) for r in records]}
    atomic_write(path, lambda tmp: np.savez(tmp, meta=np.array(json.dumps(scalars)), **arrays))


def load_checkpoint(
    path: Path, digest: str, material: ClayParameters
) -> tuple[PelletState, FlowSystem, list[dict[str, Any]], float] | None:
    """The saved state, flow system, records and reference volume, or None if absent or stale.

    A file written under another configuration (different hash) or by a version of the
    code that saved fewer arrays is ignored. The crack network, a function of the saved
    state, is rebuilt.
    """
    if not path.is_file():
        return None
    with np.load(path) as data:
        meta = json.loads(str(data["meta"]))
        needed = [f"dem_{k}" for k in _DEM_ARRAYS] + [f"contacts_{k}" for k in _CONTACT_ARRAYS]
        if meta["digest"] != digest or not set(needed) <= set(data.files):
            return None
        contacts = ContactList(skin=meta["skin"], **{k: data[f"contacts_{k}"] for k in _CONTACT_ARRAYS})
        dem = DEMState(contacts=contacts, time=meta["dem_time"],
                       **{k: data[f"dem_{k}"] for k in _DEM_ARRAYS})
        mesh = mesh_from_tetrahedra(dem.positions, data["mesh_tetrahedra"],
                                    data["mesh_neighbours"], reorient=False)
        walls = None
        if meta["walls_servo"] is not None:
            walls = Walls(lower=data["walls_lower"], upper=data["walls_upper"],
                          active=data["walls_active"], servo=meta["walls_servo"],
                          target_stress=data["walls_target"])
        state = PelletState(
            dem=dem, mesh=mesh, walls=walls, time=meta["time"], n_remesh=meta["n_remesh"],
            hydraulic_forces=data["hydraulic_forces"] if "hydraulic_forces" in data else None,
            **{k: data[f"cell_{k}"] for k in _CELL_ARRAYS},
        )
        system = FlowSystem.for_mesh(mesh, data["dirichlet"])
    update_cracks(state, material)
    records = [{k: (np.asarray(v) if isinstance(v, list) else v) for k, v in r.items()}
               for r in meta["records"]]
    return state, system, records, float(meta["reference_volume"])
