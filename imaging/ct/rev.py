"""The REV and chord-length analyses (:mod:`imaging.morphology`) of a scan's calibrated
voxels, computed in memory, with no file read or written.

:func:`scan_rev` takes the scan, the specimen image and the porosity grid of
:func:`imaging.ct.porosity.scan_datasets` (the mask and the calibration) and
:class:`~imaging.ct.settings.RevSettings`, and returns the REV Dataset.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from imaging.ct.calibration import Calibration, density_to_porosity, grey_to_density
from imaging.ct.datasets import rev_dataset
from imaging.ct.mask import inscribed_box
from imaging.ct.porosity import scan_array
from imaging.ct.scan import check_memory
from imaging.ct.settings import ONE_WORKER, RevSettings, ScanResources
from imaging.morphology import chord_lengths, rev_analyses
from shared.errors import InputError

__all__ = ["calibration_of", "scan_rev", "rev_edge", "rev_summary"]

log = logging.getLogger("imaging.ct")


def calibration_of(attrs: Mapping[str, Any]) -> Calibration:
    """The calibration recorded in a porosity grid's attributes
    (:func:`imaging.ct.datasets.porosity_dataset`).

    The anchors are numpy float64 scalars, as read from a file, in memory too: the float32
    voxels are then mapped to porosity in float64 (NumPy's promotion rules), the same
    arithmetic whether the grid comes from its file or from memory.
    """
    keys = {"grey_air": "grey_air", "grey_muscovite": "grey_muscovite",
            "air_density": "air_density", "muscovite_density": "muscovite_density",
            "dry_density": "dry_density", "mean_porosity": "mean_porosity_anchor"}
    return Calibration(**{name: np.float64(attrs[key]) for name, key in keys.items()})


def scan_rev(scan: Any, image: xr.Dataset, porosity: xr.Dataset, settings: RevSettings, *,
             resources: ScanResources = ONE_WORKER, source: str | Path = "scan",
             image_source: str | Path = "the specimen image") -> xr.Dataset:
    """REV and chord-length analyses of the voxels inside the specimen.

    The voxels are calibrated (with the porosity grid's calibration) and thresholded at
    ``pore_porosity_threshold`` into the binary pore image that both the REV (as Ferrage
    et al. 2015, Sec. V C define it) and the chords analyse; the REV of the calibrated
    (continuous) porosity is a second set of variables. The analysed region is the
    largest cube inside the specimen mask, so that outside air enters no window. The
    scan is read in slabs, never whole, by whichever dask scheduler is active.

    Parameters
    ----------
    scan
        ``(z, y, x)`` 8/16-bit greys: a numpy or dask array, or an xarray DataArray.
    image
        The specimen image: ``specimen`` of the scan's shape, attribute ``voxel_size`` [m].
    porosity
        The porosity grid, whose attributes hold the calibration.
    settings
        REV and chord settings.
    resources
        Slabs read at once, slab size of an in-memory scan, memory limit.
    source, image_source
        How messages name the scan and the specimen image.

    Returns
    -------
    xarray.Dataset
        REV curves and edges [m] of the binary and of the calibrated porosity and of the
        interface density, chord-length distributions [m-1] and anisotropies R_p, R_s [1]
        (:func:`imaging.ct.datasets.rev_dataset`).

    Raises
    ------
    InputError
        If the image holds no specimen mask of the scan's shape, or the job would exceed
        the memory limit.
    """
    rev_settings, chords_settings = settings.rev, settings.chords
    workers = resources.workers
    voxel_size = float(image.attrs["voxel_size"])
    grey, _ = scan_array(scan, voxel_size, resources.chunk_mb, source)
    check_memory(settings.sample, source, grey, resources, settings.n_windows)
    if "specimen" not in image or tuple(image["specimen"].shape) != tuple(grey.shape):
        raise InputError(f"{image_source}: no specimen mask of the scan's shape "
                         f"{tuple(grey.shape)}: rerun the imaging_porosity rule")
    specimen = image["specimen"].data
    specimen = specimen.rechunk(grey.chunks) if hasattr(specimen, "rechunk") else specimen
    box = inscribed_box(specimen.astype(bool))
    cube = grey[box]
    calibration = calibration_of(porosity.attrs)

    def calibrate(values: np.ndarray) -> np.ndarray:
        density = grey_to_density(values.astype(np.float32), calibration)
        return np.clip(density_to_porosity(density, calibration), 0, 1)

    voxel_porosity = cube.map_blocks(calibrate, dtype=np.float32)
    threshold = chords_settings["pore_porosity_threshold"]
    pore = voxel_porosity > threshold
    windows = {key: rev_settings[key] for key in ("n_sizes", "n_positions", "tolerance",
                                                 "max_window_fraction")}
    windows.update(n_centred_sizes=rev_settings["centred_n_sizes"], workers=workers)
    log.info("%s: analysing the %s-voxel cube inside the specimen", settings.sample,
             "x".join(map(str, cube.shape)))
    # the paper's REV is that of the binary image (Sec. V C), the pore space of the chords;
    # the calibrated porosity's comes from the same windows, in the same pass
    calibrated, result = rev_analyses(voxel_porosity, voxel_size,
                                      np.random.default_rng(rev_settings["seed"]),
                                      binary=pore, **windows)
    assert result is not None  # the binary image's analysis, given the binary image
    chords = chord_lengths(pore, voxel_size, chords_settings["include_edges"], workers=workers)
    ds = rev_dataset(result, calibrated, chords, voxel_size)
    ds.attrs.update(analysed_cube_edge=voxel_porosity.shape[0] * voxel_size,
                    pore_porosity_threshold=threshold,
                    rev_tolerance=rev_settings["tolerance"])
    log.info("%s", rev_summary(settings.sample, result, calibrated, chords.R_p, chords.R_s))
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
