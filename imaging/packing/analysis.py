"""Analyses of a particle bed (Ferrage et al. 2015, Secs. III.A, III.D and V.B).

Pure functions on arrays: porosity profile and the porosity of its linear part, Q-tensor
order parameters (Eqs. 1-3), the Legendre order parameter per particle or per volume
(Eq. 4) and its profile, the orientation distribution and rocking curve (Eqs. 5-7), the
specific surface areas (Eqs. 8-10) and the basal contact area (Eq. 11).

Profiles are histograms of particle barycentres: slice k holds the particles with
barycentre altitude r_z in [z_k, z_k + dz), as in the paper.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from imaging.packing import _analysis_kernels
from imaging.packing._bed import BedIndex
from imaging.packing.population import volumes

__all__ = [
    "HYDRATED_VERMICULITE_DENSITY",
    "OrderParameters",
    "profile_edges",
    "porosity_profile",
    "linear_zone",
    "zone_porosity",
    "order_tensor",
    "order_parameters",
    "legendre_order",
    "order_profile",
    "rocking_curve",
    "surface_areas",
    "basal_contact_area",
]

HYDRATED_VERMICULITE_DENSITY = 2180.0
"""Mass density of hydrated vermiculite [kg m^-3] (paper, after Eq. 8)."""


class OrderParameters(NamedTuple):
    """Eigen-analysis of the Q tensor (Eqs. 2-3).

    Attributes
    ----------
    S : float
        Scalar order parameter: the largest eigenvalue, in [0, 1] (Eppenga & Frenkel
        1984; for normals gathered around the director it is the S of Eq. 3) [1].
    eta : float
        Biaxiality: half the difference of the two other eigenvalues [1].
    beta : float
        Angle between the director l and the z axis [rad], in [0, pi/2].
    director : ndarray, shape (3,)
        Unit eigenvector l of S.
    """

    S: float
    eta: float
    beta: float
    director: npt.NDArray[np.float64]


def profile_edges(top: float, bin_width: float) -> npt.NDArray[np.float64]:
    """Slice edges 0, dz, 2 dz, ... covering [0, top] [m]."""
    n = max(int(np.ceil(top / bin_width)), 1)
    if n * bin_width <= top:
        n += 1
    return np.arange(n + 1, dtype=np.float64) * bin_width


def porosity_profile(
    altitudes: npt.NDArray[np.float64],
    particle_volumes: npt.NDArray[np.float64],
    box_width: float,
    edges: npt.NDArray[np.float64],
) -> npt.NDArray[np.float64]:
    """Porosity per slice from the volumes of the particles whose barycentre it holds.

    Parameters
    ----------
    altitudes : ndarray, shape (n,)
        Barycentre altitudes r_z [m].
    particle_volumes : ndarray, shape (n,)
        Particle volumes [m^3].
    box_width : float
        Box width w [m].
    edges : ndarray, shape (m + 1,)
        Slice edges [m].

    Returns
    -------
    ndarray, shape (m,)
        1 - (solid volume of the slice) / (w^2 dz) [1]; may be negative in a slice that
        holds the barycentres of many flat particles.
    """
    solid, _ = np.histogram(altitudes, bins=edges, weights=particle_volumes)
    return 1.0 - solid / (box_width**2 * np.diff(edges))


def linear_zone(
    edges: npt.NDArray[np.float64],
    profile: npt.NDArray[np.float64],
    tolerance: float | None = None,
) -> tuple[float, float]:
    """Bounds z_min, z_max of the part of the profile where porosity is steady.

    Starting from the median porosity of the slices in the middle 40 % of the bed, the
    zone grows from the central slice downward and upward while the slice porosity stays
    within ``tolerance`` of that median. It excludes the denser bottom (particles lying on
    the floor) and the unfilled top, as Fig. 3 of the paper does by eye.

    Parameters
    ----------
    edges : ndarray, shape (m + 1,)
        Slice edges [m].
    profile : ndarray, shape (m,)
        Porosity per slice [1].
    tolerance : float, optional
        Allowed deviation [1]; default max(0.05, 2.5 x the standard deviation of the
        central slices).

    Returns
    -------
    tuple of float
        (z_min, z_max) [m]; the whole bed if it has fewer than three slices.
    """
    m = profile.size
    if m < 3:
        return float(edges[0]), float(edges[-1])
    lo, hi = int(0.3 * m), max(int(np.ceil(0.7 * m)), int(0.3 * m) + 1)
    central = profile[lo:hi]
    reference = float(np.median(central))
    if tolerance is None:
        tolerance = max(0.05, 2.5 * float(np.std(central)))
    middle = (lo + hi - 1) // 2
    first = middle
    while first > 0 and abs(profile[first - 1] - reference) <= tolerance:
        first -= 1
    last = middle
    while last < m - 1 and abs(profile[last + 1] - reference) <= tolerance:
        last += 1
    return float(edges[first]), float(edges[last + 1])


def zone_porosity(
    altitudes: npt.NDArray[np.float64],
    particle_volumes: npt.NDArray[np.float64],
    box_width: float,
    z_min: float,
    z_max: float,
) -> float:
    """Porosity of the particles with barycentre in (z_min, z_max] [1].

    Parameters
    ----------
    altitudes, particle_volumes
        Barycentre altitudes [m] and volumes [m^3].
    box_width : float
        w [m].
    z_min, z_max : float
        Zone bounds [m].
    """
    inside = (altitudes > z_min) & (altitudes <= z_max)
    return float(1.0 - particle_volumes[inside].sum() / (box_width**2 * (z_max - z_min)))


def order_tensor(
    normals: npt.NDArray[np.float64], weights: npt.NDArray[np.float64] | None = None
) -> npt.NDArray[np.float64]:
    """Q tensor of unit normals, Q = (3/2) <v v^T> - I/2 (Eq. 1).

    The factor 3/2 makes the eigenvalues (-S/2 + eta, -S/2 - eta, S) of Eq. 3, so that
    S = 1 when all normals are parallel (Eppenga & Frenkel 1984).

    Parameters
    ----------
    normals : ndarray, shape (n, 3)
        Unit normals.
    weights : ndarray, shape (n,), optional
        Weights (e.g. volumes); equal by default.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    w = np.ones(normals.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    mean = np.einsum("n,ni,nj->ij", w, normals, normals) / w.sum()
    return 1.5 * mean - 0.5 * np.eye(3)


def order_parameters(q: npt.NDArray[np.float64]) -> OrderParameters:
    """S, eta, beta and the director of a Q tensor (Eqs. 2-3).

    Parameters
    ----------
    q : ndarray, shape (3, 3)
        Symmetric traceless tensor.

    Returns
    -------
    OrderParameters
    """
    values, vectors = np.linalg.eigh(q)
    others = values[:2]
    director = vectors[:, 2]
    beta = float(np.arccos(min(abs(director[2]), 1.0)))
    eta = float(abs(others[1] - others[0]) / 2.0)
    return OrderParameters(float(values[2]), eta, beta, director)


def legendre_order(
    normals: npt.NDArray[np.float64], weights: npt.NDArray[np.float64] | None = None
) -> float:
    """<(3 cos^2 theta - 1) / 2> over particles, theta the angle of the normal to z (Eq. 4).

    Parameters
    ----------
    normals : ndarray, shape (n, 3)
        Unit normals.
    weights : ndarray, shape (n,), optional
        Weights: none for S_part, volumes for S_vol.

    Returns
    -------
    float
        Order parameter [1]; NaN for an empty set.
    """
    if normals.shape[0] == 0:
        return float("nan")
    p2 = 1.5 * normals[:, 2] ** 2 - 0.5
    return float(np.average(p2, weights=weights))


def order_profile(
    altitudes: npt.NDArray[np.float64],
    normals: npt.NDArray[np.float64],
    edges: npt.NDArray[np.float64],
) -> npt.NDArray[np.float64]:
    """S_part per slice of barycentre altitude [1] (NaN for an empty slice).

    Parameters
    ----------
    altitudes : ndarray, shape (n,)
        Barycentre altitudes [m].
    normals : ndarray, shape (n, 3)
        Unit normals.
    edges : ndarray, shape (m + 1,)
        Slice edges [m].
    """
    p2 = 1.5 * normals[:, 2] ** 2 - 0.5
    total, _ = np.histogram(altitudes, bins=edges, weights=p2)
    count, _ = np.histogram(altitudes, bins=edges)
    out = np.full(count.size, np.nan)
    filled = count > 0
    out[filled] = total[filled] / count[filled]
    return out


def rocking_curve(
    theta: npt.NDArray[np.float64],
    particle_volumes: npt.NDArray[np.float64],
    n_bins: int,
    intensity_scale: float = 1.0,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Volume orientation distribution F_v and calculated rocking curve I_c (Eqs. 5-7).

    Normals are folded to theta in [0, pi/2], so F_v is normalised on that interval,
    and I_c(theta) = A F_v(theta) / (2 pi sin theta) with A = ``intensity_scale``
    (A = 1 gives the integral of I_c 2 pi sin theta over the half-sphere equal to 1).

    Parameters
    ----------
    theta : ndarray, shape (n,)
        Angles of the normals to z [rad].
    particle_volumes : ndarray, shape (n,)
        Volumes [m^3] (weights).
    n_bins : int
        Number of bins on [0, pi/2].
    intensity_scale : float
        A of Eq. 7, the integrated intensity of the experimental curve.

    Returns
    -------
    tuple of ndarray, each shape (n_bins,)
        Bin centres [rad], F_v [rad^-1], I_c [sr^-1 when A = 1].
    """
    edges = np.linspace(0.0, 0.5 * np.pi, n_bins + 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    weight, _ = np.histogram(theta, bins=edges, weights=particle_volumes)
    total = weight.sum()
    f_v = weight / (total * np.diff(edges)) if total > 0 else np.full(n_bins, np.nan)
    return centres, f_v, intensity_scale * f_v / (2.0 * np.pi * np.sin(centres))


def surface_areas(
    semi_axes: npt.NDArray[np.float64], density: float = HYDRATED_VERMICULITE_DENSITY
) -> tuple[float, float, float]:
    """Specific basal, lateral and total surface areas (Eqs. 8-10).

    The lateral area uses the paper's perimeter pi sqrt(2 (l_a^2 + l_b^2)).

    Parameters
    ----------
    semi_axes : ndarray, shape (n, 3)
        (l_a, l_b, h / 2) [m].
    density : float
        Particle mass density [kg m^-3].

    Returns
    -------
    tuple of float
        (A_B, A_L, A_T) [m^2 g^-1].
    """
    la, lb, h = semi_axes[:, 0], semi_axes[:, 1], 2.0 * semi_axes[:, 2]
    mass_g = 1000.0 * density * float(np.sum(volumes(semi_axes)))
    basal = float(np.sum(2.0 * np.pi * la * lb)) / mass_g
    lateral = float(np.sum(h * np.pi * np.sqrt(2.0 * (la**2 + lb**2)))) / mass_g
    return basal, lateral, basal + lateral


def basal_contact_area(
    centers: npt.NDArray[np.float64],
    rotations: npt.NDArray[np.float64],
    semi_axes: npt.NDArray[np.float64],
    box_width: float,
    contact_distance: float,
    selected: npt.NDArray[np.bool_],
    grid_step: float,
    density: float = HYDRATED_VERMICULITE_DENSITY,
) -> float:
    """Specific basal surface in contact, A_Bcont = 2 n_sc delta_m^2 / (rho V) (Eq. 11).

    Parameters
    ----------
    centers, rotations, semi_axes
        The bed: barycentres [m], rotations (upward normals), (l_a, l_b, h/2) [m].
    box_width : float
        w [m].
    contact_distance : float
        d_cont [m]: a square centre closer than this to another basal face is in contact.
    selected : ndarray of bool, shape (n,)
        Particles whose bottom faces are scanned (those of the linear zone); V is their
        total volume.
    grid_step : float
        delta_m, edge of the squares [m].
    density : float
        Particle mass density [kg m^-3].

    Returns
    -------
    float
        A_Bcont [m^2 g^-1].
    """
    bed = BedIndex.of(centers, rotations, semi_axes, box_width, contact_distance)
    count = _analysis_kernels.basal_contact_points(
        np.flatnonzero(selected), grid_step, bed.centers, bed.rotations, bed.axes, bed.extents,
        bed.fine.head, bed.coarse.head, bed.link, bed.geometry, bed.found, bed.shifts)
    mass_g = 1000.0 * density * float(np.sum(volumes(semi_axes[selected])))
    return 2.0 * count * grid_step**2 / mass_g if mass_g > 0 else float("nan")
