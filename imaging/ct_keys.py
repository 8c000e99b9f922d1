"""The imaging settings that the CT stage's entry points read: the one list of them.

The rules of ``workflow/rules/imaging.smk`` take their params from these tuples, so that
a rule's params hold exactly the keys its job reads (``tests/workflow/test_ct_settings.py``
checks them against what :func:`imaging.ct.run.porosity` and :func:`imaging.ct.run.rev`
read). The workflow reads it when it builds the DAG, so it imports nothing and sits
beside :mod:`imaging.ct`, not in it: that package's ``__init__`` imports the scan readers
(OpenCV, dask).
"""

__all__ = ["POROSITY_KEYS", "RESOURCE_KEYS", "REV_KEYS"]

POROSITY_KEYS = ("calibration", "mask", "grid_spacing_m", "min_specimen_fraction", "store_scan")
"""Keys of a sample's imaging settings that set its porosity grid (``imaging_porosity``)."""

REV_KEYS = ("rev", "chords")
"""Keys of a sample's imaging settings that set its REV and chord analyses (``imaging_rev``)."""

RESOURCE_KEYS = ("workers", "chunk_mb", "memory_limit_gb", "dask_scheduler")
"""Keys that set how a scan is read (threads, slab size, memory guard, dask cluster), read
by both entry points: machine resources, not science settings."""
