"""Virtual clay porous media by 3D sequential deposition of flat elliptic disks.

Reference implementation of Ferrage et al., Phys. Rev. E 91, 062210 (2015):
:mod:`.population` (particle sizes and shapes, Table I), :mod:`.deposition` (the
sequential deposition, Sec. II), :mod:`.analysis`, :mod:`.voxels` and :mod:`.measures`
(porosity and order profiles, Q tensor, rocking curve, surface areas, voxel image,
overlap fraction; Secs. III-V). The stage's modules (:mod:`.config`, :mod:`.dataset`, :mod:`.run`,
:mod:`.figures`) are not imported here, to keep xarray and matplotlib out of the
numerical API: ``from imaging.packing.run import run``.

The names below are imported from their submodule on first use (PEP 562), so that
importing a light submodule (:mod:`.config` for the workflow's checks) does not compile
the numba kernels; each numerical submodule's ``__all__`` is exported whole. The modules
in full: docs/packing.md, "imaging.packing".

The ``if TYPE_CHECKING:`` block is the one list of names: type checkers and IDEs read it,
and ``shared.lazy.lazy_package`` reads it from this file to build ``__all__`` and the lazy map.
"""

# the block's names are this package's exports, not unused imports (ruff reads no derived __all__)
# ruff: noqa: F401

from __future__ import annotations

from typing import TYPE_CHECKING

from shared.lazy import lazy_package

if TYPE_CHECKING:
    from imaging.packing.analysis import (
        HYDRATED_VERMICULITE_DENSITY,
        OrderParameters,
        basal_contact_area,
        legendre_order,
        linear_zone,
        order_parameters,
        order_profile,
        order_tensor,
        porosity_profile,
        profile_edges,
        rocking_curve,
        surface_areas,
        zone_porosity,
    )
    from imaging.packing.deposition import DepositionParameters, Packing, deposit
    from imaging.packing.measures import PackingMeasures, measure_packing
    from imaging.packing.orientation import euler_angles, fold_upward, normals, rotation_matrices
    from imaging.packing.population import Population, equivalent_diameter, sample_semi_axes, volumes
    from imaging.packing.voxels import VoxelImage, overlap_fraction, voxel_counts, voxelize

__all__, __getattr__ = lazy_package(globals())
