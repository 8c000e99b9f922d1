"""The pellet phantom: determined by its seed, its density field flatter along the compaction axis."""

import numpy as np

from imaging.ct.phantom import PhantomSpec, pellet_phantom


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
