"""Block averaging of a calibrated volume onto a coarse porosity grid.

The micro model assigns each tetrahedron the porosity of the grid at its centroid, with
a grid spacing equal to the mean DEM point spacing (thesis Sec. 3.3.4). A volume is
summed slab by slab (:func:`block_sums`; a block row may span slabs), so that memory is
set by the slab, and the sums make the grid (:func:`block_grid`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from imaging.ct.calibration import Calibration, density_to_porosity, grey_to_density
from shared.errors import ConfigError

__all__ = ["BlockGrid", "block_average", "block_sums", "block_grid", "block_size_voxels"]


@dataclass(frozen=True)
class BlockGrid:
    """Block-averaged fields and the grid's geometry.

    Attributes
    ----------
    density : ndarray, shape (nz, ny, nx)
        Mean density of the specimen voxels of each block [kg/m3]; NaN where too few
        voxels belong to the specimen.
    porosity : ndarray, shape (nz, ny, nx)
        Porosity of each block [-]; NaN where ``density`` is.
    specimen_fraction : ndarray, shape (nz, ny, nx)
        Fraction of each block's voxels inside the specimen [-].
    z, y, x : ndarray
        Block centres [m], with voxel ``i`` spanning ``[i, i + 1) * voxel_size``.
    block : tuple of int
        Block edge in voxels along ``(z, y, x)``.
    """

    density: npt.NDArray[np.float64]
    porosity: npt.NDArray[np.float64]
    specimen_fraction: npt.NDArray[np.float64]
    z: npt.NDArray[np.float64]
    y: npt.NDArray[np.float64]
    x: npt.NDArray[np.float64]
    block: tuple[int, int, int]


def block_size_voxels(spacing: float, voxel_size: float) -> int:
    """Block edge in voxels closest to ``spacing`` [m] for cubic voxels of ``voxel_size`` [m]."""
    if voxel_size <= 0 or spacing <= 0:
        raise ConfigError(f"spacing ({spacing}) and voxel size ({voxel_size}) must be > 0")
    return max(1, int(round(spacing / voxel_size)))


def _block_starts(n: int, size: int) -> npt.NDArray[np.intp]:
    return np.arange(0, n, size, dtype=np.intp)


def _block_centres(n: int, size: int, voxel_size: float) -> npt.NDArray[np.float64]:
    starts = _block_starts(n, size)
    ends = np.minimum(starts + size, n)
    return 0.5 * (starts + ends) * voxel_size


def block_sums(
    slab: npt.NDArray[np.unsignedinteger],
    specimen: npt.NDArray[np.bool_],
    calibration: Calibration,
    block: int,
    z0: int = 0,
) -> tuple[int, npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Sums of calibrated density [kg/m3] and counts of specimen voxels per block, over
    the slices ``[z0, z0 + len(slab))`` of a volume (a slab need not hold whole blocks:
    the sums of a block row shared by two slabs add up).

    Returns
    -------
    first_row : int
        Block row (along z) of the first row of the sums.
    density_sum, counts : ndarray, shape (block rows touched, blocks in y, blocks in x)
    """
    nz, ny, nx = slab.shape
    y_starts, x_starts = _block_starts(ny, block), _block_starts(nx, block)
    first_row = z0 // block
    # slab-local starts of the block rows it touches (the first may begin before it)
    z_starts = np.unique(np.r_[0, np.arange(-(z0 % block) + block, nz, block)]).astype(np.intp)
    density_sum = np.zeros((z_starts.size, y_starts.size, x_starts.size), dtype=np.float64)
    counts = np.zeros_like(density_sum)
    for row, (start, stop) in enumerate(zip(z_starts, np.r_[z_starts[1:], nz], strict=True)):
        slab_mask = specimen[start:stop]
        density = grey_to_density(slab[start:stop].astype(np.float32), calibration)
        density *= slab_mask
        column = density.sum(axis=0, dtype=np.float64)
        column_count = slab_mask.sum(axis=0, dtype=np.int64).astype(np.float64)
        density_sum[row] = np.add.reduceat(np.add.reduceat(column, y_starts, 0), x_starts, 1)
        counts[row] = np.add.reduceat(np.add.reduceat(column_count, y_starts, 0), x_starts, 1)
    return first_row, density_sum, counts


def block_grid(
    density_sum: npt.NDArray[np.float64],
    counts: npt.NDArray[np.float64],
    shape: tuple[int, ...],
    calibration: Calibration,
    block: int,
    voxel_size: float,
    min_specimen_fraction: float = 0.5,
) -> BlockGrid:
    """The grid of a volume of ``shape`` from its :func:`block_sums` (all rows added up)."""
    nz, ny, nx = shape
    starts = [_block_starts(n, block) for n in shape]
    sizes = np.multiply.outer(
        np.multiply.outer(np.diff(np.append(starts[0], nz)), np.diff(np.append(starts[1], ny))),
        np.diff(np.append(starts[2], nx)),
    ).astype(np.float64)
    fraction = counts / sizes
    with np.errstate(invalid="ignore", divide="ignore"):
        density = np.where(fraction >= min_specimen_fraction, density_sum / counts, np.nan)
    return BlockGrid(
        density=density,
        porosity=density_to_porosity(density, calibration).astype(np.float64, copy=False),
        specimen_fraction=fraction,
        z=_block_centres(nz, block, voxel_size),
        y=_block_centres(ny, block, voxel_size),
        x=_block_centres(nx, block, voxel_size),
        block=(block, block, block),
    )


def block_average(
    volume: npt.NDArray[np.unsignedinteger],
    specimen: npt.NDArray[np.bool_],
    calibration: Calibration,
    block: int,
    voxel_size: float,
    min_specimen_fraction: float = 0.5,
) -> BlockGrid:
    """Average calibrated density over cubic blocks of the specimen.

    Parameters
    ----------
    volume
        Greyscale volume ``(z, y, x)``.
    specimen
        Boolean specimen mask of the same shape.
    calibration
        Grey -> density -> porosity anchors.
    block
        Block edge [voxel]; blocks at the far faces may be smaller.
    voxel_size
        Voxel edge [m].
    min_specimen_fraction
        Blocks with a smaller fraction of specimen voxels are NaN [-].

    Returns
    -------
    BlockGrid
    """
    if volume.shape != specimen.shape:
        raise ValueError(f"volume {volume.shape} and mask {specimen.shape} differ in shape")
    _, density_sum, counts = block_sums(volume, specimen, calibration, block)
    return block_grid(density_sum, counts, volume.shape, calibration, block, voxel_size,
                      min_specimen_fraction)
