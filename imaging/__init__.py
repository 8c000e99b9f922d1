"""claychain imaging: images of clay media and their morphology.

Three sibling subpackages, imported on their own (this package imports none of them):

- :mod:`imaging.ct`: CT greyscale scan -> specimen mask -> calibrated density -> porosity
  grid, and the synthetic pellet phantom (the CT stage);
- :mod:`imaging.packing`: virtual clay media by sequential deposition of elliptic disks
  (the packing stage);
- :mod:`imaging.morphology`: REV, interface density and chord lengths of a 3-D image,
  used by both.
"""
