"""Readers and writers of greyscale CT volumes.

Every reader returns a 3-D array ordered ``(z, y, x)`` with the file's own integer
dtype (8 or 16 bit), so that a multi-page TIFF, a folder of slices, a raw dump and a
netCDF file of the same scan give identical arrays.
"""

from __future__ import annotations

import mmap
import os
import re
import struct
from functools import partial
from pathlib import Path
from typing import Any

import cv2
import dask.array as da
import numpy as np
import numpy.typing as npt
import xarray as xr
from dask.base import tokenize

from shared.errors import ImageError
from shared.io import atomic_write

__all__ = [
    "ImageError",
    "open_volume",
    "open_tiff_stack",
    "open_slice_folder",
    "open_raw",
    "open_netcdf_volume",
    "in_slabs",
    "read_volume",
    "read_tiff_stack",
    "read_slice_folder",
    "slice_files",
    "read_raw",
    "read_netcdf_volume",
    "write_tiff_stack",
    "write_slice_folder",
]

_SLICE_SUFFIXES = (".tif", ".tiff", ".png")
DEFAULT_CHUNK_BYTES = 64 << 20
"""Greyscale bytes per chunk when the caller gives none (``imaging.chunk_mb``)."""
_SUPPORTED_DTYPES = (np.uint8, np.uint16)


def _check_volume(volume: np.ndarray, source: str | Path) -> np.ndarray:
    if volume.ndim != 3:
        raise ImageError(f"{source}: expected a 3-D volume, got shape {volume.shape}")
    _check_dtype(volume.dtype, source)
    if min(volume.shape) < 2:
        raise ImageError(f"{source}: volume of shape {volume.shape} is not 3-D (a side < 2)")
    if volume.max() == volume.min():
        raise ImageError(f"{source}: the volume is uniform (every voxel is {volume.min()})")
    return volume


def _check_dtype(dtype: np.dtype, source: str | Path) -> None:
    if np.dtype(dtype).type not in _SUPPORTED_DTYPES:
        raise ImageError(f"{source}: expected 8- or 16-bit greyscale, got dtype {dtype}")


def _slices_per_chunk(shape: tuple[int, ...], dtype: np.dtype, chunk_bytes: int) -> int:
    """Whole slices per chunk: about ``chunk_bytes`` of greyscale, at least one."""
    return max(1, int(chunk_bytes // (int(np.prod(shape)) * np.dtype(dtype).itemsize)))


def _slabs(read: Any, n_slices: int, shape: tuple[int, int], dtype: np.dtype,
           chunk_bytes: int) -> Any:
    """A dask array of ``n_slices`` slices of ``shape`` whose chunks are slabs of about
    ``chunk_bytes``, each made by ``read(z0, count)`` when it is computed.

    One blockwise layer (not a concatenation of one layer per slab): taking a slab out of
    it, as each pass over the scan does, costs the same whatever the number of slabs."""
    step = _slices_per_chunk(shape, dtype, chunk_bytes)
    counts = tuple(min(step, n_slices - z0) for z0 in range(0, n_slices, step))
    return da.map_blocks(_read_block, read=read, chunks=(counts, (shape[0],), (shape[1],)),
                         dtype=dtype, meta=np.empty((0, 0, 0), dtype=dtype),
                         name="slabs-" + tokenize(read, n_slices, shape, dtype, step))


def _read_block(read: Any, block_info: dict | None = None) -> np.ndarray:
    """The slab of a :func:`_slabs` chunk."""
    assert block_info is not None  # dask passes it to a function that names it
    (z0, z1), _, _ = block_info[None]["array-location"]
    return read(z0, z1 - z0)


def _same_page(page: np.ndarray, shape: tuple[int, int], dtype: np.dtype, source: Path,
               what: str) -> np.ndarray:
    """A greyscale page of the stack's shape and type, else an error naming the source."""
    _as_grey_page(page, source)
    if page.shape != shape or page.dtype != dtype:
        raise ImageError(f"{source}: {what} have different shapes or types "
                         f"({shape} {dtype} and {page.shape} {page.dtype})")
    return page


def _require_file(path: Path) -> None:
    if path.is_dir():
        raise ImageError(f"{path}: is a folder, expected a file (use source: slices for a "
                         "folder of 2-D slices)")
    if not path.is_file():
        raise ImageError(f"{path}: no such file")


# TIFF field types -> item size in bytes; tags locating a page's pixels (offsets, counts)
_TYPE_SIZES = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 6: 1, 7: 1, 8: 2, 9: 4, 10: 8, 11: 4, 12: 8,
               13: 4, 16: 8, 17: 8, 18: 8}
_INTEGER_TYPES = {3: "H", 4: "I", 13: "I", 16: "Q"}
_DATA_TAGS = ((273, 279), (324, 325))  # strips, tiles


_SAMPLE_FORMATS = {1: "uint", 2: "int", 3: "float"}
"""TIFF SampleFormat (tag 339) codes: unsigned and signed integers, IEEE floats."""
_MAX_PIXELS = 1 << 30
_MAX_SIDE = 1 << 20
"""OpenCV's default limits on a page (CV_IO_MAX_IMAGE_PIXELS, CV_IO_MAX_IMAGE_WIDTH and
_HEIGHT; the environment variable OPENCV_IO_MAX_IMAGE_PIXELS raises the first)."""


def _tiff_problem(path: Path) -> str | None:
    """What keeps a TIFF from being read as a greyscale stack, from its header alone.

    Walks the chain of page directories (IFDs) against the file size: what lies beyond
    the end of the file (the first such page directory, field or pixel data; OpenCV,
    through libtiff, silently stops at the first page it cannot read, so a cut-off stack
    would read as a shorter one). Then the first page's declared size against OpenCV's
    limits and its pixel type against the 8- and 16-bit unsigned greyscale we read (OpenCV
    reports either only as an unreadable file, or raises). None if nothing is wrong.
    """
    size = path.stat().st_size
    if size < 8:
        return None  # not a TIFF header: OpenCV's own error applies
    with open(path, "rb") as handle, mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ) as data:
        truncation, first = _ifd_chain_problem(data, size)
    if truncation is not None:
        return f"truncated TIFF: {truncation}"
    width, height = first.get(256, (0,))[0], first.get(257, (0,))[0]
    limit = int(os.environ.get("OPENCV_IO_MAX_IMAGE_PIXELS", _MAX_PIXELS))
    if width * height > limit or max(width, height) > _MAX_SIDE:
        return (f"its pages are {width} x {height} pixels, beyond what OpenCV reads ({limit} "
                f"pixels and {_MAX_SIDE} per side; OPENCV_IO_MAX_IMAGE_PIXELS raises the first)")
    bits = "/".join(map(str, sorted(set(first.get(258, (1,))))))
    kind = _SAMPLE_FORMATS.get(first.get(339, (1,))[0], "unknown")
    if f"{kind}{bits}" not in ("uint8", "uint16"):
        return (f"its pixels are {kind}{bits} (TIFF BitsPerSample and SampleFormat); claychain "
                "reads 8- or 16-bit unsigned greyscale: convert the scan to uint16")
    return None


def _ifd_chain_problem(data: mmap.mmap, size: int) -> tuple[str | None, dict[int, tuple[int, ...]]]:
    """The first part of a (Big)TIFF's page chain beyond ``size`` bytes (or None), and the
    integer fields of its first page (empty for no TIFF)."""
    if data[:2] not in (b"II", b"MM"):
        return None, {}
    order = "<" if data[:2] == b"II" else ">"
    magic = struct.unpack_from(order + "H", data, 2)[0]
    if magic == 42:
        word, count_word, entry_size = "I", "H", 12
        offset = struct.unpack_from(order + "I", data, 4)[0]
    elif magic == 43 and size >= 16:  # BigTIFF
        word, count_word, entry_size = "Q", "Q", 20
        offset = struct.unpack_from(order + "Q", data, 8)[0]
    else:
        return None, {}
    word_size, count_size = struct.calcsize(word), struct.calcsize(count_word)
    seen: set[int] = set()
    page = 0
    first: dict[int, tuple[int, ...]] = {}
    while offset != 0:
        page += 1
        if offset in seen:
            return f"page {page} repeats an earlier page directory (corrupt file)", first
        seen.add(offset)
        if offset + count_size > size:
            return f"page {page} starts at byte {offset}, beyond the file's {size} bytes", first
        n_entries = struct.unpack_from(order + count_word, data, offset)[0]
        end = offset + count_size + n_entries * entry_size + word_size
        if end > size:
            return f"the directory of page {page} runs past the file's {size} bytes", first
        fields: dict[int, tuple[int, ...]] = {}
        for k in range(n_entries):
            at = offset + count_size + k * entry_size
            tag, kind = struct.unpack_from(order + "HH", data, at)
            count = struct.unpack_from(order + word, data, at + 4)[0]
            value_at = at + 4 + word_size
            if count * _TYPE_SIZES.get(kind, 1) > word_size:
                value_at = struct.unpack_from(order + word, data, value_at)[0]
                if value_at + count * _TYPE_SIZES.get(kind, 1) > size:
                    return f"field {tag} of page {page} lies beyond the file's {size} bytes", first
            if kind in _INTEGER_TYPES:
                fields[tag] = struct.unpack_from(f"{order}{count}{_INTEGER_TYPES[kind]}",
                                                 data, value_at)
        for offsets_tag, counts_tag in _DATA_TAGS:
            if fields.get(offsets_tag) and fields.get(counts_tag):
                stop = max(o + c for o, c in zip(fields[offsets_tag], fields[counts_tag], strict=True))
                if stop > size:
                    return (f"the pixels of page {page} end at byte {stop}, beyond the file's "
                            f"{size} bytes"), first
        first = first or fields
        offset = struct.unpack_from(order + word, data, end - word_size)[0]
    return None, first


def _as_grey_page(page: np.ndarray, source: str | Path) -> np.ndarray:
    if page.ndim != 2:
        raise ImageError(
            f"{source}: a slice has shape {page.shape}; expected single-channel greyscale"
        )
    return page


def _tiff_pages(path: Path, shape: tuple[int, int], dtype: np.dtype, start: int,
                count: int) -> np.ndarray:
    """Pages ``[start, start + count)`` of a multi-page TIFF, checked against the first's
    shape and dtype."""
    ok, pages = cv2.imreadmulti(str(path), start, count, flags=cv2.IMREAD_UNCHANGED)
    if not ok or len(pages) != count:
        raise ImageError(f"{path}: pages {start} to {start + count - 1} are not readable "
                         "(truncated or corrupt?)")
    return np.stack([_same_page(page, shape, dtype, path, "pages") for page in pages])


def open_tiff_stack(path: str | Path, chunk_bytes: int = DEFAULT_CHUNK_BYTES) -> Any:
    """A multi-page greyscale TIFF as a dask array ``(z, y, x)``, read page range by page
    range; the page chain is checked against the file size first (truncation).

    ``cv2.IMREAD_UNCHANGED`` keeps the bit depth; without it OpenCV silently converts
    pages to 8-bit three-channel images.
    """
    path = Path(path)
    _require_file(path)
    problem = _tiff_problem(path)
    if problem is not None:
        raise ImageError(f"{path}: {problem}")
    try:
        count = cv2.imcount(str(path))
        ok, first = cv2.imreadmulti(str(path), 0, 1, flags=cv2.IMREAD_UNCHANGED)
    except cv2.error as error:
        raise ImageError(f"{path}: OpenCV cannot read it ({str(error).strip().splitlines()[-1]})") from error
    if count < 1 or not ok or not first:
        raise ImageError(f"{path}: not a readable TIFF stack (truncated or corrupt?)")
    page = _as_grey_page(first[0], path)
    if count == 1:
        raise ImageError(f"{path}: a single page of shape {page.shape}; expected a 3-D stack")
    _check_dtype(page.dtype, path)
    return _slabs(partial(_tiff_pages, path, page.shape, page.dtype), count, page.shape,
                  page.dtype, chunk_bytes)


def read_tiff_stack(path: str | Path) -> npt.NDArray[np.unsignedinteger]:
    """Read a multi-page greyscale TIFF into a ``(z, y, x)`` array (:func:`open_tiff_stack`)."""
    return _check_volume(np.asarray(open_tiff_stack(path)), path)


def _natural_key(name: str) -> list[int | str]:
    return [int(tok) if tok.isdigit() else tok for tok in re.split(r"(\d+)", name)]


def slice_files(folder: str | Path) -> list[Path]:
    """The slice files of a folder (TIFF or PNG), in natural name order (``2`` before ``10``).

    Raises
    ------
    ImageError
        If the path is a file, missing, or a folder without slice files.
    """
    folder = Path(folder)
    if folder.is_file():
        raise ImageError(f"{folder}: is a file, expected a folder of 2-D slices (use source: "
                         "tiff for a multi-page file)")
    if not folder.is_dir():
        raise ImageError(f"{folder}: no such folder")
    files = sorted(
        (f for f in folder.iterdir() if f.suffix.lower() in _SLICE_SUFFIXES),
        key=lambda f: _natural_key(f.name),
    )
    if not files:
        raise ImageError(f"{folder}: no slice files ({', '.join(_SLICE_SUFFIXES)})")
    return files


def _slice_pages(files: list[Path], shape: tuple[int, int], dtype: np.dtype, start: int,
                 count: int) -> np.ndarray:
    """Slices ``[start, start + count)`` of a folder's files, checked against the first's
    shape and dtype."""
    pages = []
    for file in files[start:start + count]:
        page = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
        if page is None:
            raise ImageError(f"{file}: not a readable image")
        pages.append(_same_page(page, shape, dtype, file, "slices"))
    return np.stack(pages)


def open_slice_folder(folder: str | Path, chunk_bytes: int = DEFAULT_CHUNK_BYTES) -> Any:
    """A folder of 2-D greyscale slices (TIFF or PNG, natural name order) as a dask array
    ``(z, y, x)``, read a few files at a time."""
    files = slice_files(folder)
    problem = _tiff_problem(files[0]) if files[0].suffix.lower() in (".tif", ".tiff") else None
    if problem is not None:
        raise ImageError(f"{files[0]}: {problem}")
    first = cv2.imread(str(files[0]), cv2.IMREAD_UNCHANGED)
    if first is None:
        raise ImageError(f"{files[0]}: not a readable image")
    _as_grey_page(first, files[0])
    _check_dtype(first.dtype, Path(folder))
    return _slabs(partial(_slice_pages, files, first.shape, first.dtype), len(files),
                  first.shape, first.dtype, chunk_bytes)


def read_slice_folder(folder: str | Path) -> npt.NDArray[np.unsignedinteger]:
    """Read a folder of 2-D greyscale slices (:func:`open_slice_folder`)."""
    return _check_volume(np.asarray(open_slice_folder(folder)), folder)


def open_raw(
    path: str | Path,
    shape: tuple[int, int, int],
    dtype: str = "uint16",
    byte_order: str = "little",
    chunk_bytes: int = DEFAULT_CHUNK_BYTES,
) -> Any:
    """A headerless binary volume stored in C order ``(z, y, x)``, as a dask array whose
    chunks read their own slices of the file.

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
    chunk_bytes
        Bytes of greyscale per chunk.
    """
    path = Path(path)
    _require_file(path)
    if len(shape) != 3:
        raise ImageError(f"{path}: raw shape must have 3 entries (z, y, x), got {list(shape)}")
    file_dtype = np.dtype(dtype).newbyteorder("<" if byte_order == "little" else ">")
    expected = int(np.prod(shape)) * file_dtype.itemsize
    actual = path.stat().st_size
    if actual != expected:
        raise ImageError(
            f"{path}: {actual} bytes, but shape {list(shape)} of {dtype} needs {expected}"
        )
    slice_shape = (shape[1], shape[2])
    return _slabs(partial(_raw_slices, path, file_dtype, slice_shape), shape[0], slice_shape,
                  np.dtype(dtype), chunk_bytes)


def _raw_slices(path: Path, file_dtype: np.dtype, shape: tuple[int, int], z0: int,
                count: int) -> np.ndarray:
    """Slices ``[z0, z0 + count)`` of a raw volume, in the machine's byte order."""
    per_slice = int(np.prod(shape))
    values = np.fromfile(path, dtype=file_dtype, count=count * per_slice,
                         offset=z0 * per_slice * file_dtype.itemsize)
    return values.reshape(count, *shape).astype(file_dtype.newbyteorder("="), copy=False)


def read_raw(
    path: str | Path, shape: tuple[int, int, int], dtype: str = "uint16", byte_order: str = "little"
) -> npt.NDArray[np.unsignedinteger]:
    """Read a headerless binary volume (:func:`open_raw`)."""
    return _check_volume(np.asarray(open_raw(path, shape, dtype, byte_order)), path)


def open_netcdf_volume(path: str | Path, variable: str = "grey",
                       chunk_bytes: int = DEFAULT_CHUNK_BYTES) -> Any:
    """The greyscale variable of a netCDF file written by this project, as a dask array
    read through xarray's chunks."""
    path = Path(path)
    _require_file(path)
    try:
        ds = xr.open_dataset(path, engine="netcdf4", chunks={})
    except (OSError, ValueError) as err:
        reason = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise ImageError(f"{path}: not a readable netCDF file ({reason})") from err
    if variable not in ds:
        raise ImageError(f"{path}: no variable {variable!r}")
    grey = ds[variable]
    if grey.ndim != 3:
        raise ImageError(f"{path}: expected a 3-D volume, got shape {grey.shape}")
    _check_dtype(grey.dtype, path)
    step = _slices_per_chunk(grey.shape[1:], grey.dtype, chunk_bytes)
    return grey.data.rechunk((step, *grey.shape[1:]))


def read_netcdf_volume(path: str | Path, variable: str = "grey") -> npt.NDArray[np.unsignedinteger]:
    """Read the greyscale variable of a netCDF file (:func:`open_netcdf_volume`)."""
    return _check_volume(np.asarray(open_netcdf_volume(path, variable)), path)


def open_volume(
    source: str,
    path: str | Path,
    *,
    raw_shape: tuple[int, int, int] | None = None,
    raw_dtype: str = "uint16",
    raw_byte_order: str = "little",
    chunk_bytes: int = DEFAULT_CHUNK_BYTES,
) -> Any:
    """A greyscale volume of the given source kind as a dask array, chunked in slabs of
    whole slices of about ``chunk_bytes``; nothing but headers is read yet.

    Parameters
    ----------
    source
        ``"tiff"`` (multi-page file), ``"slices"`` (folder), ``"raw"`` or ``"netcdf"``.
    path
        File or folder path.
    raw_shape, raw_dtype, raw_byte_order
        Layout of a raw file.
    chunk_bytes
        Bytes of greyscale per chunk.

    Raises
    ------
    ImageError
        If the file is missing, truncated or not an 8/16-bit greyscale stack; slices of
        another shape or type are found when their chunk is read.
    """
    if source == "tiff":
        return open_tiff_stack(path, chunk_bytes)
    if source == "slices":
        return open_slice_folder(path, chunk_bytes)
    if source == "raw":
        if raw_shape is None:
            raise ImageError(f"{path}: a raw volume needs its shape (z, y, x)")
        return open_raw(path, raw_shape, raw_dtype, raw_byte_order, chunk_bytes)
    if source == "netcdf":
        return open_netcdf_volume(path, chunk_bytes=chunk_bytes)
    raise ImageError(f"{path}: unknown image source {source!r}")


def in_slabs(volume: Any, chunk_bytes: int = DEFAULT_CHUNK_BYTES, source: str | Path = "scan") -> Any:
    """A greyscale volume held in memory (or a dask array) as a dask array chunked, like
    :func:`open_volume`'s, in slabs of whole slices of about ``chunk_bytes``.

    A dask array whose chunks are already whole slices is returned as it is.

    Raises
    ------
    ImageError
        Naming ``source``, if the volume is not 3-D or not 8/16-bit greyscale.
    """
    if volume.ndim != 3:
        raise ImageError(f"{source}: expected a 3-D volume, got shape {volume.shape}")
    _check_dtype(volume.dtype, source)
    if isinstance(volume, da.Array):
        whole_slices = len(volume.chunks[1]) == 1 and len(volume.chunks[2]) == 1
        return volume if whole_slices else volume.rechunk((volume.chunks[0][0], -1, -1))
    volume = np.asarray(volume)
    step = _slices_per_chunk(volume.shape[1:], volume.dtype, chunk_bytes)
    return da.from_array(volume, chunks=(step, -1, -1))


def read_volume(source: str, path: str | Path, **layout: Any) -> npt.NDArray[np.unsignedinteger]:
    """Read a whole greyscale volume into memory (:func:`open_volume`), checked."""
    return _check_volume(np.asarray(open_volume(source, path, **layout)), path)


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
