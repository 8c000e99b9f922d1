"""Deposited beds: no interpenetration (independent dense sampling), floor contact,
determinism, and the overlap fraction of the voxel image (Table IV: f_o < 1e-4)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from imaging.packing import (
    DepositionParameters,
    Packing,
    _contact_kernels,
    _settle_kernels,
    deposit,
    legendre_order,
    linear_zone,
    porosity_profile,
    zone_porosity,
)
from imaging.packing.analysis import profile_edges
from imaging.packing.voxels import overlap_fraction, voxelize

from .conftest import small_bed


def _inside(
    points: np.ndarray, center: np.ndarray, rot: np.ndarray, axes: np.ndarray
) -> np.ndarray:
    local = (points - center) @ rot
    return (np.abs(local[:, 2]) <= axes[2]) & (
        (local[:, 0] / axes[0]) ** 2 + (local[:, 1] / axes[1]) ** 2 <= 1.0)


def _interior_points(axes: np.ndarray, n: int = 60, layers: int = 7) -> np.ndarray:
    """Dense lattice filling an elliptic disk, boundary included."""
    g = np.linspace(-1, 1, n)
    x, y, z = np.meshgrid(g * axes[0], g * axes[1], np.linspace(-axes[2], axes[2], layers))
    keep = (x / axes[0]) ** 2 + (y / axes[1]) ** 2 <= 1.0
    return np.stack([x[keep], y[keep], z[keep]], 1)


def _overlapping_points(bed: Packing) -> tuple[int, int]:
    """(sampled points of any particle that lie in another one, pairs examined)."""
    w = bed.box_width
    radius = np.hypot(bed.semi_axes[:, 0], bed.semi_axes[:, 2])
    wrapped = bed.centers.copy()
    wrapped[:, 2] = wrapped[:, 2] % (10 * w)
    tree = cKDTree(wrapped, boxsize=[w, w, 10 * w])
    bad = 0
    examined = 0
    for i, j in tree.query_pairs(2 * radius.max()):
        shift = bed.centers[j] - bed.centers[i]
        shift[:2] -= w * np.round(shift[:2] / w)
        if np.linalg.norm(shift) > radius[i] + radius[j]:
            continue
        examined += 1
        points = _interior_points(bed.semi_axes[i]) @ bed.rotations[i].T + bed.centers[i]
        other = bed.centers[i] + shift
        bad += int(_inside(points, other, bed.rotations[j], bed.semi_axes[j]).sum())
        points = _interior_points(bed.semi_axes[j]) @ bed.rotations[j].T + bed.centers[i] + shift
        bad += int(_inside(points, bed.centers[i], bed.rotations[i], bed.semi_axes[i]).sum())
    return bad, examined


def test_no_interpenetration_by_dense_sampling(elliptic_bed: Packing) -> None:
    bad, pairs = _overlapping_points(elliptic_bed)
    assert pairs > 40
    assert bad == 0


def test_no_interpenetration_in_a_polydisperse_bed(polydisperse_bed: Packing) -> None:
    radius = np.hypot(polydisperse_bed.semi_axes[:, 0], polydisperse_bed.semi_axes[:, 2])
    assert radius.max() > 2.5 * np.median(radius)
    bad, pairs = _overlapping_points(polydisperse_bed)
    assert pairs > 60
    assert bad == 0


def _support_gaps(bed: Packing) -> np.ndarray:
    """Per particle, the smallest Euclidean distance [m] to the floor or to a particle placed
    before it (periodic images included), by the GJK distance of the contact kernels."""
    w = bed.box_width
    rot, axes, centers = bed.rotations, bed.semi_axes, bed.centers
    radius = np.hypot(axes[:, 0], axes[:, 2])
    floor = centers[:, 2] - (np.sqrt((axes[:, 0] * rot[:, 2, 0]) ** 2
                                     + (axes[:, 1] * rot[:, 2, 1]) ** 2)
                             + axes[:, 2] * np.abs(rot[:, 2, 2]))
    gaps = floor.copy()
    tolerance = 1e-3 * bed.contact_distance
    for i in range(1, len(centers)):
        for j in range(i):
            for sx in (-w, 0.0, w):
                for sy in (-w, 0.0, w):
                    other = centers[j] + np.array([sx, sy, 0.0])
                    if np.linalg.norm(other - centers[i]) > radius[i] + radius[j] + gaps[i]:
                        continue
                    distance = _contact_kernels.gjk(centers[i], rot[i], axes[i], other, rot[j],
                                                    axes[j], tolerance, 0.0)[0]
                    gaps[i] = min(gaps[i], distance)
    return gaps


@pytest.mark.parametrize("fixture", ["elliptic_bed", "polydisperse_bed"])
def test_every_particle_rests_on_a_support(fixture: str, request: pytest.FixtureRequest) -> None:
    """Contact accuracy of the exact (GJK) alternative to the paper's scan: a fall stops at
    a vertical gap of d_cont / 2 (GJK bounds converged to 0.2 of that gap; the Euclidean gap
    is at most the vertical one), so every particle lies within 0.6 d_cont of the floor or
    of an earlier particle (worst measured 0.52 and 0.54 d_cont in these beds), and none
    touches or overlaps one (distance > 0)."""
    bed = request.getfixturevalue(fixture)
    gaps = _support_gaps(bed) / bed.contact_distance
    assert gaps.max() <= 0.6
    assert gaps.min() > 0.0


def test_scanned_bed_rests_on_supports_with_overlaps_at_paper_level(scanned_bed: Packing) -> None:
    """The paper's contact scan (n_sp = 150): the refinement takes every fall to within
    d_cont of the floor or of an earlier particle (the scan's own stopping rule), and the
    overlaps its blind spots leave are at the paper's level: the voxel overlap fraction is
    below 1e-4 (Table IV: 2e-6 to 6.9e-5), though not zero: a particle touches or enters
    another somewhere (the exact mode's beds keep every distance > 0)."""
    bed = scanned_bed
    gaps = _support_gaps(bed)
    assert np.all(gaps <= bed.contact_distance)
    assert gaps.min() == 0.0
    image = voxelize(bed.centers, bed.rotations, bed.semi_axes, bed.box_width, 192,
                     (0.0, float(bed.centers[:, 2].max())))
    assert overlap_fraction(image.counts) < 1e-4


def test_bed_stays_in_the_box_and_lands_on_the_floor(elliptic_bed: Packing) -> None:
    bed = elliptic_bed
    w = bed.box_width
    assert np.all((bed.centers[:, :2] >= 0) & (bed.centers[:, :2] < w))
    rot, axes = bed.rotations, bed.semi_axes
    lowest = bed.centers[:, 2] - (np.sqrt((axes[:, 0] * rot[:, 2, 0]) ** 2
                                          + (axes[:, 1] * rot[:, 2, 1]) ** 2)
                                  + axes[:, 2] * np.abs(rot[:, 2, 2]))
    assert lowest.min() == pytest.approx(bed.contact_distance / 2, rel=1e-6)
    assert np.all(lowest > 0)


def test_voxel_overlap_fraction_is_below_paper_level(elliptic_bed: Packing) -> None:
    bed = elliptic_bed
    image = voxelize(bed.centers, bed.rotations, bed.semi_axes, bed.box_width, 192,
                     (0.0, float(bed.centers[:, 2].max())))
    assert overlap_fraction(image.counts) < 1e-4


def test_bed_is_deterministic_for_a_seed() -> None:
    first = small_bed(seed=3, n=12, attempts=100)
    again = small_bed(seed=3, n=12, attempts=100)
    other = small_bed(seed=4, n=12, attempts=100)
    assert np.array_equal(first.centers, again.centers)
    assert np.array_equal(first.rotations, again.rotations)
    assert not np.allclose(first.centers, other.centers)


def test_flat_entry_and_free_moves_give_an_ordered_bed() -> None:
    """Table II series 3 (theta_ini = 0, high freedom) yields strongly oriented beds (Fig. 6)."""
    bed = small_bed(seed=5, n=30, theta_max=0.0, attempts=300)
    assert legendre_order(bed.normals) > 0.9


@pytest.mark.slow
def test_freedom_and_entry_angle_order_the_porosity() -> None:
    """Fig. 4-5 of the paper: low freedom (series 1) gives looser, less ordered beds than
    high freedom with flat entry (series 3). 150 disks per bed (formerly 300) and 400
    attempts per cycle (formerly 800; half the run time again): porosities 0.647 and
    0.509, orders 0.80 and 0.99 in the linear zone, so the margins (0.05, 0.1) hold with
    room; equal freedoms fail both (high freedom entering at up to 90 deg: 0.512 and
    0.98)."""
    def porosity_and_order(theta_max: float, slide: float, swivel: float) -> tuple[float, float]:
        rng = np.random.default_rng(21)
        semi = np.tile([0.5e-6, 0.5e-6, 0.05e-6], (150, 1))
        params = DepositionParameters(4e-6, 5e-10, theta_max, True, slide, swivel, swivel,
                                      attempts_per_cycle=400)
        bed = deposit(semi, params, rng)
        z = bed.centers[:, 2]
        edges = profile_edges(float(z.max()), 0.5e-6)
        low, high = linear_zone(edges, porosity_profile(z, bed.volumes, 4e-6, edges))
        zone = (z > low) & (z <= high)
        return zone_porosity(z, bed.volumes, 4e-6, low, high), legendre_order(bed.normals[zone])

    loose, disordered = porosity_and_order(np.pi / 2, 1e-6 / 7, np.radians(10))
    dense, ordered = porosity_and_order(0.0, 5e-6, np.radians(80))
    assert loose > dense + 0.05
    assert ordered > disordered + 0.1


def test_two_contact_swivel_turns_about_the_contact_line() -> None:
    """With two contacts the swivel is a rotation about the line through them: points of
    that line stay fixed, the barycentre circles the foot of its altitude on the line and
    descends; without the rule the axis is the steepest horizontal one through that foot."""
    center = np.array([0.3, 0.2, 0.5])
    contacts = np.zeros((8, 3))
    contacts[0] = [0.0, -1.0, 0.0]
    contacts[1] = [0.0, 1.0, 0.4]             # an inclined contact line in the x = 0 plane
    pivot, line = np.empty(3), np.empty(3)
    _settle_kernels.pivot_point(center, contacts, 2, 0.0, 1e-9, pivot, line)
    direction = (contacts[1] - contacts[0]) / np.linalg.norm(contacts[1] - contacts[0])
    assert np.allclose(np.abs(line @ direction), 1.0)
    assert abs((center - pivot) @ direction) < 1e-12          # foot of the altitude
    rot = np.eye(3)
    new_center, new_rot, work = np.empty(3), np.empty((3, 3)), np.empty((3, 3))
    for contact_line in (True, False):
        _settle_kernels.trial_move(_settle_kernels.SWIVEL, 0.3, 0.0, True, True, contact_line,
                                   center, rot, pivot, line, new_center, new_rot, work)
        lever_h = (center - pivot)[:2]
        steepest = np.array([-lever_h[1], lever_h[0], 0.0]) / np.hypot(*lever_h)
        axis = direction if contact_line else steepest
        assert np.allclose(np.abs(work @ axis), np.abs(axis))   # the axis is kept
        lever = work @ (center - pivot)
        assert lever[2] < (center - pivot)[2]                   # the barycentre descends
        assert np.allclose(new_center[:2], pivot[:2] + lever[:2])
        assert new_center[2] == center[2]                       # refall from the old altitude
        for p in contacts[:2]:
            kept = np.allclose(work @ (p - pivot) + pivot, p)
            assert kept == contact_line
