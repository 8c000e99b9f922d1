"""Voxelisation against exact volumes and overlaps."""

from __future__ import annotations

import numpy as np
import pytest

from imaging.packing.orientation import rotation_matrices
from imaging.packing.voxels import overlap_fraction, voxel_counts, voxelize


@pytest.mark.parametrize("center_x", [0.8, 0.05])
@pytest.mark.parametrize("axes", [(0.5, 0.5, 0.25), (0.6, 0.4, 0.2)])
def test_voxelised_volume_of_one_tilted_disk(
    center_x: float, axes: tuple[float, float, float]
) -> None:
    semi = np.array([axes])
    rot = rotation_matrices([[0.3, 0.7, 1.1]])
    image = voxelize(np.array([[center_x, 0.8, 0.8]]), rot, semi, 1.6, 256, (0.0, 1.6))
    volume = np.count_nonzero(image.counts) * image.voxel_size**3
    assert volume == pytest.approx(2 * np.pi * axes[0] * axes[1] * axes[2], rel=0.01)


def test_overlap_fraction_of_known_pairs() -> None:
    rot = rotation_matrices(np.zeros((2, 3)))
    semi = np.array([[0.5, 0.5, 0.1]] * 2)
    shape = (40, 200, 200)
    same = voxel_counts(np.array([[1.0, 1.0, 0.2]] * 2), rot, semi, shape, 0.01)
    assert overlap_fraction(same) == pytest.approx(1.0)
    apart = voxel_counts(np.array([[0.5, 0.5, 0.2], [1.5, 1.5, 0.2]]), rot, semi, shape, 0.01)
    assert overlap_fraction(apart) == 0.0
    # discs of radius a at distance a: lens a^2 (2 pi / 3 - sqrt(3) / 2)
    shifted = voxel_counts(np.array([[0.75, 1.0, 0.2], [1.25, 1.0, 0.2]]), rot, semi, shape, 0.01)
    lens = 2 * np.pi / 3 - np.sqrt(3) / 2
    assert overlap_fraction(shifted) == pytest.approx(lens / (2 * np.pi - lens), rel=0.02)


#: Tilted orientations (phi, theta, psi) of the thin-disk test: the one above, two random
#: ones and a nearly flat one (theta = 0.03 rad).
THIN_DISK_ANGLES = [(0.3, 0.7, 1.1), (2.2, 1.2, 4.0), (5.1, 0.35, 0.6), (1.0, 0.03, 2.0)]


@pytest.mark.parametrize("center_x", [0.8, 0.05])
@pytest.mark.parametrize("angles", THIN_DISK_ANGLES)
def test_voxelised_volume_of_a_thin_clay_disk(
    center_x: float, angles: tuple[float, float, float]
) -> None:
    """A clay-like disk: l_a = l_b = 0.5, R = h / (2 sqrt(l_a l_b)) = 0.1, so h = 0.1.
    At 128 voxels across the 1.6 box, l_v = h / 8 (l_a = 40 l_v): a tilted disk is within
    1 % of pi l_a l_b h (over 40 random poses the worst was 0.1 %, and 1.4 % at 64 voxels,
    h = 4 l_v)."""
    semi = np.array([[0.5, 0.5, 0.05]])
    image = voxelize(np.array([[center_x, 0.8, 0.83]]), rotation_matrices([angles]), semi, 1.6,
                     128, (0.0, 1.6))
    volume = np.count_nonzero(image.counts) * image.voxel_size**3
    assert volume == pytest.approx(np.pi * 0.5 * 0.5 * 0.1, rel=0.01)


@pytest.mark.parametrize("z_offset", [0.0, 0.3, 0.7])
def test_voxelised_thickness_of_a_flat_thin_disk_is_quantised(z_offset: float) -> None:
    """A disk parallel to the voxel grid keeps a whole number of voxel layers: its volume
    is within l_v / h of the exact one, not within 1 %, unless h is a multiple of l_v. At
    200 voxels across 1.6, h = 12.5 l_v: 12 or 13 layers, 4 % off."""
    semi = np.array([[0.5, 0.5, 0.05]])
    l_v = 1.6 / 200
    image = voxelize(np.array([[0.8, 0.8, 0.8 + z_offset * l_v]]),
                     rotation_matrices([(0.0, 0.0, 0.0)]), semi, 1.6, 200, (0.0, 1.6))
    volume = np.count_nonzero(image.counts) * l_v**3
    exact = np.pi * 0.5 * 0.5 * 0.1
    assert abs(volume / exact - 1.0) <= l_v / 0.1 + 0.005
    layers = np.count_nonzero(image.counts.any(axis=(1, 2)))
    assert layers in (12, 13)
