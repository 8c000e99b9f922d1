"""Chord-length distributions of the pore and solid phases (Ferrage et al. 2015, Eqs. 12-16).

A chord is a run of voxels of one phase along a lattice direction, bounded at both ends by
the other phase. Runs cut by the image border have unknown length and are left out by
default. ``f(r)`` is the number distribution of chord lengths (Eq. 12), the mean chord
length is its first moment (Eqs. 13-14), and ``R = l_z / l_xy`` (Eqs. 15-16), with
``l_xy`` the mean of the x and y mean chord lengths.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from imaging.morphology import _kernels
from imaging.morphology.slabs import slab, slab_size, slabs_in_order

__all__ = ["ChordResult", "chord_lengths"]

@dataclass(frozen=True)
class ChordResult:
    """Chord-length distributions along z, y and x.

    Attributes
    ----------
    direction : tuple of str
        ``("x", "y", "z")``.
    length : ndarray, shape (n_length,)
        Chord lengths [m] (multiples of the voxel size).
    count_pore, count_solid : ndarray of int64, shape (3, n_length)
        Number of chords of each length per direction.
    f_pore, f_solid : ndarray, shape (3, n_length)
        Probability densities f(r) [1/m], integrating to 1 over r (Eq. 12).
    mean_pore, mean_solid : ndarray, shape (3,)
        Mean chord lengths per direction [m] (Eqs. 13-14).
    R_p, R_s : float
        Anisotropy ratios l_z / l_xy of pore and solid (Eqs. 15-16) [-].
    """

    direction: tuple[str, str, str]
    length: npt.NDArray[np.float64]
    count_pore: npt.NDArray[np.int64]
    count_solid: npt.NDArray[np.int64]
    f_pore: npt.NDArray[np.float64]
    f_solid: npt.NDArray[np.float64]
    mean_pore: npt.NDArray[np.float64]
    mean_solid: npt.NDArray[np.float64]
    R_p: float
    R_s: float


def _line_histograms(
    binary: npt.NDArray[np.uint8], axis: int, include_edges: bool, size: int
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """Run-length histograms (phase 1, phase 0) along ``axis`` (1: y, 2: x) of a slab,
    padded to ``size``."""
    lines = np.ascontiguousarray(np.moveaxis(binary, axis, -1)).reshape(-1, binary.shape[axis])
    ones, zeros = _kernels.line_run_histograms(lines, include_edges, 64)
    out = np.zeros((2, size), dtype=np.int64)
    out[0, : ones.size], out[1, : zeros.size] = ones, zeros
    return out[0], out[1]


def _density(counts: npt.NDArray[np.int64], voxel_size: float) -> npt.NDArray[np.float64]:
    total = counts.sum(axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, counts / (total * voxel_size), np.nan)


def _means(counts: npt.NDArray[np.int64], length: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    total = counts.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, (counts * length).sum(axis=-1) / total, np.nan)


def chord_lengths(
    binary: Any,
    voxel_size: float,
    include_edges: bool = False,
    chunk_slices: int | None = None,
    workers: int = 1,
) -> ChordResult:
    """Chord-length distributions of a binary image along x, y and z.

    The image is read in slabs along z: x and y chords lie within a slab's slices; z
    chords are followed from slab to slab (the run open at a slab's end is carried into
    the next), so a chord crossing several slabs is counted once with its whole length.

    Parameters
    ----------
    binary
        Image ``(z, y, x)``, True (or 1) for pore, False (0) for solid; numpy or dask.
    voxel_size
        Voxel edge [m].
    include_edges
        Count chords cut by the image border (their length is then a lower bound).
    chunk_slices, workers
        Slices per slab (the dask array's chunk, or all, when None) and slabs read at a
        time; the result does not depend on them.

    Returns
    -------
    ChordResult
    """
    shape = tuple(int(n) for n in binary.shape)
    if len(shape) != 3:
        raise ValueError(f"chord analysis needs a 3-D image, got shape {shape}")
    if voxel_size <= 0:
        raise ValueError(f"voxel size must be > 0, got {voxel_size}")
    nz, ny, nx = shape
    n_length = max(shape)
    size = n_length + 1
    counts = np.zeros((2, 3, size), dtype=np.int64)  # (pore, solid) x (x, y, z)
    carry_phase = np.full((ny, nx), -1, dtype=np.int8)
    carry_length = np.zeros((ny, nx), dtype=np.int64)
    carry_bounded = np.zeros((ny, nx), dtype=np.bool_)
    step = slab_size(binary, chunk_slices)

    def in_plane(z0: int) -> tuple[np.ndarray, np.ndarray]:
        part = np.ascontiguousarray(slab(binary, z0, min(z0 + step, nz)), dtype=np.uint8)
        found = np.zeros((2, 2, size), dtype=np.int64)
        for row, axis in ((0, 2), (1, 1)):
            found[0, row], found[1, row] = _line_histograms(part, axis, include_edges, size)
        return part, found

    for part, found in slabs_in_order(in_plane, range(0, nz, step), workers):
        counts[:, :2] += found
        ones, zeros = _kernels.column_runs(part, include_edges, carry_phase, carry_length,
                                           carry_bounded, 64)
        counts[0, 2, : ones.size] += ones
        counts[1, 2, : zeros.size] += zeros
    if include_edges:
        ones, zeros = _kernels.close_runs(carry_phase, carry_length, size)
        counts[0, 2] += ones
        counts[1, 2] += zeros
    length = np.arange(1, n_length + 1, dtype=np.float64) * voxel_size
    pore, solid = counts[0, :, 1:], counts[1, :, 1:]
    mean_pore, mean_solid = _means(pore, length), _means(solid, length)
    return ChordResult(
        direction=("x", "y", "z"),
        length=length,
        count_pore=pore,
        count_solid=solid,
        f_pore=_density(pore, voxel_size),
        f_solid=_density(solid, voxel_size),
        mean_pore=mean_pore,
        mean_solid=mean_solid,
        R_p=float(mean_pore[2] / mean_pore[:2].mean()),
        R_s=float(mean_solid[2] / mean_solid[:2].mean()),
    )
