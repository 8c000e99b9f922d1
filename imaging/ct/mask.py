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

import cv2
import numpy as np
import numpy.typing as npt

__all__ = ["otsu_threshold", "specimen_mask", "cylinder_mask", "border_fraction", "inscribed_box"]

_OTSU_SAMPLE = 1 << 22


def otsu_threshold(volume: npt.NDArray[np.unsignedinteger]) -> float:
    """Otsu's threshold of a volume, computed by OpenCV on an 8-bit rescaled sample."""
    stride = max(1, int(np.ceil(volume.size / _OTSU_SAMPLE)))
    sample = volume.reshape(-1)[::stride].astype(np.float64)
    low, high = float(sample.min()), float(sample.max())
    if high <= low:
        raise ValueError("the volume is uniform: no threshold separates specimen and air")
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
    mask = np.zeros(volume.shape, dtype=np.uint8)
    for index, page in enumerate(volume):
        mask[index] = _filled_largest_component((page > level).astype(np.uint8))
    areas = mask.sum(axis=(1, 2), dtype=np.int64)
    if areas.max() == 0:
        raise ValueError(f"no voxel above the threshold {level:g}: no specimen found")
    mask[areas < min_slice_fraction * areas.max()] = 0
    return mask.view(bool)


def cylinder_mask(
    shape: tuple[int, int, int],
    voxel_size: float,
    radius: float,
    centre: tuple[float, float] | None = None,
    z_range: tuple[float, float] | None = None,
) -> npt.NDArray[np.bool_]:
    """Voxels whose centre lies inside a vertical cylinder (axis along z).

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

    Raises
    ------
    ValueError
        If the cylinder holds no voxel centre.
    """
    _, ny, nx = shape
    if centre is None:
        centre = (0.5 * ny * voxel_size, 0.5 * nx * voxel_size)
    y = (np.arange(ny) + 0.5) * voxel_size - centre[0]
    x = (np.arange(nx) + 0.5) * voxel_size - centre[1]
    z = (np.arange(shape[0]) + 0.5) * voxel_size
    low, high = (-np.inf, np.inf) if z_range is None else z_range
    inside = (y[:, None] ** 2 + x[None, :] ** 2 <= radius**2)[None] & (
        (z >= low) & (z <= high))[:, None, None]
    if not inside.any():
        raise ValueError(f"the cylinder of radius {radius:g} m at {tuple(centre)} m, z in "
                         f"{[low, high]} m, holds no voxel")
    return inside


def border_fraction(mask: npt.NDArray[np.bool_]) -> float:
    """Fraction of the lateral border voxels of the field (the outermost rows and columns
    of the slices holding specimen) that lie inside the mask: near 0 for a specimen with
    air around it, near 1 for one that fills the field of view."""
    kept = mask[mask.any(axis=(1, 2))]
    if kept.size == 0:
        return 0.0
    edges = [kept[:, 0, :], kept[:, -1, :], kept[:, 1:-1, 0], kept[:, 1:-1, -1]]
    return float(sum(int(e.sum()) for e in edges) / sum(e.size for e in edges))


def inscribed_box(mask: npt.NDArray[np.bool_]) -> tuple[slice, slice, slice]:
    """The largest cube centred on the mask's centroid that lies wholly inside the mask.

    Returns
    -------
    tuple of slice
        Index slices ``(z, y, x)`` of the cube.
    """
    centre = np.rint(np.argwhere(mask).mean(axis=0)).astype(int)
    low, high = 0, int(min(min(centre), min(np.array(mask.shape) - centre - 1)))

    def cube(half: int) -> tuple[slice, slice, slice]:
        return tuple(slice(c - half, c + half + 1) for c in centre)  # type: ignore[return-value]

    if not mask[tuple(centre)]:
        raise ValueError("the specimen's centroid lies outside it: no inscribed cube")
    while low < high:
        half = (low + high + 1) // 2
        if mask[cube(half)].all():
            low = half
        else:
            high = half - 1
    return cube(low)
