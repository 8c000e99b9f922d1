"""Entry points of the CT stage, called by the Snakemake scripts and by the tests.

``phantom`` writes the synthetic scan, ``porosity`` turns a greyscale scan into a porosity
grid, ``rev`` runs the REV and chord-length analyses (:mod:`imaging.morphology`) on the
calibrated voxels. Each takes the config sections it reads, and nothing else, so that a
rule passes exactly those as its params.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from imaging.ct import figures
from imaging.ct.calibration import (
    Calibration,
    anchors_through,
    density_to_porosity,
    grey_to_density,
    histogram_peaks,
    histogram_quantile,
)
from imaging.ct.datasets import image_dataset, porosity_dataset, rev_dataset
from imaging.ct.grid import block_grid, block_size_voxels
from imaging.ct.io import ImageError, open_volume, write_tiff_stack
from imaging.ct.mask import cylinder_section, inscribed_box, otsu_threshold
from imaging.ct.phantom import PhantomSpec, pellet_phantom
from imaging.ct.scan import (
    MaskRule,
    ScanSummary,
    anchor_histograms,
    estimated_peak_bytes,
    grid_sums,
    mask_array,
    summarize,
    threshold_areas,
)
from imaging.morphology import chord_lengths, rev_analyses
from shared.errors import InputError
from shared.io import read_dataset, write_dataset

__all__ = ["phantom", "porosity", "rev", "grid_spacing", "phantom_spec"]

log = logging.getLogger("imaging.ct")

_REFERENCE = "Caulk (2022), PhD thesis, Univ. Grenoble Alpes, Sec. 3.3.4"

CLAMPED_WARNING_FRACTION = 0.1
"""A porosity grid with more of its blocks clamped to the bounds than this is warned about."""
MIN_BLOCKS_PER_AXIS = 8
"""A porosity grid with fewer blocks than this along an axis is warned about (too coarse
for the REV and chord analyses and for the micro model's porosity field)."""


def phantom_spec(
    section: Mapping[str, Any], calibration: Mapping[str, Any], voxel_size: float
) -> PhantomSpec:
    """Phantom parameters.

    Parameters
    ----------
    section
        The ``phantom`` config section.
    calibration
        ``air_density_kg_m3`` and ``muscovite_density_kg_m3`` of ``imaging.calibration``:
        the phantom maps density to grey with the anchors that calibration inverts.
    voxel_size
        Voxel edge [m].
    """
    return PhantomSpec(
        shape=tuple(section["shape"]),
        voxel_size=voxel_size,
        mean_density=section["mean_density_kg_m3"],
        density_std=section["density_std_kg_m3"],
        correlation_length_xy=section["correlation_length_xy_m"],
        correlation_length_z=section["correlation_length_z_m"],
        n_flaws=section["n_flaws"],
        flaw_thickness=section["flaw_thickness_m"],
        flaw_density=section["flaw_density_kg_m3"],
        n_muscovite_grains=section["n_muscovite_grains"],
        air_density=calibration["air_density_kg_m3"],
        muscovite_density=calibration["muscovite_density_kg_m3"],
        blur_sigma=section["blur_sigma_voxels"],
        noise_std=section["noise_std_grey"],
        seed=section["seed"],
    )


def grid_spacing(spacing: float | None, micro_spacing: Sequence[float]) -> float:
    """Porosity grid spacing [m]: ``imaging.grid_spacing_m``, else the mean micro point
    spacing ``specimen_size_m / micro.n_points^(1/3)`` of the smallest case on the sample.

    Parameters
    ----------
    spacing
        ``imaging.grid_spacing_m`` [m], or None.
    micro_spacing
        ``(specimen_size_m, micro.n_points)`` with the smallest cube among the micro cases
        that read the sample (shared/scan_sizes.py, ``sample_point_spacing``).
    """
    if spacing is not None:
        return float(spacing)
    size, n_points = micro_spacing
    return float(size / n_points ** (1.0 / 3.0))


def phantom(
    section: Mapping[str, Any],
    calibration: Mapping[str, Any],
    sample: str,
    entry: Mapping[str, Any],
    output: str | Path,
) -> Path:
    """Write the synthetic pellet scan of a sample as a 16-bit multi-page TIFF.

    Parameters
    ----------
    section, calibration
        The ``phantom`` section and the density anchors of ``imaging.calibration`` (see
        :func:`phantom_spec`).
    sample, entry
        The sample's name and its ``samples`` entry (its ``voxel_size_m`` is read).
    output
        Target TIFF.
    """
    spec = phantom_spec(section, calibration, float(entry["voxel_size_m"]))
    grey, _ = pellet_phantom(spec)
    log.info("phantom %s: shape %s, voxel %.3g m", sample, grey.shape, spec.voxel_size)
    return write_tiff_stack(grey, output)


def _keys(sample: str, key: str) -> str:
    """How a message names an imaging key: globally or for this sample alone."""
    return f"imaging.{key} (or samples.{sample}.imaging.{key} for this sample alone)"


_NO_AIR_HINT = ("; a specimen that fills the field of view or sits in a container needs "
                "imaging.mask.mode full or cylinder and imaging.calibration.anchors "
                "histogram_peaks (or grey_air)")

BORDER_FRACTION_LIMIT = 0.5
"""A threshold mask covering more of the field's lateral border than this is taken for a
specimen that fills the field of view (the threshold then splits its own phases)."""


def _mask_rule(sample: str, scan: str | Path, grey: Any, summary: ScanSummary,
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
            raise InputError(f"{scan}: {err}; check {_keys(sample, 'mask')}") from err
        return MaskRule("cylinder", slices, disc=disc)
    level = section["threshold"]
    level = otsu_threshold(summary.sample) if level is None else float(level)
    areas, border, border_size = threshold_areas(grey, level, workers)
    if areas.max() == 0:
        raise InputError(f"{scan}: no voxel above the threshold {level:g}: no specimen found; "
                         f"check {_keys(sample, 'mask')}")
    kept = areas >= section["min_slice_fraction"] * areas.max()
    touching = float(border[kept].sum() / (border_size * kept.sum()))
    if touching > BORDER_FRACTION_LIMIT:
        raise InputError(
            f"{scan}: the specimen mask covers {touching:.0%} of the field's border, as if the "
            f"specimen filled the field of view (no air around it): set "
            f"{_keys(sample, 'mask.mode')} to full (or to cylinder with cylinder_radius_m), "
            "and the calibration anchors (calibration.anchors: histogram_peaks, or grey_air)"
        )
    return MaskRule("threshold", kept, level=level)


def _calibration(sample: str, scan: str | Path, section: Mapping[str, Any],
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
                        f"{_keys(sample, 'calibration.grey_air')}, or calibration.anchors: "
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
            f"{scan}: {err}; check {_keys(sample, 'calibration')} (anchors, grey_air, "
            "grey_muscovite, densities, dry_density_kg_m3, reference_porosity) and "
            "materials.pellet"
        ) from err
    return calibration, record


def open_scan(entry: Mapping[str, Any], scan: str | Path, chunk_mb: float) -> Any:
    """A sample's scan as a lazy dask array in slabs of about ``chunk_mb`` MiB."""
    raw = entry.get("raw", {})
    return open_volume(
        "tiff" if entry["source"] == "phantom" else entry["source"],
        scan,
        raw_shape=tuple(raw["shape"]) if "shape" in raw else None,
        raw_dtype=raw.get("dtype", "uint16"),
        raw_byte_order=raw.get("byte_order", "little"),
        chunk_bytes=int(chunk_mb * 2**20),
    )


def _check_memory(sample: str, scan: str | Path, grey: Any, imaging: Mapping[str, Any],
                  n_windows: int = 0) -> None:
    """Refuse, before reading the scan, a job whose estimated peak (slabs in flight and
    ``n_windows`` REV windows) exceeds ``imaging.memory_limit_gb`` or the machine."""
    peak = estimated_peak_bytes(grey.shape, int(grey.chunks[0][0]), imaging["workers"],
                                n_windows)
    limit = imaging["memory_limit_gb"] * 2**30 if imaging["memory_limit_gb"] else _machine_memory()
    log.info("%s: %s voxels of %s in slabs of %d slices, estimated peak %.2f GiB (limit %.1f GiB)",
             sample, "x".join(map(str, grey.shape)), grey.dtype, grey.chunks[0][0],
             peak / 2**30, limit / 2**30)
    if peak > limit:
        raise InputError(
            f"{scan}: the imaging of this {'x'.join(map(str, grey.shape))} scan would need about "
            f"{peak / 2**30:.1f} GiB, more than the {limit / 2**30:.1f} GiB allowed: lower "
            f"{_keys(sample, 'chunk_mb')} ({imaging['chunk_mb']:g}), {_keys(sample, 'workers')} "
            f"({imaging['workers']})" + (" or rev.n_positions" if n_windows else "")
            + ", or raise imaging.memory_limit_gb"
        )


@contextmanager
def _scheduler(address: str | None) -> Iterator[None]:
    """Slabs computed by a dask.distributed cluster at ``address`` (``imaging.dask_scheduler``)
    while the block runs, else by the job's own threads."""
    if address is None:
        yield
        return
    from distributed import Client

    with Client(address):
        log.info("dask scheduler %s", address)
        yield


def _machine_memory() -> float:
    """Bytes of physical memory of this machine, 80 % of it (the rest for the system)."""
    return 0.8 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def _grid_warnings(
    sample: str,
    scan: str | Path,
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
            f"{scan}: every block of the porosity grid lies outside "
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
        log.warning("%s (%s): %s", sample, scan, warning)
    return warnings


def porosity(
    sample: str,
    entry: Mapping[str, Any],
    imaging: Mapping[str, Any],
    material: Mapping[str, Any],
    micro_spacing: Sequence[float],
    scan: str | Path,
    image_output: str | Path,
    porosity_output: str | Path,
    figure_output: str | Path,
    rule: str | None = None,
) -> xr.Dataset:
    """Greyscale scan -> specimen mask -> calibrated density -> block-averaged porosity grid.

    Parameters
    ----------
    sample
        Sample name.
    entry
        The sample's ``samples`` entry (validated).
    imaging
        The keys of the ``imaging`` section that this step reads: ``calibration``,
        ``mask``, ``grid_spacing_m`` and ``min_specimen_fraction``.
    material
        ``dry_density_kg_m3`` and ``reference_porosity`` of ``materials.pellet``: the
        calibration maps the measured mean dry density to the reference porosity, the
        same phi_0 as the retention and permeability laws'.
    micro_spacing
        ``(specimen_size_m, micro.n_points)`` of the smallest micro case on the sample,
        for the default grid spacing (:func:`grid_spacing`).
    scan
        The scan's file or folder (the phantom's TIFF for a phantom sample).
    image_output, porosity_output, figure_output
        Paths of ``results/images/<sample>.nc``, ``results/porosity/<sample>.nc`` and its PNG.
    rule
        Snakemake rule name, for provenance.

    Returns
    -------
    xarray.Dataset
        The porosity dataset as written; its attribute ``warnings`` holds the warnings of
        :func:`_grid_warnings` (voxel size, clamped blocks), joined by "; ", or "".

    Raises
    ------
    ImageError
        If the scan is missing, truncated or not an 8/16-bit greyscale volume.
    ValueError
        If no specimen, no valid calibration or no block inside the porosity bounds is
        found; the message names the scan and the config keys. Nothing is written then.
    """
    voxel_size = float(entry["voxel_size_m"])
    spacing = grid_spacing(imaging["grid_spacing_m"], micro_spacing)
    block = block_size_voxels(spacing, voxel_size)
    grey = open_scan(entry, scan, imaging["chunk_mb"])
    log.info("%s: %s volume %s from %s", sample, grey.dtype, grey.shape, scan)
    _check_memory(sample, scan, grey, imaging)
    with _scheduler(imaging["dask_scheduler"]):
        return _porosity_of(sample, entry, imaging, material, scan, grey, spacing, block,
                            (image_output, porosity_output, figure_output), rule)


def _porosity_of(sample: str, entry: Mapping[str, Any], imaging: Mapping[str, Any],
                 material: Mapping[str, Any], scan: str | Path, grey: Any, spacing: float,
                 block: int, outputs: tuple, rule: str | None) -> xr.Dataset:
    """The passes of :func:`porosity` over the opened scan, and its outputs."""
    image_output, porosity_output, figure_output = outputs
    voxel_size = float(entry["voxel_size_m"])
    workers = imaging["workers"]
    summary = summarize(grey, workers)
    if summary.minimum == summary.maximum:
        raise ImageError(f"{scan}: the volume is uniform (every voxel is {summary.minimum})")
    masking = _mask_rule(sample, scan, grey, summary, imaging["mask"], voxel_size, workers)
    calibration, anchors = _calibration(sample, scan, imaging["calibration"], material, summary,
                                        lambda: anchor_histograms(grey, masking, workers))
    density_sum, counts = grid_sums(grey, masking, calibration, block, workers)
    grid = block_grid(density_sum, counts, grey.shape, calibration, block, voxel_size,
                      imaging["min_specimen_fraction"])
    if not np.isfinite(grid.porosity).any():
        raise InputError(
            f"{scan}: no grid block lies inside the specimen; check imaging.mask and "
            "imaging.min_specimen_fraction"
        )
    bounds = tuple(imaging["calibration"]["porosity_bounds"])
    warnings = _grid_warnings(sample, scan, grid.porosity, bounds, spacing, voxel_size, grey.shape)
    section = {"sample": dict(entry), "imaging": dict(imaging)}
    image_ds = image_dataset(mask_array(grey, masking), voxel_size, summary.preview,
                             summary.preview_step, grey if imaging["store_scan"] else None)
    write_dataset(image_ds, image_output, stage="imaging", title=f"CT scan of {sample}",
                  config=section, inputs=[scan], rule=rule)
    ds = porosity_dataset(grid, calibration, bounds, voxel_size)
    ds.attrs.update(anchors, mask_mode=imaging["mask"]["mode"], warnings="; ".join(warnings))
    write_dataset(ds, porosity_output, stage="imaging", title=f"porosity grid of {sample}",
                  config=section, inputs=[image_output], rule=rule, references=_REFERENCE)
    figures.porosity_figure(image_ds, ds, figure_output)
    log.info("%s: grid %s of %.3g m, mean porosity %.4f, clamped %.2g",
             sample, ds["porosity"].shape, ds.attrs["grid_spacing"],
             ds.attrs["porosity_mean"], ds.attrs["clamped_fraction"])
    return ds


def rev(
    sample: str,
    entry: Mapping[str, Any],
    settings: Mapping[str, Any],
    scan: str | Path,
    image_input: str | Path,
    porosity_input: str | Path,
    rev_output: str | Path,
    figure_output: str | Path,
    rule: str | None = None,
) -> xr.Dataset:
    """REV and chord-length analyses of the voxels inside the specimen.

    The voxels are calibrated (the calibration is read from the porosity file) and
    thresholded at ``pore_porosity_threshold`` into the binary pore image that both the
    REV (as Ferrage et al. 2015, Sec. V C define it) and the chords analyse; the REV of
    the calibrated (continuous) porosity is a second set of variables. The analysed region
    is the largest cube inside the specimen mask, so that outside air enters no window.
    The scan is read in slabs (``imaging.chunk_mb``), never whole.

    Parameters
    ----------
    sample, entry
        Sample name and its ``samples`` entry (source and layout of the scan).
    settings
        The sample's imaging settings: ``rev``, ``chords``, ``chunk_mb``, ``workers``,
        ``memory_limit_gb``, ``dask_scheduler``.
    scan
        The scan's file or folder.
    image_input, porosity_input
        ``results/images/<sample>.nc`` (the specimen mask) and ``results/porosity/<sample>.nc``.
    rev_output, figure_output
        ``results/rev/<sample>.nc`` and its PNG.
    rule
        Snakemake rule name, for provenance.
    """
    rev_settings, chords_settings = settings["rev"], settings["chords"]
    workers = settings["workers"]
    attrs = read_dataset(porosity_input, ["porosity"]).attrs
    calibration = Calibration(
        grey_air=attrs["grey_air"], grey_muscovite=attrs["grey_muscovite"],
        air_density=attrs["air_density"], muscovite_density=attrs["muscovite_density"],
        dry_density=attrs["dry_density"], mean_porosity=attrs["mean_porosity_anchor"],
    )
    grey = open_scan(entry, scan, settings["chunk_mb"])
    _check_memory(sample, scan, grey, settings,
                  (rev_settings["n_sizes"] + 1) * rev_settings["n_positions"])
    with xr.open_dataset(image_input, engine="netcdf4", chunks={}) as image:
        if "specimen" not in image or tuple(image["specimen"].shape) != tuple(grey.shape):
            raise InputError(f"{image_input}: no specimen mask of the scan's shape "
                             f"{tuple(grey.shape)}: rerun the imaging_porosity rule")
        voxel_size = float(image.attrs["voxel_size"])
        box = inscribed_box(image["specimen"].data.rechunk(grey.chunks).astype(bool))
    cube = grey[box]

    def calibrate(values: np.ndarray) -> np.ndarray:
        density = grey_to_density(values.astype(np.float32), calibration)
        return np.clip(density_to_porosity(density, calibration), 0, 1)

    voxel_porosity = cube.map_blocks(calibrate, dtype=np.float32)
    threshold = chords_settings["pore_porosity_threshold"]
    pore = voxel_porosity > threshold
    windows = {key: rev_settings[key] for key in ("n_sizes", "n_positions", "tolerance",
                                                 "max_window_fraction")}
    windows.update(n_centred_sizes=rev_settings["centred_n_sizes"], workers=workers)
    log.info("%s: analysing the %s-voxel cube inside the specimen", sample,
             "x".join(map(str, cube.shape)))
    # the paper's REV is that of the binary image (Sec. V C), the pore space of the chords;
    # the calibrated porosity's comes from the same windows, in the same pass
    with _scheduler(settings["dask_scheduler"]):
        calibrated, result = rev_analyses(voxel_porosity, voxel_size,
                                          np.random.default_rng(rev_settings["seed"]),
                                          binary=pore, **windows)
        chords = chord_lengths(pore, voxel_size, chords_settings["include_edges"],
                               workers=workers)
    ds = rev_dataset(result, calibrated, chords, voxel_size)
    ds.attrs.update(analysed_cube_edge=voxel_porosity.shape[0] * voxel_size,
                    pore_porosity_threshold=threshold,
                    rev_tolerance=rev_settings["tolerance"])
    write_dataset(ds, rev_output, stage="imaging", title=f"REV and chord lengths of {sample}",
                  config={"rev": dict(rev_settings), "chords": dict(chords_settings)},
                  seed=rev_settings["seed"], inputs=[scan, image_input, porosity_input],
                  rule=rule, references="Ferrage et al. (2015), Phys. Rev. E 91, 062210, Sec. V.C")
    figures.rev_figure(ds, figure_output)
    log.info("%s", rev_summary(sample, result, calibrated, chords.R_p, chords.R_s))
    return ds


def rev_edge(edge: float) -> str:
    """An REV edge for the log: ``"0.0068 m"``, or ``"not reached"`` when the windows
    never settled within the tolerance (NaN).

    Parameters
    ----------
    edge
        REV edge [m], NaN if not reached.

    Returns
    -------
    str
        The edge in metres, or "not reached".
    """
    return "not reached" if not np.isfinite(edge) else f"{edge:.3g} m"


def rev_summary(sample: str, result: Any, calibrated: Any, r_p: float, r_s: float) -> str:
    """The log line of the REV analysis: centred / random-window REV edges of the binary
    porosity, its interface and the calibrated porosity (an unconverged one reads "not
    reached"), and the chord ratios.

    Parameters
    ----------
    sample
        Sample name.
    result, calibrated
        REV results of the binary image and of the calibrated porosity (attributes
        ``porosity_total``, ``w_rev_porosity_centred``, ``w_rev_porosity``, and for
        ``result`` ``w_rev_interface_centred``, ``w_rev_interface``) [m].
    r_p, r_s
        Chord ratios R_p and R_s [1].

    Returns
    -------
    str
        One line.
    """
    return (f"{sample}: REV edges (centred / random windows) of the binary porosity "
            f"{result.porosity_total:.4f}: {rev_edge(result.w_rev_porosity_centred)} / "
            f"{rev_edge(result.w_rev_porosity)}, of its interface: "
            f"{rev_edge(result.w_rev_interface_centred)} / {rev_edge(result.w_rev_interface)}, "
            f"of the calibrated porosity {calibrated.porosity_total:.4f}: "
            f"{rev_edge(calibrated.w_rev_porosity_centred)} / "
            f"{rev_edge(calibrated.w_rev_porosity)}; R_p {r_p:.3g}, R_s {r_s:.3g}")
