"""Voxelisation against exact volumes and overlaps."""

from __future__ import annotations

import numpy as np
import pytest

from imaging.deposition.orientation import rotation_matrices
from imaging.deposition.voxels import overlap_fraction, voxel_counts, voxelize


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
