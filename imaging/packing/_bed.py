"""Index of a particle bed: arrays, bounding boxes and spatial hash (see _grid_kernels)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from imaging.packing import _contact_kernels, _grid_kernels
from imaging.packing.population import volumes

FINE_QUANTILE = 0.95
"""Particles whose bounding radius exceeds this quantile go to the coarse grid."""


class _Grid:
    """Cells of one size class: edges [m], margin (largest half-extent) [m], head array."""

    def __init__(self, radius: float, box_width: float, height: float) -> None:
        n_cells = max(1, int(box_width // (2.0 * radius)))
        self.cell_xy = box_width / n_cells
        self.cell_z = 2.0 * radius
        self.margin = radius
        self.head = np.full((n_cells, n_cells, int(height / self.cell_z) + 4), -1, dtype=np.int64)

    def grow(self, altitude: float) -> None:
        layer = int(altitude // self.cell_z)
        if layer >= self.head.shape[2]:
            extra = np.full(self.head.shape[:2] + (layer + 4 - self.head.shape[2],), -1, np.int64)
            self.head = np.concatenate([self.head, extra], axis=2)


class BedIndex:
    """Arrays of the placed particles, their bounding boxes and their spatial hash.

    Particles are split by bounding radius r = hypot(l_a, h/2): up to the 95th
    percentile they go to a fine grid of cells 2 r_95 wide, the others to a coarse grid of
    cells 2 r_max wide (empty for monodisperse beds). A query visits both, so its cost
    follows the local density of small particles, not the size of the largest one.
    Candidate buffers are sized for every particle and its periodic images.
    """

    def __init__(self, semi_axes: npt.NDArray[np.float64], box_width: float,
                 contact_distance: float, scan_points: int = 0) -> None:
        self.box_width = box_width
        self.contact_distance = contact_distance
        self.scan_points = scan_points
        n = semi_axes.shape[0]
        radius = np.hypot(semi_axes[:, 0], semi_axes[:, 2])
        fine_radius = float(np.quantile(radius, FINE_QUANTILE))
        self.coarse_member = radius > fine_radius
        height = 4.0 * float(np.sum(volumes(semi_axes))) / box_width**2
        self.fine = _Grid(fine_radius, box_width, height)
        self.coarse = _Grid(float(radius.max()), box_width, height)
        self.link = np.full(n, -1, dtype=np.int64)
        self.heights = np.zeros((self.fine.head.shape[0],) * 2)
        self.centers = np.zeros((n, 3))
        self.rotations = np.zeros((n, 3, 3))
        self.axes = semi_axes
        self.extents = np.zeros((n, 3))
        room = 9 * n + 64
        self.found = np.zeros(room, dtype=np.int64)
        self.shifts = np.zeros((room, 2))
        self.drops = np.zeros(room)
        self.witness = np.zeros((room, 3))

    @property
    def geometry(self) -> npt.NDArray[np.float64]:
        """Layout of the grids for the kernels (see ``_grid_kernels.gather_levels``) [m],
        then the contact scan's n_sp (0: exact contacts, see ``_settle_kernels.fall``)."""
        return np.array([self.box_width, self.contact_distance,
                         self.fine.cell_xy, self.fine.cell_z, self.fine.margin,
                         self.coarse.cell_xy, self.coarse.cell_z, self.coarse.margin,
                         float(self.scan_points)])

    @classmethod
    def of(cls, centers: npt.NDArray[np.float64], rotations: npt.NDArray[np.float64],
           semi_axes: npt.NDArray[np.float64], box_width: float,
           contact_distance: float) -> BedIndex:
        """Index of a finished bed."""
        bed = cls(semi_axes, box_width, contact_distance)
        bed.centers[:] = centers
        bed.rotations[:] = rotations
        bed.extents[:] = _contact_kernels.bounding_half_extents(rotations, semi_axes)
        top = float(centers[:, 2].max()) if len(centers) else 0.0
        for grid, members in ((bed.fine, ~bed.coarse_member), (bed.coarse, bed.coarse_member)):
            grid.grow(top)
            _grid_kernels.insert_all(np.flatnonzero(members), bed.centers, grid.head, bed.link,
                                     grid.cell_xy, grid.cell_z)
        return bed

    def add(
        self, index: int, center: npt.NDArray[np.float64], rot: npt.NDArray[np.float64]
    ) -> None:
        """Place particle ``index`` at ``center`` [m] with rotation ``rot``."""
        self.centers[index] = center
        self.rotations[index] = rot
        _contact_kernels.half_extents(rot, self.axes[index], self.extents[index])
        grid = self.coarse if self.coarse_member[index] else self.fine
        grid.grow(center[2])
        _grid_kernels.insert(index, self.centers, grid.head, self.link, grid.cell_xy, grid.cell_z)
        _grid_kernels.raise_heights(center, self.extents[index], self.heights, self.fine.cell_xy)
