"""Chord-length distributions of the pore and solid phases (Ferrage et al. 2015, Eqs. 12-16).

A chord is a run of voxels of one phase along a lattice direction, bounded at both ends by
the other phase. Runs cut by the image border have unknown length and are left out by
default. ``f(r)`` is the number distribution of chord lengths (Eq. 12), the mean chord
length is its first moment (Eqs. 13-14), and ``R = l_z / l_xy`` (Eqs. 15-16), with
``l_xy`` the mean of the x and y mean chord lengths.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from imaging.morphology import _kernels

__all__ = ["ChordResult", "chord_lengths"]

_AXES = {"z": 0, "y": 1, "x": 2}


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


def _axis_histograms(
    binary: npt.NDArray[np.uint8], axis: int, include_edges: bool
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    lines = np.ascontiguousarray(np.moveaxis(binary, axis, -1)).reshape(-1, binary.shape[axis])
    return _kernels.line_run_histograms(lines, include_edges, 64)


def _density(counts: npt.NDArray[np.int64], voxel_size: float) -> npt.NDArray[np.float64]:
    total = counts.sum(axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, counts / (total * voxel_size), np.nan)


def _means(counts: npt.NDArray[np.int64], length: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    total = counts.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, (counts * length).sum(axis=-1) / total, np.nan)


def chord_lengths(
    binary: npt.NDArray[np.bool_], voxel_size: float, include_edges: bool = False
) -> ChordResult:
    """Chord-length distributions of a binary image along x, y and z.

    Parameters
    ----------
    binary
        Image ``(z, y, x)``, True (or 1) for pore, False (0) for solid.
    voxel_size
        Voxel edge [m].
    include_edges
        Count chords cut by the image border (their length is then a lower bound).

    Returns
    -------
    ChordResult
    """
    if binary.ndim != 3:
        raise ValueError(f"chord analysis needs a 3-D image, got shape {binary.shape}")
    if voxel_size <= 0:
        raise ValueError(f"voxel size must be > 0, got {voxel_size}")
    image = np.ascontiguousarray(binary, dtype=np.uint8)
    n_length = max(binary.shape)
    length = np.arange(1, n_length + 1, dtype=np.float64) * voxel_size
    pore = np.zeros((3, n_length), dtype=np.int64)
    solid = np.zeros((3, n_length), dtype=np.int64)
    for row, name in enumerate(("x", "y", "z")):
        ones, zeros = _axis_histograms(image, _AXES[name], include_edges)
        pore[row, : ones.size - 1] = ones[1:]
        solid[row, : zeros.size - 1] = zeros[1:]
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
