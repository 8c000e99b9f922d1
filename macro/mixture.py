"""Geometry of the pellet-powder systems on the Delaunay mesh of the pellet centres and
of fixed points on the container.

Mesh vertices 0..n_p-1 are the pellet centres, the others points on the container's
wall and plates (:func:`container_points`, radius 0), so that the cells fill the
container. Systems are the pellets (indices 0..n_p-1) and the cells (tetrahedra,
indices n_p..n_p+n_c-1) whose void, outside the pellets, holds the powder. Exchanges
(Fig. 4.2, Eqs. 4.13-4.15), each with an area A [m2] and a length L [m]: pellet-pellet
(the overlap disk, L the centre distance), pellet-cell (the spherical triangle of the
pellet inside the cell, L to the cell centroid) and cell-cell (the shared triangle
minus the pellet sectors, L the centroid distance). The void of a cell is its volume
minus the pellet parts inside it, floored at ``void_floor`` times its volume. The
formulas: docs/macro.md, "macro.mixture".
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import replace as dataclass_replace

import numpy as np
import numpy.typing as npt

from shared.mesh import Mesh

__all__ = [
    "Exchanges", "cell_voids", "container_points", "end_cells", "exchanges", "facet_angles", "matching_keys",
    "mesh_edges", "moved_mesh", "solid_angles",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def solid_angles(points: FloatArray, tetrahedra: IntArray) -> FloatArray:
    """(n_c, 4) solid angle of each tetrahedron at each vertex [sr] (Van Oosterom-Strackee)."""
    out = np.empty(tetrahedra.shape)
    for v in range(4):
        others = [w for w in range(4) if w != v]
        apex = points[tetrahedra[:, v]]
        a, b, c = (points[tetrahedra[:, w]] - apex for w in others)
        la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
        triple = np.abs(np.einsum("ij,ij->i", a, np.cross(b, c)))
        denom = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc
                 + np.einsum("ij,ij->i", a, c) * lb + np.einsum("ij,ij->i", b, c) * la)
        out[:, v] = 2.0 * np.arctan2(triple, denom)
    return out


def facet_angles(points: FloatArray, triangles: IntArray) -> FloatArray:
    """(n_f, 3) interior angle of each triangle at each of its vertices [rad]."""
    out = np.empty(triangles.shape)
    for v in range(3):
        apex = points[triangles[:, v]]
        a = points[triangles[:, (v + 1) % 3]] - apex
        b = points[triangles[:, (v + 2) % 3]] - apex
        cos = np.einsum("ij,ij->i", a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
        out[:, v] = np.arccos(np.clip(cos, -1.0, 1.0))
    return out


def cell_voids(mesh: Mesh, radii: FloatArray, omega: FloatArray, void_floor: float) -> FloatArray:
    """(n_c,) void volume of each cell outside the pellets [m3]."""
    inside = (omega * radii[mesh.tetrahedra] ** 3).sum(axis=1) / 3.0
    return np.maximum(mesh.volumes - inside, void_floor * mesh.volumes)


@dataclass
class Exchanges:
    """Edges between systems: ``pairs`` (m, 2) system indices, ``area`` [m2], ``length`` [m],
    ``kind`` (m,) 0 pellet-pellet, 1 pellet-cell, 2 cell-cell."""

    pairs: IntArray
    area: FloatArray
    length: FloatArray
    kind: npt.NDArray[np.int8]


def mesh_edges(mesh: Mesh) -> IntArray:
    """(m, 2) the Delaunay edges of the mesh, each once (i < j)."""
    tet = mesh.tetrahedra
    edges = np.concatenate([tet[:, [a, b]] for a in range(4) for b in range(a + 1, 4)])
    return np.unique(np.sort(edges, axis=1), axis=0)


def exchanges(mesh: Mesh, radii: FloatArray, n_pellets: int, omega: FloatArray, min_area_fraction: float,
              edges: IntArray | None = None) -> Exchanges:
    """All exchanges of the mesh for the current radii of its vertices (0 on the container;
    see the module docstring); the first ``n_pellets`` vertices are the pellets.

    Cell-cell areas are floored at ``min_area_fraction`` of the triangle so that a facet
    covered by swollen pellets keeps a small powder path. ``edges``: the mesh's
    :func:`mesh_edges`, when the caller keeps them between steps (same connectivity).
    """
    points = mesh.points
    n_p = n_pellets
    # pellet-pellet: Delaunay edges whose pellets overlap
    tet = mesh.tetrahedra
    if edges is None:
        edges = mesh_edges(mesh)
    edges = edges[edges.max(axis=1) < n_p]
    d = np.linalg.norm(points[edges[:, 1]] - points[edges[:, 0]], axis=1)
    ri, rj = radii[edges[:, 0]], radii[edges[:, 1]]
    touching = ri + rj > d
    x = (d**2 + ri**2 - rj**2) / (2.0 * d)
    a2 = np.maximum(ri**2 - x**2, 0.0)
    pp = edges[touching]
    pp_area = np.pi * a2[touching]
    pp_length = d[touching]
    # pellet-cell
    cells: IntArray = np.repeat(np.arange(mesh.n_cells), 4)
    verts: IntArray = tet.ravel()
    pellet = verts < n_p
    cells, verts = cells[pellet], verts[pellet]
    pc_area = (omega * radii[tet] ** 2).ravel()[pellet]
    pc_length = np.linalg.norm(mesh.centroids[cells] - points[verts], axis=1)
    pc = np.column_stack([verts, n_p + cells])
    # cell-cell
    theta = facet_angles(points, mesh.facet_vertices)
    sectors = (0.5 * theta * radii[mesh.facet_vertices] ** 2).sum(axis=1)
    cc_area = np.maximum(mesh.facet_areas - sectors, min_area_fraction * mesh.facet_areas)
    i, j = mesh.facet_cells[:, 0], mesh.facet_cells[:, 1]
    cc_length = np.linalg.norm(mesh.centroids[j] - mesh.centroids[i], axis=1)
    cc = np.column_stack([n_p + i, n_p + j])
    return Exchanges(
        pairs=np.concatenate([pp, pc, cc]).astype(np.int64),
        area=np.concatenate([pp_area, pc_area, cc_area]),
        length=np.concatenate([pp_length, pc_length, cc_length]),
        kind=np.concatenate([np.zeros(len(pp), np.int8), np.ones(len(pc), np.int8),
                             np.full(len(cc), 2, np.int8)]),
    )


def container_points(height: float, radius: float, spacing: float,
                     rng: np.random.Generator) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Fixed mesh vertices on the container (origin at its centre), and which are on a plate.

    Rings on the curved wall every ``spacing`` along the axis (staggered by half a
    step), the two rims included, and a triangular lattice of the same spacing on each
    plate, all on the container's surface (they are the mesh's hull). Each point is moved
    along the surface by up to 10 % of the spacing (seeded), the rims only around, so that
    no four points are co-circular (a Delaunay mesh of them could have flat cells).

    Parameters
    ----------
    height, radius
        Container height and radius [m].
    spacing
        Distance between neighbouring points [m].
    rng
        Jitter generator.

    Returns
    -------
    points : ndarray, shape (n, 3) [m]
    on_plate : ndarray of bool, shape (n,)
        The points of the plates and of the two rims.
    """
    n_around = max(6, int(np.ceil(2.0 * np.pi * radius / spacing)))
    n_rings = max(2, int(np.ceil(height / spacing)) + 1)
    z = np.linspace(-0.5 * height, 0.5 * height, n_rings)
    angle = (np.arange(n_around)[None, :] + 0.5 * (np.arange(n_rings)[:, None] % 2)) * 2.0 * np.pi / n_around
    angle = angle + rng.uniform(-0.1, 0.1, angle.shape) * spacing / radius
    along = np.broadcast_to(z[:, None], angle.shape).copy()
    along[1:-1] += rng.uniform(-0.1, 0.1, (n_rings - 2, n_around)) * spacing
    side = np.column_stack([(radius * np.cos(angle)).ravel(), (radius * np.sin(angle)).ravel(), along.ravel()])
    rim = np.zeros(angle.shape, dtype=np.bool_)
    rim[[0, -1]] = True
    # a triangular lattice inside the rim, at least half a spacing from it
    n_row = int(np.ceil(radius / spacing))
    i, j = np.meshgrid(np.arange(-2 * n_row, 2 * n_row + 1), np.arange(-2 * n_row, 2 * n_row + 1))
    lattice = np.column_stack([(i + 0.5 * j).ravel(), (0.5 * np.sqrt(3.0) * j).ravel()]) * spacing
    lattice = lattice[np.hypot(lattice[:, 0], lattice[:, 1]) < radius - 0.5 * spacing]
    plates = []
    for end in (-1.0, 1.0):
        xy = lattice + rng.uniform(-0.1, 0.1, lattice.shape) * spacing
        plates.append(np.column_stack([xy, np.full(lattice.shape[0], end * 0.5 * height)]))
    points = np.concatenate([side, *plates])
    on_plate = np.concatenate([rim.ravel(), np.ones(2 * lattice.shape[0], dtype=np.bool_)])
    return points, on_plate


def end_cells(mesh: Mesh, on_plate: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """(n_c,) cells with a vertex on a plate: the hydrated ends of Appendix .1
    (cellBndCondIsDirichlet on z- and z+)."""
    return np.any(on_plate[mesh.tetrahedra], axis=1)


def moved_mesh(mesh: Mesh, points: FloatArray) -> tuple[Mesh, npt.NDArray[np.bool_]]:
    """The mesh's geometry at moved points, same connectivity; also the inverted cells.

    Unlike :func:`shared.mesh.update_mesh` this tolerates inverted cells (hull slivers
    that the model keeps inert flip with the slightest motion): volumes are absolute
    values, normals are oriented by the cell centroids. The caller decides whether an
    inverted cell that matters needs a new mesh.
    """
    tet = mesh.tetrahedra
    p = points[tet]
    signed = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) / 6.0
    centroids = p.mean(axis=1)

    def triangles(vertices: IntArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        q = points[vertices]
        cross = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
        norm = np.linalg.norm(cross, axis=1)
        return 0.5 * norm, cross / np.maximum(norm, 1e-300)[:, None], q.mean(axis=1)

    area, normal, centre = triangles(mesh.facet_vertices)
    direction = centroids[mesh.facet_cells[:, 1]] - centroids[mesh.facet_cells[:, 0]]
    normal *= np.where(np.einsum("ij,ij->i", normal, direction) < 0.0, -1.0, 1.0)[:, None]
    b_area, b_normal, b_centre = triangles(mesh.boundary_vertices)
    outward = b_centre - centroids[mesh.boundary_cells]
    b_normal *= np.where(np.einsum("ij,ij->i", b_normal, outward) < 0.0, -1.0, 1.0)[:, None]
    moved = dataclass_replace(
        mesh, points=points.copy(), volumes=np.abs(signed), centroids=centroids,
        facet_areas=area, facet_normals=normal, facet_centroids=centre,
        boundary_areas=b_area, boundary_normals=b_normal, boundary_centroids=b_centre,
    )
    return moved, signed <= 0.0


def matching_keys(old: IntArray, new: IntArray) -> IntArray:
    """(n_new,) index of the entry of ``old`` equal to each of ``new`` (integer keys, each
    at most once in ``old``), -1 where there is none."""
    if old.size == 0:
        return np.full(new.shape, -1, dtype=np.int64)
    order = np.argsort(old)
    where = np.clip(np.searchsorted(old[order], new), 0, old.size - 1)
    return np.where(old[order][where] == new, order[where], -1)
