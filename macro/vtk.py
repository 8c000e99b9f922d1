"""ParaView snapshots of the mixture (``macro.vtk_snapshots`` > 0).

One snapshot is an unstructured grid (``.vtu``, meshio) whose points are the pellet
centres and the container's points, and whose cells are the Delaunay tetrahedra holding
the powder: point data per pellet (``radius_m``, ``suction_Pa``, ``saturation``,
``swelling_strain``, ``is_pellet``; 0 on the container's points), cell data per
tetrahedron (``suction_Pa``, ``saturation``, ``swelling_strain``,
``powder_pressure_Pa``, ``has_powder``). Snapshots are taken when the simulated time
first passes each of ``vtk_snapshots`` times spaced geometrically from 100 s to
``max_time_s`` and at the end, into ``results/macro/<case>_vtk/step_<step>.vtu``;
``<case>.pvd`` lists them with the simulated time in days as time step. The fields
with their units: docs/macro.md, "macro.vtk".
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

from macro.model import MacroModel
from shared.io import atomic_write
from shared.vtk import write_collection

DAY = 86400.0
"""Seconds per day: the collection's time unit."""

__all__ = ["snapshot_mesh", "SnapshotSeries"]


def snapshot_mesh(model: MacroModel) -> meshio.Mesh:
    """The mixture's state as a meshio mesh (no file I/O)."""
    n_p = model.n_pellets
    sat = model.saturations()
    strain = np.where(model.inert, 0.0, model.volume / model.reference_volume - 1.0)
    pressure = model.powder_pressure()[0]
    # the container points carry the pellet fields as 0 (is_pellet tells them apart)
    n_w = model.container.shape[0]

    def pellet_field(values: np.ndarray) -> np.ndarray:
        return np.concatenate([values, np.zeros(n_w)])

    point_data = {"radius_m": pellet_field(model.radii), "suction_Pa": pellet_field(-model.pressure[:n_p]),
                  "saturation": pellet_field(sat[:n_p]), "swelling_strain": pellet_field(strain[:n_p]),
                  "is_pellet": np.concatenate([np.ones(n_p, np.int8), np.zeros(n_w, np.int8)])}
    cells = slice(n_p, None)
    cell_data = {"suction_Pa": [-model.pressure[cells]], "saturation": [sat[cells]],
                 "swelling_strain": [strain[cells]], "powder_pressure_Pa": [pressure],
                 "has_powder": [(~model.inert[cells]).astype(np.int8)]}
    return meshio.Mesh(model.vertex_positions(), [("tetra", model.mesh.tetrahedra)],
                       point_data=point_data, cell_data=cell_data)


class SnapshotSeries:
    """The snapshots of one run in ``directory`` and their collection ``<name>.pvd``.

    Parameters
    ----------
    directory
        ``results/macro/<case>_vtk``; snapshots of an earlier run of the case (not
        resumed) are removed.
    name
        The case.
    count
        Number of snapshot times between 100 s and ``max_time`` [s].
    max_time
        ``macro.numerics.max_time_s`` [s].
    resumed
        Keep the snapshots already written (a resumed run).
    """

    def __init__(self, directory: Path, name: str, count: int, max_time: float, resumed: bool) -> None:
        self.directory = Path(directory)
        self.collection = self.directory / f"{name}.pvd"
        self.times = np.geomspace(100.0, max_time, count) if count > 0 else np.empty(0)
        self.entries: list[tuple[float, str]] = []
        if resumed and self.directory.is_dir():
            self.entries = sorted(_listed(self.directory))
        elif self.directory.is_dir():
            for old in self.directory.glob("step_*.vtu"):
                old.unlink()
            self.collection.unlink(missing_ok=True)

    def due(self, model: MacroModel) -> bool:
        """Whether the run passed a snapshot time since the last snapshot."""
        last = self.entries[-1][0] if self.entries else -1.0
        return bool(np.any((self.times > last) & (self.times <= model.time)))

    def write(self, model: MacroModel) -> None:
        """Write a snapshot of the current state and update the collection."""
        name = f"step_{model.steps:07d}.vtu"
        mesh = snapshot_mesh(model)
        atomic_write(self.directory / name, lambda tmp: meshio.write(tmp, mesh, file_format="vtu"))
        self.entries = [e for e in self.entries if e[1] != name] + [(model.time, name)]
        write_collection(self.collection, [(t / DAY, f) for t, f in self.entries])


def _listed(directory: Path) -> list[tuple[float, str]]:
    """(time [s], file) of the snapshots a collection lists, its time steps being in days
    (a resumed run appends to them)."""
    import xml.etree.ElementTree as ET

    found = list(directory.glob("*.pvd"))
    if not found:
        return []
    root = ET.parse(found[0]).getroot()
    return [(float(d.get("timestep", "0")) * DAY, str(d.get("file"))) for d in root.iter("DataSet")]
