"""Entry points of the imaging stage, called by the Snakemake scripts and by the tests.

``phantom`` writes the synthetic scan, ``porosity`` turns a greyscale scan into a porosity
grid, ``rev`` runs the REV and chord-length analyses on the calibrated voxels.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from imaging import figures
from imaging.calibration import Calibration, density_to_porosity, grey_anchors, grey_to_density
from imaging.chords import chord_lengths
from imaging.datasets import image_dataset, porosity_dataset, rev_dataset
from imaging.grid import block_average, block_size_voxels
from imaging.io import read_volume, write_tiff_stack
from imaging.mask import inscribed_box, specimen_mask
from imaging.phantom import PhantomSpec, pellet_phantom
from imaging.rev import rev_analysis
from shared.io import read_dataset, write_dataset

__all__ = ["phantom", "porosity", "rev", "grid_spacing", "phantom_spec"]

log = logging.getLogger("imaging")

_REFERENCE = "Caulk (2022), PhD thesis, Univ. Grenoble Alpes, Sec. 3.3.4"


def phantom_spec(config: Mapping[str, Any], voxel_size: float) -> PhantomSpec:
    """Phantom parameters from the ``phantom`` config section and a voxel size [m]."""
    section = config["phantom"]
    calibration = config["imaging"]["calibration"]
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


def grid_spacing(config: Mapping[str, Any]) -> float:
    """Porosity grid spacing [m]: the configured one, else the mean micro point spacing."""
    spacing = config["imaging"]["grid_spacing_m"]
    if spacing is not None:
        return float(spacing)
    micro = config["micro"]
    return float(micro["specimen_size_m"] / micro["n_points"] ** (1.0 / 3.0))


def phantom(config: Mapping[str, Any], sample: str, output: str | Path) -> Path:
    """Write the synthetic pellet scan of ``sample`` as a 16-bit multi-page TIFF."""
    spec = phantom_spec(config, config["samples"][sample]["voxel_size_m"])
    grey, _ = pellet_phantom(spec)
    log.info("phantom %s: shape %s, voxel %.3g m", sample, grey.shape, spec.voxel_size)
    return write_tiff_stack(grey, output)


def _calibration(config: Mapping[str, Any], grey: np.ndarray, specimen: np.ndarray) -> Calibration:
    section = config["imaging"]["calibration"]
    grey_air, grey_muscovite = section["grey_air"], section["grey_muscovite"]
    if grey_air is None or grey_muscovite is None:
        auto_air, auto_muscovite = grey_anchors(grey, specimen, section["muscovite_percentile"])
        grey_air = auto_air if grey_air is None else grey_air
        grey_muscovite = auto_muscovite if grey_muscovite is None else grey_muscovite
    return Calibration(
        grey_air=float(grey_air),
        grey_muscovite=float(grey_muscovite),
        air_density=section["air_density_kg_m3"],
        muscovite_density=section["muscovite_density_kg_m3"],
        dry_density=section["dry_density_kg_m3"],
        mean_porosity=section["mean_porosity"],
    )


def porosity(
    config: Mapping[str, Any],
    sample: str,
    scan: str | Path,
    image_output: str | Path,
    porosity_output: str | Path,
    figure_output: str | Path,
    rule: str | None = None,
) -> xr.Dataset:
    """Greyscale scan -> specimen mask -> calibrated density -> block-averaged porosity grid.

    Parameters
    ----------
    config
        The validated configuration.
    sample
        Sample name (a key of ``config["samples"]``).
    scan
        The scan's file or folder (the phantom's TIFF for a phantom sample).
    image_output, porosity_output, figure_output
        Paths of ``results/images/<sample>.nc``, ``results/porosity/<sample>.nc`` and its PNG.
    rule
        Snakemake rule name, for provenance.

    Returns
    -------
    xarray.Dataset
        The porosity dataset as written.
    """
    entry = config["samples"][sample]
    source = "tiff" if entry["source"] == "phantom" else entry["source"]
    voxel_size = float(entry["voxel_size_m"])
    raw = entry.get("raw", {})
    grey = read_volume(
        source,
        scan,
        raw_shape=tuple(raw["shape"]) if "shape" in raw else None,
        raw_dtype=raw.get("dtype", "uint16"),
        raw_byte_order=raw.get("byte_order", "little"),
    )
    log.info("%s: read %s volume %s from %s", sample, grey.dtype, grey.shape, scan)
    mask_cfg = config["imaging"]["mask"]
    specimen = specimen_mask(grey, mask_cfg["threshold"], mask_cfg["min_slice_fraction"])
    calibration = _calibration(config, grey, specimen)
    block = block_size_voxels(grid_spacing(config), voxel_size)
    grid = block_average(
        grey, specimen, calibration, block, voxel_size, config["imaging"]["min_specimen_fraction"]
    )
    if not np.isfinite(grid.porosity).any():
        raise ValueError(f"{scan}: no grid block lies inside the specimen; check the mask settings")
    section = {"sample": dict(entry), "imaging": dict(config["imaging"])}
    image_ds = image_dataset(grey, specimen, voxel_size)
    write_dataset(image_ds, image_output, stage="imaging", title=f"CT scan of {sample}",
                  config=section, inputs=[scan] if Path(scan).is_file() else [], rule=rule)
    bounds = tuple(config["imaging"]["calibration"]["porosity_bounds"])
    ds = porosity_dataset(grid, calibration, bounds, voxel_size)
    write_dataset(ds, porosity_output, stage="imaging", title=f"porosity grid of {sample}",
                  config=section, inputs=[image_output], rule=rule, references=_REFERENCE)
    figures.porosity_figure(image_ds, ds, figure_output)
    log.info("%s: grid %s of %.3g m, mean porosity %.4f, clamped %.2g",
             sample, ds["porosity"].shape, ds.attrs["grid_spacing"],
             ds.attrs["porosity_mean"], ds.attrs["clamped_fraction"])
    return ds


def rev(
    config: Mapping[str, Any],
    sample: str,
    image_input: str | Path,
    porosity_input: str | Path,
    rev_output: str | Path,
    figure_output: str | Path,
    rule: str | None = None,
) -> xr.Dataset:
    """REV and chord-length analyses of the calibrated voxels inside the specimen.

    The analysed region is the largest cube inside the specimen mask, so that outside
    air does not enter any window.
    """
    image = read_dataset(image_input, ["grey", "specimen"])
    attrs = read_dataset(porosity_input, ["porosity"]).attrs
    calibration = Calibration(
        grey_air=attrs["grey_air"], grey_muscovite=attrs["grey_muscovite"],
        air_density=attrs["air_density"], muscovite_density=attrs["muscovite_density"],
        dry_density=attrs["dry_density"], mean_porosity=attrs["mean_porosity_anchor"],
    )
    voxel_size = float(image.attrs["voxel_size"])
    box = inscribed_box(image["specimen"].values.astype(bool))
    grey = image["grey"].values[box].astype(np.float32)
    voxel_porosity = np.clip(density_to_porosity(grey_to_density(grey, calibration), calibration), 0, 1)
    section = config["imaging"]
    pore = voxel_porosity > section["chords"]["pore_porosity_threshold"]
    rev_cfg = section["rev"]
    result = rev_analysis(
        voxel_porosity, voxel_size, np.random.default_rng(rev_cfg["seed"]), binary=pore,
        n_sizes=rev_cfg["n_sizes"], n_positions=rev_cfg["n_positions"],
        tolerance=rev_cfg["tolerance"], max_window_fraction=rev_cfg["max_window_fraction"],
    )
    chords = chord_lengths(pore, voxel_size, section["chords"]["include_edges"])
    ds = rev_dataset(result, chords, voxel_size)
    ds.attrs.update(analysed_cube_edge=voxel_porosity.shape[0] * voxel_size,
                    pore_porosity_threshold=section["chords"]["pore_porosity_threshold"],
                    rev_tolerance=rev_cfg["tolerance"])
    write_dataset(ds, rev_output, stage="imaging", title=f"REV and chord lengths of {sample}",
                  config=dict(section), seed=rev_cfg["seed"], inputs=[image_input, porosity_input],
                  rule=rule, references="Ferrage et al. (2015), Phys. Rev. E 91, 062210, Sec. V.C")
    figures.rev_figure(ds, figure_output)
    log.info("%s: REV porosity %.3g m, interface %.3g m; R_p %.3g, R_s %.3g", sample,
             result.w_rev_porosity, result.w_rev_interface, chords.R_p, chords.R_s)
    return ds
