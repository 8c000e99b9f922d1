"""Specimen mask: which voxels belong to the scanned specimen rather than the air around it.

Air must not bias calibration or averages. By default (``threshold`` mode) the mask is a
threshold (Otsu's by default) followed, slice by slice, by the largest connected
component with its holes filled: cracks and flaws inside the specimen are part of its
pore space, not outside air. Slices whose specimen section is small compared with the
largest one (the ends of the specimen, stray bright voxels) are dropped. A scan without
air around the specimen (it fills the field of view) or of a specimen inside a container
needs another mode: the whole field (``full``) or a given vertical cylinder
(``cylinder``, e.g. the container's inner wall).
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from shared.errors import InputError

__all__ = [
    "SAMPLE_SIZE",
    "sample_stride",
    "grey_sample",
    "otsu_threshold",
    "specimen_mask",
    "slice_masks",
    "cylinder_section",
    "border_counts",
    "inscribed_box",
]

SAMPLE_SIZE = 1 << 22
"""Voxels (at most) of the strided sample of a volume that the threshold and the grey
histogram read."""


def sample_stride(size: int) -> int:
    """Stride along each axis of the sample ``volume[::s, ::s, ::s]`` of a volume of
    ``size`` voxels: at most ``SAMPLE_SIZE`` voxels, spread over the whole volume."""
    return max(1, int(np.ceil((size / SAMPLE_SIZE) ** (1.0 / 3.0) - 1e-9)))


def grey_sample(volume: npt.NDArray) -> npt.NDArray:
    """The strided sample of a volume (:func:`sample_stride`), flattened; a 1-D array is
    taken as a sample already."""
    if volume.ndim != 3:
        return volume.reshape(-1)
    step = sample_stride(volume.size)
    return volume[::step, ::step, ::step].reshape(-1)


def otsu_threshold(volume: npt.NDArray[np.unsignedinteger]) -> float:
    """Otsu's threshold of a volume (or of its :func:`grey_sample`, which gives the same),
    computed by OpenCV on an 8-bit rescaled sample."""
    sample = grey_sample(volume).astype(np.float64)
    low, high = float(sample.min()), float(sample.max())
    if high <= low:
        raise InputError("the volume is uniform: no threshold separates specimen and air")
    scaled = np.rint((sample - low) * (255.0 / (high - low))).astype(np.uint8)
    level, _ = cv2.threshold(scaled.reshape(1, -1), 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    return low + (level + 0.5) * (high - low) / 255.0


def _filled_largest_component(binary: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
    count, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    if count <= 1:
        return np.zeros_like(binary)
    largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    component = (labels == largest).astype(np.uint8)
    contours, _ = cv2.findContours(component, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    filled = np.zeros_like(binary)
    cv2.drawContours(filled, contours, -1, color=1, thickness=cv2.FILLED)
    return filled


def specimen_mask(
    volume: npt.NDArray[np.unsignedinteger],
    threshold: float | None = None,
    min_slice_fraction: float = 0.2,
) -> npt.NDArray[np.bool_]:
    """Boolean mask of the specimen in a ``(z, y, x)`` greyscale volume.

    Parameters
    ----------
    volume
        Greyscale volume.
    threshold
        Grey value above which a voxel is material; Otsu's threshold when None.
    min_slice_fraction
        A slice is kept only if its specimen section is at least this fraction of the
        largest section [-].

    Raises
    ------
    ValueError
        If no specimen is found.
    """
    level = otsu_threshold(volume) if threshold is None else float(threshold)
    mask = slice_masks(volume, level)
    areas = mask.sum(axis=(1, 2), dtype=np.int64)
    if areas.max() == 0:
        raise InputError(f"no voxel above the threshold {level:g}: no specimen found")
    mask[areas < min_slice_fraction * areas.max()] = 0
    return mask.view(bool)


def slice_masks(slab: npt.NDArray[np.unsignedinteger], level: float) -> npt.NDArray[np.uint8]:
    """Per slice of a slab, the largest connected component above ``level`` with its holes
    filled (1 inside, 0 outside)."""
    mask = np.zeros(slab.shape, dtype=np.uint8)
    for index, page in enumerate(slab):
        mask[index] = _filled_largest_component((page > level).astype(np.uint8))
    return mask


def cylinder_section(
    shape: tuple[int, int, int],
    voxel_size: float,
    radius: float,
    centre: tuple[float, float] | None = None,
    z_range: tuple[float, float] | None = None,
) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """A vertical cylinder (axis along z) as the slices it spans and its disc: the mask of
    the voxels whose centre lies inside it is ``slices[:, None, None] & disc``.

    Parameters
    ----------
    shape
        Volume shape ``(z, y, x)``.
    voxel_size
        Voxel edge [m].
    radius
        Cylinder radius [m].
    centre
        ``(y, x)`` of the axis from the volume's corner [m]; the field's centre when None.
    z_range
        ``(bottom, top)`` of the cylinder from the first slice's lower face [m]; every
        slice when None.

    Returns
    -------
    slices : ndarray of bool, shape (z,)
    disc : ndarray of bool, shape (y, x)

    Raises
    ------
    ValueError
        If the cylinder holds no voxel centre.
    """
    nz, ny, nx = shape
    if centre is None:
        centre = (0.5 * ny * voxel_size, 0.5 * nx * voxel_size)
    y = (np.arange(ny) + 0.5) * voxel_size - centre[0]
    x = (np.arange(nx) + 0.5) * voxel_size - centre[1]
    z = (np.arange(nz) + 0.5) * voxel_size
    low, high = (-np.inf, np.inf) if z_range is None else z_range
    disc = y[:, None] ** 2 + x[None, :] ** 2 <= radius**2
    slices = (z >= low) & (z <= high)
    if not (disc.any() and slices.any()):
        raise InputError(f"the cylinder of radius {radius:g} m at {tuple(centre)} m, z in "
                         f"{[low, high]} m, holds no voxel")
    return slices, disc


def border_counts(mask: npt.NDArray) -> tuple[npt.NDArray[np.int64], int]:
    """Per slice, the number of lateral border voxels (outermost rows and columns) inside
    the mask, and the number of border voxels of a slice."""
    ny, nx = mask.shape[1:]
    inside = (mask[:, 0, :].sum(axis=1, dtype=np.int64) + mask[:, -1, :].sum(axis=1, dtype=np.int64)
              + mask[:, 1:-1, 0].sum(axis=1, dtype=np.int64)
              + mask[:, 1:-1, -1].sum(axis=1, dtype=np.int64))
    return inside, 2 * nx + 2 * max(ny - 2, 0)


def inscribed_box(mask: Any) -> tuple[slice, slice, slice]:
    """The largest cube centred on the mask's centroid that lies wholly inside the mask.

    ``mask`` may be numpy or dask: only its sums and the candidate cubes are computed.

    Returns
    -------
    tuple of slice
        Index slices ``(z, y, x)`` of the cube.
    """
    def value(x: Any) -> Any:
        return x.compute() if hasattr(x, "compute") else x

    total = float(value(mask.sum()))
    if total == 0:
        raise InputError("the specimen mask is empty: no inscribed cube")
    def profile(axis: int) -> np.ndarray:
        return np.asarray(value(mask.sum(axis=tuple(a for a in range(3) if a != axis))))

    centre = np.array([
        int(np.rint((np.arange(n) * profile(axis)).sum() / total)) for axis, n in enumerate(mask.shape)
    ])
    low, high = 0, int(min(min(centre), min(np.array(mask.shape) - centre - 1)))

    def cube(half: int) -> tuple[slice, slice, slice]:
        z, y, x = (slice(c - half, c + half + 1) for c in centre)
        return z, y, x

    if not bool(value(mask[tuple(centre)])):
        raise InputError("the specimen's centroid lies outside it: no inscribed cube")
    while low < high:
        half = (low + high + 1) // 2
        if bool(value(mask[cube(half)].all())):
            low = half
        else:
            high = half - 1
    return cube(low)
