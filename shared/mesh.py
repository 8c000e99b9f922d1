"""Delaunay finite-volume mesh of DEM points: tetrahedra, facets, dual lengths, walls.

Each tetrahedron of the plain (unweighted) Delaunay tetrahedralisation of the points is
a finite volume with its circumcentre as dual point, so that the two-point flux
g_ij (p_j - p_i) uses the dual length l_ij = (c_j - c_i) . n_ij, which is non-negative
on a Delaunay mesh: the scheme reproduces linear pressure fields exactly. A dual length
that is not finite or below ``min_dual_length_ratio`` times the centroid distance is
replaced by the centroid distance (:attr:`Mesh.facet_length_fallback`). A hull facet
belongs to the wall (:data:`WALLS`, index ``2 * axis + side``) of the bounding-box face
nearest its centroid; pressure conditions use a boundary layer of cells
(:func:`boundary_cell_mask`). :func:`update_mesh` recomputes the geometry of moved
points on the connectivity of a previous mesh. Why plain Delaunay, and the wall rules:
docs/micro.md, "shared.mesh".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import xarray as xr
from numba import njit, prange
from scipy.interpolate import RegularGridInterpolator

from shared.delaunay import delaunay_tetrahedra
from shared.errors import InputError
from shared.tetrahedra import cell_geometry, cell_volumes

__all__ = [
    "WALLS",
    "Mesh",
    "build_mesh",
    "cell_geometry",
    "cell_volumes",
    "mesh_from_tetrahedra",
    "update_mesh",
    "wall_index",
    "boundary_cell_mask",
    "mean_spacing",
    "porosity_at_points",
    "face_planes",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

WALLS: tuple[str, ...] = ("x-", "x+", "y-", "y+", "z-", "z+")


@dataclass(frozen=True)
class Mesh:
    """Tetrahedral finite-volume mesh (all lengths in m, areas in m2, volumes in m3).

    Attributes
    ----------
    points : ndarray, shape (n_points, 3)
        Vertex coordinates [m].
    tetrahedra : ndarray of int64, shape (n_cells, 4)
        Vertex indices, positively oriented.
    neighbours : ndarray of int64, shape (n_cells, 4)
        Cell across the face opposite each vertex of ``tetrahedra``, -1 on the hull
        (consistent with the reoriented ``tetrahedra``: pass both to
        :func:`mesh_from_tetrahedra` to update the geometry of moved points).
    volumes : ndarray, shape (n_cells,)
        Tetrahedron volumes [m3], all > 0.
    centroids, circumcentres : ndarray, shape (n_cells, 3)
        Vertex centroid and circumcentre (dual point) of each cell [m]; circumcentres
        of hull slivers may lie far outside the box.
    facet_cells : ndarray of int64, shape (n_facets, 2)
        The two cells (i < j) sharing each internal triangle.
    facet_vertices : ndarray of int64, shape (n_facets, 3)
        Vertices of each internal triangle.
    facet_areas : ndarray, shape (n_facets,)
        Triangle areas A_ij [m2].
    facet_normals : ndarray, shape (n_facets, 3)
        Unit normals pointing from cell i to cell j.
    facet_centroids : ndarray, shape (n_facets, 3)
        Triangle centroids [m].
    facet_lengths : ndarray, shape (n_facets,)
        Dual lengths l_ij > 0 [m].
    facet_length_fallback : ndarray of bool, shape (n_facets,)
        True where l_ij fell back to the centroid distance.
    boundary_cells : ndarray of int64, shape (n_boundary,)
        Cell owning each hull triangle.
    boundary_vertices : ndarray of int64, shape (n_boundary, 3)
    boundary_areas : ndarray, shape (n_boundary,)  [m2]
    boundary_normals : ndarray, shape (n_boundary, 3)
        Outward unit normals.
    boundary_centroids : ndarray, shape (n_boundary, 3)  [m]
    boundary_walls : ndarray of int64, shape (n_boundary,)
        Wall index in ``range(6)`` of the bounding-box face nearest to each hull
        triangle's centroid (see :data:`WALLS`).
    bounds : ndarray, shape (2, 3)
        Lower and upper corners of the points' bounding box [m].
    """

    points: FloatArray
    tetrahedra: IntArray
    neighbours: IntArray
    volumes: FloatArray
    centroids: FloatArray
    circumcentres: FloatArray
    facet_cells: IntArray
    facet_vertices: IntArray
    facet_areas: FloatArray
    facet_normals: FloatArray
    facet_centroids: FloatArray
    facet_lengths: FloatArray
    facet_length_fallback: npt.NDArray[np.bool_]
    boundary_cells: IntArray
    boundary_vertices: IntArray
    boundary_areas: FloatArray
    boundary_normals: FloatArray
    boundary_centroids: FloatArray
    boundary_walls: IntArray
    bounds: FloatArray

    @property
    def n_cells(self) -> int:
        """Number of tetrahedra."""
        return int(self.tetrahedra.shape[0])

    @property
    def n_facets(self) -> int:
        """Number of internal facets."""
        return int(self.facet_cells.shape[0])


@njit(cache=True)
def _facet_topology(
    tetrahedra: IntArray, neighbours: IntArray
) -> tuple[IntArray, IntArray, IntArray, IntArray]:
    """Internal facets (cell i < neighbour j) and hull facets, each with its vertices.

    Returns ``facet_cells`` (n_facets, 2), ``facet_vertices`` (n_facets, 3),
    ``hull_cells`` (n_hull,) and ``hull_vertices`` (n_hull, 3), in cell order.
    """
    n_inner, n_hull = 0, 0
    for c in range(neighbours.shape[0]):
        for m in range(4):
            if neighbours[c, m] > c:
                n_inner += 1
            elif neighbours[c, m] < 0:
                n_hull += 1
    facet_cells = np.empty((n_inner, 2), dtype=np.int64)
    facet_vertices = np.empty((n_inner, 3), dtype=np.int64)
    hull_cells = np.empty(n_hull, dtype=np.int64)
    hull_vertices = np.empty((n_hull, 3), dtype=np.int64)
    inner, hull = 0, 0
    for c in range(neighbours.shape[0]):
        for m in range(4):
            other = neighbours[c, m]
            if other > c:
                facet_cells[inner, 0], facet_cells[inner, 1] = c, other
                target, row = facet_vertices, inner
                inner += 1
            elif other < 0:
                hull_cells[hull] = c
                target, row = hull_vertices, hull
                hull += 1
            else:
                continue
            k = 0
            for v in range(4):
                if v != m:
                    target[row, k] = tetrahedra[c, v]
                    k += 1
    return facet_cells, facet_vertices, hull_cells, hull_vertices


@njit(cache=True, parallel=True)
def _triangle_geometry(
    points: FloatArray, vertices: IntArray, cells: IntArray, centroids: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Areas, unit normals pointing away from the owning cell, and centroids.

    The owning cell's centroid lies on the side of its fourth vertex, so the sign test
    against it equals the test against that vertex and needs no vertex look-up.
    """
    n = vertices.shape[0]
    areas = np.empty(n)
    normals = np.empty((n, 3))
    centres = np.empty((n, 3))
    for f in prange(n):
        a, b, c = vertices[f, 0], vertices[f, 1], vertices[f, 2]
        ux = points[b, 0] - points[a, 0]
        uy = points[b, 1] - points[a, 1]
        uz = points[b, 2] - points[a, 2]
        vx = points[c, 0] - points[a, 0]
        vy = points[c, 1] - points[a, 1]
        vz = points[c, 2] - points[a, 2]
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        for d in range(3):
            centres[f, d] = (points[a, d] + points[b, d] + points[c, d]) / 3.0
        towards = (
            nx * (centroids[cells[f], 0] - centres[f, 0])
            + ny * (centroids[cells[f], 1] - centres[f, 1])
            + nz * (centroids[cells[f], 2] - centres[f, 2])
        )
        twice = np.sqrt(nx * nx + ny * ny + nz * nz)
        scale = (-1.0 if towards > 0.0 else 1.0) / twice
        areas[f] = 0.5 * twice
        normals[f, 0] = nx * scale
        normals[f, 1] = ny * scale
        normals[f, 2] = nz * scale
    return areas, normals, centres


@njit(cache=True, parallel=True)
def _dual_lengths(
    centroids: FloatArray,
    circumcentres: FloatArray,
    facet_cells: IntArray,
    normals: FloatArray,
    ratio: float,
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Circumcentre distances projected on the facet normals, with the fallback."""
    n = facet_cells.shape[0]
    lengths = np.empty(n)
    fallback = np.zeros(n, dtype=np.bool_)
    for f in prange(n):
        i, j = facet_cells[f, 0], facet_cells[f, 1]
        dual = 0.0
        squared = 0.0
        for d in range(3):
            dual += (circumcentres[j, d] - circumcentres[i, d]) * normals[f, d]
            squared += (centroids[j, d] - centroids[i, d]) ** 2
        distance = np.sqrt(squared)
        # NaN compares false, so non-finite circumcentres fall back too.
        if np.isfinite(dual) and dual > ratio * distance:
            lengths[f] = dual
        else:
            lengths[f] = distance
            fallback[f] = True
    return lengths, fallback


def build_mesh(
    points: npt.ArrayLike,
    *,
    min_dual_length_ratio: float = 1e-6,
    degenerate_volume_ratio: float = 1e-12,
) -> Mesh:
    """Delaunay-tetrahedralise points and compute the finite-volume geometry.

    Parameters
    ----------
    points
        Point coordinates [m], shape (n_points, 3), n_points >= 5, not coplanar.
    min_dual_length_ratio, degenerate_volume_ratio
        See :func:`mesh_from_tetrahedra`.

    Returns
    -------
    Mesh
        The mesh.

    Raises
    ------
    ValueError
        If points are not finite, fewer than 5, or give degenerate (flat) tetrahedra.
    """
    return mesh_from_tetrahedra(
        *delaunay_tetrahedra(points),
        min_dual_length_ratio=min_dual_length_ratio,
        degenerate_volume_ratio=degenerate_volume_ratio,
    )


def mesh_from_tetrahedra(
    points: FloatArray,
    tetrahedra: IntArray,
    neighbours: IntArray,
    *,
    reorient: bool = True,
    min_dual_length_ratio: float = 1e-6,
    degenerate_volume_ratio: float = 1e-12,
) -> Mesh:
    """Finite-volume geometry of a tetrahedralisation.

    Parameters
    ----------
    points, tetrahedra, neighbours
        As returned by :func:`delaunay_tetrahedra`, or a previous mesh's
        ``tetrahedra`` and ``neighbours`` with moved points (not modified).
    reorient
        True for fresh Delaunay output, whose cells may be negatively oriented: they
        are reoriented. False for the cells of a previous :class:`Mesh` (positively
        oriented): a negative volume then means the cell inverted and raises.
    min_dual_length_ratio
        A circumcentre distance not larger than this fraction of the centroid distance
        (or not finite) is replaced by the centroid distance [1].
    degenerate_volume_ratio
        A tetrahedron whose volume is below this fraction of the mean volume is
        degenerate and raises [1].

    Returns
    -------
    Mesh
        The mesh.

    Raises
    ------
    ValueError
        If a tetrahedron is degenerate (flat), as exactly coplanar or duplicated points
        give (jitter such inputs), or, with ``reorient=False``, inverted (remesh).
    """
    tetrahedra = np.array(tetrahedra, dtype=np.int64)
    neighbours = np.array(neighbours, dtype=np.int64)
    points = np.ascontiguousarray(points, dtype=np.float64)
    signed, centroids, circumcentres = cell_geometry(points, tetrahedra)
    if reorient:
        # Swapping two vertices flips the orientation; neighbours are indexed by the
        # opposite vertex and must be swapped alongside.
        negative = signed < 0.0
        tetrahedra[negative] = tetrahedra[negative][:, [0, 1, 3, 2]]
        neighbours[negative] = neighbours[negative][:, [0, 1, 3, 2]]
        signed = np.abs(signed)
    facet_cells, facet_vertices, hull_cells, hull_vertices = _facet_topology(tetrahedra, neighbours)
    return _mesh_geometry(
        points, tetrahedra, neighbours, _checked_volumes(signed, degenerate_volume_ratio),
        centroids, circumcentres, facet_cells, facet_vertices, hull_cells, hull_vertices,
        min_dual_length_ratio,
    )


def update_mesh(
    mesh: Mesh,
    points: npt.ArrayLike,
    *,
    min_dual_length_ratio: float = 1e-6,
    degenerate_volume_ratio: float = 1e-12,
) -> Mesh:
    """Geometry of a mesh for moved points, keeping its connectivity.

    Same result as ``mesh_from_tetrahedra(points, mesh.tetrahedra, mesh.neighbours,
    reorient=False)``, but the connectivity and facet lists of ``mesh`` are shared
    (not copied or recomputed), so that only the geometry is computed: the per-step
    update of a coupled run.

    Parameters
    ----------
    mesh
        Mesh of the points before they moved.
    points
        Moved vertex coordinates [m], shape ``mesh.points.shape``.
    min_dual_length_ratio, degenerate_volume_ratio
        See :func:`mesh_from_tetrahedra`.

    Returns
    -------
    Mesh
        The mesh with the same cells and facets at the new points.

    Raises
    ------
    ValueError
        If the points do not match the mesh, or a cell inverted or degenerated (the
        mesh must then be rebuilt).
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    if points.shape != mesh.points.shape:
        raise ValueError(f"points must have shape {mesh.points.shape}, got {points.shape}")
    signed, centroids, circumcentres = cell_geometry(points, mesh.tetrahedra)
    return _mesh_geometry(
        points, mesh.tetrahedra, mesh.neighbours,
        _checked_volumes(signed, degenerate_volume_ratio), centroids, circumcentres,
        mesh.facet_cells, mesh.facet_vertices, mesh.boundary_cells, mesh.boundary_vertices,
        min_dual_length_ratio,
    )


def _checked_volumes(signed: FloatArray, degenerate_volume_ratio: float) -> FloatArray:
    """Volumes of positively oriented cells [m3]; raise on inverted or flat ones."""
    negative = signed < 0.0
    if np.any(negative):
        raise ValueError(f"{int(negative.sum())} inverted tetrahedra: the mesh must be rebuilt")
    degenerate = signed <= degenerate_volume_ratio * signed.mean()
    if np.any(degenerate):
        raise ValueError(
            f"{int(degenerate.sum())} degenerate (flat) tetrahedra: points are coplanar or "
            "duplicated; jitter them"
        )
    return signed


def _mesh_geometry(
    points: FloatArray,
    tetrahedra: IntArray,
    neighbours: IntArray,
    volumes: FloatArray,
    centroids: FloatArray,
    circumcentres: FloatArray,
    facet_cells: IntArray,
    facet_vertices: IntArray,
    hull_cells: IntArray,
    hull_vertices: IntArray,
    min_dual_length_ratio: float,
) -> Mesh:
    """Facet and hull geometry on given connectivity, gathered into a :class:`Mesh`."""
    areas, normals, facet_centroids = _triangle_geometry(
        points, facet_vertices, facet_cells[:, 0], centroids
    )
    lengths, fallback = _dual_lengths(
        centroids, circumcentres, facet_cells, normals, min_dual_length_ratio
    )
    b_areas, b_normals, b_centroids = _triangle_geometry(
        points, hull_vertices, hull_cells, centroids
    )
    bounds = np.stack([points.min(axis=0), points.max(axis=0)])
    return Mesh(
        points=points,
        tetrahedra=tetrahedra,
        neighbours=neighbours,
        volumes=volumes,
        centroids=centroids,
        circumcentres=circumcentres,
        facet_cells=facet_cells,
        facet_vertices=facet_vertices,
        facet_areas=areas,
        facet_normals=normals,
        facet_centroids=facet_centroids,
        facet_lengths=lengths,
        facet_length_fallback=fallback,
        boundary_cells=hull_cells,
        boundary_vertices=hull_vertices,
        boundary_areas=b_areas,
        boundary_normals=b_normals,
        boundary_centroids=b_centroids,
        boundary_walls=_walls_of_positions(b_centroids, bounds),
        bounds=bounds,
    )


def _walls_of_positions(centroids: FloatArray, bounds: FloatArray) -> IntArray:
    """Nearest bounding-box face (wall index) of each point."""
    distances = np.abs(centroids[:, None, :] - bounds[None, :, :])  # (n, side, axis)
    nearest = np.argmin(distances.transpose(0, 2, 1).reshape(-1, 6), axis=1)
    return nearest.astype(np.int64)


def wall_index(wall: str) -> int:
    """Index of a wall name of :data:`WALLS` (``"x-"``, ``"x+"``, ..., ``"z+"``)."""
    try:
        return WALLS.index(wall)
    except ValueError:
        raise ValueError(f"unknown wall {wall!r}; expected one of {WALLS}") from None


def mean_spacing(mesh: Mesh) -> float:
    """Mean point spacing (bounding-box volume / n_points)^(1/3) [m]."""
    extent = mesh.bounds[1] - mesh.bounds[0]
    return float(np.cbrt(np.prod(extent) / mesh.points.shape[0]))


def boundary_cell_mask(
    mesh: Mesh,
    walls: tuple[str, ...] | list[str],
    layer_thickness: float | None = None,
) -> npt.NDArray[np.bool_]:
    """Cells forming the boundary layer of the given box walls.

    The hull of a jittered or packed point cloud has few, large triangles, so hull
    adjacency alone marks few cells. A cell belongs to wall w if it owns a hull
    triangle assigned to w or if one of its vertices lies within ``layer_thickness``
    of w's plane (:func:`face_planes`), or beyond it: the cells resting on the
    outer layer of points, like the cells Yade attaches to its wall vertices. Its
    centroid must also lie within twice that distance of the plane: the convex hull of
    a specimen whose edges swelled concave is filled by slivers that run along an edge
    from one wall to the opposite one, and such a cell, counted in the inlet layer of
    a permeability measurement, sat next to outlet cells 4 mm away; across an open
    crack it carried gas at 1e-11 m2.

    Parameters
    ----------
    mesh
        The mesh.
    walls
        Wall names from :data:`WALLS`.
    layer_thickness
        Distance from the wall plane within which a vertex is on the wall [m];
        default half the mean point spacing (:func:`mean_spacing`).

    Returns
    -------
    ndarray of bool, shape (n_cells,)
    """
    thickness = 0.5 * mean_spacing(mesh) if layer_thickness is None else layer_thickness
    planes = face_planes(mesh.points)
    mask = np.zeros(mesh.n_cells, dtype=bool)
    for wall in walls:
        index = wall_index(wall)
        axis, side = divmod(index, 2)
        inward = 1.0 if side == 0 else -1.0
        vertex_depth = inward * (mesh.points[mesh.tetrahedra, axis] - planes[side, axis])
        centroid_depth = inward * (mesh.centroids[:, axis] - planes[side, axis])
        touching = np.any(vertex_depth <= thickness, axis=1)
        touching[mesh.boundary_cells[mesh.boundary_walls == index]] = True
        mask |= touching & (centroid_depth <= 2.0 * thickness)
    return mask


def face_planes(points: npt.ArrayLike) -> FloatArray:
    """Positions of the six faces of a box-shaped point cloud [m], shape (2, 3).

    Row 0 holds the lower faces (x-, y-, z-), row 1 the upper ones. A face's plane is
    the mean position of the outermost points along its axis, as many as one layer of
    the cloud holds (N s / L along an axis of extent L, s = (V / N)^(1/3) the mean
    spacing: N^(2/3) for a cube), not the outermost one: a single point pushed out of a
    face would otherwise move the whole face, and the face's membrane load would fall
    on that one point. Counting the layer per axis keeps an elongated cloud's end faces
    on its end layers.
    """
    points = np.asarray(points, dtype=np.float64)
    n = points.shape[0]
    extent = np.maximum(np.ptp(points, axis=0), np.finfo(np.float64).tiny)
    spacing = (np.prod(extent) / n) ** (1.0 / 3.0)
    planes = np.empty((2, 3))
    for axis in range(3):
        face = min(max(round(n * spacing / extent[axis]), 1), n)
        coordinate = points[:, axis]
        planes[0, axis] = np.partition(coordinate, face - 1)[:face].mean()
        planes[1, axis] = -np.partition(-coordinate, face - 1)[:face].mean()
    return planes


def porosity_at_points(points: npt.ArrayLike, porosity: xr.DataArray) -> FloatArray:
    """Trilinear interpolation of a porosity grid at given points.

    Parameters
    ----------
    points
        (n, 3) query points x, y, z [m].
    porosity
        Grid ``porosity(z, y, x)`` [1] with strictly monotonic coordinates ``z, y, x``
        in m, values in (0, 1).

    Returns
    -------
    ndarray, shape (n,)
        Porosity at each point [1].

    Raises
    ------
    ValueError
        If the grid is not (z, y, x), holds NaN or values outside (0, 1), or does not
        cover every point.
    """
    source = porosity.encoding.get("source")
    name = f"porosity grid {source}" if source else "porosity grid"
    if tuple(porosity.dims) != ("z", "y", "x"):
        raise InputError(
            f"{name}: dims {tuple(porosity.dims)}; expected ('z', 'y', 'x') in m"
        )
    values = np.asarray(porosity.values, dtype=np.float64)
    if not np.all(np.isfinite(values)):
        where = ", ".join(f"{axis} = {float(porosity[axis][int(k[0])]):.4g} m" for axis, k in
                          zip(("z", "y", "x"), np.nonzero(~np.isfinite(values)), strict=True))
        raise InputError(f"{name}: NaN or inf at {where} "
                         f"({int((~np.isfinite(values)).sum())} value(s)) where the mesh needs it")
    if not np.all((values > 0.0) & (values < 1.0)):
        raise InputError(
            f"{name}: values must lie in (0, 1), range [{values.min():.4g}, {values.max():.4g}] "
            "(see imaging.calibration.porosity_bounds)"
        )
    axes = tuple(np.asarray(porosity[axis].values, dtype=np.float64) for axis in ("z", "y", "x"))
    query = np.asarray(points, dtype=np.float64)[:, ::-1]
    for k, axis in enumerate(("z", "y", "x")):
        low, high = min(axes[k][0], axes[k][-1]), max(axes[k][0], axes[k][-1])
        outside = (query[:, k] < low) | (query[:, k] > high)
        if np.any(outside):
            raise InputError(
                f"{name} does not cover the mesh along {axis}: grid [{low:.6g}, {high:.6g}] m, "
                f"cells [{query[:, k].min():.6g}, {query[:, k].max():.6g}] m "
                f"({int(outside.sum())} cells outside; see micro.specimen_size_m)"
            )
    interpolator = RegularGridInterpolator(axes, values, method="linear", bounds_error=True)
    return interpolator(query)
