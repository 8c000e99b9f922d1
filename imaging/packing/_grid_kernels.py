"""Spatial hash of the particle bed, periodic in x and y, numba kernels.

A grid cuts the box into cells of edge at least the bounding diameter of the particles
it holds; each particle is listed in the cell that holds its centre (a linked list per
cell: ``head`` holds the first particle, ``link`` the next one). A query visits the
cells that an axis-aligned box can touch, with unwrapped x and y cell indices so that
each visited cell also fixes the periodic image (the shift added to stored centres).
The cost of a query depends on the local density only, not on the size of the bed.
Polydisperse beds use two grids (see :mod:`._bed`): fine cells for the bulk of the
particles and coarse cells for the few largest, so that rare large particles do not
make every cell hold hundreds of small ones.

A height map (highest particle top over each column of a fine xy grid) tells where a
new particle can enter the box without touching anything.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def insert(index, centers, head, link, cell_xy, cell_z):
    """List particle ``index`` in the cell of ``head`` that holds its centre."""
    nx, ny, nz = head.shape
    ix = int(np.floor(centers[index, 0] / cell_xy)) % nx
    iy = int(np.floor(centers[index, 1] / cell_xy)) % ny
    iz = min(int(np.floor(centers[index, 2] / cell_z)), nz - 1)
    link[index] = head[ix, iy, iz]
    head[ix, iy, iz] = index


@njit(cache=True)
def raise_heights(center, ext, heights, cell_xy):
    """Raise the height map to the top of a particle over its footprint [m]."""
    nx, ny = heights.shape
    top = center[2] + ext[2]
    x0 = int(np.floor((center[0] - ext[0]) / cell_xy))
    x1 = int(np.floor((center[0] + ext[0]) / cell_xy))
    y0 = int(np.floor((center[1] - ext[1]) / cell_xy))
    y1 = int(np.floor((center[1] + ext[1]) / cell_xy))
    for jx in range(x0, x1 + 1):
        for jy in range(y0, y1 + 1):
            heights[jx % nx, jy % ny] = max(heights[jx % nx, jy % ny], top)


@njit(cache=True)
def insert_all(members, centers, head, link, cell_xy, cell_z):
    """List the particles ``members`` of a finished bed in a grid."""
    for index in members:
        insert(index, centers, head, link, cell_xy, cell_z)


@njit(cache=True)
def entry_altitude(center, ext, heights, cell_xy):
    """Highest bed top [m] under the footprint of a particle centred at ``center``."""
    nx, ny = heights.shape
    x0 = int(np.floor((center[0] - ext[0]) / cell_xy))
    x1 = int(np.floor((center[0] + ext[0]) / cell_xy))
    y0 = int(np.floor((center[1] - ext[1]) / cell_xy))
    y1 = int(np.floor((center[1] + ext[1]) / cell_xy))
    best = 0.0
    for jx in range(x0, x1 + 1):
        for jy in range(y0, y1 + 1):
            best = max(best, heights[jx % nx, jy % ny])
    return best


@njit(cache=True)
def gather(lo, hi, centers, exts, head, link, box_width, cell_xy, cell_z, margin, found, shifts,
           start):
    """Particles of one grid whose bounding box meets the box [lo, hi] (x, y unwrapped) [m].

    ``margin`` is the largest bounding half-extent of the grid's particles [m]. Writes
    particle indices into ``found`` and the periodic shift of each (x, y) [m] into
    ``shifts`` from position ``start`` on; returns the new end (at most ``found.size``).
    """
    nx, ny, nz = head.shape
    x0 = int(np.floor((lo[0] - margin) / cell_xy))
    x1 = int(np.floor((hi[0] + margin) / cell_xy))
    y0 = int(np.floor((lo[1] - margin) / cell_xy))
    y1 = int(np.floor((hi[1] + margin) / cell_xy))
    z0 = max(int(np.floor((lo[2] - margin) / cell_z)), 0)
    z1 = min(int(np.floor((hi[2] + margin) / cell_z)), nz - 1)
    count = start
    for jx in range(x0, x1 + 1):
        sx = np.floor(jx / nx) * box_width
        for jy in range(y0, y1 + 1):
            sy = np.floor(jy / ny) * box_width
            for jz in range(z0, z1 + 1):
                j = head[jx % nx, jy % ny, jz]
                while j >= 0:
                    if (
                        centers[j, 0] + sx + exts[j, 0] >= lo[0]
                        and centers[j, 0] + sx - exts[j, 0] <= hi[0]
                        and centers[j, 1] + sy + exts[j, 1] >= lo[1]
                        and centers[j, 1] + sy - exts[j, 1] <= hi[1]
                        and centers[j, 2] + exts[j, 2] >= lo[2]
                        and centers[j, 2] - exts[j, 2] <= hi[2]
                        and count < found.size
                    ):
                        found[count] = j
                        shifts[count, 0] = sx
                        shifts[count, 1] = sy
                        count += 1
                    j = link[j]
    return count


@njit(cache=True)
def gather_levels(lo, hi, centers, exts, fine, coarse, link, geometry, found, shifts):
    """Particles of both grids whose bounding box meets [lo, hi] (see :func:`gather`).

    ``geometry`` = (box width, d_cont, fine cell x-y, fine cell z, fine margin, coarse cell
    x-y, coarse cell z, coarse margin) [m].
    """
    count = gather(lo, hi, centers, exts, fine, link, geometry[0], geometry[2], geometry[3],
                   geometry[4], found, shifts, np.int64(0))  # int64: one compiled gather
    return gather(lo, hi, centers, exts, coarse, link, geometry[0], geometry[5], geometry[6],
                  geometry[7], found, shifts, count)
