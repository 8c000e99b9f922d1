"""Entry point of the packing stage: build a bed from a config entry, write it.

``run(section, name, PackingOutputs("results/packing/<name>.nc", "results/packing/<name>.png"))``
builds and measures the packing (:func:`imaging.packing.dataset.packed_bed`, no file I/O)
and writes the netCDF file of docs/design.md §2 and its figure
(:func:`shared.io.write_outputs`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import xarray as xr

from imaging.packing.dataset import packed_bed
from imaging.packing.figures import packing_figure
from shared.io import write_outputs

__all__ = ["PackingOutputs", "run"]

log = logging.getLogger("imaging.packing")

_FERRAGE = "E. Ferrage et al., Phys. Rev. E 91, 062210 (2015), doi:10.1103/PhysRevE.91.062210"


class PackingOutputs(NamedTuple):
    """The files of :func:`run`: ``results/packing/<name>.nc`` and its PNG."""

    result: str | Path
    figure: str | Path


def run(section: Mapping[str, Any], name: str, outputs: PackingOutputs, *,
        rule: str | None = None) -> xr.Dataset:
    """Build, measure and write a virtual clay porous medium.

    Parameters
    ----------
    section : mapping
        One entry of ``packings``, validated (:func:`imaging.packing.dataset.packed_bed`).
    name : str
        Its name in ``packings``.
    outputs : PackingOutputs
        The netCDF file and the figure.
    rule : str, optional
        Snakemake rule name, for provenance.

    Returns
    -------
    xarray.Dataset
        The written dataset.

    Raises
    ------
    ConfigError
        As :func:`imaging.packing.dataset.packed_bed`; nothing is written then.
    """
    ds, image = packed_bed(section)
    write_outputs(ds, outputs.result, stage="packing", title=f"Sequential deposition packing {name}",
                  config=dict(section), seed=int(section["seed"]), references=_FERRAGE, rule=rule,
                  figure=(outputs.figure, lambda png: packing_figure(ds, image, png)))
    log.info("packing %s: porosity %.3f, S_part %.3f, f_o %.2e", name,
             float(ds["porosity"]), float(ds["S_part"]), float(ds["overlap_fraction"]))
    return ds
