"""Named runs: where a configuration's outputs live, and the entries an overlay removes.

A configuration with ``run_name: null`` (the default) writes under ``results/``; with
``run_name: myscan`` every output, log and benchmark of the run goes under
``results/myscan/`` instead, laid out as ``results/`` is (docs/howto-own-scan.md). Each
output path then belongs to one configuration, so two runs keep their files and
Snakemake's records apart, and switching between them reruns nothing.

An overlay file can only add or change keys (Snakemake merges the configuration files
mapping by mapping); an entry of ``samples``, ``packings``, ``micro.cases`` or
``macro.cases`` set to null is removed instead (:func:`drop_removed_entries`), so that
one overlay can run a scan without the default's phantom, packing or cases.
"""

from __future__ import annotations

from collections.abc import Mapping, MutableMapping
from typing import Any

__all__ = [
    "RESULTS", "STAGE_FOLDERS", "REMOVABLE_SECTIONS", "drop_removed_entries", "run_folder",
]

RESULTS = "results"
"""The folder of every run's outputs, relative to the working directory."""

STAGE_FOLDERS = (
    "phantom", "images", "porosity", "rev", "packing", "micro", "studies", "upscaling",
    "macro", "logs", "benchmarks",
)
"""The folders a run writes under its own folder; a run may not be named like one."""

REMOVABLE_SECTIONS = (("samples",), ("packings",), ("micro", "cases"), ("macro", "cases"))
"""The mappings whose entries an overlay removes by setting them to null."""


def run_folder(config: Mapping[str, Any]) -> str:
    """The folder of a run's outputs.

    Parameters
    ----------
    config
        The configuration (its ``run_name``; absent or null: the unnamed run).

    Returns
    -------
    str
        ``results`` for the unnamed run, ``results/<run_name>`` for a named one.
    """
    name = config.get("run_name")
    return RESULTS if name is None else f"{RESULTS}/{name}"


def drop_removed_entries(config: MutableMapping[str, Any]) -> list[str]:
    """Remove the entries that an overlay set to null, in place.

    Parameters
    ----------
    config
        The merged configuration, before validation.

    Returns
    -------
    list of str
        The dotted keys removed, e.g. ``["micro.cases.homogeneous"]``.
    """
    removed = []
    for path in REMOVABLE_SECTIONS:
        section: Any = config
        for key in path:
            section = section.get(key) if isinstance(section, Mapping) else None
        if not isinstance(section, MutableMapping):
            continue
        for name in [name for name, entry in section.items() if entry is None]:
            del section[name]
            removed.append(".".join((*path, name)))
    return removed
