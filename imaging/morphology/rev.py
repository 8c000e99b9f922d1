"""Representative elementary volume (REV) of porosity and solid-pore interface density.

Random windows: for cubic windows of growing edge at seeded random positions, the mean
and standard deviation of porosity and interface density (solid-pore area per unit
volume); the REV edge is the smallest window from which the relative standard deviation
stays below a tolerance. Centred window (Ferrage et al. 2015, Sec. V C): the smallest
centred window whose value stays within the tolerance of the whole image's for every
larger window. Window sums come from summed-volume tables built slab by slab
(:mod:`.slabs`), eight look-ups per window. Interface area is counted from voxel faces
between unlike phases times 2/3 (face counting overestimates an isotropic surface by
3/2). Details: docs/imaging.md, "imaging.morphology.rev".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from imaging.morphology import _kernels
from imaging.morphology.slabs import slab, slab_size, slabs_in_order
from shared.errors import InputError

__all__ = [
    "FACE_COUNT_CORRECTION",
    "RevResult",
    "window_sizes",
    "interface_area",
    "rev_analysis",
    "rev_analyses",
    "rev_size",
    "centred_rev_size",
]

FACE_COUNT_CORRECTION = 2.0 / 3.0
_BATCH = 1 << 21  # windows looked up at a time: bounds the temporaries of a slab


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
        raise InputError(f"image edge {max_edge} is smaller than the smallest window {min_edge}")
    sizes = np.unique(np.rint(np.geomspace(min_edge, max_edge, n_sizes)).astype(np.int64))
    return sizes


def _table(values: npt.NDArray) -> npt.NDArray:
    """Summed-volume table of a slab, with a zero first plane, row and column."""
    exact = values.dtype.kind in "biu"
    dtype = (np.int32 if values.size < 2**31 else np.int64) if exact else np.float64
    table = np.zeros(tuple(n + 1 for n in values.shape), dtype=dtype)
    np.cumsum(values, axis=0, dtype=dtype, out=table[1:, 1:, 1:])
    np.cumsum(table[1:, 1:, 1:], axis=1, out=table[1:, 1:, 1:])
    np.cumsum(table[1:, 1:, 1:], axis=2, out=table[1:, 1:, 1:])
    return table


class WindowSums:
    """Sums of a field, pore-voxel counts and unlike-neighbour faces over box windows,
    accumulated slab by slab along z.

    A slab ``[z0, z1)`` contributes, for every window that overlaps it, the sums over the
    window's part inside the slab, from the slab's own summed-volume tables; a window's
    face between slices ``k`` and ``k + 1`` belongs to the slab holding ``k`` (the slab is
    given the next slice for those faces). Integer sums are exact whatever the slabs;
    field sums agree with a single slab to rounding.
    """

    def __init__(self, starts: npt.NDArray[np.integer], edges: npt.NDArray[np.integer]) -> None:
        self.starts, self.edges = starts.astype(np.int32), edges.astype(np.int32)
        self.order = np.argsort(starts[:, 0], kind="stable")
        self.sorted_z0 = starts[self.order, 0]
        n = starts.shape[0]
        self.field = np.zeros(n)
        self.pore = np.zeros(n, dtype=np.int64)
        self.faces = np.zeros(n, dtype=np.int64)

    def partial(self, z0: int, field: npt.NDArray, pore: npt.NDArray[np.bool_] | None
                ) -> tuple[npt.NDArray[np.int64], npt.NDArray, npt.NDArray | None, npt.NDArray | None]:
        """The contribution of the slab starting at slice ``z0``: ``field`` of its ``c``
        slices and the binary ``pore`` of the same slices plus the next one if any.

        Returns the indices of the windows it overlaps and their field sums, pore counts
        and face counts there (None without ``pore``).
        """
        c = field.shape[0]
        candidates = self.order[: np.searchsorted(self.sorted_z0, z0 + c)]
        chosen = candidates[self.starts[candidates, 0] + self.edges[candidates, 0] > z0]
        tables = {"field": _table(field)}
        if pore is not None:
            inside = pore[:c]
            across = np.diff(pore.view(np.uint8), axis=0) != 0  # plane j: slices j | j + 1
            if across.shape[0] < c:
                across = np.concatenate([across, np.zeros((1,) + across.shape[1:], bool)])
            tables.update(pore=_table(inside), z=_table(across),
                          y=_table(np.diff(inside.view(np.uint8), axis=1) != 0),
                          x=_table(np.diff(inside.view(np.uint8), axis=2) != 0))
        sums = {"field": np.zeros(chosen.size),
                **{name: np.zeros(chosen.size, np.int64) for name in ("pore", "faces")}}
        for first in range(0, chosen.size, _BATCH):
            part = chosen[first:first + _BATCH]
            out = slice(first, first + part.size)
            low = self.starts[part].astype(np.int64)
            high = low + self.edges[part]
            end = high[:, 0].copy()
            low[:, 0] = np.clip(low[:, 0] - z0, 0, c)
            high[:, 0] = np.clip(high[:, 0] - z0, 0, c)
            _kernels.add_box_sums(tables["field"], low, high, sums["field"][out])
            if pore is None:
                continue
            _kernels.add_box_sums(tables["pore"], low, high, sums["pore"][out])
            for axis, name in ((1, "y"), (2, "x")):  # faces within a slice's rectangle
                inner = high.copy()
                inner[:, axis] -= 1
                _kernels.add_box_sums(tables[name], low, inner, sums["faces"][out])
            inner = high.copy()  # faces k | k + 1 with both slices in the window
            inner[:, 0] = np.maximum(np.clip(end - 1 - z0, 0, c), low[:, 0])
            _kernels.add_box_sums(tables["z"], low, inner, sums["faces"][out])
        if pore is None:
            return chosen, sums["field"], None, None
        return chosen, sums["field"], sums["pore"], sums["faces"]

    def add(self, part: tuple) -> None:
        """Add a slab's :meth:`partial` contribution."""
        chosen, field_sums, counts, faces = part
        self.field[chosen] += field_sums
        if counts is not None:
            self.pore[chosen] += counts
            self.faces[chosen] += faces


def window_sums(
    field: Any,
    pore: Any | None,
    starts: npt.NDArray[np.integer],
    edges: npt.NDArray[np.integer],
    chunk_slices: int | None = None,
    workers: int = 1,
) -> WindowSums:
    """Window sums of ``field`` (and of the binary ``pore`` image: pore voxels, faces)
    over the boxes ``[starts, starts + edges)``, slab by slab.

    Parameters
    ----------
    field, pore
        ``(z, y, x)`` numpy or dask arrays; a dask array is computed one slab at a time
        (the pair together, so a common source is read once).
    starts, edges
        ``(n, 3)`` window corners and edges [voxel].
    chunk_slices
        Slices per slab; the dask array's first chunk, or the whole image, when None.
    workers
        Slabs computed at a time (threads); results are added in slab order, so the sums
        do not depend on it.
    """
    nz = field.shape[0]
    step = slab_size(field, chunk_slices)
    sums = WindowSums(starts, edges)

    def contribution(z0: int) -> tuple:
        z1 = min(z0 + step, nz)
        if pore is None:
            return sums.partial(z0, slab(field, z0, z1), None)
        if hasattr(field, "compute") or hasattr(pore, "compute"):
            import dask

            values, binary = dask.compute(field[z0:z1], pore[z0:min(z1 + 1, nz)])
            return sums.partial(z0, np.asarray(values), np.asarray(binary))
        return sums.partial(z0, slab(field, z0, z1), slab(pore, z0, min(z1 + 1, nz)))

    for part in slabs_in_order(contribution, range(0, nz, step), workers):
        sums.add(part)
    return sums


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


def rev_analysis(porosity: Any, voxel_size: float, rng: np.random.Generator, **settings: Any
                 ) -> RevResult:
    """REV analysis of a porosity field and, optionally, of a binary pore image (its
    interface density): :func:`rev_analyses`' first result."""
    return rev_analyses(porosity, voxel_size, rng, **settings)[0]


def rev_analyses(
    porosity: Any,
    voxel_size: float,
    rng: np.random.Generator,
    *,
    binary: Any | None = None,
    n_sizes: int = 12,
    n_positions: int = 2**20,
    tolerance: float = 0.01,
    min_edge: int = 2,
    max_window_fraction: float = 0.5,
    n_centred_sizes: int = 32,
    chunk_slices: int | None = None,
    workers: int = 1,
) -> tuple[RevResult, RevResult | None]:
    """REV analyses of a porosity field and, optionally, of a binary pore image, in one
    pass over the image with the same windows.

    Parameters
    ----------
    porosity
        Voxel porosity ``(z, y, x)`` [-], numpy or dask; a binary pore image (pore = 1)
        works as well.
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
    chunk_slices, workers
        Slabs along z and how many are computed at a time (:func:`window_sums`); the
        window positions, and so the result, do not depend on them.

    Returns
    -------
    field, binary : RevResult
        The field's porosity statistics, and the binary image's (its pore fraction as the
        porosity; None without ``binary``), both with the binary image's interface.
    """
    shape = tuple(int(n) for n in porosity.shape)
    if len(shape) != 3:
        raise ValueError(f"REV analysis needs a 3-D image, got shape {shape}")
    if binary is not None and tuple(binary.shape) != shape:
        raise ValueError(f"binary image {tuple(binary.shape)} and porosity {shape} differ")
    whole = np.array(shape, dtype=np.int64)
    sizes = window_sizes(int(max_window_fraction * min(shape)), n_sizes, min_edge)
    sizes_c = window_sizes(int(min(shape)), n_centred_sizes, min_edge)
    random_starts = [_window_starts(whole - width + 1, n_positions, rng).astype(np.int32)
                     for width in sizes]
    counts = [len(b) for b in random_starts]
    starts = np.concatenate(random_starts + [((whole - w) // 2).reshape(1, 3) for w in sizes_c]
                            + [np.zeros((1, 3), np.int64)]).astype(np.int32)
    del random_starts
    edges = np.concatenate([np.full((n, 3), w, np.int32) for n, w in zip(counts, sizes, strict=True)]
                           + [np.full((1, 3), w, np.int32) for w in sizes_c]
                           + [whole[None].astype(np.int32)])
    sums = window_sums(porosity, binary, starts, edges, chunk_slices, workers)
    if not np.isfinite(sums.field).all():
        raise InputError("REV analysis needs a finite porosity field (crop away NaN first)")
    volume = np.prod(edges.astype(np.float64), axis=1)
    if binary is None:
        interface = np.full(starts.shape[0], np.nan)
    else:
        interface = FACE_COUNT_CORRECTION * sums.faces / (volume * voxel_size)
    parts = np.cumsum([0] + counts)
    layout = (parts, sizes, sizes_c, voxel_size, tolerance, bool(np.all(whole == sizes_c[-1])))
    field_result = _result(sums.field / volume, interface, *layout)
    if binary is None:
        return field_result, None
    return field_result, _result(sums.pore / volume, interface, *layout)


def _result(porosity: npt.NDArray, interface: npt.NDArray, parts: npt.NDArray,
            sizes: npt.NDArray[np.int64], sizes_c: npt.NDArray[np.int64], voxel_size: float,
            tolerance: float, is_whole: bool) -> RevResult:
    """The statistics and REV edges of per-window values laid out as :func:`rev_analyses`
    queries them: the random windows edge by edge, the centred ones, the whole image."""
    stats = np.full((4, sizes.size), np.nan)
    for index in range(sizes.size):
        part = slice(parts[index], parts[index + 1])
        stats[:, index] = (porosity[part].mean(), porosity[part].std(),
                           interface[part].mean(), interface[part].std())
    centred = np.stack([porosity[parts[-1]:-1], interface[parts[-1]:-1]])
    porosity_total, interface_total = float(porosity[-1]), float(interface[-1])
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
