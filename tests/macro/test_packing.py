"""The pellet packing: the mock-up's fraction without overlaps (checked by brute force),
the count from the packing fraction, radii of a size distribution, the wall's ordering."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import pdist, squareform

from macro.packing import TOLERANCE, Packing, pack_cylinder, pellet_count

HEIGHT, RADIUS = 0.12, 0.03
MOCK_UP = 1490.0 * 0.8 / (2770.0 * 0.75)
"""The mock-up's pellet packing fraction: 80 % of 1490 kg/m3 of dry mass in pellets of
dry density 2770 (1 - 0.25) kg/m3."""


def brute_force_overlap(packing: Packing, height: float, radius: float) -> float:
    """Largest overlap [m] of any two pellets (every pair), a pellet and the curved wall,
    or a pellet and a plate; 0 when none."""
    r = packing.radii
    gaps = squareform(pdist(packing.positions)) - (r[:, None] + r[None, :])
    np.fill_diagonal(gaps, np.inf)
    wall = np.hypot(packing.positions[:, 0], packing.positions[:, 1]) + r - radius
    plates = np.abs(packing.positions[:, 2]) + r - 0.5 * height
    return max(float(-gaps.min()), float(wall.max()), float(plates.max()), 0.0)


@pytest.fixture(scope="module")
def mock_up() -> Packing:
    """7 mm pellets at the mock-up's fraction in its container, the default iterations."""
    return pack_cylinder(HEIGHT, RADIUS, 3.5e-3, MOCK_UP, np.random.default_rng(0), 3000)


def test_mock_up_fraction_is_packed_without_overlaps(mock_up):
    """The count is the fraction's volume over a pellet's (1084 pellets), the fraction
    their volume over the container's, and no pair, wall or plate overlaps by more than
    1e-4 r, by a check of every pair."""
    r = 3.5e-3
    n = round(MOCK_UP * RADIUS**2 * HEIGHT / (4.0 / 3.0 * r**3))
    assert mock_up.radii.size == n == 1084
    assert np.all(mock_up.radii == r)
    assert mock_up.packing_fraction == pytest.approx(n * 4.0 / 3.0 * r**3 / (RADIUS**2 * HEIGHT), rel=1e-12)
    assert abs(mock_up.packing_fraction - MOCK_UP) < 0.5 * 4.0 / 3.0 * r**3 / (RADIUS**2 * HEIGHT)
    largest = brute_force_overlap(mock_up, HEIGHT, RADIUS)
    assert largest <= TOLERANCE * r
    assert mock_up.largest_overlap == pytest.approx(largest, abs=1e-12 * r)


def test_first_layer_sits_one_radius_from_the_wall(mock_up):
    """Random packings order against a flat or curved wall: the centres' number density
    against the distance from the curved wall peaks one radius from it (the layer of
    pellets touching the wall), at several times the bulk density; none is closer."""
    r = 3.5e-3
    distance = RADIUS - np.hypot(mock_up.positions[:, 0], mock_up.positions[:, 1])
    edges = np.arange(0.0, 4.0 * r + 1e-12, 0.1 * r)
    counts, _ = np.histogram(distance, edges)
    shell = np.pi * ((RADIUS - edges[:-1]) ** 2 - (RADIUS - edges[1:]) ** 2) * HEIGHT
    density = counts / shell
    bulk = mock_up.radii.size / (np.pi * RADIUS**2 * HEIGHT)
    assert distance.min() >= r * (1.0 - TOLERANCE)
    assert edges[np.argmax(density)] == pytest.approx(r)
    assert density.max() > 4.0 * bulk


def test_same_seed_gives_the_same_packing_and_another_seed_another():
    """Default pellets (5.99 mm) at the default 0.50: bit for bit the same for a seed,
    without overlaps (brute force), and another packing for another seed."""
    r = 5.99e-3
    first, again, other = (pack_cylinder(HEIGHT, RADIUS, r, 0.5, np.random.default_rng(seed), 3000)
                           for seed in (3, 3, 4))
    assert first.radii.size == round(0.5 * RADIUS**2 * HEIGHT / (4.0 / 3.0 * r**3)) == 188
    assert np.array_equal(first.positions, again.positions)
    assert first.largest_overlap == again.largest_overlap
    assert not np.allclose(first.positions, other.positions)
    assert brute_force_overlap(first, HEIGHT, RADIUS) <= TOLERANCE * r


def test_size_distribution_fills_the_target_fraction():
    """Radii uniform within +-20 % at the mock-up's fraction (7 mm): all inside the
    bounds, the count from the analytic mean volume r^3 (1 + spread^2) gives the target
    packing fraction within sampling error (about 1/sqrt(n) of the volume), no overlap
    above 1e-4 r (brute force)."""
    r, spread = 3.5e-3, 0.2
    packing = pack_cylinder(HEIGHT, RADIUS, r, MOCK_UP, np.random.default_rng(4), 3000, spread)
    n = packing.radii.size
    assert n == pellet_count(HEIGHT, RADIUS, r, MOCK_UP, spread)
    assert n == round(MOCK_UP * RADIUS**2 * HEIGHT / (4.0 / 3.0 * r**3 * (1.0 + spread**2)))
    assert packing.radii.min() >= (1 - spread) * r and packing.radii.max() <= (1 + spread) * r
    assert packing.radii.std() > 0.1 * r
    assert abs(packing.packing_fraction - MOCK_UP) < 3.0 * MOCK_UP / np.sqrt(n)
    assert brute_force_overlap(packing, HEIGHT, RADIUS) <= TOLERANCE * r


def test_fraction_beyond_jamming_is_returned_with_its_overlaps():
    """0.62 in a narrow container (R = 3.75 r) jams: the packing comes back with its
    overlaps, reported as they are (brute force), for the caller to refuse."""
    height, radius, r = 0.05, 0.015, 4e-3
    packing = pack_cylinder(height, radius, r, 0.62, np.random.default_rng(0), 3000)
    largest = brute_force_overlap(packing, height, radius)
    assert largest > 100.0 * TOLERANCE * r
    assert packing.largest_overlap == pytest.approx(largest, rel=1e-9)
