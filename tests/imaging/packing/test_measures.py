"""The measures of a bed (imaging.packing.measures) on a hand-built stack of flat disks:
zone, porosity, order and voxel image known by construction."""

from __future__ import annotations

import numpy as np
import pytest

from imaging.packing.deposition import Packing
from imaging.packing.measures import measure_packing

A, C, W = 1.0e-6, 0.1e-6, 3.0e-6  # disk radius a, half-thickness c, box width
ALTITUDES = np.array([0.1, 0.35, 0.6, 0.85]) * 1e-6  # 0.25 um apart > 2c: no overlap
ZONE = (0.2e-6, 0.7e-6)


def _stack() -> Packing:
    n = ALTITUDES.size
    centers = np.column_stack([np.full(n, W / 2), np.full(n, W / 2), ALTITUDES])
    return Packing(centers=centers, rotations=np.repeat(np.eye(3)[None], n, axis=0),
                   semi_axes=np.tile([A, A, C], (n, 1)), box_width=W, contact_distance=1e-9,
                   accepted_moves=np.zeros(n, np.int64), wall_time=np.zeros(n))


def _measure(zone=ZONE):
    return measure_packing(_stack(), profile_bin_width=0.05e-6, contact_grid=0.05e-6,
                           voxel_resolution=120, rocking_curve_bins=9,
                           z_min=zone[0], z_max=zone[1])


def test_a_stack_of_horizontal_disks_has_its_hand_computed_measures():
    m = _measure()
    # the two middle disks lie in the zone (0.2, 0.7] um
    assert m.in_zone.tolist() == [False, True, True, False]
    disk = np.pi * A * A * 2 * C  # a flat cylinder, pi l_a l_b h
    assert m.porosity == pytest.approx(1.0 - 2 * disk / (W**2 * (ZONE[1] - ZONE[0])), rel=1e-12)
    # every normal vertical: perfect order
    assert m.S == pytest.approx(1.0, abs=1e-12)
    assert m.S_part == pytest.approx(1.0, abs=1e-12)
    assert m.S_vol == pytest.approx(1.0, abs=1e-12)
    # the image covers the zone: the two disks, not overlapping, within the voxel size
    assert m.image.z_origin == pytest.approx(ZONE[0])
    assert m.image.voxel_size == pytest.approx(W / 120)
    assert m.image.counts.max() == 1 and m.overlap_fraction == 0.0
    assert m.image.counts.sum() * m.image.voxel_size**3 == pytest.approx(2 * disk, rel=0.1)


def test_a_zone_without_barycentre_is_refused():
    with pytest.raises(ValueError, match="z_min_m, z_max_m"):
        _measure((0.2e-6, 0.3e-6))
