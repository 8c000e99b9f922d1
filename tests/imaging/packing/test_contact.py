"""Exact contact geometry against sampled surfaces and hand-computed falls."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from imaging.packing import _contact_kernels as contact
from imaging.packing.orientation import rotation_matrices


def _surface_points(center: np.ndarray, rot: np.ndarray, axes: np.ndarray, n: int) -> np.ndarray:
    """Points on the faces and rim of an elliptic disk, spaced about 1/n of l_a."""
    a, b, c = axes
    g = np.linspace(-1, 1, 2 * n + 1)
    x, y = np.meshgrid(g * a, g * b)
    inside = (x / a) ** 2 + (y / b) ** 2 <= 1
    faces = [np.stack([x[inside], y[inside], np.full(inside.sum(), s * c)], 1) for s in (-1, 1)]
    t = np.linspace(0, 2 * np.pi, 8 * n, endpoint=False)
    zs = np.linspace(-c, c, max(3, int(n * c / a) + 2))
    tt, zz = np.meshgrid(t, zs)
    rim = np.stack([a * np.cos(tt).ravel(), b * np.sin(tt).ravel(), zz.ravel()], 1)
    local = np.concatenate(faces + [rim])
    return center + local @ rot.T


@pytest.mark.parametrize("seed", range(6))
def test_gjk_distance_brackets_the_sampled_distance(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rot = rotation_matrices(rng.uniform([0, 0, 0], [2 * np.pi, np.pi / 2, 2 * np.pi], (2, 3)))
    axes = np.array([[1.0, 0.6, 0.1], [0.8, 0.8, 0.2]])
    ca = np.zeros(3)
    direction = rng.standard_normal(3)
    cb = 2.2 * direction / np.linalg.norm(direction)
    upper, lower, *_ = contact.gjk(ca, rot[0], axes[0], cb, rot[1], axes[1], 1e-10, 0.0)
    pa = _surface_points(ca, rot[0], axes[0], 70)
    pb = _surface_points(cb, rot[1], axes[1], 70)
    # pairs farther apart than the GJK distance + 0.1 are not searched (inf): a sampled
    # distance beyond that fails the last assertion all the same
    sampled = cKDTree(pb).query(pa, distance_upper_bound=upper + 0.1)[0].min()
    assert upper > 0
    assert lower <= sampled + 1e-12
    assert sampled == pytest.approx(upper, abs=5e-3)


def test_flat_disk_falls_onto_flat_disk_by_the_gap() -> None:
    rot = np.eye(3)
    axes = np.array([1.0, 1.0, 0.05])
    drop, *point = contact.drop_to_contact(np.array([0.3, 0.2, 1.0]), rot, axes, np.zeros(3), rot,
                                           axes, 10.0, 1e-6)
    assert drop == pytest.approx(0.9, abs=1e-6)
    assert point[2] == pytest.approx(0.05)


def test_tilted_disk_lands_on_its_rim() -> None:
    """Disk tilted by 0.7 rad about x: lowest rim corner at
    z = 2 - sin(0.7) - 0.05 cos(0.7), y = 1.5 - cos(0.7) + 0.05 sin(0.7)."""
    rot_a = rotation_matrices([[0.0, 0.7, 0.0]])[0]
    axes = np.array([1.0, 1.0, 0.05])
    drop, qx, qy, qz = contact.drop_to_contact(np.array([0.0, 1.5, 2.0]), rot_a, axes, np.zeros(3),
                                               np.eye(3), axes, 10.0, 1e-9)
    assert drop == pytest.approx(2 - np.sin(0.7) - 0.05 * np.cos(0.7) - 0.05, abs=1e-7)
    assert qy == pytest.approx(1.5 - np.cos(0.7) + 0.05 * np.sin(0.7), abs=1e-6)


def test_overlapping_start_and_passing_particles() -> None:
    rot = np.eye(3)
    axes = np.array([1.0, 1.0, 0.05])
    assert contact.drop_to_contact(np.array([0.5, 0, 0.05]), rot, axes, np.zeros(3), rot, axes,
                                   10.0, 1e-6)[0] == -1.0
    beside = contact.drop_to_contact(np.array([2.5, 0, 1.0]), rot, axes, np.zeros(3), rot, axes,
                                     10.0, 1e-6)[0]
    assert beside == contact.INFINITE_DROP


def test_a_particle_grazing_a_flank_is_not_in_contact() -> None:
    """Two upright disks (normals along x) face to face, 1e-8 apart: the Euclidean gap is
    far below the contact tolerance, but a vertical fall never closes it (the paper's
    contact is a vertical distance), so A slides past B; with a disk under B's flank
    reaching out below A (top face at z = 0.05), A lands on its rim after 1 - 0.5 - 0.05."""
    upright = rotation_matrices([[np.pi / 2, np.pi / 2, 0.0]])[0]
    assert np.allclose(np.abs(upright[:, 2]), [1.0, 0.0, 0.0])
    axes = np.array([0.5, 0.5, 0.05])
    a = np.array([0.1 + 1e-8, 0.0, 1.0])
    b = np.array([0.0, 0.0, 0.5])
    assert contact.gjk(a, upright, axes, b, upright, axes, 1e-12, 1e-9)[0] < 1e-6
    passing = contact.drop_to_contact(a, upright, axes, b, upright, axes, 10.0, 1e-6)[0]
    assert passing == contact.INFINITE_DROP
    floor_disk = np.array([0.4, 0.0, 0.0])
    landing = contact.drop_to_contact(a, upright, axes, floor_disk, np.eye(3), axes, 10.0, 1e-9)
    assert landing[0] == pytest.approx(1.0 - 0.5 - 0.05, abs=1e-8)


def test_support_and_bounding_boxes_against_sampled_surfaces() -> None:
    rng = np.random.default_rng(8)
    rot = rotation_matrices(rng.uniform([0, 0, 0], [2 * np.pi, np.pi / 2, 2 * np.pi], (5, 3)))
    axes = np.array([[1.0, 0.6, 0.1]] * 5)
    center = np.array([0.3, -0.2, 0.5])
    boxes = contact.bounding_half_extents(rot, axes)
    for k in range(5):
        points = _surface_points(center, rot[k], axes[k], 60)
        for d in rng.standard_normal((4, 3)):
            far = np.array(contact.support(center, rot[k], axes[k], *d))
            assert far @ d >= (points @ d).max() - 1e-12
            assert far @ d == pytest.approx((points @ d).max(), abs=2e-3)
        assert boxes[k] == pytest.approx(np.abs(points - center).max(axis=0), abs=2e-3)
        single = np.empty(3)
        contact.half_extents(rot[k], axes[k], single)
        assert single == pytest.approx(boxes[k], rel=1e-12)
