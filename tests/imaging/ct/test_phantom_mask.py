"""Phantom determinism and the specimen mask against the phantom's known cylinder."""

import numpy as np
import pytest

from imaging.ct.mask import inscribed_box, specimen_mask
from imaging.ct.phantom import PhantomSpec, pellet_phantom
from imaging.ct.run import grid_spacing


def test_phantom_is_deterministic_for_a_seed():
    spec = PhantomSpec(shape=(24, 24, 24), seed=5)
    first, _ = pellet_phantom(spec)
    again, _ = pellet_phantom(spec)
    other, _ = pellet_phantom(PhantomSpec(shape=(24, 24, 24), seed=6))
    np.testing.assert_array_equal(first, again)
    assert np.any(first != other)


def test_density_field_is_flatter_along_the_compaction_axis():
    """Correlation shorter along z: neighbouring voxels differ more along z than along x."""
    spec = PhantomSpec(shape=(48, 48, 48), n_flaws=0, n_muscovite_grains=0, seed=2)
    _, density = pellet_phantom(spec)
    core = density[12:36, 12:36, 12:36]
    along_z = np.abs(np.diff(core, axis=0)).mean()
    along_x = np.abs(np.diff(core, axis=2)).mean()
    assert along_z > 1.5 * along_x


def test_mask_matches_the_cylinder():
    spec = PhantomSpec(shape=(40, 48, 48), seed=1)
    grey, density = pellet_phantom(spec)
    mask = specimen_mask(grey)
    truth = density > spec.air_density
    # the blurred edge moves the boundary by at most about one voxel
    radius = spec.radius_fraction * 24
    height = spec.height_fraction * 40
    shell = 2 * np.pi * radius * height + 2 * np.pi * radius**2
    assert abs(int(mask.sum()) - int(truth.sum())) < shell
    assert np.mean(mask == truth) > 0.97
    box = inscribed_box(mask)
    assert mask[box].all()
    edge = box[0].stop - box[0].start
    # the largest centred cube in a cylinder of radius r has half-diagonal r in xy
    assert edge == pytest.approx(np.sqrt(2) * radius, abs=3)


def test_grid_spacing_defaults_to_micro_point_spacing():
    micro_spacing = (8e-3, 512)  # micro.specimen_size_m, micro.n_points
    assert grid_spacing(None, micro_spacing) == pytest.approx(1e-3)
    assert grid_spacing(3e-4, micro_spacing) == 3e-4
