"""claychain imaging: CT greyscale -> calibrated density -> porosity grid; REV and chord lengths.

The sequential-deposition generator of virtual clay media lives in ``imaging.deposition``.
"""

from imaging.calibration import Calibration, density_to_porosity, grey_anchors, grey_to_density
from imaging.chords import ChordResult, chord_lengths
from imaging.grid import BlockGrid, block_average, block_size_voxels
from imaging.io import ImageError, read_volume, write_slice_folder, write_tiff_stack
from imaging.mask import inscribed_box, specimen_mask
from imaging.phantom import PhantomSpec, pellet_phantom
from imaging.rev import RevResult, interface_area, rev_analysis

__all__ = [
    "BlockGrid",
    "Calibration",
    "ChordResult",
    "ImageError",
    "PhantomSpec",
    "RevResult",
    "block_average",
    "block_size_voxels",
    "chord_lengths",
    "density_to_porosity",
    "grey_anchors",
    "grey_to_density",
    "inscribed_box",
    "interface_area",
    "pellet_phantom",
    "read_volume",
    "rev_analysis",
    "specimen_mask",
    "write_slice_folder",
    "write_tiff_stack",
]
