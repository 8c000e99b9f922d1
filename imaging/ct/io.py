"""Readers and writers of greyscale CT volumes.

Every reader returns a 3-D array ordered ``(z, y, x)`` with the file's own integer
dtype (8 or 16 bit), so that a multi-page TIFF, a folder of slices, a raw dump and a
netCDF file of the same scan give identical arrays.
"""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import xarray as xr

from shared.io import atomic_write

__all__ = [
    "ImageError",
    "read_volume",
    "read_tiff_stack",
    "read_slice_folder",
    "read_raw",
    "read_netcdf_volume",
    "write_tiff_stack",
    "write_slice_folder",
]

_SLICE_SUFFIXES = (".tif", ".tiff", ".png")
_SUPPORTED_DTYPES = (np.uint8, np.uint16)


class ImageError(ValueError):
    """An image that is missing, unreadable, or of the wrong shape or type."""


def _check_volume(volume: np.ndarray, source: str | Path) -> np.ndarray:
    if volume.ndim != 3:
        raise ImageError(f"{source}: expected a 3-D volume, got shape {volume.shape}")
    if volume.dtype.type not in _SUPPORTED_DTYPES:
        raise ImageError(f"{source}: expected 8- or 16-bit greyscale, got dtype {volume.dtype}")
    if min(volume.shape) < 2:
        raise ImageError(f"{source}: volume of shape {volume.shape} is not 3-D (a side < 2)")
    if volume.max() == volume.min():
        raise ImageError(f"{source}: the volume is uniform (every voxel is {volume.min()})")
    return volume


def _as_grey_page(page: np.ndarray, source: str | Path) -> np.ndarray:
    if page.ndim != 2:
        raise ImageError(
            f"{source}: a slice has shape {page.shape}; expected single-channel greyscale"
        )
    return page


def read_tiff_stack(path: str | Path) -> npt.NDArray[np.unsignedinteger]:
    """Read a multi-page greyscale TIFF into a ``(z, y, x)`` array.

    ``cv2.IMREAD_UNCHANGED`` keeps the bit depth; without it OpenCV silently converts
    pages to 8-bit three-channel images.
    """
    path = Path(path)
    if not path.is_file():
        raise ImageError(f"{path}: no such file")
    ok, pages = cv2.imreadmulti(str(path), flags=cv2.IMREAD_UNCHANGED)
    if not ok or len(pages) == 0:
        raise ImageError(f"{path}: not a readable TIFF stack (truncated or corrupt?)")
    shapes = {p.shape for p in pages}
    if len(shapes) != 1:
        raise ImageError(f"{path}: pages have different shapes {sorted(shapes)}")
    if len(pages) == 1:
        raise ImageError(f"{path}: a single page of shape {pages[0].shape}; expected a 3-D stack")
    return _check_volume(np.stack([_as_grey_page(p, path) for p in pages]), path)


def _natural_key(name: str) -> list[int | str]:
    return [int(tok) if tok.isdigit() else tok for tok in re.split(r"(\d+)", name)]


def read_slice_folder(folder: str | Path) -> npt.NDArray[np.unsignedinteger]:
    """Read a folder of 2-D greyscale slices (TIFF or PNG), ordered by natural name sort."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ImageError(f"{folder}: no such folder")
    files = sorted(
        (f for f in folder.iterdir() if f.suffix.lower() in _SLICE_SUFFIXES),
        key=lambda f: _natural_key(f.name),
    )
    if not files:
        raise ImageError(f"{folder}: no slice files ({', '.join(_SLICE_SUFFIXES)})")
    slices = []
    for file in files:
        page = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
        if page is None:
            raise ImageError(f"{file}: not a readable image")
        slices.append(_as_grey_page(page, file))
    shapes = {s.shape for s in slices}
    if len(shapes) != 1:
        raise ImageError(f"{folder}: slices have different shapes {sorted(shapes)}")
    return _check_volume(np.stack(slices), folder)


def read_raw(
    path: str | Path, shape: tuple[int, int, int], dtype: str = "uint16", byte_order: str = "little"
) -> npt.NDArray[np.unsignedinteger]:
    """Read a headerless binary volume stored in C order ``(z, y, x)``.

    Parameters
    ----------
    path
        File path.
    shape
        ``(nz, ny, nx)`` voxel counts.
    dtype
        ``"uint8"`` or ``"uint16"``.
    byte_order
        ``"little"`` or ``"big"``.
    """
    path = Path(path)
    if not path.is_file():
        raise ImageError(f"{path}: no such file")
    if len(shape) != 3:
        raise ImageError(f"{path}: raw shape must have 3 entries (z, y, x), got {list(shape)}")
    file_dtype = np.dtype(dtype).newbyteorder("<" if byte_order == "little" else ">")
    expected = int(np.prod(shape)) * file_dtype.itemsize
    actual = path.stat().st_size
    if actual != expected:
        raise ImageError(
            f"{path}: {actual} bytes, but shape {list(shape)} of {dtype} needs {expected}"
        )
    volume = np.fromfile(path, dtype=file_dtype).reshape(shape)
    return _check_volume(volume.astype(np.dtype(dtype), copy=False), path)


def read_netcdf_volume(path: str | Path, variable: str = "grey") -> npt.NDArray[np.unsignedinteger]:
    """Read the greyscale variable of a netCDF file written by this project."""
    path = Path(path)
    if not path.is_file():
        raise ImageError(f"{path}: no such file")
    try:
        with xr.open_dataset(path) as ds:
            if variable not in ds:
                raise ImageError(f"{path}: no variable {variable!r}")
            volume = ds[variable].values
    except (OSError, ValueError) as err:
        if isinstance(err, ImageError):
            raise
        raise ImageError(f"{path}: not a readable netCDF file ({err})") from err
    return _check_volume(volume, path)


def read_volume(
    source: str,
    path: str | Path,
    *,
    raw_shape: tuple[int, int, int] | None = None,
    raw_dtype: str = "uint16",
    raw_byte_order: str = "little",
) -> npt.NDArray[np.unsignedinteger]:
    """Read a greyscale volume of the given source kind.

    Parameters
    ----------
    source
        ``"tiff"`` (multi-page file), ``"slices"`` (folder), ``"raw"`` or ``"netcdf"``.
    path
        File or folder path.
    raw_shape, raw_dtype, raw_byte_order
        Layout of a raw file.
    """
    if source == "tiff":
        return read_tiff_stack(path)
    if source == "slices":
        return read_slice_folder(path)
    if source == "raw":
        if raw_shape is None:
            raise ImageError(f"{path}: a raw volume needs its shape (z, y, x)")
        return read_raw(path, raw_shape, raw_dtype, raw_byte_order)
    if source == "netcdf":
        return read_netcdf_volume(path)
    raise ImageError(f"{path}: unknown image source {source!r}")


def write_tiff_stack(volume: np.ndarray, path: str | Path) -> Path:
    """Write a ``(z, y, x)`` 8/16-bit volume as one multi-page TIFF, atomically."""
    path = Path(path)
    _check_volume(volume, path)

    def write(tmp: str) -> None:
        if not cv2.imwritemulti(tmp, list(volume)):
            raise ImageError(f"{path}: OpenCV could not write the TIFF stack")

    return atomic_write(path, write)


def write_slice_folder(volume: np.ndarray, folder: str | Path, stem: str = "slice") -> Path:
    """Write a volume as one TIFF per z slice, named ``<stem>_<index>.tif``."""
    folder = Path(folder)
    _check_volume(volume, folder)
    folder.mkdir(parents=True, exist_ok=True)
    width = len(str(volume.shape[0]))
    for index, page in enumerate(volume):
        if not cv2.imwrite(str(folder / f"{stem}_{index:0{width}d}.tif"), page):
            raise ImageError(f"{folder}: OpenCV could not write slice {index}")
    return folder
