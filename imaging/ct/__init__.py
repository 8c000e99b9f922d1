"""The CT stage: greyscale scan -> specimen mask -> calibrated density -> porosity grid.

Readers of greyscale volumes (:mod:`.io`), the specimen mask, the grey -> density ->
porosity calibration, block averaging onto the porosity grid, and a synthetic pellet
phantom so that the chain runs without data. The stage's computations on arrays
(:func:`.porosity.porosity_grid`, :func:`.rev.scan_rev`, docs/api.md), its entry points
(:mod:`.run`), datasets and figures are not imported here, to keep xarray, matplotlib and
the netCDF writer out of the import of the numerical API:
``from imaging.ct.porosity import porosity_grid``, ``from imaging.ct import run``.
"""

from imaging.ct.calibration import Calibration, density_to_porosity, grey_anchors, grey_to_density
from imaging.ct.grid import BlockGrid, block_average, block_size_voxels
from imaging.ct.io import ImageError, read_volume, write_slice_folder, write_tiff_stack
from imaging.ct.mask import inscribed_box, specimen_mask
from imaging.ct.phantom import PhantomSpec, pellet_phantom

__all__ = [
    "BlockGrid",
    "Calibration",
    "ImageError",
    "PhantomSpec",
    "block_average",
    "block_size_voxels",
    "density_to_porosity",
    "grey_anchors",
    "grey_to_density",
    "inscribed_box",
    "pellet_phantom",
    "read_volume",
    "specimen_mask",
    "write_slice_folder",
    "write_tiff_stack",
]
