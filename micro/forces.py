"""Hydro-mechanical forces on DEM points and point suctions (Caulk 2022, Sec. 3.3.5).

Force of the pore fluid on the points, Eqs. 3.28-3.32 with Bishop's chi = S (as Yade):
across each facet between cells i and j the jump S_i p_i - S_j p_j acts on the whole
triangle, A_ij (S_i p_i - S_j p_j) n_ij, and vertex k receives the fraction
A^k / sum_x A^x of it, A^k = theta_k r_k^2 / 2 the sector of its interaction radius
(Eqs. 3.29, 3.31). A hull triangle sees ``exterior_pressure`` instead of S_j p_j (Yade's
boundary cells at the imposed pressure: pass S(p_b) p_b). The specimen's hull loads per
face (:func:`hull_face_loads`) can instead be shared by the outer points as a membrane
would (:func:`membrane_forces`). Details: docs/micro.md, "micro.forces".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numba import njit, prange

from shared.mesh import Mesh, face_planes

__all__ = [
    "SectorWeights",
    "facet_vertex_weights",
    "hull_face_loads",
    "hydromechanical_forces",
    "membrane_forces",
    "point_suction",
    "sector_weights",
]

FloatArray = npt.NDArray[np.float64]


@njit(cache=True)
def _angle(positions, p, q, r):
    """Angle of triangle (p, q, r) at vertex p [rad]."""
    ux = positions[q, 0] - positions[p, 0]
    uy = positions[q, 1] - positions[p, 1]
    uz = positions[q, 2] - positions[p, 2]
    vx = positions[r, 0] - positions[p, 0]
    vy = positions[r, 1] - positions[p, 1]
    vz = positions[r, 2] - positions[p, 2]
    cross = np.sqrt((uy * vz - uz * vy) ** 2 + (uz * vx - ux * vz) ** 2 + (ux * vy - uy * vx) ** 2)
    return np.arctan2(cross, ux * vx + uy * vy + uz * vz)


@njit(cache=True)
def _sector_weights(positions, radii, a, b, c):
    """Sector areas theta_k r_k^2 / 2 of triangle (a, b, c), normalised."""
    w0 = _angle(positions, a, b, c) * radii[a] ** 2
    w1 = _angle(positions, b, c, a) * radii[b] ** 2
    w2 = _angle(positions, c, a, b) * radii[c] ** 2
    total = w0 + w1 + w2
    return w0 / total, w1 / total, w2 / total


@njit(cache=True)
def _triangle_weights(positions, radii, triangles):
    """(n_triangles, 3) sector weights of every triangle."""
    weights = np.empty(triangles.shape, dtype=np.float64)
    for f in range(triangles.shape[0]):
        weights[f, 0], weights[f, 1], weights[f, 2] = _sector_weights(
            positions, radii, triangles[f, 0], triangles[f, 1], triangles[f, 2]
        )
    return weights


@njit(cache=True)
def _scatter_facet_forces(positions, radii, triangles, reference_normals, weights, jumps,
                          first, last, forces):
    """Scatter jump A n of triangles first..last-1 over their vertices, by sector weights.

    The area vector comes from the current positions, oriented like the mesh normal.
    With an empty ``weights`` the sector weights theta_k r_k^2 / sum are computed here
    from the same edge vectors: the angles share the cross product (twice the area),
    and the third is pi minus the other two (absolute round-off ~1e-15 rad), so a
    triangle costs one cross product, two dot products and two arctangents, and no
    weight array is written or read.
    """
    inline = weights.shape[0] == 0
    for f in range(first, last):
        a, b, c = triangles[f, 0], triangles[f, 1], triangles[f, 2]
        ux = positions[b, 0] - positions[a, 0]
        uy = positions[b, 1] - positions[a, 1]
        uz = positions[b, 2] - positions[a, 2]
        vx = positions[c, 0] - positions[a, 0]
        vy = positions[c, 1] - positions[a, 1]
        vz = positions[c, 2] - positions[a, 2]
        ax = 0.5 * (uy * vz - uz * vy)
        ay = 0.5 * (uz * vx - ux * vz)
        az = 0.5 * (ux * vy - uy * vx)
        if inline:
            twice = 2.0 * np.sqrt(ax * ax + ay * ay + az * az)
            uv = ux * vx + uy * vy + uz * vz
            angle_a = np.arctan2(twice, uv)
            # angle at b, between b -> a = -u and b -> c = v - u
            angle_b = np.arctan2(twice, ux * ux + uy * uy + uz * uz - uv)
            w0 = angle_a * radii[a] ** 2
            w1 = angle_b * radii[b] ** 2
            w2 = (np.pi - angle_a - angle_b) * radii[c] ** 2
            total = w0 + w1 + w2
            share = (w0 / total, w1 / total, w2 / total)
        else:
            share = (weights[f, 0], weights[f, 1], weights[f, 2])
        if ax * reference_normals[f, 0] + ay * reference_normals[f, 1] \
                + az * reference_normals[f, 2] < 0.0:
            ax, ay, az = -ax, -ay, -az
        for k in range(3):
            scale = share[k] * jumps[f]
            forces[triangles[f, k], 0] += scale * ax
            forces[triangles[f, k], 1] += scale * ay
            forces[triangles[f, k], 2] += scale * az


# Fixed number of triangle blocks scattered in parallel, each into its own force array,
# summed in block order: the forces do not depend on the thread count. Fewer triangles
# than _PARALLEL_TRIANGLES (the hull's) are scattered serially: for them the block
# arrays and the thread start cost more than the scatter.
_FORCE_BLOCKS = 4
_PARALLEL_TRIANGLES = 20000


@njit(cache=True, parallel=True)
def _facet_forces(positions, radii, triangles, reference_normals, weights, jumps, forces):
    """Add the forces of all triangles to ``forces`` (see :func:`_scatter_facet_forces`)."""
    n = triangles.shape[0]
    if n < _PARALLEL_TRIANGLES:
        _scatter_facet_forces(positions, radii, triangles, reference_normals, weights, jumps,
                              0, n, forces)
        return
    partial = np.zeros((_FORCE_BLOCKS, forces.shape[0], 3))
    for block in prange(_FORCE_BLOCKS):
        _scatter_facet_forces(
            positions, radii, triangles, reference_normals, weights, jumps,
            block * n // _FORCE_BLOCKS, (block + 1) * n // _FORCE_BLOCKS, partial[block],
        )
    for block in range(_FORCE_BLOCKS):
        forces += partial[block]


@dataclass(frozen=True)
class SectorWeights:
    """Vertex shares of the mesh triangles' forces, A^k / sum_x A^x [1].

    Attributes
    ----------
    facets
        (n_facets, 3) weights of the internal triangles' vertices.
    boundary
        (n_boundary, 3) weights of the hull triangles' vertices.
    """

    facets: FloatArray
    boundary: FloatArray


def facet_vertex_weights(
    positions: npt.ArrayLike, radii: npt.ArrayLike, triangles: npt.ArrayLike
) -> FloatArray:
    """Share of each vertex in a triangle's force, A^k / sum_x A^x (Eqs. 3.29-3.31).

    Parameters
    ----------
    positions
        (n_points, 3) point centres [m].
    radii
        (n_points,) interaction radii [m].
    triangles
        (n_triangles, 3) vertex indices.

    Returns
    -------
    ndarray, shape (n_triangles, 3)
        Weights theta_k r_k^2 / sum_x theta_x r_x^2 [1]; rows sum to 1.
    """
    return _triangle_weights(
        np.ascontiguousarray(positions, dtype=np.float64),
        np.ascontiguousarray(radii, dtype=np.float64),
        np.ascontiguousarray(triangles, dtype=np.int64),
    )


def sector_weights(mesh: Mesh, positions: npt.ArrayLike, radii: npt.ArrayLike) -> SectorWeights:
    """Vertex weights of all mesh triangles (three arctangents per triangle).

    Parameters
    ----------
    mesh
        Delaunay mesh (``facet_vertices``, ``boundary_vertices``).
    positions
        (n_points, 3) point centres [m].
    radii
        (n_points,) interaction radii [m].

    Returns
    -------
    SectorWeights
        Exact for these positions and radii only: weights kept from a remesh are
        approximate once the points move, while :func:`hydromechanical_forces`
        computes exact ones in its kernel at a small cost.
    """
    return SectorWeights(
        facets=facet_vertex_weights(positions, radii, mesh.facet_vertices),
        boundary=facet_vertex_weights(positions, radii, mesh.boundary_vertices),
    )


def hydromechanical_forces(
    mesh: Mesh,
    positions: npt.ArrayLike,
    radii: npt.ArrayLike,
    pressure: npt.ArrayLike,
    saturation: npt.ArrayLike,
    exterior_pressure: float | npt.ArrayLike = 0.0,
    weights: SectorWeights | None = None,
) -> FloatArray:
    """Force of the pore water on each point, Eqs. 3.28-3.32 with chi = S [N].

    Parameters
    ----------
    mesh
        Delaunay mesh of the points; uses ``facet_cells``, ``facet_vertices``,
        ``facet_normals``, ``boundary_cells``, ``boundary_vertices``,
        ``boundary_normals``.
    positions
        (n_points, 3) current point centres [m]; may have moved since the mesh was
        built (the triangles' area vectors are recomputed, their orientation kept).
    radii
        (n_points,) interaction radii [m] (sector weights, if ``weights`` is None).
    pressure
        (n_cells,) water pressure p per cell [Pa], negative under suction.
    saturation
        (n_cells,) water saturation S per cell [1] (Bishop's chi).
    exterior_pressure
        chi p of the medium outside the hull [Pa], scalar or one value per hull
        triangle (``mesh.boundary_cells`` order); 0 for gas at the reference pressure.
    weights
        Precomputed :func:`sector_weights`, or None (default) to compute them from
        ``positions`` and ``radii`` on the fly, in the force kernel itself: exact for
        the current positions and about as cheap as reading cached weights.

    Returns
    -------
    ndarray, shape (n_points, 3)
        Force per point [N]. Under a uniform S p inside, interior points get zero and
        the hull triangles carry (S p - exterior_pressure) A n_out to their vertices,
        pushing outwards for positive pressure, pulling inwards under suction.
    """
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    stress = np.asarray(saturation, dtype=np.float64) * np.asarray(pressure, dtype=np.float64)
    if stress.shape != (mesh.n_cells,):
        raise ValueError(f"pressure and saturation must have shape ({mesh.n_cells},)")
    if positions.shape != mesh.points.shape:
        raise ValueError("positions must match the mesh points")
    radii = np.ascontiguousarray(radii, dtype=np.float64)
    if radii.shape != (positions.shape[0],):
        raise ValueError(f"radii must have shape ({positions.shape[0]},)")
    none = np.empty((0, 3))
    facet_weights = none if weights is None else weights.facets
    boundary_weights = none if weights is None else weights.boundary
    forces = np.zeros_like(positions)
    interior_jump = stress[mesh.facet_cells[:, 0]] - stress[mesh.facet_cells[:, 1]]
    _facet_forces(
        positions, radii, mesh.facet_vertices, mesh.facet_normals, facet_weights,
        interior_jump, forces,
    )
    boundary_jump = stress[mesh.boundary_cells] - np.broadcast_to(
        np.asarray(exterior_pressure, dtype=np.float64), mesh.boundary_cells.shape
    )
    _facet_forces(
        positions, radii, mesh.boundary_vertices, mesh.boundary_normals, boundary_weights,
        boundary_jump, forces,
    )
    return forces


@njit(cache=True)
def _incident_sums(tetrahedra, volumes, values, n_points):
    """Per point, sum of incident cell volumes and of volume times value."""
    weight = np.zeros(n_points)
    weighted = np.zeros(n_points)
    for cell in range(tetrahedra.shape[0]):
        for k in range(4):
            weight[tetrahedra[cell, k]] += volumes[cell]
            weighted[tetrahedra[cell, k]] += volumes[cell] * values[cell]
    return weight, weighted


def point_suction(
    tetrahedra: npt.ArrayLike,
    volumes: npt.ArrayLike,
    cell_suction: npt.ArrayLike,
    n_points: int,
    fallback: float | npt.ArrayLike | None = None,
) -> FloatArray:
    """Suction of each point: volume-weighted mean over its incident cells (Sec. 3.3.5).

    Parameters
    ----------
    tetrahedra
        (n_cells, 4) vertex indices.
    volumes
        (n_cells,) cell volumes [m3], the weights.
    cell_suction
        (n_cells,) suction per cell [Pa].
    n_points
        Number of points.
    fallback
        Suction [Pa] (scalar or (n_points,)) of points without an incident cell (not
        triangulated, e.g. duplicates); None uses the volume-weighted mean of all
        cells. Yade divides by zero there (docs/yade.md §8, defect 10).

    Returns
    -------
    ndarray, shape (n_points,)
        Point suction [Pa].
    """
    tetrahedra = np.ascontiguousarray(tetrahedra, dtype=np.int64)
    volumes = np.ascontiguousarray(volumes, dtype=np.float64)
    cell_suction = np.ascontiguousarray(cell_suction, dtype=np.float64)
    if volumes.shape != (tetrahedra.shape[0],) or cell_suction.shape != volumes.shape:
        raise ValueError("volumes and cell_suction must have one value per tetrahedron")
    weight, weighted = _incident_sums(tetrahedra, volumes, cell_suction, n_points)
    if fallback is None:
        fallback = float((volumes * cell_suction).sum() / volumes.sum())
    fallback = np.broadcast_to(np.asarray(fallback, dtype=np.float64), (n_points,))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(weight > 0.0, weighted / weight, fallback)


def hull_face_loads(mesh: Mesh, bishop_pressure: FloatArray) -> FloatArray:
    """Resultant of the pore-fluid pull on the hull, per face of the specimen [N], (6, 3).

    Each hull triangle carries chi p A n (chi p = S p of the cell it closes, air outside,
    n outward; chi p < 0 pulls inward), summed over the triangles of each face
    (:attr:`shared.mesh.Mesh.boundary_walls`, order of :data:`shared.mesh.WALLS`). The
    six sum to -(resultant of the internal facet forces) exactly, so the specimen as a
    whole carries no net force whatever the saturation field.
    """
    loads = bishop_pressure[mesh.boundary_cells, None] * mesh.boundary_areas[:, None] \
        * mesh.boundary_normals
    return np.stack([loads[mesh.boundary_walls == wall].sum(axis=0) for wall in range(6)])


def membrane_forces(positions: FloatArray, face_loads: FloatArray, layer: float) -> FloatArray:
    """Forces of six face loads shared by the outer points, as a membrane would [N].

    Each face's load (a vector) is shared equally by the points within ``layer`` of
    that face's plane (or beyond it); points on an edge or corner take a share from
    each of their faces. The planes are :func:`shared.mesh.face_planes`, robust to a
    point pushed out of a face.

    Parameters
    ----------
    positions
        (n, 3) point centres [m].
    face_loads
        (6, 3) load of each face [N], order of :data:`shared.mesh.WALLS` (x-, x+, y-,
        ...), e.g. :func:`hull_face_loads`.
    layer
        Thickness of the loaded outer layer [m].
    """
    forces = np.zeros_like(positions)
    lower, upper = face_planes(positions)
    for wall in range(6):
        axis, side = divmod(wall, 2)
        if side == 0:
            distance = positions[:, axis] - lower[axis]
        else:
            distance = upper[axis] - positions[:, axis]
        loaded = distance <= layer
        forces[loaded] += face_loads[wall] / loaded.sum()
    return forces
