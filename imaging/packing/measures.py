"""All the measures of a deposited bed, gathered in one record (Ferrage et al. 2015, Table IV)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from imaging.packing import analysis
from imaging.packing.deposition import Packing
from imaging.packing.voxels import VoxelImage, overlap_fraction, voxelize
from shared.errors import ConfigError

__all__ = ["PackingMeasures", "measure_packing"]


@dataclass(frozen=True)
class PackingMeasures:
    """Profiles, order parameters, surfaces and voxel overlap of a bed.

    Scalars other than the profiles are computed on the particles of the linear zone
    z_min < r_z <= z_max. Angles in radians, surfaces in m^2 g^-1, lengths in m.
    """

    edges: npt.NDArray[np.float64]
    porosity_profile: npt.NDArray[np.float64]
    order_profile: npt.NDArray[np.float64]
    z_min: float
    z_max: float
    in_zone: npt.NDArray[np.bool_]
    porosity: float
    S: float
    eta: float
    beta: float
    S_part: float
    S_vol: float
    theta: npt.NDArray[np.float64]
    orientation_distribution: npt.NDArray[np.float64]
    rocking_curve: npt.NDArray[np.float64]
    A_B: float
    A_L: float
    A_T: float
    A_Bcont: float
    image: VoxelImage
    overlap_fraction: float


def measure_packing(
    packing: Packing,
    *,
    profile_bin_width: float,
    contact_grid: float,
    voxel_resolution: int,
    rocking_curve_bins: int,
    density: float = analysis.HYDRATED_VERMICULITE_DENSITY,
    z_min: float | None = None,
    z_max: float | None = None,
    zone_tolerance: float | None = None,
) -> PackingMeasures:
    """Measure a bed.

    Parameters
    ----------
    packing : Packing
    profile_bin_width : float
        Slice thickness dz of the profiles [m].
    contact_grid : float
        delta_m of Eq. 11 [m].
    voxel_resolution : int
        Voxels across the box; the image covers z_min to min(z_min + w, z_max).
    rocking_curve_bins : int
        Bins of theta on [0, pi/2].
    density : float
        Particle density [kg m^-3].
    z_min, z_max : float, optional
        Linear-zone bounds [m]; detected by :func:`analysis.linear_zone` when None.
    zone_tolerance : float, optional
        Porosity band of the detection [1].

    Returns
    -------
    PackingMeasures

    Raises
    ------
    ValueError
        If no barycentre lies in the zone.
    """
    z = packing.centers[:, 2]
    vol = packing.volumes
    normals = packing.normals
    w = packing.box_width
    edges = analysis.profile_edges(float(z.max()), profile_bin_width)
    profile = analysis.porosity_profile(z, vol, w, edges)
    auto_min, auto_max = analysis.linear_zone(edges, profile, zone_tolerance)
    low = auto_min if z_min is None else z_min
    high = auto_max if z_max is None else z_max
    zone = (z > low) & (z <= high)
    if not zone.any():
        raise ConfigError(f"z_min_m, z_max_m: no particle barycentre in ({low:.3g}, {high:.3g}] m")
    order = analysis.order_parameters(analysis.order_tensor(normals[zone]))
    theta, f_v, i_c = analysis.rocking_curve(packing.euler[zone, 1], vol[zone], rocking_curve_bins)
    a_b, a_l, a_t = analysis.surface_areas(packing.semi_axes[zone], density)
    image = voxelize(packing.centers, packing.rotations, packing.semi_axes, w, voxel_resolution,
                     (low, min(low + w, high)))
    return PackingMeasures(
        edges=edges,
        porosity_profile=profile,
        order_profile=analysis.order_profile(z, normals, edges),
        z_min=low,
        z_max=high,
        in_zone=zone,
        porosity=analysis.zone_porosity(z, vol, w, low, high),
        S=order.S,
        eta=order.eta,
        beta=order.beta,
        S_part=analysis.legendre_order(normals[zone]),
        S_vol=analysis.legendre_order(normals[zone], vol[zone]),
        theta=theta,
        orientation_distribution=f_v,
        rocking_curve=i_c,
        A_B=a_b,
        A_L=a_l,
        A_T=a_t,
        A_Bcont=analysis.basal_contact_area(
            packing.centers, packing.rotations, packing.semi_axes, w, packing.contact_distance,
            zone, contact_grid, density),
        image=image,
        overlap_fraction=overlap_fraction(image.counts),
    )
