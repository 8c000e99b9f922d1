"""Representative elementary volume (REV) of porosity and solid-pore interface density.

Two criteria are computed. Random windows: for cubic windows of growing edge at seeded
random positions, the mean and standard deviation of porosity and of interface density
(solid-pore area per unit volume); the REV edge is the smallest window from which the
relative standard deviation stays below a tolerance. Centred window (Ferrage et al. 2015,
Sec. V C): a window centred in the image and grown in all directions up to the whole
image; the REV edge is the smallest window whose value stays within the tolerance of the
whole image's for every larger window.

Window sums come from summed-volume tables (one per field, one per face direction), so
a window costs eight look-ups whatever its size: a million windows per edge take about a
second, enough that the random-window curves do not depend on the seed (and every
position is taken when there are fewer).

Interface area is counted from voxel faces between unlike phases. For an isotropic
surface, face counting overestimates the area by 3/2 (the mean of |n_x| + |n_y| + |n_z|
over the sphere), so counted area is multiplied by 2/3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = [
    "FACE_COUNT_CORRECTION",
    "RevResult",
    "window_sizes",
    "interface_area",
    "rev_analysis",
    "rev_size",
    "centred_rev_size",
]

FACE_COUNT_CORRECTION = 2.0 / 3.0


@dataclass(frozen=True)
class RevResult:
    """Window statistics and REV sizes.

    Attributes
    ----------
    window : ndarray of int
        Edges of the random windows [voxel].
    porosity_mean, porosity_std : ndarray
        Over window positions [-].
    interface_mean, interface_std : ndarray
        Interface density over window positions [1/m]; NaN when no binary image is given.
    window_centred : ndarray of int
        Edges of the centred windows [voxel], up to the image's smallest side.
    porosity_centred, interface_centred : ndarray
        Values in the centred windows [-], [1/m].
    porosity_total, interface_total : float
        Whole-image values [-], [1/m].
    w_rev_porosity, w_rev_interface : float
        REV edges by the relative-std criterion [m]; NaN when not reached.
    w_rev_porosity_centred, w_rev_interface_centred : float
        REV edges by the centred-window criterion [m]; NaN when not reached inside the
        image (see :func:`centred_rev_size`).
    """

    window: npt.NDArray[np.int64]
    porosity_mean: npt.NDArray[np.float64]
    porosity_std: npt.NDArray[np.float64]
    interface_mean: npt.NDArray[np.float64]
    interface_std: npt.NDArray[np.float64]
    window_centred: npt.NDArray[np.int64]
    porosity_centred: npt.NDArray[np.float64]
    interface_centred: npt.NDArray[np.float64]
    porosity_total: float
    interface_total: float
    w_rev_porosity: float
    w_rev_interface: float
    w_rev_porosity_centred: float
    w_rev_interface_centred: float


def window_sizes(max_edge: int, n_sizes: int, min_edge: int = 2) -> npt.NDArray[np.int64]:
    """Geometrically spaced distinct window edges from ``min_edge`` to ``max_edge`` [voxel]."""
    if max_edge < min_edge:
        raise ValueError(f"image edge {max_edge} is smaller than the smallest window {min_edge}")
    sizes = np.unique(np.rint(np.geomspace(min_edge, max_edge, n_sizes)).astype(np.int64))
    return sizes


class _BoxSums:
    """Sums of an array over axis-aligned boxes, from its summed-volume table."""

    def __init__(self, values: npt.NDArray) -> None:
        dtype = np.int64 if values.dtype.kind in "biu" else np.float64
        table = np.zeros(tuple(n + 1 for n in values.shape), dtype=dtype)
        np.cumsum(values, axis=0, dtype=dtype, out=table[1:, 1:, 1:])
        np.cumsum(table[1:, 1:, 1:], axis=1, out=table[1:, 1:, 1:])
        np.cumsum(table[1:, 1:, 1:], axis=2, out=table[1:, 1:, 1:])
        self.table = table

    def __call__(self, starts: npt.NDArray[np.int64], edges: npt.NDArray[np.int64]) -> npt.NDArray:
        """Sums over the boxes ``[starts, starts + edges)``, one per row of ``starts``."""
        low, high = starts, starts + edges
        total = np.zeros(starts.shape[0], dtype=self.table.dtype)
        for corner in np.ndindex(2, 2, 2):
            index = tuple(np.where(corner[a], high[:, a], low[:, a]) for a in range(3))
            sign = -1 if (3 - sum(corner)) % 2 else 1
            total += sign * self.table[index]
        return total


class _FaceSums:
    """Number of voxel faces between unlike phases inside boxes of a binary image."""

    def __init__(self, pore: npt.NDArray[np.bool_]) -> None:
        self.per_axis = [_BoxSums(np.diff(pore.view(np.uint8), axis=a) != 0) for a in range(3)]

    def __call__(self, starts: npt.NDArray[np.int64], edges: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
        total = np.zeros(starts.shape[0], dtype=np.int64)
        for axis, sums in enumerate(self.per_axis):
            inner = edges.copy()
            inner[axis] -= 1  # faces between the window's own voxels along this axis
            total += sums(starts, inner)
        return total


def interface_area(binary: npt.NDArray[np.bool_], voxel_size: float) -> float:
    """Solid-pore interface area of a binary image [m2], with the 2/3 face-count correction."""
    faces = sum(int(np.count_nonzero(np.diff(binary.view(np.uint8), axis=a))) for a in range(3))
    return FACE_COUNT_CORRECTION * faces * voxel_size**2


def rev_size(
    window_edges: npt.NDArray[np.floating],
    relative_deviation: npt.NDArray[np.floating],
    tolerance: float,
) -> float:
    """Smallest window edge from which ``relative_deviation`` stays at or below ``tolerance``.

    Returns NaN when even the largest window does not satisfy it.
    """
    ok = np.asarray(relative_deviation) <= tolerance
    if not ok[-1]:
        return float("nan")
    failing = np.flatnonzero(~ok)
    first = 0 if failing.size == 0 else failing[-1] + 1
    return float(window_edges[first])


def centred_rev_size(
    window_edges: npt.NDArray[np.floating],
    deviation: npt.NDArray[np.floating],
    whole: bool,
    tolerance: float,
) -> float:
    """REV edge of the centred-window criterion [m], as :func:`rev_size`, except that
    a last window equal to the whole image (``whole``) is left out: it agrees with itself
    by construction, so reaching the REV only there says nothing (NaN)."""
    if whole:
        window_edges, deviation = window_edges[:-1], deviation[:-1]
    if window_edges.size == 0:
        return float("nan")
    return rev_size(window_edges, deviation, tolerance)


def _window_starts(
    positions: npt.NDArray[np.int64], n_positions: int, rng: np.random.Generator
) -> npt.NDArray[np.int64]:
    """Lowest corners of the windows of one edge: every position when there are at most
    ``n_positions`` of them (the statistics are then exact and seed-free), else
    ``n_positions`` drawn at random."""
    count = int(np.prod(positions))
    if count <= n_positions:
        return np.stack(np.unravel_index(np.arange(count), tuple(positions)), axis=1)
    return rng.integers(0, positions, size=(n_positions, 3), dtype=np.int64)


def rev_analysis(
    porosity: npt.NDArray[np.floating],
    voxel_size: float,
    rng: np.random.Generator,
    *,
    binary: npt.NDArray[np.bool_] | None = None,
    n_sizes: int = 12,
    n_positions: int = 2**20,
    tolerance: float = 0.01,
    min_edge: int = 2,
    max_window_fraction: float = 0.5,
    n_centred_sizes: int = 32,
) -> RevResult:
    """REV analysis of a porosity field and, optionally, of a binary pore image.

    Parameters
    ----------
    porosity
        Voxel porosity ``(z, y, x)`` [-]; a binary pore image (pore = 1) works as well.
    voxel_size
        Voxel edge [m].
    rng
        Generator of window positions.
    binary
        Pore (True) / solid image of the same shape for interface density; None to skip.
    n_sizes
        Number of random-window edges, geometrically spaced up to ``max_window_fraction``
        of the image's smallest side.
    n_positions
        Random windows per edge; every position is used when there are no more.
    tolerance
        Relative deviation defining the REV [-] (0.01: the paper's +-1 %).
    min_edge
        Smallest window edge [voxel].
    max_window_fraction
        Largest random window edge as a fraction of the image's smallest side [-]: windows
        close to the whole image overlap so much that their spread says nothing of the REV.
    n_centred_sizes
        Number of centred-window edges, geometrically spaced up to the smallest side.

    Returns
    -------
    RevResult
    """
    values = np.asarray(porosity)
    if values.ndim != 3:
        raise ValueError(f"REV analysis needs a 3-D image, got shape {values.shape}")
    if not np.isfinite(values).all():
        raise ValueError("REV analysis needs a finite porosity field (crop away NaN first)")
    if binary is not None and binary.shape != values.shape:
        raise ValueError(f"binary image {binary.shape} and porosity {values.shape} differ")
    whole = np.array(values.shape, dtype=np.int64)
    field = _BoxSums(values if values.dtype.kind in "biu" else values.astype(np.float64))
    faces = None if binary is None else _FaceSums(np.asarray(binary, dtype=bool))

    def porosity_of(starts: np.ndarray, edges: np.ndarray) -> np.ndarray:
        return field(starts, edges) / float(np.prod(edges))

    def interface_of(starts: np.ndarray, edges: np.ndarray) -> np.ndarray:
        if faces is None:
            return np.full(starts.shape[0], np.nan)
        return FACE_COUNT_CORRECTION * faces(starts, edges) / (float(np.prod(edges)) * voxel_size)

    origin = np.zeros((1, 3), dtype=np.int64)
    porosity_total = float(porosity_of(origin, whole)[0])
    interface_total = float(interface_of(origin, whole)[0])

    sizes = window_sizes(int(max_window_fraction * min(values.shape)), n_sizes, min_edge)
    stats = np.full((4, sizes.size), np.nan)
    for index, width in enumerate(sizes):
        edges = np.full(3, width, dtype=np.int64)
        starts = _window_starts(whole - width + 1, n_positions, rng)
        local = porosity_of(starts, edges)
        stats[0, index], stats[1, index] = local.mean(), local.std()
        local = interface_of(starts, edges)
        stats[2, index], stats[3, index] = local.mean(), local.std()

    sizes_c = window_sizes(int(min(values.shape)), n_centred_sizes, min_edge)
    centred = np.full((2, sizes_c.size), np.nan)
    for index, width in enumerate(sizes_c):
        edges = np.full(3, width, dtype=np.int64)
        start = ((whole - width) // 2).reshape(1, 3)
        centred[0, index] = porosity_of(start, edges)[0]
        centred[1, index] = interface_of(start, edges)[0]
    is_whole = bool(np.all(whole == sizes_c[-1]))

    edges_m, edges_c = sizes * voxel_size, sizes_c * voxel_size
    with np.errstate(invalid="ignore", divide="ignore"):
        spread = stats[[1, 3]] / np.abs(stats[[0, 2]])
        deviation = np.abs(centred / np.array([[porosity_total], [interface_total]]) - 1.0)
    return RevResult(
        window=sizes,
        porosity_mean=stats[0],
        porosity_std=stats[1],
        interface_mean=stats[2],
        interface_std=stats[3],
        window_centred=sizes_c,
        porosity_centred=centred[0],
        interface_centred=centred[1],
        porosity_total=porosity_total,
        interface_total=interface_total,
        w_rev_porosity=rev_size(edges_m, spread[0], tolerance),
        w_rev_interface=rev_size(edges_m, spread[1], tolerance),
        w_rev_porosity_centred=centred_rev_size(edges_c, deviation[0], is_whole, tolerance),
        w_rev_interface_centred=centred_rev_size(edges_c, deviation[1], is_whole, tolerance),
    )
