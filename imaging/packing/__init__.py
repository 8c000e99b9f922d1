"""Virtual clay porous media by 3D sequential deposition of flat elliptic disks.

Reference implementation of Ferrage et al., Phys. Rev. E 91, 062210 (2015):
:mod:`.population` (particle sizes and shapes, Table I), :mod:`.deposition` (the
sequential deposition, Sec. II), :mod:`.analysis`, :mod:`.voxels` and :mod:`.measures`
(porosity and order profiles, Q tensor, rocking curve, surface areas, voxel image,
overlap fraction; Secs. III-V). The stage's modules (:mod:`.config`, :mod:`.run`,
:mod:`.figures`) are not imported here, to keep xarray and matplotlib out of the
numerical API: ``from imaging.packing.run import run``.

The names below are imported from their submodule on first use (PEP 562), so that
importing a light submodule (:mod:`.config` for the workflow's checks) does not compile
the numba kernels. The modules in full: docs/packing.md, "imaging.packing".
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from shared.lazy import lazy_getattr

if TYPE_CHECKING:
    from imaging.packing.analysis import (
        OrderParameters,
        basal_contact_area,
        legendre_order,
        linear_zone,
        order_parameters,
        order_profile,
        order_tensor,
        porosity_profile,
        rocking_curve,
        surface_areas,
        zone_porosity,
    )
    from imaging.packing.deposition import DepositionParameters, Packing, deposit
    from imaging.packing.measures import PackingMeasures, measure_packing
    from imaging.packing.orientation import euler_angles, normals, rotation_matrices
    from imaging.packing.population import Population, equivalent_diameter, sample_semi_axes, volumes
    from imaging.packing.voxels import VoxelImage, overlap_fraction, voxel_counts, voxelize

__all__ = [
    "DepositionParameters",
    "OrderParameters",
    "Packing",
    "PackingMeasures",
    "Population",
    "VoxelImage",
    "basal_contact_area",
    "deposit",
    "equivalent_diameter",
    "euler_angles",
    "legendre_order",
    "linear_zone",
    "measure_packing",
    "normals",
    "order_parameters",
    "order_profile",
    "order_tensor",
    "overlap_fraction",
    "porosity_profile",
    "rocking_curve",
    "rotation_matrices",
    "sample_semi_axes",
    "surface_areas",
    "voxel_counts",
    "voxelize",
    "volumes",
    "zone_porosity",
]

# public name -> its submodule
_EXPORTS = {
    "OrderParameters": "analysis",
    "basal_contact_area": "analysis",
    "legendre_order": "analysis",
    "linear_zone": "analysis",
    "order_parameters": "analysis",
    "order_profile": "analysis",
    "order_tensor": "analysis",
    "porosity_profile": "analysis",
    "rocking_curve": "analysis",
    "surface_areas": "analysis",
    "zone_porosity": "analysis",
    "DepositionParameters": "deposition",
    "Packing": "deposition",
    "deposit": "deposition",
    "PackingMeasures": "measures",
    "measure_packing": "measures",
    "euler_angles": "orientation",
    "normals": "orientation",
    "rotation_matrices": "orientation",
    "Population": "population",
    "equivalent_diameter": "population",
    "sample_semi_axes": "population",
    "volumes": "population",
    "VoxelImage": "voxels",
    "overlap_fraction": "voxels",
    "voxel_counts": "voxels",
    "voxelize": "voxels",
}


__getattr__ = lazy_getattr(__name__, _EXPORTS, globals())
