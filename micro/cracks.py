"""Crack model of the micro pellet (Caulk 2022, Sec. 3.3.6; docs/design.md §3).

A broken bond (:func:`shared.dem.bond_tension`) is open while its aperture w, its
stretch beyond the stress-free contact, is positive; an open bond on an edge of the
Delaunay mesh is a crack, a planar gap normal to the bond through
p3 = x_a + n (r_a + w/2). Each facet around the edge is a patch of half-area
1/2 |(C_i - p3) x (C_j - p3)| (Eq. 3.36, C the cell centroids) and trace width b.
The crack is imbibed while its mean local suction is below the water-entry suction
gamma / w (Eqs. 3.33, 3.38), gas-filled otherwise. A gas-filled crack scales its facets'
water conductivity by eta (Eq. 3.34) and adds the cubic-law gas conductivity
w^3 / (12 mu_gas) b / l_ij (Eq. 3.37), with w capped at b; an imbibed crack does the
reverse with the water viscosity. Readings and details: docs/micro.md, "micro.cracks".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
import numpy.typing as npt

from shared.dem.hertz import bond_stretches
from shared.materials import ClayParameters

__all__ = ["CrackNetwork", "CrackConductivity", "bond_apertures", "crack_network",
           "crack_conductivity", "centroid_distances", "capillary_release_forces"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

_TRIANGLE_EDGES = ((0, 1, 2), (1, 2, 0), (0, 2, 1))


@dataclass(frozen=True)
class CrackNetwork:
    """Open bonds that are mesh edges, and their patches on the facets around them.

    Attributes
    ----------
    bonds
        (n_cracks,) index of each crack in the bond list.
    pairs
        (n_cracks, 2) point indices a < b.
    apertures
        (n_cracks,) w [m], > 0.
    normals
        (n_cracks, 3) unit vectors from a to b (normal to the crack plane).
    suctions
        (n_cracks,) local suction [Pa].
    entry_suctions
        (n_cracks,) water-entry suction gamma / w [Pa].
    imbibed
        (n_cracks,) True while suction < gamma / w (water-filled).
    areas
        (n_cracks,) crack area a_c, sum of its patch areas [m2].
    volumes
        (n_cracks,) crack volume a_c w [m3].
    patch_cracks
        (n_patches,) crack of each patch (index into the arrays above).
    patch_facets
        (n_patches,) internal facet crossed by each patch.
    patch_areas
        (n_patches,) patch half-areas [m2].
    patch_widths
        (n_patches,) width b of the crack across the facet [m].
    """

    bonds: IntArray
    pairs: IntArray
    apertures: FloatArray
    normals: FloatArray
    suctions: FloatArray
    entry_suctions: FloatArray
    imbibed: BoolArray
    areas: FloatArray
    volumes: FloatArray
    patch_cracks: IntArray
    patch_facets: IntArray
    patch_areas: FloatArray
    patch_widths: FloatArray


@dataclass(frozen=True)
class CrackConductivity:
    """Per-facet change of the conductivities: g_new = scale g + added.

    Attributes
    ----------
    water_scale, gas_scale
        (n_facets,) factors [1]: eta where a crack of the other phase blocks the facet,
        1 elsewhere.
    water_added, gas_added
        (n_facets,) cubic-law crack conductivities [m3/(Pa s)], 0 without crack.
    """

    water_scale: FloatArray
    water_added: FloatArray
    gas_scale: FloatArray
    gas_added: FloatArray


def bond_apertures(
    bonds: npt.ArrayLike,
    positions: npt.ArrayLike,
    radii: npt.ArrayLike,
    reference_overlaps: npt.ArrayLike | None = None,
    reference_radii: npt.ArrayLike | None = None,
) -> FloatArray:
    """Opening w of each bond beyond its stress-free contact [m]; > 0 means open.

    The DEM's bond stretch (:func:`shared.dem.bond_stretches`, whose parameters these
    are, ``reference_overlaps`` being its ``bond_overlaps``): the number bonds break
    by is the crack's aperture.
    """
    return bond_stretches(bonds, positions, radii, reference_overlaps, reference_radii)


def _edge_patches(
    pairs: IntArray, facet_vertices: IntArray, n_points: int
) -> tuple[IntArray, IntArray, IntArray]:
    """Match crack pairs to facet edges: (crack, facet, third vertex) of each match."""
    crack_keys = pairs[:, 0] * np.int64(n_points) + pairs[:, 1]
    order = np.argsort(crack_keys, kind="stable")
    sorted_keys = crack_keys[order]
    cracks, facets, thirds = [], [], []
    for first, second, third in _TRIANGLE_EDGES:
        u, v = facet_vertices[:, first], facet_vertices[:, second]
        keys = np.minimum(u, v) * np.int64(n_points) + np.maximum(u, v)
        where = np.minimum(np.searchsorted(sorted_keys, keys), max(sorted_keys.size - 1, 0))
        hit = np.nonzero(sorted_keys[where] == keys)[0] if sorted_keys.size else where[:0]
        cracks.append(order[where[hit]])
        facets.append(hit)
        thirds.append(facet_vertices[hit, third])
    crack, facet, third = (np.concatenate(parts) for parts in (cracks, facets, thirds))
    sort = np.lexsort((facet, crack))
    return crack[sort], facet[sort], third[sort]


def _trace_widths(a: FloatArray, b: FloatArray, c: FloatArray, centre: FloatArray,
                  normal: FloatArray) -> FloatArray:
    """Length of the cut of the plane (centre, normal) through triangles (a, b, c).

    The plane separates a from b; it leaves through a-c when c lies beyond it on b's
    side or on it, else through b-c.
    """
    height_c = np.einsum("ij,ij->i", c - centre, normal)
    from_a = np.where(height_c >= 0.0, 1.0, 0.0)[:, None]
    start = from_a * a + (1.0 - from_a) * b
    height_start = np.einsum("ij,ij->i", start - centre, normal)
    t = height_start / (height_start - height_c)
    exit_point = start + t[:, None] * (c - start)
    return np.linalg.norm(exit_point - centre, axis=1)


def crack_network(
    bonds: npt.ArrayLike,
    positions: npt.ArrayLike,
    radii: npt.ArrayLike,
    facet_vertices: npt.ArrayLike,
    facet_cells: npt.ArrayLike,
    cell_centres: npt.ArrayLike,
    cell_suction: npt.ArrayLike,
    material: ClayParameters,
    min_aperture: float = 0.0,
    *,
    reference_overlaps: npt.ArrayLike | None = None,
    reference_radii: npt.ArrayLike | None = None,
    broken: npt.ArrayLike | None = None,
) -> CrackNetwork:
    """Cracks (open broken bonds on mesh edges), their patches, state and geometry.

    Parameters
    ----------
    bonds
        (n_bonds, 2) point pairs bonded in the reference state (``DEMState.bonds``).
    positions
        (n_points, 3) current point centres [m].
    radii
        (n_points,) current interaction radii [m].
    facet_vertices
        (n_facets, 3) vertices of the internal triangles (``Mesh.facet_vertices``).
    facet_cells
        (n_facets, 2) cells on either side (``Mesh.facet_cells``).
    cell_centres
        (n_cells, 3) cell centres C [m] (``Mesh.centroids``).
    cell_suction
        (n_cells,) suction per cell [Pa].
    material
        ``surface_tension`` gamma [N/m].
    min_aperture
        Bonds open wider than this count as cracks [m]; 0 follows the zero-force rule.
    reference_overlaps, reference_radii
        Stress-free bond overlaps [m] and reference radii [m]
        (``DEMState.bond_overlaps``, ``DEMState.reference_radii``); see
        :func:`bond_apertures`. None: apertures are the gaps between the spheres.
    broken
        (n_bonds,) which bonds broke (``DEMState.bond_broken``); an intact bond is
        never a crack. None: every bond may be.

    Returns
    -------
    CrackNetwork
        Cracks in bond order; patches sorted by crack, then facet.
    """
    bonds = np.sort(np.asarray(bonds, dtype=np.int64).reshape(-1, 2), axis=1)
    positions = np.asarray(positions, dtype=np.float64)
    radii = np.asarray(radii, dtype=np.float64)
    facet_vertices = np.asarray(facet_vertices, dtype=np.int64)
    facet_cells = np.asarray(facet_cells, dtype=np.int64)
    cell_centres = np.asarray(cell_centres, dtype=np.float64)
    cell_suction = np.asarray(cell_suction, dtype=np.float64)

    apertures = bond_apertures(bonds, positions, radii, reference_overlaps, reference_radii)
    candidates = apertures > min_aperture
    if broken is not None:
        candidates &= np.asarray(broken, dtype=bool)
    open_bonds = np.nonzero(candidates)[0]
    crack, facet, third = _edge_patches(bonds[open_bonds], facet_vertices, positions.shape[0])
    on_mesh, crack = np.unique(crack, return_inverse=True)
    index = open_bonds[on_mesh]
    pairs = bonds[index]
    w = apertures[index]
    x_a, x_b = positions[pairs[:, 0]], positions[pairs[:, 1]]
    normals = (x_b - x_a) / np.linalg.norm(x_b - x_a, axis=1, keepdims=True)
    # the crack plane lies midway between the two spheres' surfaces along the bond
    distance = np.linalg.norm(x_b - x_a, axis=1)
    centres = x_a + normals * (0.5 * (distance + radii[pairs[:, 0]] - radii[pairs[:, 1]]))[:, None]

    p3 = centres[crack]
    c_i, c_j = cell_centres[facet_cells[facet, 0]], cell_centres[facet_cells[facet, 1]]
    patch_areas = 0.5 * np.linalg.norm(np.cross(c_i - p3, c_j - p3), axis=1)
    patch_widths = _trace_widths(
        x_a[crack], x_b[crack], positions[third], p3, normals[crack]
    )
    facet_suction = 0.5 * cell_suction[facet_cells[facet]].sum(axis=1)
    n_cracks = index.size
    patches_per_crack = np.bincount(crack, minlength=n_cracks)
    suctions = np.bincount(crack, weights=facet_suction, minlength=n_cracks) / np.maximum(
        patches_per_crack, 1
    )
    areas = cast(FloatArray, np.bincount(crack, weights=patch_areas, minlength=n_cracks))  # weighted: floats
    entry = material.surface_tension / w
    return CrackNetwork(
        bonds=index,
        pairs=pairs,
        apertures=w,
        normals=normals,
        suctions=suctions,
        entry_suctions=entry,
        imbibed=suctions < entry,
        areas=areas,
        volumes=areas * w,
        patch_cracks=crack.astype(np.int64),
        patch_facets=facet.astype(np.int64),
        patch_areas=patch_areas,
        patch_widths=patch_widths,
    )


def centroid_distances(facet_cells: npt.ArrayLike, centroids: npt.ArrayLike) -> FloatArray:
    """(n_facets,) distance between the centroids of each facet's two cells [m]."""
    cells = np.asarray(facet_cells, dtype=np.int64)
    centroids = np.asarray(centroids, dtype=np.float64)
    return np.linalg.norm(centroids[cells[:, 1]] - centroids[cells[:, 0]], axis=1)


def _sum_per_facet(facet: IntArray, values: FloatArray, n_facets: int) -> FloatArray:
    # np.bincount returns integers when given no entries at all
    return np.bincount(facet, weights=values, minlength=n_facets).astype(np.float64)


def crack_conductivity(
    network: CrackNetwork,
    flow_lengths: npt.ArrayLike,
    material: ClayParameters,
) -> CrackConductivity:
    """Per-facet conductivity changes of the cracks, for the water and the gas solves.

    Parameters
    ----------
    network
        Cracks from :func:`crack_network`.
    flow_lengths
        (n_facets,) length l_ij of the flow along a crack between the two cells of each
        facet [m]: the distance between their centroids (:func:`centroid_distances`),
        the points the crack's patches are built from. Not the dual length of the clay
        conductances: between near-cospherical cells it tends to zero, and a crack
        there would conduct without bound.
    material
        ``crack_roughness_factor`` eta [1], ``water_viscosity`` and ``gas_viscosity``
        [Pa s].

    Returns
    -------
    CrackConductivity
        A facet crossed by several cracks adds all their cubic-law terms; one blocking
        crack suffices to scale it by eta.
    """
    flow_lengths = np.asarray(flow_lengths, dtype=np.float64)
    n_facets = flow_lengths.size
    facet = network.patch_facets
    imbibed = network.imbibed[network.patch_cracks]
    aperture = np.minimum(network.apertures[network.patch_cracks], network.patch_widths)
    cubic = aperture**3 / 12.0
    geometric = cubic * network.patch_widths / flow_lengths[facet]
    eta = material.crack_roughness_factor
    water_scale = np.ones(n_facets)
    gas_scale = np.ones(n_facets)
    water_scale[facet[~imbibed]] = eta
    gas_scale[facet[imbibed]] = eta
    water_added = _sum_per_facet(
        facet[imbibed], geometric[imbibed] / material.water_viscosity, n_facets
    )
    gas_added = _sum_per_facet(
        facet[~imbibed], geometric[~imbibed] / material.gas_viscosity, n_facets
    )
    return CrackConductivity(water_scale, water_added, gas_scale, gas_added)


def capillary_release_forces(
    network: CrackNetwork,
    pressure: npt.ArrayLike,
    saturation: npt.ArrayLike,
    facet_cells: npt.ArrayLike,
    radii: npt.ArrayLike,
) -> FloatArray:
    """Forces that remove the capillary pull across gas-filled cracks (Eq. 3.35) [N].

    A gas-filled crack no longer holds water between its faces, so the pull chi p
    of the pore water across it is removed: point a gets n_ab a p S and point b
    the opposite, n_ab the unit vector from a to b, a the crack area and p, S the
    crack's water pressure and saturation, the means over its patches of the two
    incident cells' means. Under suction (p < 0) this pushes a and b apart. Eq. 3.35
    prints the factor as (p_i + p_j)(s_i - s_j) / 2, which vanishes for equal
    saturations and is not a pressure; the text beneath it says both are means of the
    two cells, which is the reading used here. Imbibed cracks keep their water and
    its pull: no force.

    The area is the crack area a_c (Eq. 3.36) but at most the bond's section
    pi r_m^2 (r_m the pair's mean radius, the section of the bond model): the pull
    released cannot exceed what the two points' bond carried. Inside the specimen
    a_c is about that section; on the hull the patches reach to the centroids of hull
    slivers, and without the bound a boundary point pushed out by its crack would
    grow the crack's area, hence the push, as it left.

    Parameters
    ----------
    network
        Cracks from :func:`crack_network` on the current mesh.
    pressure
        (n_cells,) water pressure per cell [Pa], negative under suction.
    saturation
        (n_cells,) water saturation per cell [1].
    facet_cells
        (n_facets, 2) cells on either side of each internal facet (``Mesh.facet_cells``).
    radii
        (n_points,) current point radii [m].

    Returns
    -------
    ndarray, shape (n_points, 3)
        Force per point [N]; the forces of each crack sum to zero.
    """
    radii = np.asarray(radii, dtype=np.float64)
    forces = np.zeros((radii.size, 3))
    gas = ~network.imbibed
    if not np.any(gas):
        return forces
    pressure = np.asarray(pressure, dtype=np.float64)
    saturation = np.asarray(saturation, dtype=np.float64)
    cells = np.asarray(facet_cells, dtype=np.int64)[network.patch_facets]
    n_cracks = network.pairs.shape[0]
    patches = np.maximum(np.bincount(network.patch_cracks, minlength=n_cracks), 1)

    def crack_mean(values: FloatArray) -> FloatArray:
        patch = 0.5 * values[cells].sum(axis=1)
        return np.bincount(network.patch_cracks, weights=patch, minlength=n_cracks) / patches

    section = np.pi * (0.5 * radii[network.pairs].sum(axis=1)) ** 2
    area = np.minimum(network.areas, section)
    magnitude = area * crack_mean(pressure) * crack_mean(saturation)
    on_a = network.normals[gas] * magnitude[gas, None]
    np.add.at(forces, network.pairs[gas, 0], on_a)
    np.add.at(forces, network.pairs[gas, 1], -on_a)
    return forces
