"""Checkpoint files of a micro run (micro.checkpoint): the state round trip, files of older
versions and other configurations ignored, the flow numbering of the last remesh kept."""

from __future__ import annotations

import numpy as np

from micro.checkpoint import load_checkpoint, save_checkpoint
from micro.hydration import FlowSystem
from micro.pellet import SpecimenSpec, initial_state
from shared.checkpointer import Checkpointer
from shared.mesh import update_mesh
from tests._defaults import CLAY, DEM


def test_checkpoint_round_trip_and_files_of_older_versions_are_ignored(tmp_path):
    state = initial_state(SpecimenSpec(edge_length=4e-3, n_points=125, seed=3), None, None, CLAY, DEM)
    system = FlowSystem.for_mesh(state.mesh)
    state.dem.bond_broken[:3] = True
    path = tmp_path / "case.checkpoint.npz"
    save_checkpoint(Checkpointer(path, "abc"), state, system, [], 1.0)
    loaded, _, _, _, _ = load_checkpoint(Checkpointer(path, "abc"), CLAY)
    np.testing.assert_array_equal(loaded.dem.bond_broken, state.dem.bond_broken)
    np.testing.assert_array_equal(loaded.dem.bond_overlaps, state.dem.bond_overlaps)
    assert load_checkpoint(Checkpointer(path, "another config"), CLAY) is None
    with np.load(path) as data:
        older = {k: data[k] for k in data.files if k != "dem_bond_broken"}
    np.savez(path, **older)
    assert load_checkpoint(Checkpointer(path, "abc"), CLAY) is None



def test_the_flow_numbering_of_the_last_remesh_is_kept(tmp_path):
    """The unknowns are numbered by the centroids at the last remesh: a checkpoint after
    the points moved (here a 2 % stretch, which inverts no cell) restores that
    numbering, not the one of the current geometry."""
    state = initial_state(SpecimenSpec(edge_length=4e-3, n_points=216, seed=3), None, None,
                          CLAY, DEM)
    system = FlowSystem.for_mesh(state.mesh)
    state.dem.positions[:] = state.dem.positions * np.array([1.02, 1.0, 0.98])
    state.mesh = update_mesh(state.mesh, state.dem.positions)
    rebuilt = FlowSystem.for_mesh(state.mesh, system.dirichlet)
    assert not np.array_equal(rebuilt.pattern.free_cells, system.pattern.free_cells)
    path = tmp_path / "case.checkpoint.npz"
    save_checkpoint(Checkpointer(path, "abc"), state, system, [], 1.0)
    _, loaded, _, _, balance = load_checkpoint(Checkpointer(path, "abc"), CLAY)
    assert balance is None
    for name in ("dirichlet", "free_cells", "free_index", "indptr", "indices",
                 "diagonal_position", "facet_position"):
        np.testing.assert_array_equal(getattr(loaded.pattern, name),
                                      getattr(system.pattern, name), err_msg=name)
