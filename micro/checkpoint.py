"""Checkpoint files of a micro run: the whole coupled state after a suction checkpoint,
or between two flow steps of the balance at the next one (``micro.snapshot_interval_s``).

A killed run resumes from the last file with the same configuration hash and continues
bit for bit as if it had not stopped (``tests/micro/test_resume.py``). Besides the
state's own arrays, a file holds the flow system's numbering of the unknowns
(:class:`shared.fv.FlowPattern`, rebuilding it would change the round-off of every
later solve), the solver's reuse state (:meth:`shared.solver.SPDSolver.reuse_state`),
the wall time spent so far per phase (:class:`shared.progress.PhaseClock`) and, between
flow steps, the balance's progress (:class:`micro.hydration.BalanceProgress`). A file is
data only (:mod:`shared.snapshot`: the configuration hash and a checksum in its header,
checked before anything is used); one that cannot be read, is damaged or was written by
a version that saved fewer arrays is moved aside with one log line and the case starts
from the beginning. Details: docs/micro.md, "micro.checkpoint".
"""

from __future__ import annotations

from dataclasses import asdict, fields
from typing import Any

import numpy as np

from micro.hydration import BalanceProgress, FlowSystem, PelletState, update_cracks
from shared.checkpointer import Checkpointer
from shared.dem.state import ContactList, DEMState
from shared.dem.walls import Walls
from shared.errors import SnapshotError
from shared.fv import FlowPattern
from shared.materials import ClayParameters
from shared.mesh import Mesh
from shared.solver import SPDSolver

__all__ = ["save_checkpoint", "load_checkpoint"]

_DEM_ARRAYS = ("positions", "velocities", "spins", "radii", "reference_radii", "masses",
               "inertia", "bonds", "bond_overlaps", "bond_broken", "fixed")
_CONTACT_ARRAYS = ("pairs", "shear_forces", "detection_positions", "detection_radii",
                   "reference_overlaps")
_CELL_ARRAYS = ("pressure", "saturation", "solid_volume", "porosity", "reference_extent")
_PATTERN_ARRAYS = ("free_cells", "free_index", "indptr", "indices", "diagonal_position",
                   "facet_position")


def _jsonable(record: dict[str, Any]) -> dict[str, Any]:
    return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in record.items()}


def save_checkpoint(
    checkpointer: Checkpointer, state: PelletState, system: FlowSystem,
    records: list[dict[str, Any]], reference_volume: float,
    balance: BalanceProgress | None = None,
) -> None:
    """Write the state, its flow system and the records so far to the checkpointer's
    file, atomically, with the wall time so far (:meth:`shared.checkpointer.Checkpointer.save`).

    ``balance`` is where the balance at the next checkpoint stands, for a file written
    between two flow steps.
    """
    arrays: dict[str, Any] = {f"dem_{k}": getattr(state.dem, k) for k in _DEM_ARRAYS}
    arrays.update({f"contacts_{k}": getattr(state.dem.contacts, k) for k in _CONTACT_ARRAYS})
    arrays.update({f"cell_{k}": getattr(state, k) for k in _CELL_ARRAYS})
    arrays.update({f"mesh_{f.name}": getattr(state.mesh, f.name) for f in fields(Mesh)})
    arrays["dirichlet"] = system.dirichlet
    arrays.update({f"pattern_{k}": getattr(system.pattern, k) for k in _PATTERN_ARRAYS})
    solver_scalars, solver_arrays = system.solver.reuse_state()
    arrays.update({f"solver_{k}": v for k, v in solver_arrays.items()})
    if state.hydraulic_forces is not None:
        arrays["hydraulic_forces"] = state.hydraulic_forces
    if state.walls is not None:
        arrays.update(walls_lower=state.walls.lower, walls_upper=state.walls.upper,
                      walls_active=state.walls.active, walls_target=state.walls.target_stress)
    scalars = {"time": state.time, "dem_time": state.dem.time,
               "n_remesh": state.n_remesh, "skin": state.dem.contacts.skin,
               "reference_volume": reference_volume,
               "walls_servo": None if state.walls is None else bool(state.walls.servo),
               "solver": solver_scalars,
               "records": [_jsonable(r) for r in records],
               "balance": None if balance is None else asdict(balance)}
    checkpointer.save(scalars, arrays)


def load_checkpoint(
    checkpointer: Checkpointer, material: ClayParameters
) -> tuple[PelletState, FlowSystem, list[dict[str, Any]], float, BalanceProgress | None] | None:
    """The saved state, flow system, records, reference volume and, for a file written
    between two flow steps, the balance in progress; None if there is no usable file.

    A file written under another configuration or code (different hash) is ignored; one
    that fails its checks, or written by a version of the code that saved fewer arrays, is
    moved aside (:meth:`shared.checkpointer.Checkpointer.resume`). The crack network, a function of
    the saved state, is rebuilt.
    """
    needed = ([f"dem_{k}" for k in _DEM_ARRAYS] + [f"contacts_{k}" for k in _CONTACT_ARRAYS]
              + [f"pattern_{k}" for k in _PATTERN_ARRAYS] + [f"mesh_{f.name}" for f in fields(Mesh)])

    def restore(meta: dict[str, Any], data: dict[str, Any]) -> tuple[
            PelletState, FlowSystem, list[dict[str, Any]], float, BalanceProgress | None]:
        missing = sorted(set(needed) - set(data))
        if missing or "solver" not in meta:
            raise SnapshotError(f"written by an older version (no {', '.join(missing) or 'solver state'})")
        contacts = ContactList(skin=meta["skin"], **{k: data[f"contacts_{k}"] for k in _CONTACT_ARRAYS})
        dem = DEMState(contacts=contacts, time=meta["dem_time"],
                       **{k: data[f"dem_{k}"] for k in _DEM_ARRAYS})
        # the mesh as it was (its geometry recomputed from the points rounds differently)
        mesh = Mesh(**{f.name: data[f"mesh_{f.name}"] for f in fields(Mesh)})
        walls = None
        if meta["walls_servo"] is not None:
            walls = Walls(lower=data["walls_lower"], upper=data["walls_upper"],
                          active=data["walls_active"], servo=meta["walls_servo"],
                          target_stress=data["walls_target"])
        state = PelletState(
            dem=dem, mesh=mesh, walls=walls, time=meta["time"], n_remesh=meta["n_remesh"],
            hydraulic_forces=data.get("hydraulic_forces"),
            **{k: data[f"cell_{k}"] for k in _CELL_ARRAYS},
        )
        dirichlet = data["dirichlet"]
        pattern = FlowPattern(dirichlet=dirichlet,
                              **{k: data[f"pattern_{k}"] for k in _PATTERN_ARRAYS})
        system = FlowSystem(dirichlet, pattern, SPDSolver())
        system.solver.restore_reuse_state(
            meta["solver"], {k: data[f"solver_{k}"] for k in ("indptr", "indices", "data")
                             if f"solver_{k}" in data})
        update_cracks(state, material)
        records = [{k: (np.asarray(v) if isinstance(v, list) else v) for k, v in r.items()}
                   for r in meta["records"]]
        balance = None if meta.get("balance") is None else BalanceProgress(**meta["balance"])
        return state, system, records, float(meta["reference_volume"]), balance

    return checkpointer.resume(restore)
