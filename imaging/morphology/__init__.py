"""Morphology of a 3-D image: REV, solid-pore interface density and chord lengths.

Pure functions on arrays (summed-volume tables for the windows, numba kernels in
:mod:`._kernels` for the chords), shared by the CT stage (the binary and calibrated voxels
of a scan) and the packing stage (voxel image of a bed).
"""

from imaging.morphology.chords import ChordResult, chord_lengths
from imaging.morphology.rev import (
    FACE_COUNT_CORRECTION,
    RevResult,
    centred_rev_size,
    interface_area,
    rev_analyses,
    rev_analysis,
    rev_size,
    window_sizes,
)

__all__ = [
    "FACE_COUNT_CORRECTION",
    "ChordResult",
    "RevResult",
    "centred_rev_size",
    "chord_lengths",
    "interface_area",
    "rev_analyses",
    "rev_analysis",
    "rev_size",
    "window_sizes",
]
