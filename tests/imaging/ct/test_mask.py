"""The specimen mask against the phantom's known cylinder, and the cylinder of a container."""

import numpy as np
import pytest

from imaging.ct.mask import cylinder_section, inscribed_box, specimen_mask
from imaging.ct.phantom import PhantomSpec, pellet_phantom


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


def test_cylinder_section_has_the_disc_area():
    slices, disc = cylinder_section((5, 200, 240), 1e-4, 6e-3, centre=(10e-3, 11e-3))
    assert disc.sum() == pytest.approx(np.pi * 60**2, rel=0.01)
    y, x = np.argwhere(disc).mean(axis=0)
    assert (y + 0.5) * 1e-4 == pytest.approx(10e-3, abs=1e-6)
    assert (x + 0.5) * 1e-4 == pytest.approx(11e-3, abs=1e-6)
    assert slices.all()
    ends, _ = cylinder_section((5, 20, 20), 1e-4, 6e-4, z_range=(1e-4, 3e-4))
    assert ends.tolist() == [False, True, True, False, False]
