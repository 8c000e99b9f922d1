"""Entry point of the micro stage: one case's grid in, its netCDF, figure and restart file out.

A case is a specimen (CT-informed or homogeneous porosity), a crack model switch and a
confinement. :func:`run` reads the porosity grid, hydrates the case through its suction
checkpoints (:func:`micro.case.checkpoints_reached`, the loop of the library function
:func:`micro.case.hydrate`, with no file), resuming from and saving to the restart file
beside the output (:class:`shared.checkpointer.Checkpointer`: a killed run resumes at
its last save), and writes ``results/micro/<case>.nc`` (docs/design.md §2) and its
figure (:func:`shared.io.write_outputs`); with ``micro.vtk_snapshots``, also ParaView
snapshots in ``results/micro/<case>_vtk/`` (:mod:`micro.vtk`). The restart file is
removed when the case finishes.
"""

from __future__ import annotations

import logging
import resource
from collections.abc import Mapping
from functools import partial
from pathlib import Path
from typing import Any, NamedTuple

import xarray as xr

from micro import figures, vtk
from micro.case import checkpoints_reached, hydrate, resumed_or_settled
from micro.pool import measuring
from micro.settings import (
    case_material,
    case_parameters,
    case_settings,
    hydration_settings,
    micro_settings,
)
from shared.checkpointer import Checkpointer, run_digest
from shared.io import read_dataset, write_outputs
from shared.progress import Progress

__all__ = [
    "CaseOutputs",
    "hydrate",
    "micro_settings",
    "phase_wall_times",
    "run",
    # the settings' builders (micro.settings): tests and benchmarks read them here
    "case_settings",
    "hydration_settings",
    "case_material",
    "case_parameters",
]

log = logging.getLogger("micro")


class CaseOutputs(NamedTuple):
    """The files of :func:`run`: ``results/micro/<case>.nc`` and its PNG."""

    result: str | Path
    figure: str | Path


def phase_wall_times(attrs: Mapping[str, Any]) -> dict[str, float]:
    """The wall time per phase [s] that :func:`run` writes as ``wall_time_<phase>_s``
    attributes, by phase name (empty for an output written before phases were timed)."""
    return {key[len("wall_time_"):-len("_s")]: float(value) for key, value in attrs.items()
            if key.startswith("wall_time_") and key.endswith("_s") and key != "wall_time_s"}


def run(
    config: Mapping[str, Any],
    case: str,
    porosity_input: str | Path,
    outputs: CaseOutputs,
    *,
    rule: str | None = None,
) -> xr.Dataset:
    """Hydrate one case through the configured suction checkpoints and write its results.

    Parameters
    ----------
    config
        Validated configuration: its ``micro`` section (with at least this case) and
        ``materials.pellet``.
    case
        Case name (a key of ``micro.cases``).
    porosity_input
        ``results/porosity/<sample>.nc`` of the CT sample.
    outputs
        ``results/micro/<case>.nc`` and its PNG; the restart file is
        ``<case>.checkpoint.npz`` beside the netCDF.
    rule
        Snakemake rule name, for provenance.

    Returns
    -------
    xarray.Dataset
        The written results (:func:`micro.case.hydrate`'s). Besides ``wall_time_s`` and
        ``peak_memory_mb``, the attributes ``wall_time_<phase>_s`` split the wall time
        [s] into settling, flow, swelling, relaxation, geometry, remesh, cracks,
        measurement and output (what remains is set-up and the figure).

    Raises
    ------
    micro.hydration.DivergenceError
        If the coupled solution diverges; the last good checkpoint stays on disk.
    """
    settings = micro_settings(config, case)
    # the studies aggregate finished cases: they are not part of a case's configuration
    section = {"micro": {k: v for k, v in config["micro"].items() if k != "studies"}, "case": case,
               "material": case_material(config, case)}
    result = Path(outputs.result)
    # the code too (this module and what it imports): a checkpoint of other code is not resumed
    checkpointer = Checkpointer(result.with_suffix(".checkpoint.npz"), run_digest(section, __file__),
                                float(config["micro"]["snapshot_interval_s"]),
                                logging.getLogger("micro.checkpoint"))
    grid = read_dataset(porosity_input, ["porosity"])
    hydration = resumed_or_settled(grid["porosity"], settings, checkpointer)
    # optional ParaView snapshots, a side product beside the netCDF (not a rule output)
    vtk_dir = result.with_name(f"{result.stem}_vtk") if config["micro"].get("vtk_snapshots") else None
    if vtk_dir is not None and not checkpointer.resumed:
        vtk.clear_snapshots(vtk_dir, result.stem)
    progress = Progress(len(settings.checkpoints), f"micro {case}", log, interval=0.0,
                        trend=True, done_before=len(hydration.records))
    checkpointer.restart_cadence()  # the cadence counts from here, settled
    clock = checkpointer.clock
    with measuring(hydration.state.mesh.n_cells) as executor:
        for reached in checkpoints_reached(hydration, clock, executor, checkpointer):
            if vtk_dir is not None:
                with clock.phase("output"):
                    vtk.write_checkpoint_snapshot(vtk_dir, result.stem, reached.index,
                                                  hydration.state, settings.checkpoints)
            progress.update(reached.index + 1)
    ds = hydration.dataset()
    ds.attrs.update(wall_time_s=checkpointer.wall_time(),
                    peak_memory_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
                    **{f"wall_time_{name}_s": seconds for name, seconds in clock.seconds.items()})
    write_outputs(ds, result, stage="micro", title=f"micro pellet hydration, case {case}",
                  config=section, seed=settings.specimen.seed, inputs=[porosity_input], rule=rule,
                  references="Caulk (2022), PhD thesis, Univ. Grenoble Alpes, Chap. 3",
                  figure=(outputs.figure, partial(figures.case_figure, ds, case)))
    checkpointer.finish()
    return ds
