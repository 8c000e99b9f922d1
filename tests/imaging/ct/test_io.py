"""Greyscale readers: one volume through every format, and bad files."""

import numpy as np
import pytest

from imaging.ct.datasets import image_dataset
from imaging.ct.io import (
    ImageError,
    read_raw,
    read_slice_folder,
    read_tiff_stack,
    read_volume,
    write_slice_folder,
    write_tiff_stack,
)
from shared.io import write_dataset


@pytest.fixture(params=[np.uint8, np.uint16])
def volume(request, rng):
    info = np.iinfo(request.param)
    return rng.integers(0, info.max, size=(5, 12, 9), dtype=request.param, endpoint=True)


def test_every_format_gives_the_same_array(volume, tmp_path):
    tiff = write_tiff_stack(volume, tmp_path / "scan.tif")
    folder = write_slice_folder(volume, tmp_path / "slices")
    raw = tmp_path / "scan.raw"
    volume.astype(volume.dtype.newbyteorder(">")).tofile(raw)
    ncfile = write_dataset(image_dataset(volume > 0, 1e-5, volume, 1, grey=volume),
                           tmp_path / "scan.nc",
                           stage="imaging", title="t")
    arrays = [
        read_tiff_stack(tiff),
        read_slice_folder(folder),
        read_raw(raw, volume.shape, str(volume.dtype), "big"),
        read_volume("netcdf", ncfile),
    ]
    for array in arrays:
        assert array.dtype == volume.dtype
        np.testing.assert_array_equal(array, volume)


def test_slices_sort_naturally(tmp_path, rng):
    volume = rng.integers(0, 255, size=(12, 4, 4), dtype=np.uint8)
    write_slice_folder(volume, tmp_path / "s")
    for index in range(12):  # unpadded names: slice_10 must come after slice_9
        (tmp_path / "s" / f"slice_{index:02d}.tif").rename(tmp_path / "s" / f"slice_{index}.tif")
    np.testing.assert_array_equal(read_slice_folder(tmp_path / "s"), volume)


def test_truncated_tiff_is_refused(volume, tmp_path):
    tiff = write_tiff_stack(volume, tmp_path / "scan.tif")
    data = tiff.read_bytes()
    tiff.write_bytes(data[: len(data) // 3])
    with pytest.raises(ImageError, match="scan.tif"):
        read_tiff_stack(tiff)


@pytest.mark.parametrize("kept", [10.5 / 32, 0.5, 0.999, 1.0 - 1e-6])
def test_a_stack_cut_anywhere_is_refused_not_read_short(kept, tmp_path, rng):
    """OpenCV alone reads the pages before the cut as a shorter volume (10 of 32)."""
    volume = rng.integers(0, 65535, size=(32, 20, 24), dtype=np.uint16)
    tiff = write_tiff_stack(volume, tmp_path / "scan.tif")
    np.testing.assert_array_equal(read_tiff_stack(tiff), volume)
    data = tiff.read_bytes()
    tiff.write_bytes(data[: int(len(data) * kept)])
    with pytest.raises(ImageError, match=r"scan\.tif: truncated TIFF"):
        read_tiff_stack(tiff)


def test_a_folder_and_a_file_are_told_apart(tmp_path, rng):
    (tmp_path / "scan.tif").mkdir()
    with pytest.raises(ImageError, match="scan.tif: is a folder"):
        read_volume("tiff", tmp_path / "scan.tif")
    with pytest.raises(ImageError, match="scan.tif: is a folder"):
        read_volume("raw", tmp_path / "scan.tif", raw_shape=(2, 2, 2))
    stack = write_tiff_stack(rng.integers(0, 255, (3, 4, 4), dtype=np.uint8), tmp_path / "s.tif")
    with pytest.raises(ImageError, match="s.tif: is a file"):
        read_volume("slices", stack)


def test_two_dimensional_image_is_refused(tmp_path, rng):
    import cv2

    cv2.imwrite(str(tmp_path / "flat.tif"), rng.integers(0, 255, (8, 8), dtype=np.uint8))
    with pytest.raises(ImageError, match="3-D"):
        read_tiff_stack(tmp_path / "flat.tif")


def test_all_black_volume_is_refused(tmp_path):
    black = np.zeros((4, 6, 6), dtype=np.uint16)
    black.tofile(tmp_path / "black.raw")
    with pytest.raises(ImageError, match="uniform"):
        read_raw(tmp_path / "black.raw", (4, 6, 6))


def test_raw_of_the_wrong_size_is_refused(tmp_path):
    np.arange(100, dtype=np.uint16).tofile(tmp_path / "short.raw")
    with pytest.raises(ImageError, match="needs 400"):
        read_raw(tmp_path / "short.raw", (2, 10, 10))


def test_missing_file_is_named(tmp_path):
    with pytest.raises(ImageError, match="nowhere.tif: no such file"):
        read_volume("tiff", tmp_path / "nowhere.tif")


def test_colour_slices_are_refused(tmp_path, rng):
    import cv2

    folder = tmp_path / "rgb"
    folder.mkdir()
    for index in range(3):
        cv2.imwrite(str(folder / f"s{index}.png"), rng.integers(0, 255, (6, 6, 3), dtype=np.uint8))
    with pytest.raises(ImageError, match="single-channel"):
        read_slice_folder(folder)
