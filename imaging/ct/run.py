"""Entry points of the CT stage, called by the Snakemake scripts: files in, files out.

``phantom`` writes the synthetic scan; ``porosity`` reads a greyscale scan, computes its
specimen image and porosity grid (:func:`imaging.ct.porosity.scan_datasets`) and writes
them with their figure; ``rev`` reads the scan, the specimen image and the porosity grid,
runs :func:`imaging.ct.rev.scan_rev` and writes its result and figure. The computations
live in those modules and touch no file; each run only builds the settings from the
rule's configuration, reads, calls and writes (:func:`shared.io.write_outputs`), with the
signature of every stage's run (docs/development.md, "Adding a stage").
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import xarray as xr

from imaging.ct import figures
from imaging.ct.io import open_volume, write_tiff_stack
from imaging.ct.phantom import PhantomSpec, pellet_phantom
from imaging.ct.porosity import scan_datasets
from imaging.ct.rev import scan_rev
from imaging.ct.settings import ONE_WORKER, PorositySettings, RevSettings, ScanResources
from shared.io import read_dataset, write_outputs

__all__ = ["PorosityOutputs", "RevInputs", "RevOutputs", "phantom", "porosity", "rev", "phantom_spec",
           "open_scan"]

log = logging.getLogger("imaging.ct")

_REFERENCE = "Caulk (2022), PhD thesis, Univ. Grenoble Alpes, Sec. 3.3.4"


class PorosityOutputs(NamedTuple):
    """The files of :func:`porosity`: ``results/images/<sample>.nc``,
    ``results/porosity/<sample>.nc`` and its PNG."""

    image: str | Path
    porosity: str | Path
    figure: str | Path


class RevInputs(NamedTuple):
    """The files :func:`rev` reads: the scan's file or folder, ``results/images/<sample>.nc``
    (the specimen mask) and ``results/porosity/<sample>.nc``."""

    scan: str | Path
    image: str | Path
    porosity: str | Path


class RevOutputs(NamedTuple):
    """The files of :func:`rev`: ``results/rev/<sample>.nc`` and its PNG."""

    rev: str | Path
    figure: str | Path


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


def phantom(config: Mapping[str, Any], sample: str, output: str | Path) -> Path:
    """Write the synthetic pellet scan of a sample as a 16-bit multi-page TIFF.

    Parameters
    ----------
    config
        The rule's configuration: ``phantom``, the section, ``calibration``, the density
        anchors of ``imaging.calibration`` (see :func:`phantom_spec`), and ``sample``, the
        sample's ``samples`` entry (its ``voxel_size_m`` is read).
    sample
        The sample's name.
    output
        Target TIFF.
    """
    entry = config["sample"]
    spec = phantom_spec(config["phantom"], config["calibration"], float(entry["voxel_size_m"]))
    grey, _ = pellet_phantom(spec)
    log.info("phantom %s: shape %s, voxel %.3g m", sample, grey.shape, spec.voxel_size)
    return write_tiff_stack(grey, output)


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


def porosity(
    config: Mapping[str, Any],
    sample: str,
    scan: str | Path,
    outputs: PorosityOutputs,
    *,
    resources: ScanResources = ONE_WORKER,
    rule: str | None = None,
) -> xr.Dataset:
    """Read a greyscale scan, compute its specimen image and porosity grid
    (:func:`imaging.ct.porosity.scan_datasets`), write both and the figure.

    Parameters
    ----------
    config
        The rule's validated configuration: ``sample``, the sample's ``samples`` entry
        (source, layout, ``voxel_size_m``), and the arguments of
        :meth:`PorositySettings.from_config`, ``imaging``, ``material`` and
        ``micro_spacing``.
    sample
        The sample's name.
    scan
        The scan's file or folder (the phantom's TIFF for a phantom sample).
    outputs
        The image, porosity and figure paths.
    resources
        Workers, slab size, memory limit and dask scheduler.
    rule
        Snakemake rule name, for provenance.

    Returns
    -------
    xarray.Dataset
        The porosity dataset as written.

    Raises
    ------
    ImageError, InputError
        As :func:`imaging.ct.porosity.scan_datasets`; nothing is written then.
    """
    entry = config["sample"]
    settings = PorositySettings.from_config(sample, config["imaging"], config["material"],
                                            config["micro_spacing"])
    grey = open_scan(entry, scan, resources.chunk_mb)
    record = {"sample": dict(entry), "imaging": settings.record()}
    with resources.scheduler():
        image, ds = scan_datasets(grey, settings, voxel_size=float(entry["voxel_size_m"]),
                                  resources=resources, source=scan)
        write_outputs(image, outputs.image, stage="imaging", title=f"CT scan of {sample}",
                      config=record, inputs=[scan], rule=rule)
        write_outputs(ds, outputs.porosity, stage="imaging", title=f"porosity grid of {sample}",
                      config=record, inputs=[outputs.image], rule=rule, references=_REFERENCE,
                      figure=(outputs.figure, lambda path: figures.porosity_figure(image, ds, path)))
    log.info("%s: grid %s of %.3g m, mean porosity %.4f, clamped %.2g",
             sample, ds["porosity"].shape, ds.attrs["grid_spacing"],
             ds.attrs["porosity_mean"], ds.attrs["clamped_fraction"])
    return ds


def rev(
    config: Mapping[str, Any],
    sample: str,
    inputs: RevInputs,
    outputs: RevOutputs,
    *,
    resources: ScanResources = ONE_WORKER,
    rule: str | None = None,
) -> xr.Dataset:
    """Read a scan, its specimen image and porosity grid, run the REV and chord-length
    analyses (:func:`imaging.ct.rev.scan_rev`), write the result and its figure.

    Parameters
    ----------
    config
        The rule's validated configuration: ``sample``, the sample's ``samples`` entry
        (source and layout), and ``settings``, its ``rev`` and ``chords`` sections
        (:class:`RevSettings`).
    sample
        The sample's name.
    inputs
        The scan, its specimen image and its porosity grid.
    outputs
        ``results/rev/<sample>.nc`` and its PNG.
    resources
        Workers, slab size, memory limit and dask scheduler.
    rule
        Snakemake rule name, for provenance.
    """
    entry = config["sample"]
    settings = RevSettings(config["settings"]["rev"], config["settings"]["chords"], sample)
    scan, image_input, porosity_input = inputs
    grid = read_dataset(porosity_input, ["porosity"])
    grey = open_scan(entry, scan, resources.chunk_mb)
    with resources.scheduler(), xr.open_dataset(image_input, engine="netcdf4", chunks={}) as image:
        ds = scan_rev(grey, image, grid, settings, resources=resources, source=scan,
                      image_source=image_input)
        write_outputs(ds, outputs.rev, stage="imaging",
                      title=f"REV and chord lengths of {settings.sample}",
                      config={"rev": dict(settings.rev), "chords": dict(settings.chords)},
                      seed=settings.rev["seed"], inputs=[scan, image_input, porosity_input],
                      rule=rule,
                      references="Ferrage et al. (2015), Phys. Rev. E 91, 062210, Sec. V.C",
                      figure=(outputs.figure, lambda path: figures.rev_figure(ds, path)))
    return ds
