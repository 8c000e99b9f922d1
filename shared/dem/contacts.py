"""Contact detection by cell lists, and the Verlet contact list of a DEM state."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from shared.dem import _kernels
from shared.dem.parameters import DEMParameters

if TYPE_CHECKING:
    from shared.dem.state import DEMState

__all__ = [
    "detect_contacts", "bond_pairs", "pair_values", "contacts_need_update", "update_contacts",
    "held_points", "point_bins",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def point_bins(
    positions: FloatArray, cell_size: float
) -> tuple[FloatArray, FloatArray, IntArray, IntArray, IntArray]:
    """Points sorted into a grid of cells at least ``cell_size`` [m] wide (stretched to
    fit the points' bounding box, and no more cells than about one per point).

    Returns
    -------
    lower : ndarray, shape (3,)
        The box's lower corner [m].
    spacing : ndarray, shape (3,)
        Cell widths [m].
    dims : ndarray of int64, shape (3,)
        Cells per axis (flat index x-major, z fastest).
    cell_start, cell_points : ndarray of int64
        Points of cell c: ``cell_points[cell_start[c]:cell_start[c + 1]]``.
    """
    lower, upper = _kernels.bounding_box(positions)
    extent = upper - lower
    # cap the grid at about one cell per point so sparse clouds do not allocate huge grids
    cell_size = max(cell_size,
                    float(np.prod(extent + cell_size) / positions.shape[0]) ** (1.0 / 3.0))
    dims = np.maximum(np.floor(extent / cell_size).astype(np.int64), 1)
    spacing = extent / dims + 1e-300
    cell_of_point = _kernels.cell_indices(positions, lower, spacing, dims)
    cell_start, cell_points = _kernels.bin_points(cell_of_point, int(np.prod(dims)))
    return lower, spacing, dims, cell_start, cell_points


def detect_contacts(
    positions: npt.ArrayLike,
    radii: npt.ArrayLike,
    cutoff_factor: float = 1.0,
    skin: float = 0.0,
) -> IntArray:
    """All pairs closer than ``cutoff_factor (r_i + r_j) + skin``, by a cell list.

    Parameters
    ----------
    positions
        (n, 3) point centres [m].
    radii
        (n,) interaction radii [m].
    cutoff_factor
        Interaction radius factor [1]; 1 gives the overlapping pairs.
    skin
        Extra detection margin [m] (Verlet skin).

    Returns
    -------
    ndarray of int64, shape (n_pairs, 2)
        Pairs (i, j), i < j, sorted lexicographically (deterministic).

    Notes
    -----
    Cells are cubes no smaller than the largest cutoff, so every pair lies in the same
    or an adjacent cell: O(n) work for bounded radius ratios.
    """
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    radii = np.ascontiguousarray(radii, dtype=np.float64)
    n = positions.shape[0]
    if positions.ndim != 2 or positions.shape[1] != 3 or radii.shape != (n,):
        raise ValueError("positions must have shape (n, 3) and radii shape (n,)")
    if n < 2:
        return np.empty((0, 2), dtype=np.int64)
    if not cutoff_factor > 0.0 or skin < 0.0:
        raise ValueError("cutoff_factor must be > 0 and skin >= 0")
    _, _, dims, cell_start, cell_points = point_bins(
        positions, 2.0 * cutoff_factor * float(radii.max()) + skin)
    capacity = 4 * n
    while True:
        pairs, count = _kernels.find_pairs(
            positions, radii, float(cutoff_factor), float(skin), dims, cell_start,
            cell_points, capacity,
        )
        if count <= capacity:
            return pairs
        capacity = count


def bond_pairs(
    positions: npt.ArrayLike, radii: npt.ArrayLike, tolerance: float = 1e-9
) -> IntArray:
    """Pairs in contact: centre distance at most (1 + tolerance)(r_i + r_j).

    Parameters
    ----------
    positions
        (n, 3) point centres [m].
    radii
        (n,) interaction radii [m].
    tolerance
        Relative margin [1] so that exactly touching points (a regular grid) count.

    Returns
    -------
    ndarray of int64, shape (n_bonds, 2)
        Sorted pairs i < j.
    """
    return detect_contacts(positions, radii, 1.0 + tolerance, 0.0)


def pair_values(
    pairs: IntArray, keyed_pairs: IntArray, values: npt.ArrayLike
) -> npt.NDArray[np.float64]:
    """``values`` of the pairs found in ``keyed_pairs``, 0 for the others.

    Parameters
    ----------
    pairs
        (m, 2) pairs i < j to look up, sorted lexicographically (as
        :func:`detect_contacts` returns them).
    keyed_pairs
        (k, 2) pairs i < j, sorted lexicographically (e.g. ``DEMState.bonds``).
    values
        (k, ...) value of each keyed pair (a scalar or an array per pair).

    Raises
    ------
    ValueError
        If either list is not sorted (the lookup is one merge of the two).
    """
    values = np.asarray(values, dtype=np.float64)
    rows = _kernels.match_sorted_pairs(
        np.ascontiguousarray(pairs, dtype=np.int64).reshape(-1, 2),
        np.ascontiguousarray(keyed_pairs, dtype=np.int64).reshape(-1, 2),
    )
    flat = np.ascontiguousarray(values.reshape(values.shape[0], int(np.prod(values.shape[1:]))))
    return _kernels.gather_rows(flat, rows).reshape((rows.shape[0],) + values.shape[1:])


def contacts_need_update(state: DEMState) -> bool:
    """True once some pair may have closed the Verlet skin since the last detection.

    A pair's gap shrinks by at most the sum of the two displacements plus the two
    radius increments, so the list stays exact while twice the largest of each stays
    below the skin.
    """
    contacts = state.contacts
    moved = _kernels.largest_distance(state.positions, contacts.detection_positions)
    grown = state.radii - contacts.detection_radii
    return bool(2.0 * moved + 2.0 * grown.max(initial=0.0) >= contacts.skin)


def update_contacts(
    state: DEMState, parameters: DEMParameters, force: bool = False
) -> bool:
    """Rebuild the contact list when needed, carrying the shear history of kept pairs.

    Parameters
    ----------
    state
        Assembly; ``state.contacts`` is replaced in place.
    parameters
        Interaction radius factor [1].
    force
        Rebuild even if the list is still valid.

    Returns
    -------
    bool
        Whether the list was rebuilt.
    """
    if not (force or contacts_need_update(state)):
        return False
    contacts = state.contacts
    pairs = detect_contacts(
        state.positions, state.radii, parameters.interaction_radius_factor, contacts.skin
    )
    shear = pair_values(pairs, contacts.pairs, contacts.shear_forces)
    contacts.pairs = pairs
    contacts.shear_forces = shear
    contacts.reference_overlaps = pair_values(pairs, state.bonds, state.bond_overlaps)
    contacts.detection_positions = state.positions.copy()
    contacts.detection_radii = state.radii.copy()
    return True


def held_points(state: DEMState, normal_forces: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    """Points that carry a compressive contact force or hold an intact bond.

    Parameters
    ----------
    state
        Assembly (its contact list as the forces were computed, bonds and broken flags).
    normal_forces
        (n_contacts,) normal force per candidate contact [N], as :func:`step` reports it.
    """
    return _kernels.holding_points(state.contacts.pairs, normal_forces, state.bonds,
                                   state.bond_broken, state.n_points)
