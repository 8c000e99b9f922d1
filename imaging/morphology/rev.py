"""Representative elementary volume (REV) of porosity and solid-pore interface density.

For cubic windows of growing edge at seeded random positions, the mean and standard
deviation of porosity and of interface density (solid-pore area per unit volume) are
computed; the REV edge is the smallest window from which the relative standard deviation
stays below a tolerance. The criterion of Ferrage et al. (2015, Sec. V.C) is also
provided: a window centred in the image whose value stays within the tolerance of the
whole-image value for all larger windows.

Interface area is counted from voxel faces between unlike phases. For an isotropic
surface, face counting overestimates the area by 3/2 (the mean of |n_x| + |n_y| + |n_z|
over the sphere), so counted area is multiplied by 2/3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from imaging.morphology import _kernels

__all__ = [
    "FACE_COUNT_CORRECTION",
    "RevResult",
    "window_sizes",
    "interface_area",
    "rev_analysis",
    "rev_size",
]

FACE_COUNT_CORRECTION = 2.0 / 3.0


@dataclass(frozen=True)
class RevResult:
    """Window statistics and REV sizes.

    Attributes
    ----------
    window : ndarray of int
        Window edges [voxel].
    porosity_mean, porosity_std : ndarray
        Over window positions [-].
    interface_mean, interface_std : ndarray
        Interface density over window positions [1/m]; NaN when no binary image is given.
    porosity_centred, interface_centred : ndarray
        Values in the centred window [-], [1/m].
    porosity_total, interface_total : float
        Whole-image values [-], [1/m].
    w_rev_porosity, w_rev_interface : float
        REV edges by the relative-std criterion [m]; NaN when not reached.
    w_rev_porosity_centred, w_rev_interface_centred : float
        REV edges by the centred-window criterion [m]; NaN when not reached.
    """

    window: npt.NDArray[np.int64]
    porosity_mean: npt.NDArray[np.float64]
    porosity_std: npt.NDArray[np.float64]
    interface_mean: npt.NDArray[np.float64]
    interface_std: npt.NDArray[np.float64]
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


def _interface_density(
    pore: npt.NDArray[np.uint8],
    starts: npt.NDArray[np.int64],
    edges: npt.NDArray[np.int64],
    voxel_size: float,
) -> npt.NDArray[np.float64]:
    """Interface area per unit volume [1/m] of box windows, with the 2/3 correction."""
    faces = _kernels.window_interface_faces(pore, starts, edges)
    return FACE_COUNT_CORRECTION * faces / (float(np.prod(edges)) * voxel_size)


def _mean(
    values: npt.NDArray[np.float32], starts: npt.NDArray[np.int64], edges: npt.NDArray[np.int64]
) -> npt.NDArray[np.float64]:
    return _kernels.window_sums(values, starts, edges) / float(np.prod(edges))


def interface_area(binary: npt.NDArray[np.bool_], voxel_size: float) -> float:
    """Solid-pore interface area of a binary image [m2], with the 2/3 face-count correction."""
    edges = np.array(binary.shape, dtype=np.int64)
    pore = np.ascontiguousarray(binary, dtype=np.uint8)
    density = _interface_density(pore, np.zeros((1, 3), np.int64), edges, voxel_size)[0]
    return float(density * np.prod(edges) * voxel_size**3)


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


def rev_analysis(
    porosity: npt.NDArray[np.floating],
    voxel_size: float,
    rng: np.random.Generator,
    *,
    binary: npt.NDArray[np.bool_] | None = None,
    n_sizes: int = 12,
    n_positions: int = 64,
    tolerance: float = 0.01,
    min_edge: int = 2,
    max_window_fraction: float = 0.5,
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
        Number of window edges, geometrically spaced up to the image's smallest side.
    n_positions
        Random windows per edge.
    tolerance
        Relative deviation defining the REV [-] (0.01: the paper's +-1 %).
    min_edge
        Smallest window edge [voxel].
    max_window_fraction
        Largest window edge as a fraction of the image's smallest side [-]: windows close
        to the whole image overlap so much that their spread says nothing of the REV.

    Returns
    -------
    RevResult
    """
    values = np.ascontiguousarray(porosity, dtype=np.float32)
    if values.ndim != 3:
        raise ValueError(f"REV analysis needs a 3-D image, got shape {values.shape}")
    if not np.isfinite(values).all():
        raise ValueError("REV analysis needs a finite porosity field (crop away NaN first)")
    if binary is not None and binary.shape != values.shape:
        raise ValueError(f"binary image {binary.shape} and porosity {values.shape} differ")
    sizes = window_sizes(int(max_window_fraction * min(values.shape)), n_sizes, min_edge)
    pore = None if binary is None else np.ascontiguousarray(binary, dtype=np.uint8)
    whole = np.array(values.shape, dtype=np.int64)
    origin = np.zeros((1, 3), dtype=np.int64)
    stats = np.full((6, sizes.size), np.nan)
    for index, width in enumerate(sizes):
        edges = np.full(3, width, dtype=np.int64)
        starts = rng.integers(0, whole - width + 1, size=(n_positions, 3), dtype=np.int64)
        centred = ((whole - width) // 2).reshape(1, 3)
        local = _mean(values, starts, edges)
        stats[0, index], stats[1, index] = local.mean(), local.std()
        stats[4, index] = _mean(values, centred, edges)[0]
        if pore is not None:
            local = _interface_density(pore, starts, edges, voxel_size)
            stats[2, index], stats[3, index] = local.mean(), local.std()
            stats[5, index] = _interface_density(pore, centred, edges, voxel_size)[0]
    edges_m = sizes * voxel_size
    porosity_total = float(_mean(values, origin, whole)[0])
    interface_total = w_interface = w_interface_c = float("nan")
    if pore is not None:
        interface_total = float(_interface_density(pore, origin, whole, voxel_size)[0])
        with np.errstate(invalid="ignore", divide="ignore"):
            w_interface = rev_size(edges_m, stats[3] / np.abs(stats[2]), tolerance)
            w_interface_c = rev_size(
                edges_m, np.abs(stats[5] / interface_total - 1.0), tolerance
            )
    return RevResult(
        window=sizes,
        porosity_mean=stats[0],
        porosity_std=stats[1],
        interface_mean=stats[2],
        interface_std=stats[3],
        porosity_centred=stats[4],
        interface_centred=stats[5],
        porosity_total=porosity_total,
        interface_total=interface_total,
        w_rev_porosity=rev_size(edges_m, stats[1] / np.abs(stats[0]), tolerance),
        w_rev_interface=w_interface,
        w_rev_porosity_centred=rev_size(
            edges_m, np.abs(stats[4] / porosity_total - 1.0), tolerance
        ),
        w_rev_interface_centred=w_interface_c,
    )
