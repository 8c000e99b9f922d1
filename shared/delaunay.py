"""Delaunay tetrahedralisation of points: from scratch, or repaired from a previous one.

A tetrahedron is a Delaunay cell if (for points in general position, only if) its
circumsphere holds no other point, which a uniform grid of the points decides per cell
in O(1). :func:`update_delaunay` keeps the previous cells whose circumsphere is still
empty (insphere determinant, points within its rounding bound count as inside),
triangulates only the vertices of the others (scipy/Qhull, one thread per group of
face-connected components), and keeps the new cells empty among all points. The union
is the whole tetrahedralisation exactly when its volume equals the convex hull's and no
face has more than two cells, which is checked; otherwise the caller triangulates from
scratch. Why the subset suffices: docs/micro.md, "shared.delaunay".
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from functools import partial

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from numba import get_num_threads, njit, prange
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, Delaunay, QhullError

from shared.dem import point_bins
from shared.tetrahedra import cell_geometry

__all__ = ["delaunay_tetrahedra", "qhull_delaunay", "same_cells", "update_delaunay"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

# a point this close to a circumsphere (relative squared distance) is decided by the
# insphere determinant; one whose determinant is within its rounding bound is inside
_SPHERE_BAND = 1e-6
_DETERMINANT_BOUND = 1e-12
# relative mismatch of the union's volume and the hull's that rejects the repair
_VOLUME_TOLERANCE = 1e-10
# face keys pack three vertex indices into an int64
_MAX_POINTS = 1 << 21


@njit(cache=True)
def _inside_or_undecided(points: FloatArray, cell: IntArray, p: int) -> bool:
    """Whether point p lies inside the circumsphere of the positively oriented cell,
    or so close that the insphere determinant's rounding could hide the sign."""
    rows = np.empty((4, 4))
    for m in range(4):
        squared = 0.0
        for d in range(3):
            rows[m, d] = points[cell[m], d] - points[p, d]
            squared += rows[m, d] ** 2
        rows[m, 3] = squared
    determinant = 0.0
    permanent = 0.0
    for m in range(4):
        i, j, k = [r for r in range(4) if r != m]
        minor = (rows[i, 0] * (rows[j, 1] * rows[k, 2] - rows[j, 2] * rows[k, 1])
                 - rows[i, 1] * (rows[j, 0] * rows[k, 2] - rows[j, 2] * rows[k, 0])
                 + rows[i, 2] * (rows[j, 0] * rows[k, 1] - rows[j, 1] * rows[k, 0]))
        bound = (abs(rows[i, 0]) * (abs(rows[j, 1] * rows[k, 2]) + abs(rows[j, 2] * rows[k, 1]))
                 + abs(rows[i, 1]) * (abs(rows[j, 0] * rows[k, 2]) + abs(rows[j, 2] * rows[k, 0]))
                 + abs(rows[i, 2]) * (abs(rows[j, 0] * rows[k, 1]) + abs(rows[j, 1] * rows[k, 0])))
        sign = 1.0 if m % 2 == 1 else -1.0
        determinant += sign * rows[m, 3] * minor
        permanent += rows[m, 3] * bound
    return determinant <= _DETERMINANT_BOUND * permanent


@njit(cache=True, parallel=True)
def _empty_spheres(
    points: FloatArray, tetrahedra: IntArray, signed: FloatArray, centres: FloatArray,
    low: FloatArray, spacing: FloatArray, shape: IntArray, start: IntArray, order: IntArray,
    min_volume: float,
) -> npt.NDArray[np.bool_]:
    """Positively oriented cells above ``min_volume`` whose circumsphere holds no point
    but their own vertices. The distance to the circumcentre decides clear cases; a
    point near the sphere (far-away circumcentres of flat hull cells are not accurate)
    is decided by the insphere determinant."""
    n = tetrahedra.shape[0]
    empty = np.zeros(n, dtype=np.bool_)
    for c in prange(n):
        if not signed[c] > min_volume:
            continue
        a = tetrahedra[c, 0]
        cx, cy, cz = centres[c, 0], centres[c, 1], centres[c, 2]
        radius2 = (points[a, 0] - cx) ** 2 + (points[a, 1] - cy) ** 2 + (points[a, 2] - cz) ** 2
        if not np.isfinite(radius2):
            continue
        radius = np.sqrt(radius2)
        near = radius2 * (1.0 + _SPHERE_BAND)
        box = np.empty((3, 2), dtype=np.int64)
        for d, centre in enumerate((cx, cy, cz)):
            box[d, 0] = max(int(np.floor((centre - radius - low[d]) / spacing[d])), 0)
            box[d, 1] = min(int(np.floor((centre + radius - low[d]) / spacing[d])), shape[d] - 1)
        inside = False
        for i in range(box[0, 0], box[0, 1] + 1):
            for j in range(box[1, 0], box[1, 1] + 1):
                row = (i * shape[1] + j) * shape[2]
                for s in range(start[row + box[2, 0]], start[row + box[2, 1] + 1]):
                    p = order[s]
                    if (p == a or p == tetrahedra[c, 1] or p == tetrahedra[c, 2]
                            or p == tetrahedra[c, 3]):
                        continue
                    distance2 = ((points[p, 0] - cx) ** 2 + (points[p, 1] - cy) ** 2
                                 + (points[p, 2] - cz) ** 2)
                    if distance2 < near and _inside_or_undecided(points, tetrahedra[c], p):
                        inside = True
                        break
                if inside:
                    break
            if inside:
                break
        empty[c] = not inside
    return empty


@njit(cache=True)
def _sorted_rows(tetrahedra: IntArray) -> IntArray:
    rows = tetrahedra.copy()
    for c in range(rows.shape[0]):
        for a in range(1, 4):
            value, b = rows[c, a], a
            while b > 0 and rows[c, b - 1] > value:
                rows[c, b] = rows[c, b - 1]
                b -= 1
            rows[c, b] = value
    return rows


@njit(cache=True)
def same_cells(old: IntArray, new: IntArray, n_points: int) -> IntArray:
    """Old cell with the same four vertices as each new cell, -1 where there is none.

    The old cells are listed under their smallest vertex (a counting sort), so each new
    cell is compared with the few old cells that share its smallest vertex.
    """
    old_rows, new_rows = _sorted_rows(old), _sorted_rows(new)
    start = np.zeros(n_points + 1, dtype=np.int64)
    for c in range(old_rows.shape[0]):
        start[old_rows[c, 0] + 1] += 1
    for v in range(n_points):
        start[v + 1] += start[v]
    listed = np.empty(old_rows.shape[0], dtype=np.int64)
    fill = start[:-1].copy()
    for c in range(old_rows.shape[0]):
        listed[fill[old_rows[c, 0]]] = c
        fill[old_rows[c, 0]] += 1
    same = np.full(new_rows.shape[0], -1, dtype=np.int64)
    for c in range(new_rows.shape[0]):
        v = new_rows[c, 0]
        for slot in range(start[v], start[v + 1]):
            o = listed[slot]
            if (old_rows[o, 1] == new_rows[c, 1] and old_rows[o, 2] == new_rows[c, 2]
                    and old_rows[o, 3] == new_rows[c, 3]):
                same[c] = o
                break
    return same


@njit(cache=True)
def _open_faces(
    tetrahedra: IntArray, neighbours: IntArray, n_points: int
) -> tuple[IntArray, IntArray]:
    """Key (three sorted vertices packed in an int64) and slot (4 * cell + face) of
    every face without a neighbour."""
    count = 0
    for c in range(tetrahedra.shape[0]):
        for k in range(4):
            if neighbours[c, k] < 0:
                count += 1
    keys = np.empty(count, dtype=np.int64)
    slots = np.empty(count, dtype=np.int64)
    f = 0
    for c in range(tetrahedra.shape[0]):
        for k in range(4):
            if neighbours[c, k] >= 0:
                continue
            a, b, d = [tetrahedra[c, m] for m in range(4) if m != k]
            if a > b:
                a, b = b, a
            if b > d:
                b, d = d, b
            if a > b:
                a, b = b, a
            keys[f] = (a * n_points + b) * n_points + d
            slots[f] = 4 * c + k
            f += 1
    return keys, slots


def _link_open_faces(
    tetrahedra: IntArray, neighbours: IntArray, n_points: int
) -> bool:
    """Pair the faces without a neighbour that two cells share (in place); False if a
    face belongs to more than two cells."""
    keys, slots = _open_faces(tetrahedra, neighbours, n_points)
    order = np.argsort(keys, kind="stable")
    keys, slots = keys[order], slots[order]
    equal = keys[1:] == keys[:-1]
    if np.any(equal[1:] & equal[:-1]):
        return False
    first, second = slots[:-1][equal], slots[1:][equal]
    flat = neighbours.reshape(-1)
    flat[first] = second // 4
    flat[second] = first // 4
    return True


def qhull_delaunay(points: FloatArray) -> Delaunay:
    """Qhull's plain Delaunay tetrahedralisation of (n, 3) float64 points, as scipy's
    object (for callers that also locate points in it, ``find_simplex``).

    Raises
    ------
    ValueError
        If Qhull fails (coplanar or duplicated points).
    """
    try:
        return Delaunay(points)
    except QhullError as error:
        raise ValueError(f"Delaunay failed (coplanar or duplicated points?): {error}") from error


def delaunay_tetrahedra(points: npt.ArrayLike) -> tuple[FloatArray, IntArray, IntArray]:
    """Plain Delaunay tetrahedralisation of points (scipy/Qhull).

    Parameters
    ----------
    points
        Point coordinates [m], shape (n_points, 3), n_points >= 5, not coplanar.

    Returns
    -------
    points : ndarray, shape (n_points, 3)
        The points as contiguous float64 [m].
    tetrahedra : ndarray of int64, shape (n_cells, 4)
        Vertex indices of each cell.
    neighbours : ndarray of int64, shape (n_cells, 4)
        Cell across the face opposite each vertex, -1 on the hull.

    Raises
    ------
    ValueError
        If points are not finite, not of shape (n >= 5, 3), or all coplanar.
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] < 5:
        raise ValueError(f"points must have shape (n >= 5, 3), got {points.shape}")
    if not np.all(np.isfinite(points)):
        raise ValueError("points contain NaN or inf")
    triangulation = qhull_delaunay(points)
    return (
        points,
        triangulation.simplices.astype(np.int64),
        triangulation.neighbors.astype(np.int64),
    )


def update_delaunay(
    points: npt.ArrayLike, tetrahedra: npt.ArrayLike, neighbours: npt.ArrayLike,
    min_volume: float,
) -> tuple[IntArray, IntArray] | None:
    """Delaunay tetrahedralisation of moved points from the previous one's cells.

    Parameters
    ----------
    points
        Point coordinates [m], shape (n_points, 3).
    tetrahedra, neighbours
        Cells of a Delaunay tetrahedralisation of the same points before they moved,
        positively oriented then (as :class:`shared.mesh.Mesh` keeps them; flat cells
        may be missing), and the cell across the face opposite each vertex, -1 for none.
    min_volume
        Cells of this volume or less [m3] are left out (flat), the caller's rule.

    Returns
    -------
    tetrahedra, neighbours : ndarray of int64, shape (n, 4)
        Positively oriented cells (the previous cells still Delaunay first, in their
        order, then the new ones) and their neighbours (-1 on the hull and next to
        left-out flat cells); None when the result cannot be certified (the caller
        triangulates from scratch).
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    previous = np.ascontiguousarray(tetrahedra, dtype=np.int64)
    n_points = points.shape[0]
    if n_points >= _MAX_POINTS:
        return None
    # about one point per cell
    grid = point_bins(points, 0.0)
    signed, _, centres = cell_geometry(points, previous)
    kept = _empty_spheres(points, previous, signed, centres, *grid, min_volume)
    try:
        hull = ConvexHull(points)
    except QhullError:
        return None
    # where the hull moved, new cells join vertices of cells that were on the hull
    # and stay Delaunay (the argument above needs the previous cells to tile the hull)
    neighbours = np.asarray(neighbours, dtype=np.int64)
    redo = ~kept | np.any(neighbours < 0, axis=1)
    subsets = _vertex_groups(points, previous, neighbours, redo, hull.vertices,
                             get_num_threads())
    new = _new_cells(points, subsets, previous[kept], grid, min_volume)
    if new is None:
        return None
    added, added_volumes = new
    cells = np.concatenate([previous[kept], added])
    volume = np.concatenate([signed[kept], added_volumes]).sum()
    if abs(volume - hull.volume) > _VOLUME_TOLERANCE * hull.volume:
        return None
    renumber = np.full(previous.shape[0] + 1, -1, dtype=np.int64)
    renumber[:-1][kept] = np.arange(int(kept.sum()))
    links = np.concatenate([renumber[neighbours[kept]],
                            np.full((added.shape[0], 4), -1, dtype=np.int64)])
    if not _link_open_faces(cells, links, n_points):
        return None
    return cells, links


def _vertex_groups(
    points: FloatArray, previous: IntArray, neighbours: IntArray,
    redo: npt.NDArray[np.bool_], extra: IntArray, parts: int,
) -> list[IntArray]:
    """Vertex sets to triangulate, one per thread: the vertices of the cells to redo,
    their face-connected components split into ``parts`` groups of about equal size
    in the order of their mean x (a new cell lies within one component, so its
    vertices are in one group); ``extra`` joins every group."""
    cells = np.flatnonzero(redo)
    if parts < 2 or cells.size < 2:
        return [np.unique(np.concatenate([previous[cells].ravel(), extra]))]
    index = np.full(previous.shape[0] + 1, -1, dtype=np.int64)
    index[:-1][cells] = np.arange(cells.size)
    links = index[neighbours[cells]]
    rows, slots = np.nonzero(links >= 0)
    graph = sp.csr_matrix((np.ones(rows.size), (rows, links[rows, slots])),
                          shape=(cells.size, cells.size))
    _, labels = connected_components(graph, directed=False)
    sizes = np.bincount(labels)
    mean_x = np.bincount(labels, points[previous[cells], 0].mean(axis=1)) / sizes
    order = np.argsort(mean_x, kind="stable")
    middle = np.cumsum(sizes[order]) - 0.5 * sizes[order]
    group = np.empty(sizes.size, dtype=np.int64)
    group[order] = np.minimum((middle * parts / cells.size).astype(np.int64), parts - 1)
    return [np.unique(np.concatenate([previous[cells[group[labels] == g]].ravel(), extra]))
            for g in range(parts)]


def _triangulated(points: FloatArray, subset: IntArray) -> IntArray:
    """Qhull's Delaunay cells of a subset of the points, as indices of all points."""
    if subset.size < 5:
        return np.empty((0, 4), dtype=np.int64)
    return subset[Delaunay(points[subset]).simplices]


def _canonical(cells: IntArray, volumes: FloatArray) -> tuple[IntArray, FloatArray]:
    """Positively oriented cells in an order that does not depend on how they were found
    (the groups, hence the thread count): each from its smallest vertex up, the last two
    swapped where that order is an odd permutation (the orientation is kept), the cells
    sorted; a cell found in two groups once."""
    order = np.argsort(cells, axis=1)
    ranked = np.take_along_axis(cells, order, axis=1)
    inversions = sum((order[:, i] > order[:, j]).astype(np.int64)
                     for i in range(4) for j in range(i + 1, 4))
    odd = inversions % 2 == 1
    ranked[odd] = ranked[odd][:, [0, 1, 3, 2]]
    _, first = np.unique(ranked, axis=0, return_index=True)
    return ranked[first], volumes[first]


def _new_cells(
    points: FloatArray, subsets: list[IntArray], kept: IntArray,
    grid: tuple[FloatArray, FloatArray, IntArray, IntArray, IntArray], min_volume: float,
) -> tuple[IntArray, FloatArray] | None:
    """Cells of the Delaunay tetrahedralisations of the ``subsets`` (on threads: Qhull
    releases the GIL) that are Delaunay among all points and not in ``kept``, once
    each, positively oriented, in :func:`_canonical` order, and their volumes [m3]; None
    if Qhull fails."""
    try:
        if len(subsets) == 1:
            parts = [_triangulated(points, subsets[0])]
        else:
            with ThreadPoolExecutor(len(subsets)) as pool:
                parts = list(pool.map(partial(_triangulated, points), subsets))
    except QhullError:
        return None
    candidates = np.concatenate(parts).astype(np.int64)
    signed, _, centres = cell_geometry(points, candidates)
    negative = signed < 0.0
    candidates[negative] = candidates[negative][:, [0, 1, 3, 2]]
    signed[negative] = -signed[negative]
    # the circumcentre does not depend on the orientation
    certified = _empty_spheres(points, candidates, signed, centres, *grid, min_volume)
    candidates, signed = _canonical(candidates[certified], signed[certified])
    new = same_cells(kept, candidates, points.shape[0]) < 0
    return candidates[new], signed[new]
