"""Entry point of the packing stage: build a bed from a config entry, write it.

``run(section, "results/packing/<name>.nc")`` builds and measures the packing
(:func:`imaging.packing.dataset.packed_bed`, no file I/O) and writes the netCDF file of
docs/design.md §2 with a figure ``<name>.png`` beside it (:func:`shared.io.write_outputs`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import xarray as xr

from imaging.packing.dataset import packed_bed
from imaging.packing.figures import packing_figure
from shared.io import write_outputs

__all__ = ["run"]

log = logging.getLogger("imaging.packing")

_FERRAGE = "E. Ferrage et al., Phys. Rev. E 91, 062210 (2015), doi:10.1103/PhysRevE.91.062210"


def run(section: Mapping[str, Any], output_path: str | Path, rule: str | None = None) -> xr.Dataset:
    """Build, measure and write a virtual clay porous medium.

    Parameters
    ----------
    section : mapping
        One entry of ``packings``, validated (:func:`imaging.packing.dataset.packed_bed`).
    output_path : str or Path
        Target ``.nc`` file; the figure is written beside it with suffix ``.png``.
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
    path = Path(output_path)
    write_outputs(ds, path, stage="packing", title=f"Sequential deposition packing {path.stem}",
                  config=dict(section), seed=int(section["seed"]), references=_FERRAGE, rule=rule,
                  figure=(path.with_suffix(".png"), lambda png: packing_figure(ds, image, png)))
    log.info("packing %s: porosity %.3f, S_part %.3f, f_o %.2e", path.stem,
             float(ds["porosity"]), float(ds["S_part"]), float(ds["overlap_fraction"]))
    return ds
