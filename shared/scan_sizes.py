"""The sizes of an own scan against the micro cases it informs, checked when the config loads.

A micro case with ``porosity: ct`` cuts a cube of ``specimen_size_m`` out of its sample's
porosity grid (micro/pellet.py, ``centred_grid``), so a scan shorter than that cube, or
a grid too coarse to hold it, fails after the imaging jobs have run. The workflow checks
both before any job starts (workflow/rules/common.smk), from the scan's shape (its
headers only) and ``samples.<sample>.voxel_size_m``:

- the porosity grid's spacing of a sample is ``imaging.grid_spacing_m`` when it is set,
  else ``specimen_size_m / micro.n_points^(1/3)`` with the smallest ``specimen_size_m`` of
  the cases that read the sample (:func:`sample_point_spacing`);
- the grid's block centres span the scan's extent less one spacing; along every axis
  that span must hold the case's cube and twice its ``offset_m`` along that axis
  (:func:`check_scan_sizes`).

The condition is necessary, not sufficient: the specimen may fill only part of the field
of view, which the micro job checks against the grid itself.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from shared.config import ConfigError, sample_imaging

__all__ = ["sample_point_spacing", "sample_grid_spacing", "check_scan_sizes"]


def _cases_of(config: Mapping[str, Any], sample: str) -> list[str]:
    """The micro cases whose porosity grid is this sample's."""
    micro = config.get("micro") or {}
    return [case for case, entry in micro.get("cases", {}).items()
            if entry.get("sample", micro["sample"]) == sample]


def _edge_and_points(config: Mapping[str, Any], case: str) -> tuple[float, int]:
    micro = config["micro"]
    entry = micro["cases"][case]
    return (float(entry.get("specimen_size_m", micro["specimen_size_m"])),
            int(entry.get("n_points", micro["n_points"])))


def sample_point_spacing(config: Mapping[str, Any], sample: str) -> list[float]:
    """``[edge, micro.n_points]``, whose mean point spacing ``edge / n_points^(1/3)`` is the
    sample's default grid spacing: ``edge`` is the smallest ``specimen_size_m`` of the
    cases that read the sample (none: ``micro.specimen_size_m``).

    The point count is the section's, not the cases' own: cases that differ only in their
    number of points (the convergence study, thesis Sec. 3.5.8) read one porosity grid.

    Parameters
    ----------
    config
        The validated configuration.
    sample
        A name of ``samples``.

    Returns
    -------
    list of float
        The cube's edge [m] and the number of points.
    """
    micro = config["micro"]
    edges = [_edge_and_points(config, case)[0] for case in _cases_of(config, sample)]
    return [min(edges, default=float(micro["specimen_size_m"])), int(micro["n_points"])]


def sample_grid_spacing(config: Mapping[str, Any], sample: str,
                        schema: Mapping[str, Any] | None = None) -> float:
    """The porosity grid spacing [m] of a sample: its ``imaging.grid_spacing_m``, else
    :func:`sample_point_spacing`'s mean spacing."""
    spacing = sample_imaging(config, sample, schema)["grid_spacing_m"]
    if spacing is not None:
        return float(spacing)
    edge, n_points = sample_point_spacing(config, sample)
    return float(edge / n_points ** (1.0 / 3.0))


def check_scan_sizes(config: Mapping[str, Any], shapes: Mapping[str, Sequence[int]],
                     schema: Mapping[str, Any] | None = None) -> None:
    """Every ``porosity: ct`` micro case's cube fits inside its sample's porosity grid.

    Parameters
    ----------
    config
        The validated configuration.
    shapes
        Sample name -> the scan's voxel counts ``(nz, ny, nx)``; samples left out (their
        file could not be opened: the imaging job names the problem) are not checked.
    schema
        The configuration schema (default: the workflow's).

    Raises
    ------
    ConfigError
        Naming the case's ``specimen_size_m``, the sample's ``voxel_size_m`` and the grid
        spacing's key, with the scan's extent and the largest cube that fits.
    """
    for sample, shape in shapes.items():
        voxel_size = float(config["samples"][sample]["voxel_size_m"])
        spacing = sample_grid_spacing(config, sample, schema)
        explicit = sample_imaging(config, sample, schema)["grid_spacing_m"] is not None
        spacing_key = f"samples.{sample}.imaging.grid_spacing_m" + (
            "" if explicit else "; null: the finest point spacing of the cases on it")
        extent = {axis: n * voxel_size for axis, n in zip("zyx", shape, strict=True)}
        for case in _cases_of(config, sample):
            entry = config["micro"]["cases"][case]
            if entry.get("porosity", "ct") != "ct":
                continue
            edge, _ = _edge_and_points(config, case)
            offset = dict(zip("xyz", entry.get("offset_m", (0.0, 0.0, 0.0)), strict=True))
            for axis in "zyx":
                room = extent[axis] - max(spacing, voxel_size) - 2.0 * abs(offset[axis])
                if edge > room * (1.0 + 1e-9):
                    default = "" if "specimen_size_m" in entry else " (micro.specimen_size_m)"
                    shift = f" and twice offset_m ({abs(offset[axis]):g} m)" if offset[axis] else ""
                    raise ConfigError(
                        f"config key 'micro.cases.{case}.specimen_size_m': the {edge * 1e3:g} mm "
                        f"cube{default} does not fit in sample {sample!r} along {axis}: "
                        f"{shape['zyx'.index(axis)]} voxels of {voxel_size:g} m "
                        f"(samples.{sample}.voxel_size_m) = {extent[axis] * 1e3:.4g} mm, less one "
                        f"grid spacing of {spacing * 1e3:.4g} mm ({spacing_key}){shift}, hold "
                        f"at most {max(room, 0.0) * 1e3:.4g} mm: set a smaller specimen_size_m "
                        "or check the voxel size"
                    )
