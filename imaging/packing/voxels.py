"""Voxel image of a particle bed and its overlap fraction (Ferrage et al. 2015, Sec. V.B).

A voxel is solid if its centre lies in at least one particle. The image spans the
periodic box in x and y with ``resolution`` voxels of edge l_v = w / resolution, and a
range of altitudes. The overlap fraction f_o is the share of solid voxels whose centre
lies in two or more particles: it measures interpenetration independently of how the
bed was built.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from imaging.packing import _analysis_kernels
from imaging.packing._contact_kernels import bounding_half_extents

__all__ = ["VoxelImage", "voxel_counts", "voxelize", "overlap_fraction"]


class VoxelImage(NamedTuple):
    """Voxel image of a bed.

    Attributes
    ----------
    counts : ndarray of uint8, shape (nz, ny, nx)
        Particles containing each voxel centre (saturates at 255).
    voxel_size : float
        Voxel edge l_v [m].
    z_origin : float
        Altitude of the bottom of the image [m].
    """

    counts: npt.NDArray[np.uint8]
    voxel_size: float
    z_origin: float

    @property
    def solid(self) -> npt.NDArray[np.bool_]:
        """True where a voxel centre lies in a particle."""
        return self.counts > 0


def voxel_counts(
    centers: npt.NDArray[np.float64],
    rotations: npt.NDArray[np.float64],
    semi_axes: npt.NDArray[np.float64],
    shape: tuple[int, int, int],
    voxel_size: float,
    z_origin: float = 0.0,
) -> npt.NDArray[np.uint8]:
    """Number of particles containing each voxel centre.

    Parameters
    ----------
    centers : ndarray, shape (n, 3)
        Barycentres [m].
    rotations : ndarray, shape (n, 3, 3)
        Particle axes in the box frame.
    semi_axes : ndarray, shape (n, 3)
        (l_a, l_b, h / 2) [m].
    shape : tuple of int
        (nz, ny, nx); x and y are periodic with period nx l_v and ny l_v.
    voxel_size : float
        l_v [m].
    z_origin : float
        Altitude of the bottom of the image [m].

    Returns
    -------
    ndarray of uint8, shape ``shape``
    """
    centers = np.ascontiguousarray(centers, dtype=np.float64)
    rotations = np.ascontiguousarray(rotations, dtype=np.float64)
    semi_axes = np.ascontiguousarray(semi_axes, dtype=np.float64)
    exts = bounding_half_extents(rotations, semi_axes)
    counts = np.zeros(shape, dtype=np.uint8)
    _analysis_kernels.voxel_coverage(centers, rotations, semi_axes, exts, float(z_origin),
                                     float(voxel_size), counts)
    return counts


def voxelize(
    centers: npt.NDArray[np.float64],
    rotations: npt.NDArray[np.float64],
    semi_axes: npt.NDArray[np.float64],
    box_width: float,
    resolution: int,
    z_range: tuple[float, float],
) -> VoxelImage:
    """Voxel image of the bed between two altitudes, periodic in x and y.

    Parameters
    ----------
    centers, rotations, semi_axes
        The bed ([m], rotation matrices, (l_a, l_b, h/2) [m]).
    box_width : float
        w [m].
    resolution : int
        Voxels along x and y; l_v = w / resolution.
    z_range : tuple of float
        (bottom, top) altitudes [m]; the image holds round((top - bottom) / l_v) layers
        (at least one).

    Returns
    -------
    VoxelImage
    """
    voxel_size = box_width / resolution
    layers = max(int(round((z_range[1] - z_range[0]) / voxel_size)), 1)
    counts = voxel_counts(centers, rotations, semi_axes, (layers, resolution, resolution),
                          voxel_size, z_range[0])
    return VoxelImage(counts, voxel_size, float(z_range[0]))


def overlap_fraction(counts: npt.NDArray[np.uint8]) -> float:
    """Share of solid voxels covered by two or more particles, f_o [1] (0 if no solid)."""
    solid = int(np.count_nonzero(counts))
    overlap = int(np.count_nonzero(counts >= 2))
    return overlap / solid if solid else 0.0
