"""The imaging settings that the CT stage's entry points read: the one list of them, and
the resources they run with.

The rules of ``workflow/rules/imaging.smk`` take their params from these tuples, so that
a rule's params hold exactly the science keys its job reads (``tests/workflow/
test_ct_settings.py`` checks them against what :func:`imaging.ct.run.porosity` and
:func:`imaging.ct.run.rev` read). The machine resources (:data:`RESOURCE_KEYS`) go through
Snakemake's ``threads:`` and ``resources:`` instead, never a param (docs/design.md §7):
changing them reruns nothing. The workflow reads this module when it builds the DAG, so
it imports nothing heavy and sits beside :mod:`imaging.ct`, not in it: that package's
``__init__`` imports the scan readers (OpenCV, dask).
"""

from __future__ import annotations

import ast
from collections.abc import Mapping
from typing import Any

from shared.errors import ConfigError

__all__ = ["POROSITY_KEYS", "RESOURCE_KEYS", "REV_KEYS", "job_resources", "resource_value"]

POROSITY_KEYS = ("calibration", "mask", "grid_spacing_m", "min_specimen_fraction", "store_scan")
"""Keys of a sample's imaging settings that set its porosity grid (``imaging_porosity``)."""

REV_KEYS = ("rev", "chords")
"""Keys of a sample's imaging settings that set its REV and chord analyses (``imaging_rev``)."""

RESOURCE_KEYS = ("workers", "chunk_mb", "memory_limit_gb", "dask_scheduler")
"""Keys that set how a scan is read (threads, slab size, memory guard, dask cluster), read
by both entry points: machine resources, not science settings. ``workers`` is the jobs'
``threads:``, the others are Snakemake resources of the same names."""


def resource_value(value: float | str | None) -> str | None:
    """A resource key's value as a Snakemake resource: a string, since Snakemake rounds a
    float resource to an integer (``chunk_mb`` is often below 1 MiB in tests); None (a
    null key) leaves the resource out."""
    return None if value is None else str(value)


def job_resources(threads: int, resources: Mapping[str, Any]) -> dict[str, Any]:
    """A CT job's :data:`RESOURCE_KEYS` from the threads and resources it runs with (for
    :meth:`imaging.ct.settings.ScanResources.from_mapping`).

    Parameters
    ----------
    threads
        The job's threads (``snakemake.threads``), the ``workers``.
    resources
        The job's resources (``snakemake.resources``): ``chunk_mb`` [MiB], and
        ``memory_limit_gb`` [GiB] and ``dask_scheduler`` unless null, as
        :func:`resource_value` wrote them or as ``--set-resources`` gave them.
    """
    limit = resources.get("memory_limit_gb")
    return {"workers": int(threads), "chunk_mb": _number(resources["chunk_mb"]),
            "memory_limit_gb": None if limit is None else _number(limit),
            "dask_scheduler": resources.get("dask_scheduler")}


def _number(value: int | float | str) -> int | float:
    """A numeric resource back as the config wrote it (``"32"`` -> 32, ``"0.5"`` -> 0.5),
    so that the settings in a file's provenance are the config's."""
    try:
        number = ast.literal_eval(value) if isinstance(value, str) else value
    except (ValueError, SyntaxError):
        number = None
    if not isinstance(number, int | float) or isinstance(number, bool) or not number > 0:
        raise ConfigError(f"a CT job's chunk_mb and memory_limit_gb resources are positive "
                          f"numbers, got {value!r} (--set-resources?)")
    return number
