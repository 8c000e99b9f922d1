"""VTK snapshots of the pellet state for ParaView (optional, ``micro.vtk_snapshots``).

One snapshot is an unstructured grid (``.vtu``, written by meshio) of the DEM points and
the Delaunay tetrahedra, with cell data ``pressure_Pa``, ``suction_Pa``, ``saturation``
and ``porosity``, point data ``radius_m`` and ``suction_Pa``, and the cracks as a second
block of ``line`` cells with ``crack_aperture_m`` and ``crack_imbibed`` (NaN and -1 on
the tetrahedra, NaN in the tetrahedron fields on the lines). A ``.pvd`` collection lists
the snapshots; its time step is the hydration progress in decades of suction,
``log10(s_0 / s_i)`` (0 at 132 MPa, 1 at 13.2 MPa: ParaView needs increasing times, the
suction decreases, and the model's own clock is a relaxation pseudo-time). Every file is
written to a temporary name and renamed. Fields in full: docs/micro.md, "micro.vtk".
"""

from __future__ import annotations

import re
from pathlib import Path

import meshio
import numpy as np
import numpy.typing as npt

from micro.forces import point_suction
from micro.hydration import PelletState
from shared.io import atomic_write
from shared.vtk import write_collection

__all__ = ["snapshot_mesh", "write_snapshot", "write_checkpoint_snapshot", "suction_progress",
           "clear_snapshots", "snapshot_name"]

FloatArray = npt.NDArray[np.float64]

_SNAPSHOT = re.compile(r"^checkpoint_(\d+)\.vtu$")


def snapshot_name(index: int) -> str:
    """File name of the snapshot of checkpoint ``index``: ``checkpoint_<index:02d>.vtu``."""
    return f"checkpoint_{index:02d}.vtu"


def snapshot_mesh(state: PelletState, cracks: bool = True) -> meshio.Mesh:
    """The pellet state as a meshio mesh (no file I/O).

    Parameters
    ----------
    state
        Pellet state; ``state.mesh`` must be the mesh of ``state.dem.positions``.
    cracks
        Whether to add the open cracks of ``state.cracks`` (if any) as ``line`` cells.

    Returns
    -------
    meshio.Mesh
        Points: DEM point positions (n_points, 3) [m]. Cell blocks: ``tetra``
        (state.mesh.tetrahedra), then ``line`` (crack point pairs) if there are cracks.
        Data and units as in the module docstring.

    Raises
    ------
    ValueError
        If the mesh's vertex count or a cell array's length does not match the state.
    """
    positions = np.ascontiguousarray(state.dem.positions, dtype=np.float64)
    mesh = state.mesh
    n_cells = mesh.n_cells
    if mesh.points.shape != positions.shape:
        raise ValueError(f"the mesh has {mesh.points.shape[0]} vertices, the DEM "
                         f"{positions.shape[0]} points")
    cell_fields = {
        "pressure_Pa": np.asarray(state.pressure, dtype=np.float64),
        "suction_Pa": np.maximum(-np.asarray(state.pressure, dtype=np.float64), 0.0),
        "saturation": np.asarray(state.saturation, dtype=np.float64),
        "porosity": np.asarray(state.porosity, dtype=np.float64),
    }
    for name, values in cell_fields.items():
        if values.shape != (n_cells,):
            raise ValueError(f"{name}: {values.shape[0]} values for {n_cells} cells")
    point_data = {
        "radius_m": np.asarray(state.dem.radii, dtype=np.float64),
        "suction_Pa": point_suction(mesh.tetrahedra, mesh.volumes, cell_fields["suction_Pa"],
                                    positions.shape[0]),
    }
    network = state.cracks if cracks else None
    n_lines = 0 if network is None else int(network.pairs.shape[0])
    cells: list[tuple[str, npt.NDArray[np.int64]]] = [
        ("tetra", np.ascontiguousarray(mesh.tetrahedra, dtype=np.int64))
    ]
    cell_data: dict[str, list[npt.NDArray]] = {
        name: [values] for name, values in cell_fields.items()
    }
    cell_data["crack_aperture_m"] = [np.full(n_cells, np.nan)]
    cell_data["crack_imbibed"] = [np.full(n_cells, -1, dtype=np.int8)]
    if network is not None and n_lines:
        cells.append(("line", np.ascontiguousarray(network.pairs, dtype=np.int64)))
        for name in cell_fields:
            cell_data[name].append(np.full(n_lines, np.nan))
        cell_data["crack_aperture_m"].append(np.asarray(network.apertures, dtype=np.float64))
        cell_data["crack_imbibed"].append(np.asarray(network.imbibed, dtype=np.int8))
    return meshio.Mesh(positions, cells, point_data=point_data, cell_data=cell_data)


def write_snapshot(path: str | Path, state: PelletState, cracks: bool = True) -> Path:
    """Write one snapshot of the pellet state to a ``.vtu`` file, atomically.

    Parameters
    ----------
    path
        Output file (``.vtu``); its directory is created if missing.
    state, cracks
        As in :func:`snapshot_mesh`.

    Returns
    -------
    Path
        ``path``.
    """
    grid = snapshot_mesh(state, cracks)
    # binary, zlib-compressed appended data (meshio's default for vtu)
    return atomic_write(path, lambda tmp: meshio.write(tmp, grid, file_format="vtu"))


def _snapshots(directory: Path) -> list[tuple[int, str]]:
    """(index, file name) of the snapshots in a directory, by index."""
    if not directory.is_dir():
        return []
    found = [(int(m.group(1)), p.name) for p in directory.iterdir()
             if (m := _SNAPSHOT.match(p.name))]
    return sorted(found)


def suction_progress(suctions: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """The collection's time steps: hydration progress ``log10(s_0 / s_i)`` [decades].

    Parameters
    ----------
    suctions
        Checkpoint suctions [Pa], decreasing, the first the initial one.

    Returns
    -------
    numpy.ndarray
        0 for the first checkpoint, increasing by one per decade of suction relieved.
    """
    s = np.asarray(suctions, dtype=float)
    return np.log10(s[0] / s)


def write_checkpoint_snapshot(
    directory: str | Path, name: str, index: int, state: PelletState,
    suctions: npt.ArrayLike | None = None,
) -> Path:
    """Snapshot of checkpoint ``index`` and the run's collection ``<name>.pvd``.

    The collection lists every ``checkpoint_*.vtu`` up to ``index`` in ``directory``
    (a resumed run keeps the snapshots written before it was killed), time step =
    the hydration progress ``log10(suctions[0] / suctions[i])`` in decades of suction
    (:func:`suction_progress`; increasing, as ParaView needs), or the checkpoint index
    when ``suctions`` is not given.

    Parameters
    ----------
    directory
        Snapshot directory, e.g. ``results/micro/<case>_vtk``.
    name
        Stem of the collection file (the case).
    index
        Checkpoint index.
    state
        Pellet state after the checkpoint was measured (cracks up to date).
    suctions
        Suctions [Pa] of all the run's checkpoints (``micro.checkpoints_suction_pa``).

    Returns
    -------
    Path
        The snapshot written.
    """
    directory = Path(directory)
    written = write_snapshot(directory / snapshot_name(index), state)
    progress = None if suctions is None else suction_progress(suctions)
    entries = [(float(i) if progress is None else float(progress[i]), file)
               for i, file in _snapshots(directory) if i <= index]
    write_collection(directory / f"{name}.pvd", entries)
    return written


def clear_snapshots(directory: str | Path, name: str) -> None:
    """Remove the snapshots and collection of an earlier run (a fresh run starts clean)."""
    directory = Path(directory)
    for _, file in _snapshots(directory):
        (directory / file).unlink(missing_ok=True)
    (directory / f"{name}.pvd").unlink(missing_ok=True)
