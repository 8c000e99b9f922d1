"""The CT stage's results as the xarray datasets of the data contracts (docs/design.md §2)."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
import xarray as xr

from imaging.ct.calibration import Calibration
from imaging.ct.grid import BlockGrid
from imaging.morphology import ChordResult, RevResult

__all__ = ["image_dataset", "porosity_dataset", "rev_dataset", "voxel_coordinates"]


def _coord(values: npt.ArrayLike, name: str, units: str, long_name: str) -> xr.Variable:
    return xr.Variable((name,), np.asarray(values, dtype=np.float64), {"units": units, "long_name": long_name})


def voxel_coordinates(shape: tuple[int, ...], voxel_size: float) -> dict[str, xr.Variable]:
    """Voxel-centre coordinates ``z, y, x`` [m], voxel ``i`` spanning ``[i, i+1) * voxel_size``."""
    return {
        axis: _coord((np.arange(n) + 0.5) * voxel_size, axis, "m", f"{axis} position of voxel centre")
        for axis, n in zip("zyx", shape, strict=True)
    }


def image_dataset(
    specimen: Any,
    voxel_size: float,
    preview: npt.NDArray[np.unsignedinteger],
    preview_step: int,
    grey: Any | None = None,
) -> xr.Dataset:
    """The specimen mask, a strided preview of the scan and, if given, the scan itself,
    with coordinates in metres (numpy or lazy dask arrays: written slab by slab)."""
    coords = voxel_coordinates(tuple(specimen.shape), voxel_size)
    preview_coords = {
        f"{axis}_preview": _coord(coords[axis].values[::preview_step], f"{axis}_preview", "m",
                                  f"{axis} position of preview voxel centre")
        for axis in "zyx"
    }
    data = {
        "specimen": (("z", "y", "x"), specimen,
                     {"units": "1", "long_name": "specimen mask (1 inside, 0 outside)"}),
        "grey_preview": (("z_preview", "y_preview", "x_preview"), preview,
                         {"units": "1", "long_name": f"CT grey value, one voxel in {preview_step} along each axis"}),
    }
    if grey is not None:
        data["grey"] = (("z", "y", "x"), grey, {"units": "1", "long_name": "CT grey value"})
    ds = xr.Dataset(data, coords={**coords, **preview_coords},
                    attrs={"voxel_size": voxel_size, "voxel_size_units": "m",
                           "preview_step": preview_step, "scan_stored": int(grey is not None)})
    # one compressed chunk per slice: a slab writes whole chunks (no read-modify-write)
    for name in ("specimen", "grey"):
        if name in ds:
            ds[name].encoding["chunksizes"] = (1, *ds[name].shape[1:])
    return ds


def porosity_dataset(
    grid: BlockGrid,
    calibration: Calibration,
    porosity_bounds: tuple[float, float],
    voxel_size: float,
) -> xr.Dataset:
    """Block-averaged density and porosity, with calibration anchors as attributes.

    Porosity is clamped to ``porosity_bounds``; the fraction of clamped blocks is recorded.
    """
    finite = np.isfinite(grid.porosity)
    low, high = porosity_bounds
    clamped = finite & ((grid.porosity < low) | (grid.porosity > high))
    porosity = np.where(finite, np.clip(grid.porosity, low, high), np.nan)
    coords = {
        axis: _coord(values, axis, "m", f"{axis} position of grid block centre")
        for axis, values in zip("zyx", (grid.z, grid.y, grid.x), strict=True)
    }
    dims = ("z", "y", "x")
    return xr.Dataset(
        {
            "porosity": (dims, porosity, {
                "units": "1",
                "long_name": "porosity (block average; NaN outside the specimen)",
                "valid_min": low,
                "valid_max": high,
            }),
            "density": (dims, grid.density, {
                "units": "kg m-3",
                "long_name": "dry density (block average of specimen voxels)",
            }),
            "specimen_fraction": (dims, grid.specimen_fraction, {
                "units": "1",
                "long_name": "fraction of the block's voxels inside the specimen",
            }),
        },
        coords=coords,
        attrs={
            "voxel_size": voxel_size,
            "grid_spacing": grid.block[0] * voxel_size,
            "block_voxels": grid.block[0],
            "grey_air": calibration.grey_air,
            "grey_muscovite": calibration.grey_muscovite,
            "air_density": calibration.air_density,
            "muscovite_density": calibration.muscovite_density,
            "dry_density": calibration.dry_density,
            "mean_porosity_anchor": calibration.mean_porosity,
            "clamped_fraction": float(clamped.sum() / max(finite.sum(), 1)),
            "porosity_mean": float(np.nanmean(porosity)),
        },
    )


def rev_dataset(
    rev: RevResult, calibrated: RevResult, chords: ChordResult, voxel_size: float
) -> xr.Dataset:
    """REV statistics and chord-length distributions (docs/design.md §2, ``results/rev``).

    ``rev`` is the analysis of the binary pore image (the paper's porosity and interface),
    ``calibrated`` that of the calibrated voxel porosity (``calibrated_porosity_*``).
    """
    window = _coord(rev.window * voxel_size, "window", "m", "random window edge")
    centred = _coord(rev.window_centred * voxel_size, "window_centred", "m", "centred window edge")
    scalar = {"units": "m"}
    binary = "binary image's porosity (pore fraction)"
    data = {
        "porosity_mean": ("window", rev.porosity_mean, {"units": "1", "long_name": f"mean {binary} over random windows"}),
        "porosity_std": ("window", rev.porosity_std, {"units": "1", "long_name": f"std of the {binary} over random windows"}),
        "porosity_centred": ("window_centred", rev.porosity_centred, {"units": "1", "long_name": f"{binary} of the centred window"}),
        "interface_mean": ("window", rev.interface_mean, {"units": "m-1", "long_name": "mean solid-pore interface density over random windows"}),
        "interface_std": ("window", rev.interface_std, {"units": "m-1", "long_name": "std of interface density over random windows"}),
        "interface_centred": ("window_centred", rev.interface_centred, {"units": "m-1", "long_name": "interface density of the centred window"}),
        "porosity_total": ((), rev.porosity_total, {"units": "1", "long_name": f"{binary}, whole analysed cube"}),
        "interface_total": ((), rev.interface_total, {"units": "m-1", "long_name": "interface density of the analysed cube"}),
        "w_rev_porosity": ((), rev.w_rev_porosity, {**scalar, "long_name": "REV edge for porosity (relative std criterion)"}),
        "w_rev_interface": ((), rev.w_rev_interface, {**scalar, "long_name": "REV edge for interface density (relative std criterion)"}),
        "w_rev_porosity_centred": ((), rev.w_rev_porosity_centred, {**scalar, "long_name": "REV edge for porosity (centred window criterion, Ferrage 2015 Sec. V C)"}),
        "w_rev_interface_centred": ((), rev.w_rev_interface_centred, {**scalar, "long_name": "REV edge for interface density (centred window criterion)"}),
        "calibrated_porosity_mean": ("window", calibrated.porosity_mean, {"units": "1", "long_name": "mean calibrated porosity over random windows"}),
        "calibrated_porosity_std": ("window", calibrated.porosity_std, {"units": "1", "long_name": "std of calibrated porosity over random windows"}),
        "calibrated_porosity_centred": ("window_centred", calibrated.porosity_centred, {"units": "1", "long_name": "calibrated porosity of the centred window"}),
        "calibrated_porosity_total": ((), calibrated.porosity_total, {"units": "1", "long_name": "calibrated porosity, whole analysed cube"}),
        "w_rev_calibrated_porosity": ((), calibrated.w_rev_porosity, {**scalar, "long_name": "REV edge for calibrated porosity (relative std criterion)"}),
        "w_rev_calibrated_porosity_centred": ((), calibrated.w_rev_porosity_centred, {**scalar, "long_name": "REV edge for calibrated porosity (centred window criterion)"}),
        "chord_pore": (("direction", "length"), chords.f_pore, {"units": "m-1", "long_name": "pore chord-length probability density f_p(r)"}),
        "chord_solid": (("direction", "length"), chords.f_solid, {"units": "m-1", "long_name": "solid chord-length probability density f_s(r)"}),
        "chord_count_pore": (("direction", "length"), chords.count_pore, {"units": "1", "long_name": "number of pore chords"}),
        "chord_count_solid": (("direction", "length"), chords.count_solid, {"units": "1", "long_name": "number of solid chords"}),
        "mean_chord_pore": ("direction", chords.mean_pore, {**scalar, "long_name": "mean pore chord length (Eq. 13)"}),
        "mean_chord_solid": ("direction", chords.mean_solid, {**scalar, "long_name": "mean solid chord length (Eq. 14)"}),
        "R_p": ((), chords.R_p, {"units": "1", "long_name": "pore chord anisotropy l_z/l_xy (Eq. 15)"}),
        "R_s": ((), chords.R_s, {"units": "1", "long_name": "solid chord anisotropy l_z/l_xy (Eq. 16)"}),
    }
    coords = {
        "window": window,
        "window_centred": centred,
        "length": _coord(chords.length, "length", "m", "chord length"),
        "direction": xr.Variable(("direction",), np.array(chords.direction), {"long_name": "lattice direction"}),
    }
    return xr.Dataset(data, coords=coords)
