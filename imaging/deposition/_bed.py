"""Index of a particle bed: arrays, bounding boxes and spatial hash (see _grid_kernels)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from imaging.deposition import _contact_kernels, _grid_kernels
from imaging.deposition.population import volumes


class BedIndex:
    """Arrays of the placed particles, their bounding boxes and their spatial hash.

    Cells are at least the largest particle's bounding diameter wide, so a query only
    visits neighbouring cells; candidate buffers are sized for every particle and its
    periodic images.
    """

    def __init__(self, semi_axes: npt.NDArray[np.float64], box_width: float,
                 contact_distance: float) -> None:
        self.box_width = box_width
        self.contact_distance = contact_distance
        n = semi_axes.shape[0]
        radius = float(np.max(np.hypot(semi_axes[:, 0], semi_axes[:, 2])))
        n_cells = max(1, int(box_width // (2.0 * radius)))
        self.cell_xy = box_width / n_cells
        self.cell_z = 2.0 * radius
        self.margin = radius
        solid_height = float(np.sum(volumes(semi_axes))) / box_width**2
        n_layers = int(4.0 * solid_height / self.cell_z) + 4
        self.head = np.full((n_cells, n_cells, n_layers), -1, dtype=np.int64)
        self.link = np.full(n, -1, dtype=np.int64)
        self.heights = np.zeros((n_cells, n_cells))
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
        """(box width, cell edge x-y, cell edge z, largest half-extent, d_cont) [m]."""
        return np.array([self.box_width, self.cell_xy, self.cell_z, self.margin,
                         self.contact_distance])

    @classmethod
    def of(cls, centers: npt.NDArray[np.float64], rotations: npt.NDArray[np.float64],
           semi_axes: npt.NDArray[np.float64], box_width: float,
           contact_distance: float) -> "BedIndex":
        """Index of a finished bed."""
        bed = cls(semi_axes, box_width, contact_distance)
        bed.centers[:] = centers
        bed.rotations[:] = rotations
        bed.extents[:] = _contact_kernels.bounding_half_extents(rotations, semi_axes)
        bed._grow(int(centers[:, 2].max() // bed.cell_z) if len(centers) else 0)
        _grid_kernels.insert_all(bed.centers, bed.extents, bed.head, bed.link, bed.heights,
                                 bed.cell_xy, bed.cell_z)
        return bed

    def _grow(self, layer: int) -> None:
        if layer >= self.head.shape[2]:
            extra = np.full(self.head.shape[:2] + (layer + 4 - self.head.shape[2],), -1, np.int64)
            self.head = np.concatenate([self.head, extra], axis=2)

    def add(
        self, index: int, center: npt.NDArray[np.float64], rot: npt.NDArray[np.float64]
    ) -> None:
        """Place particle ``index`` at ``center`` [m] with rotation ``rot``."""
        self._grow(int(center[2] // self.cell_z))
        self.centers[index] = center
        self.rotations[index] = rot
        _contact_kernels.half_extents(rot, self.axes[index], self.extents[index])
        top = center[2] + self.extents[index, 2]
        _grid_kernels.insert(index, self.centers, top, self.extents[index], self.head, self.link,
                             self.heights, self.cell_xy, self.cell_z)
