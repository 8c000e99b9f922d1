"""Crack model against closed-form geometry and the cubic law.

The test crack: bond a-b along x, six points on a ring of radius R in the plane x = 0
(the crack plane of two equal radii). The Delaunay mesh is six tetrahedra
(a, b, c_k, c_k+1) around the edge a-b, so every facet (a, b, c_k) is crossed by the
crack over the width b = R, between cells whose circumcentres are rho = (R^2 - d^2) /
(sqrt(3) R) from the axis and 60 degrees apart (dual length l = rho), and whose
centroids are R cos(30 deg) / 2 from the axis (six patches of half-area
(R cos 30 / 2)^2 sin(60) / 2), 60 degrees apart too: the crack's flow length between
two cells, the centroid distance, is R cos(30 deg) / 2 as well.
"""

import dataclasses

import numpy as np
import pytest

from micro.cracks import (
    bond_apertures,
    capillary_release_forces,
    centroid_distances,
    crack_conductivity,
    crack_network,
)
from shared.mesh import build_mesh
from tests._defaults import CLAY

HALF_GAP, RING = 1e-4, 2e-4
RADIUS = 0.99e-4  # aperture w = 2 (HALF_GAP - RADIUS) = 2 um
APERTURE = 2e-6
DUAL_LENGTH = (RING**2 - HALF_GAP**2) / (np.sqrt(3.0) * RING)
CENTROID_DISTANCE = RING * np.cos(np.pi / 6) / 2


@pytest.fixture(scope="module")
def ring():
    angles = np.arange(6) * np.pi / 3
    points = np.vstack(
        [[-HALF_GAP, 0, 0], [HALF_GAP, 0, 0], np.c_[np.zeros(6), RING * np.cos(angles),
                                                      RING * np.sin(angles)]]
    )
    return points, build_mesh(points)


def _network(ring, suction, radius=RADIUS):
    points, mesh = ring
    return crack_network(
        [[0, 1], [2, 3]], points, np.full(8, radius), mesh.facet_vertices, mesh.facet_cells,
        mesh.centroids, np.full(mesh.n_cells, suction), CLAY,
    )


def test_aperture_is_gap_between_interaction_radii(ring):
    points, _ = ring
    w = bond_apertures([[0, 1], [2, 3]], points, np.full(8, RADIUS))
    assert w == pytest.approx([APERTURE, RING - 2 * RADIUS], rel=1e-9)


def test_imbibed_crack_adds_cubic_law_water_conductivity(ring):
    _, mesh = ring
    assert mesh.n_cells == 6 and mesh.n_facets == 6
    np.testing.assert_allclose(mesh.facet_lengths, DUAL_LENGTH, rtol=1e-12)
    network = _network(ring, suction=1e3)  # below gamma / w = 36.4 kPa
    np.testing.assert_array_equal(network.pairs, [[0, 1]])  # (2, 3) is no mesh edge
    assert network.imbibed[0]
    assert network.entry_suctions[0] == pytest.approx(0.0728 / APERTURE, rel=1e-9)
    lengths = centroid_distances(mesh.facet_cells, mesh.centroids)
    np.testing.assert_allclose(lengths, CENTROID_DISTANCE, rtol=1e-12)
    change = crack_conductivity(network, lengths, CLAY)
    cubic = APERTURE**3 / (12.0 * 1e-3) * RING / CENTROID_DISTANCE
    np.testing.assert_allclose(change.water_added, cubic, rtol=1e-9)
    np.testing.assert_array_equal(change.water_scale, 1.0)
    np.testing.assert_array_equal(change.gas_scale, 1e-3)
    np.testing.assert_array_equal(change.gas_added, 0.0)


def test_gas_filled_crack_blocks_water_and_carries_gas(ring):
    _, mesh = ring
    network = _network(ring, suction=1e5)  # above gamma / w
    assert not network.imbibed[0]
    change = crack_conductivity(network, centroid_distances(mesh.facet_cells, mesh.centroids), CLAY)
    np.testing.assert_array_equal(change.water_scale, CLAY.crack_roughness_factor)
    np.testing.assert_array_equal(change.water_added, 0.0)
    np.testing.assert_allclose(
        change.gas_added, APERTURE**3 / (12.0 * 1.8e-5) * RING / CENTROID_DISTANCE, rtol=1e-9
    )


def test_cubic_law_aperture_is_capped_at_the_crack_width(ring):
    """A bond opened wider than the crack's width b across a facet conducts as w = b."""
    _, mesh = ring
    network = _network(ring, suction=1e5)
    wide = dataclasses.replace(network, apertures=np.array([2.5 * RING]))
    change = crack_conductivity(wide, centroid_distances(mesh.facet_cells, mesh.centroids), CLAY)
    np.testing.assert_allclose(
        change.gas_added, RING**3 / (12.0 * 1.8e-5) * RING / CENTROID_DISTANCE, rtol=1e-9
    )


def test_crack_area_and_volume(ring):
    network = _network(ring, suction=1e3)
    centroid_radius = RING * np.cos(np.pi / 6) / 2
    area = 6 * 0.5 * centroid_radius**2 * np.sin(np.pi / 3)
    assert network.areas[0] == pytest.approx(area, rel=1e-9)
    assert network.volumes[0] == pytest.approx(area * APERTURE, rel=1e-9)
    np.testing.assert_allclose(network.patch_widths, RING, rtol=1e-9)


def test_gas_filled_crack_releases_its_capillary_pull(ring):
    """Eq. 3.35: a and b pushed apart by a p S along the bond, nothing if imbibed.

    a is the crack area a_c, or the bond section pi r^2 if smaller.

    The six cells carry different pressures and saturations; the crack's p and S are
    the means over its six patches of the two incident cells' means, i.e. (every cell
    being on two of the six facets) the plain cell means.
    """
    points, mesh = ring
    rng = np.random.default_rng(3)
    pressure = -rng.uniform(1e5, 2e5, mesh.n_cells)
    saturation = rng.uniform(0.3, 0.6, mesh.n_cells)
    network = _network(ring, suction=1e5)  # gas-filled
    centroid_radius = RING * np.cos(np.pi / 6) / 2
    area = 6 * 0.5 * centroid_radius**2 * np.sin(np.pi / 3)
    # a_c = 1.9e-8 m2 lies between the sections of these radii (3.1e-8, 2.8e-9 m2)
    for radius, released in ((RADIUS, area), (0.3 * RADIUS, np.pi * (0.3 * RADIUS) ** 2)):
        radii = np.full(8, radius)
        forces = capillary_release_forces(network, pressure, saturation, mesh.facet_cells, radii)
        push = released * pressure.mean() * saturation.mean()  # negative: a is pushed to -x
        np.testing.assert_allclose(forces[0], [push, 0.0, 0.0], atol=1e-12 * abs(push))
        np.testing.assert_allclose(forces[1], [-push, 0.0, 0.0], atol=1e-12 * abs(push))
        np.testing.assert_array_equal(forces[2:], 0.0)
    imbibed = _network(ring, suction=1e3)
    forces = capillary_release_forces(imbibed, pressure, saturation, mesh.facet_cells, radii)
    assert not forces.any()


def test_closed_bond_is_no_crack(ring):
    network = _network(ring, suction=1e3, radius=1.0001e-4)
    assert network.pairs.shape == (0, 2)
    change = crack_conductivity(network, ring[1].facet_lengths, CLAY)  # any lengths: no crack
    np.testing.assert_array_equal(change.water_scale, 1.0)
    assert change.water_added.dtype == np.float64 and not change.water_added.any()


def test_trace_width_and_patch_area_on_a_skewed_triangle():
    """Crack plane x = 1 cuts triangle (0,0,0), (2,0,0), (0.5,1,0) from (1,0,0) to
    (1, 2/3, 0) on edge b-c; cell centres (1, 0.5, +-1) make a patch of half-area
    |(0, 0.5, 1) x (0, 0.5, -1)| / 2 = 0.5."""
    scale = 1e-4
    points = np.array([[0.0, 0, 0], [2.0, 0, 0], [0.5, 1.0, 0]]) * scale
    network = crack_network(
        [[0, 1]], points, np.full(3, 0.9 * scale), [[0, 1, 2]], [[0, 1]],
        np.array([[1.0, 0.5, 1.0], [1.0, 0.5, -1.0]]) * scale, [1e3, 1e3], CLAY,
    )
    assert network.patch_widths[0] == pytest.approx(2.0 / 3.0 * scale, rel=1e-12)
    assert network.patch_areas[0] == pytest.approx(0.5 * scale**2, rel=1e-12)
    assert network.apertures[0] == pytest.approx(0.2 * scale, rel=1e-12)
