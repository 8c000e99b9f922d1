"""SPD test systems of the solver tests: random graph Laplacians, their drifted copies,
and flow systems of the micro model."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from shared.solver import SPDSolver


def laplacian_system(n: int, rng: np.random.Generator) -> sp.csc_matrix:
    """SPD graph Laplacian of a random sparse graph plus a positive diagonal."""
    rows = rng.integers(0, n, 4 * n)
    cols = rng.integers(0, n, 4 * n)
    keep = rows != cols
    weights = rng.uniform(0.5, 2.0, keep.sum())
    adjacency = sp.coo_matrix((weights, (rows[keep], cols[keep])), shape=(n, n)).tocsr()
    adjacency = adjacency + adjacency.T
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    return (sp.diags(degree + rng.uniform(0.01, 0.1, n)) - adjacency).tocsc()


def drift_conductances(
    matrix: sp.csc_matrix, amplitude: float, rng: np.random.Generator
) -> sp.csc_matrix:
    """The system with every conductance (off-diagonal) scaled by 1 +- amplitude.

    Storage (row sums) is kept, so the result is again a Laplacian plus a positive
    diagonal, hence SPD.
    """
    storage = np.asarray(matrix.sum(axis=1)).ravel()
    adjacency = sp.diags(matrix.diagonal()) - matrix
    adjacency.data *= 1.0 + amplitude * rng.uniform(-1.0, 1.0, adjacency.nnz)
    adjacency = (adjacency + adjacency.T) / 2.0
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    return (sp.diags(degree + storage) - adjacency).tocsc()


def lower_of(matrix: sp.spmatrix) -> sp.csc_matrix:
    lower = sp.tril(matrix, format="csc")
    lower.sort_indices()
    return lower


def flow_system(
    per_side: int, case: str, rng: np.random.Generator, contrast: float = 1e15
) -> tuple[sp.csc_matrix, np.ndarray]:
    """Lower triangle and rhs of a flow system of the micro model on a jittered mesh.

    ``transient``: every cell free, storage of a 1000 s step; ``steady``: two opposite
    walls imposed, no storage; ``cracked``: the steady system with rings of facets
    around 25 edges conducting ``contrast`` times the clay (1e15: the permeability
    test's contrast).
    """
    from shared.fv import assemble_matrix, facet_divergence, flow_pattern
    from shared.mesh import WALLS, boundary_cell_mask, build_mesh

    spacing = 7e-3 / per_side
    axis = (np.arange(per_side) + 0.5) * spacing
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    mesh = build_mesh(grid + rng.uniform(-0.3, 0.3, grid.shape) * spacing)
    conductance = rng.uniform(0.5, 2.0, mesh.n_facets) * 1e-22
    storage = np.zeros(mesh.n_cells)
    if case == "transient":
        dirichlet = np.zeros(mesh.n_cells, dtype=bool)
        storage = mesh.volumes * 0.3 * 1e-9 / 1e3
    else:
        dirichlet = boundary_cell_mask(mesh, [WALLS[4], WALLS[5]])
    if case == "cracked":
        edges = np.sort(mesh.facet_vertices, axis=1)
        ring = np.zeros(mesh.n_facets, dtype=bool)
        for a, b in edges[rng.choice(mesh.n_facets, 25, replace=False)][:, :2]:
            ring |= (edges == a).any(axis=1) & (edges == b).any(axis=1)
        conductance = np.where(ring, conductance * contrast, conductance)
    pattern = flow_pattern(mesh, dirichlet)
    pressure = np.where(mesh.circumcentres[:, 2] < 3.5e-3, -1e8, -2e7)
    rhs = facet_divergence(mesh, conductance, pressure)[pattern.free_cells]
    return assemble_matrix(mesh, pattern, conductance, storage), rhs


def drifting_start(rng: np.random.Generator, **options: object) -> tuple[sp.csc_matrix, np.ndarray, SPDSolver]:
    """A 100-cell conductance system, a random right-hand side and a solver with ``options``
    (drawn in that order from ``rng``)."""
    return laplacian_system(100, rng), rng.standard_normal(100), SPDSolver(**options)

