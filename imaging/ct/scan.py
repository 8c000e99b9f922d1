"""Passes over a chunked greyscale scan, slab by slab along z.

A scan is a dask array of whole-slice slabs (:func:`imaging.ct.io.open_volume`); each
pass reads it once, ``workers`` slabs at a time, and keeps only small results per slab
(sums, histograms, a sample), so memory is set by the slab size (``imaging.chunk_mb``),
not by the scan. The passes are: a summary (extremes, the strided sample that the
threshold and the histogram peaks read, a strided preview), the threshold mask's slice
areas, the grey histograms outside and inside the specimen (calibration anchors) and
the block sums of the porosity grid. The specimen mask itself is never held whole: a
:class:`MaskRule` remakes it for any slab.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import dask.array as da
import numpy as np
import numpy.typing as npt

from imaging.ct.calibration import Calibration
from imaging.ct.grid import block_sums
from imaging.ct.mask import border_counts, sample_stride, slice_masks
from imaging.ct.settings import ScanResources, setting_keys
from imaging.morphology.slabs import slab as read_slab
from imaging.morphology.slabs import slabs_in_order
from shared.errors import InputError
from shared.progress import Progress

__all__ = [
    "ScanSummary",
    "MaskRule",
    "each_slab",
    "summarize",
    "threshold_areas",
    "anchor_histograms",
    "grid_sums",
    "mask_array",
    "estimated_peak_bytes",
    "check_memory",
]

log = logging.getLogger("imaging.ct")

PREVIEW_VOXELS = 256
"""Largest side of the strided preview stored instead of the scan."""


def each_slab(grey: Any, function: Callable[[int, np.ndarray], Any], label: str,
              workers: int) -> Iterator[Any]:
    """``function(z0, slab)`` over the scan's chunks along z, in order, with a progress
    line (done slices, ETA) at most every 10 s."""
    bounds = np.cumsum((0,) + tuple(grey.chunks[0]))
    ends = dict(zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True))
    progress = Progress(int(grey.shape[0]), label, log)

    def read(z0: int) -> Any:
        return function(z0, read_slab(grey, z0, ends[z0]))

    for z0, result in zip(ends, slabs_in_order(read, ends, workers), strict=False):
        progress.update(ends[z0])
        yield result
    progress.update(int(grey.shape[0]), force=True)


@dataclass(frozen=True)
class ScanSummary:
    """What one pass learns of a scan.

    Attributes
    ----------
    minimum, maximum : int
        Extreme greys.
    sample : ndarray
        The strided sample of :func:`imaging.ct.mask.grey_sample`.
    preview : ndarray
        ``grey[::step, ::step, ::step]``.
    preview_step : int
        Its stride [voxel].
    """

    minimum: int
    maximum: int
    sample: npt.NDArray
    preview: npt.NDArray
    preview_step: int


def summarize(grey: Any, workers: int = 1) -> ScanSummary:
    """Extremes, strided sample and strided preview of a scan in one pass."""
    stride = sample_stride(int(grey.size))
    step = max(1, int(np.ceil(max(grey.shape) / PREVIEW_VOXELS)))

    def visit(z0: int, slab: np.ndarray) -> tuple:
        # copies: a strided view would keep its whole slab alive
        return (slab.min(), slab.max(), slab[(-z0) % stride::stride, ::stride, ::stride].copy(),
                slab[(-z0) % step::step, ::step, ::step].copy())

    parts = list(each_slab(grey, visit, "scan summary", workers))
    return ScanSummary(
        minimum=int(min(p[0] for p in parts)),
        maximum=int(max(p[1] for p in parts)),
        sample=np.concatenate([p[2] for p in parts]).reshape(-1),
        preview=np.concatenate([p[3] for p in parts]),
        preview_step=step,
    )


@dataclass(frozen=True)
class MaskRule:
    """How the specimen mask of any slab is made.

    Attributes
    ----------
    mode : str
        ``threshold``, ``full`` or ``cylinder``.
    kept : ndarray of bool
        Per slice, whether it holds specimen (threshold: its section is large enough;
        cylinder: it lies in the cylinder's z range).
    level : float
        Threshold mode's grey level.
    disc : ndarray of bool or None
        Cylinder mode's ``(y, x)`` section.
    """

    mode: str
    kept: npt.NDArray[np.bool_]
    level: float = float("nan")
    disc: npt.NDArray[np.bool_] | None = None

    def slab(self, z0: int, grey: np.ndarray) -> npt.NDArray[np.bool_]:
        """The specimen mask of the slab of ``grey`` starting at slice ``z0``."""
        kept = self.kept[z0:z0 + grey.shape[0]]
        if self.mode == "threshold":
            mask = slice_masks(grey, self.level).view(bool)
        elif self.mode == "cylinder":
            assert self.disc is not None  # a cylinder's mask has its disc
            mask = np.broadcast_to(self.disc, grey.shape).copy()
        else:
            mask = np.ones(grey.shape, dtype=bool)
        mask[~kept] = False
        return mask


def threshold_areas(grey: Any, level: float, workers: int = 1
                    ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], int]:
    """Per slice, the area of the threshold mask and its voxels on the field's border,
    and the border's size (:func:`imaging.ct.mask.border_counts`)."""

    def visit(z0: int, slab: np.ndarray) -> tuple:
        mask = slice_masks(slab, level)
        return mask.sum(axis=(1, 2), dtype=np.int64), border_counts(mask)

    parts = list(each_slab(grey, visit, "specimen mask", workers))
    return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1][0] for p in parts]),
            parts[0][1][1])


def anchor_histograms(grey: Any, rule: MaskRule, workers: int = 1
                      ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """Grey histograms (one bin per grey value) outside and inside the specimen."""
    size = 1 << (8 * grey.dtype.itemsize)

    def visit(z0: int, slab: np.ndarray) -> tuple:
        mask = rule.slab(z0, slab)
        return (np.bincount(slab[~mask], minlength=size),
                np.bincount(slab[mask], minlength=size))

    outside = np.zeros(size, dtype=np.int64)
    inside = np.zeros(size, dtype=np.int64)
    for out, inn in each_slab(grey, visit, "calibration histograms", workers):
        outside += out
        inside += inn
    return outside, inside


def grid_sums(grey: Any, rule: MaskRule, calibration: Calibration, block: int,
              workers: int = 1) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Block sums of calibrated density and specimen counts over the whole scan
    (:func:`imaging.ct.grid.block_sums`, added up row by row across slabs)."""
    nz, ny, nx = grey.shape
    shape = (-(-nz // block), -(-ny // block), -(-nx // block))
    density_sum, counts = np.zeros(shape), np.zeros(shape)

    def visit(z0: int, slab: np.ndarray) -> tuple:
        return block_sums(slab, rule.slab(z0, slab), calibration, block, z0)

    for first, density, count in each_slab(grey, visit, "porosity grid", workers):
        density_sum[first:first + density.shape[0]] += density
        counts[first:first + count.shape[0]] += count
    return density_sum, counts


def mask_array(grey: Any, rule: MaskRule) -> Any:
    """The specimen mask as a lazy uint8 dask array chunked like the scan."""

    def make(slab: np.ndarray, block_info: dict | None = None) -> np.ndarray:
        z0 = block_info[0]["array-location"][0][0] if block_info else 0
        return rule.slab(z0, slab).astype(np.uint8)

    return da.map_blocks(make, grey, dtype=np.uint8)


BYTES_PER_SLAB_VOXEL = 40
"""Peak bytes per voxel of a slab in flight: the greys, the calibrated field and pore
image, and the summed-volume tables of the REV windows (the largest pass)."""
BYTES_PER_WINDOW = 96
"""Bytes per REV window: corners, edges, sums and the look-ups of a slab's share."""
BASE_BYTES = 400 << 20
"""Interpreter, libraries and small arrays."""


def estimated_peak_bytes(shape: tuple[int, ...], chunk_slices: int, workers: int,
                         n_windows: int) -> int:
    """Estimated peak memory [bytes] of the imaging stage on a scan of ``shape`` read in
    slabs of ``chunk_slices`` slices, ``workers`` at a time (plus one waiting each), with
    ``n_windows`` REV windows."""
    slab_voxels = int(chunk_slices) * int(np.prod(shape[1:]))
    return int(BASE_BYTES + 2 * max(1, workers) * BYTES_PER_SLAB_VOXEL * slab_voxels
               + BYTES_PER_WINDOW * n_windows)


def check_memory(sample: str, source: str | Path, grey: Any, resources: ScanResources,
                 n_windows: int = 0) -> None:
    """Refuse, before reading the scan, a job whose estimated peak (slabs in flight and
    ``n_windows`` REV windows) exceeds the resources' memory limit.

    Raises
    ------
    InputError
        Naming ``source`` and the settings that lower the peak.
    """
    peak = estimated_peak_bytes(grey.shape, int(grey.chunks[0][0]), resources.workers, n_windows)
    limit = resources.memory_limit_bytes()
    log.info("%s: %s voxels of %s in slabs of %d slices, estimated peak %.2f GiB (limit %.1f GiB)",
             sample, "x".join(map(str, grey.shape)), grey.dtype, grey.chunks[0][0],
             peak / 2**30, limit / 2**30)
    if peak > limit:
        raise InputError(
            f"{source}: the imaging of this {'x'.join(map(str, grey.shape))} scan would need about "
            f"{peak / 2**30:.1f} GiB, more than the {limit / 2**30:.1f} GiB allowed: lower "
            f"{setting_keys(sample, 'chunk_mb')} ({resources.chunk_mb:g}), "
            f"{setting_keys(sample, 'workers')} ({resources.workers})"
            + (" or rev.n_positions" if n_windows else "") + ", or raise imaging.memory_limit_gb"
        )
