"""The datasets the CT stage writes (imaging.ct.datasets): coordinates at voxel centres."""

import numpy as np
import xarray as xr

from imaging.ct.datasets import image_dataset


def test_image_dataset_coordinates_are_voxel_centres():
    volume = np.arange(2 * 3 * 4, dtype=np.uint8).reshape(2, 3, 4)
    ds = image_dataset(volume > 3, 2e-5, volume[::2, ::2, ::2], 2)
    np.testing.assert_allclose(ds["x"].values, [1e-5, 3e-5, 5e-5, 7e-5])
    np.testing.assert_allclose(ds["x_preview"].values, [1e-5, 5e-5])
    assert isinstance(ds, xr.Dataset) and ds["specimen"].sum() == 20 and "grey" not in ds
