"""The porosity grid of a greyscale scan: specimen mask -> calibrated density -> block
averages (Caulk 2022, Sec. 3.3.4), computed in memory, with no file read or written.

:func:`porosity_grid` takes the scan (a numpy or dask array, or a DataArray carrying its
voxel size) and :class:`~imaging.ct.settings.PorositySettings`, and returns the porosity
Dataset; :func:`scan_datasets` also returns the specimen image (mask and preview) that
the stage writes beside it (:func:`imaging.ct.run.porosity`). The scan is read slab by
slab (:mod:`imaging.ct.scan`), by whichever dask scheduler is active.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import xarray as xr

from imaging.ct.calibration import Calibration, anchors_through, histogram_peaks, histogram_quantile
from imaging.ct.datasets import image_dataset, porosity_dataset
from imaging.ct.grid import block_grid, block_size_voxels
from imaging.ct.io import ImageError, in_slabs
from imaging.ct.mask import cylinder_section, otsu_threshold
from imaging.ct.scan import (
    MaskRule,
    ScanSummary,
    anchor_histograms,
    check_memory,
    grid_sums,
    mask_array,
    summarize,
    threshold_areas,
)
from imaging.ct.settings import ONE_WORKER, PorositySettings, ScanResources, setting_keys
from shared.errors import InputError

__all__ = ["ScanDatasets", "porosity_grid", "scan_datasets", "scan_array"]

log = logging.getLogger("imaging.ct")

CLAMPED_WARNING_FRACTION = 0.1
"""A porosity grid with more of its blocks clamped to the bounds than this is warned about."""
MIN_BLOCKS_PER_AXIS = 8
"""A porosity grid with fewer blocks than this along an axis is warned about (too coarse
for the REV and chord analyses and for the micro model's porosity field)."""




class ScanDatasets(NamedTuple):
    """The two datasets of a scan (:func:`scan_datasets`).

    Attributes
    ----------
    image : xarray.Dataset
        The specimen mask (lazy, chunked like the scan), a strided preview and, with
        ``store_scan``, the scan itself (:func:`imaging.ct.datasets.image_dataset`).
    porosity : xarray.Dataset
        The porosity grid (:func:`porosity_grid`).
    """

    image: xr.Dataset
    porosity: xr.Dataset


def scan_array(scan: Any, voxel_size: float | None = None, chunk_mb: float = 64.0,
               source: str | Path = "scan") -> tuple[Any, float]:
    """A greyscale scan as a dask array of whole-slice slabs, and its voxel edge [m].

    Parameters
    ----------
    scan
        ``(z, y, x)`` 8/16-bit greys: a numpy or dask array, or an xarray DataArray whose
        attribute ``voxel_size`` [m] is used when ``voxel_size`` is not given.
    voxel_size
        Voxel edge [m].
    chunk_mb
        Greyscale per slab of an in-memory scan [MiB].
    source
        How messages name the scan.

    Raises
    ------
    ImageError
        If the scan is not a 3-D 8/16-bit volume.
    ValueError
        If the voxel size is neither given nor carried by the DataArray, or not positive.
    """
    if isinstance(scan, xr.DataArray):
        voxel_size = scan.attrs.get("voxel_size") if voxel_size is None else voxel_size
        scan = scan.data
    if voxel_size is None or not float(voxel_size) > 0:
        raise ValueError(f"{source}: the voxel size must be a positive length [m], got "
                         f"{voxel_size} (pass voxel_size, or a DataArray with attribute voxel_size)")
    return in_slabs(scan, int(chunk_mb * 2**20), source), float(voxel_size)


def scan_datasets(scan: Any, settings: PorositySettings, *, voxel_size: float | None = None,
                  resources: ScanResources = ONE_WORKER, source: str | Path = "scan"
                  ) -> ScanDatasets:
    """The specimen image and the porosity grid of a greyscale scan.

    Parameters
    ----------
    scan, voxel_size
        The scan and its voxel edge [m] (:func:`scan_array`).
    settings
        Mask, calibration and grid settings.
    resources
        Slabs read at once, slab size of an in-memory scan, memory limit.
    source
        How messages name the scan (its file, in the stage).

    Returns
    -------
    ScanDatasets
        ``(image, porosity)``; see :func:`porosity_grid` for the porosity grid.

    Raises
    ------
    ImageError
        If the scan is not an 8/16-bit greyscale volume, or is uniform.
    InputError
        If the job would exceed the memory limit, or no specimen, no valid calibration or
        no block inside the porosity bounds is found; the message names the scan and the
        config keys.
    """
    grey, voxel_size = scan_array(scan, voxel_size, resources.chunk_mb, source)
    block = block_size_voxels(settings.grid_spacing, voxel_size)
    sample, workers = settings.sample, resources.workers
    log.info("%s: %s volume %s from %s", sample, grey.dtype, grey.shape, source)
    check_memory(sample, source, grey, resources)
    summary = summarize(grey, workers)
    if summary.minimum == summary.maximum:
        raise ImageError(f"{source}: the volume is uniform (every voxel is {summary.minimum})")
    masking = _mask_rule(sample, source, grey, summary, settings.mask, voxel_size, workers)
    calibration, anchors = _calibration(sample, source, settings.calibration, settings.material,
                                        summary, lambda: anchor_histograms(grey, masking, workers))
    density_sum, counts = grid_sums(grey, masking, calibration, block, workers)
    grid = block_grid(density_sum, counts, grey.shape, calibration, block, voxel_size,
                      settings.min_specimen_fraction)
    if not np.isfinite(grid.porosity).any():
        raise InputError(
            f"{source}: no grid block lies inside the specimen; check imaging.mask and "
            "imaging.min_specimen_fraction"
        )
    bounds = tuple(settings.calibration["porosity_bounds"])
    warnings = _grid_warnings(sample, source, grid.porosity, bounds, settings.grid_spacing,
                              voxel_size, grey.shape)
    image = image_dataset(mask_array(grey, masking), voxel_size, summary.preview,
                          summary.preview_step, grey if settings.store_scan else None)
    porosity = porosity_dataset(grid, calibration, bounds, voxel_size)
    porosity.attrs.update(anchors, mask_mode=settings.mask["mode"], warnings="; ".join(warnings))
    return ScanDatasets(image, porosity)


def porosity_grid(scan: Any, settings: PorositySettings, *, voxel_size: float | None = None,
                  resources: ScanResources = ONE_WORKER, source: str | Path = "scan"
                  ) -> xr.Dataset:
    """Greyscale scan -> specimen mask -> calibrated density -> block-averaged porosity grid.

    Parameters
    ----------
    scan
        ``(z, y, x)`` 8/16-bit greys: a numpy or dask array, or an xarray DataArray with
        attribute ``voxel_size`` [m].
    settings
        Mask, calibration and grid settings.
    voxel_size
        Voxel edge [m], when ``scan`` does not carry it.
    resources
        Slabs read at once, slab size of an in-memory scan, memory limit.
    source
        How messages name the scan.

    Returns
    -------
    xarray.Dataset
        ``porosity`` [1] (clamped to the calibration's ``porosity_bounds``, NaN outside
        the specimen), ``density`` [kg m-3] and ``specimen_fraction`` [1] on the block
        centres ``z, y, x`` [m]; the calibration anchors, ``grid_spacing`` [m],
        ``porosity_mean``, ``clamped_fraction`` and ``warnings`` (voxel size, clamped
        blocks; joined by "; ", or "") as attributes.

    Raises
    ------
    ImageError, InputError
        As :func:`scan_datasets`.
    """
    return scan_datasets(scan, settings, voxel_size=voxel_size, resources=resources,
                         source=source).porosity


_NO_AIR_HINT = ("; a specimen that fills the field of view or sits in a container needs "
                "imaging.mask.mode full or cylinder and imaging.calibration.anchors "
                "histogram_peaks (or grey_air)")

BORDER_FRACTION_LIMIT = 0.5
"""A threshold mask covering more of the field's lateral border than this is taken for a
specimen that fills the field of view (the threshold then splits its own phases)."""


def _mask_rule(sample: str, source: str | Path, grey: Any, summary: ScanSummary,
               section: Mapping[str, Any], voxel_size: float, workers: int) -> MaskRule:
    """How the specimen mask is made in the configured mode, or an error naming the setting."""
    nz = int(grey.shape[0])
    if section["mode"] == "full":
        return MaskRule("full", np.ones(nz, dtype=bool))
    if section["mode"] == "cylinder":
        centre, z_range = section["cylinder_centre_m"], section["cylinder_z_m"]
        try:
            slices, disc = cylinder_section((nz, *grey.shape[1:]), voxel_size,
                                            section["cylinder_radius_m"],
                                            None if centre is None else tuple(centre),
                                            None if z_range is None else tuple(z_range))
        except ValueError as err:
            raise InputError(f"{source}: {err}; check {setting_keys(sample, 'mask')}") from err
        return MaskRule("cylinder", slices, disc=disc)
    level = section["threshold"]
    level = otsu_threshold(summary.sample) if level is None else float(level)
    areas, border, border_size = threshold_areas(grey, level, workers)
    if areas.max() == 0:
        raise InputError(f"{source}: no voxel above the threshold {level:g}: no specimen found; "
                         f"check {setting_keys(sample, 'mask')}")
    kept = areas >= section["min_slice_fraction"] * areas.max()
    touching = float(border[kept].sum() / (border_size * kept.sum()))
    if touching > BORDER_FRACTION_LIMIT:
        raise InputError(
            f"{source}: the specimen mask covers {touching:.0%} of the field's border, as if the "
            f"specimen filled the field of view (no air around it): set "
            f"{setting_keys(sample, 'mask.mode')} to full (or to cylinder with cylinder_radius_m), "
            "and the calibration anchors (calibration.anchors: histogram_peaks, or grey_air)"
        )
    return MaskRule("threshold", kept, level=level)


def _calibration(sample: str, source: str | Path, section: Mapping[str, Any],
                 material: Mapping[str, Any], summary: ScanSummary,
                 histograms: Callable[[], tuple[np.ndarray, np.ndarray]]
                 ) -> tuple[Calibration, dict[str, Any]]:
    """The calibration, and the attributes that say where its anchors come from;
    ``histograms`` gives the greys outside and inside the specimen when they are needed."""
    grey_air, grey_muscovite = section["grey_air"], section["grey_muscovite"]
    record: dict[str, Any] = {"calibration_anchors": section["anchors"]}
    try:
        if section["anchors"] == "histogram_peaks":
            peaks, prominence = histogram_peaks(summary.sample)
            log.info("%s: grey histogram peaks %s (prominence %s)", sample,
                     np.round(peaks, 1).tolist(), np.round(prominence, 3).tolist())
            densities = section["peak_densities_kg_m3"]
            grey_air, grey_muscovite = anchors_through(
                tuple(peaks), tuple(densities), section["air_density_kg_m3"],
                section["muscovite_density_kg_m3"])
            record.update(histogram_peak_greys=peaks, histogram_peak_densities=np.asarray(densities))
        elif grey_air is None or grey_muscovite is None:
            # the median grey outside the specimen, a high percentile inside it
            outside, inside = histograms()
            if grey_air is None:
                if outside.sum() == 0:
                    raise InputError(
                        "no air around the specimen to estimate grey_air from: set "
                        f"{setting_keys(sample, 'calibration.grey_air')}, or calibration.anchors: "
                        "histogram_peaks with peak_densities_kg_m3")
                grey_air = histogram_quantile(outside, 50.0)
            if grey_muscovite is None:
                grey_muscovite = histogram_quantile(inside, section["muscovite_percentile"])
        calibration = Calibration(
            grey_air=float(grey_air),
            grey_muscovite=float(grey_muscovite),
            air_density=section["air_density_kg_m3"],
            muscovite_density=section["muscovite_density_kg_m3"],
            dry_density=section["dry_density_kg_m3"] or material["dry_density_kg_m3"],
            mean_porosity=section["reference_porosity"] or material["reference_porosity"],
        )
    except ValueError as err:
        raise InputError(
            f"{source}: {err}; check {setting_keys(sample, 'calibration')} (anchors, grey_air, "
            "grey_muscovite, densities, dry_density_kg_m3, reference_porosity) and "
            "materials.pellet"
        ) from err
    return calibration, record


def _grid_warnings(
    sample: str,
    source: str | Path,
    porosity: np.ndarray,
    bounds: tuple[float, float],
    spacing: float,
    voxel_size: float,
    shape: tuple[int, ...],
) -> list[str]:
    """Warnings about a suspicious porosity grid, each also logged.

    A grid spacing below the voxel size (one voxel per block) or a grid of a single
    block along an axis usually means a voxel size in the wrong unit; fewer than
    ``MIN_BLOCKS_PER_AXIS`` blocks, a grid spacing too coarse for the scan; many blocks
    clamped to the porosity bounds, a wrong calibration or voxel size.

    Raises
    ------
    ValueError
        If every block inside the specimen lies outside the porosity bounds.
    """
    key = f"samples.{sample}.voxel_size_m"
    finite = porosity[np.isfinite(porosity)]
    low, high = bounds
    clamped = float(np.count_nonzero((finite < low) | (finite > high)) / finite.size)
    if clamped == 1.0:
        raise InputError(
            f"{source}: every block of the porosity grid lies outside "
            f"imaging.calibration.porosity_bounds [{low:g}, {high:g}] (porosity "
            f"{finite.min():.3g} to {finite.max():.3g}): check {key} "
            f"({voxel_size:g} m) and the imaging.calibration anchors{_NO_AIR_HINT}"
        )
    warnings = []
    if spacing < voxel_size:
        warnings.append(
            f"the grid spacing {spacing:.3g} m is finer than the voxel size {voxel_size:.3g} m "
            f"({key}): every block is one voxel; is the voxel size in metres?"
        )
    blocks = [int(np.ceil(n * voxel_size / max(spacing, voxel_size) - 1e-9)) for n in shape]
    if min(blocks) < 2:
        axis = "zyx"[int(np.argmin(blocks))]
        warnings.append(
            f"the scan ({shape[0]} x {shape[1]} x {shape[2]} voxels of {voxel_size:.3g} m, "
            f"{key}) is at most one grid spacing ({spacing:.3g} m) long along {axis}: "
            "is the voxel size in metres?"
        )
    elif min(blocks) < MIN_BLOCKS_PER_AXIS:
        axis = "zyx"[int(np.argmin(blocks))]
        warnings.append(
            f"the porosity grid has only {min(blocks)} blocks of {spacing:.3g} m along {axis}: "
            f"set imaging.grid_spacing_m to at most "
            f"{shape['zyx'.index(axis)] * voxel_size / MIN_BLOCKS_PER_AXIS:.3g} m for "
            f"{MIN_BLOCKS_PER_AXIS} blocks (its default is the micro model's point spacing)"
        )
    if clamped > CLAMPED_WARNING_FRACTION:
        warnings.append(
            f"{clamped:.0%} of the grid blocks are clamped to "
            f"imaging.calibration.porosity_bounds [{low:g}, {high:g}]: check {key} and the "
            f"imaging.calibration anchors{_NO_AIR_HINT}"
        )
    for warning in warnings:
        log.warning("%s (%s): %s", sample, source, warning)
    return warnings


