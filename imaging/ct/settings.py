"""Settings of the CT stage's computations, and the machine resources they run with.

:class:`PorositySettings` and :class:`RevSettings` hold the science settings (validated
config sections), :class:`ScanResources` how many slabs are read at once, how large they
are and where they are computed: resources change how fast a scan is read, never a
result, so they are a separate argument and enter no settings object.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, fields
from typing import Any

from imaging.ct_keys import RESOURCE_KEYS

__all__ = ["ONE_WORKER", "PorositySettings", "RevSettings", "ScanResources", "grid_spacing",
           "setting_keys"]

log = logging.getLogger("imaging.ct")

_MASK_MODES = ("threshold", "full", "cylinder")


def setting_keys(sample: str, key: str) -> str:
    """How a message names an imaging key: globally or for this sample alone."""
    return f"imaging.{key} (or samples.{sample}.imaging.{key} for this sample alone)"


def grid_spacing(spacing: float | None, micro_spacing: Sequence[float]) -> float:
    """Porosity grid spacing [m]: ``imaging.grid_spacing_m``, else the mean micro point
    spacing ``specimen_size_m / micro.n_points^(1/3)`` of the smallest case on the sample.

    Parameters
    ----------
    spacing
        ``imaging.grid_spacing_m`` [m], or None.
    micro_spacing
        ``(specimen_size_m, micro.n_points)`` with the smallest cube among the micro cases
        that read the sample (shared/scan_sizes.py, ``sample_point_spacing``).
    """
    if spacing is not None:
        return float(spacing)
    size, n_points = micro_spacing
    return float(size / n_points ** (1.0 / 3.0))


@dataclass(frozen=True)
class ScanResources:
    """How a scan is read: machine resources, not science settings.

    Attributes
    ----------
    workers : int
        Slabs read and reduced at once (threads).
    chunk_mb : float
        Greyscale per slab [MiB] of a scan opened from a file.
    memory_limit_gb : float or None
        Estimated peak above which a job is refused [GiB]; None: 80 % of the machine's.
    dask_scheduler : str or None
        Address of a dask.distributed scheduler, or None for the job's own threads.
    """

    workers: int = 1
    chunk_mb: float = 64.0
    memory_limit_gb: float | None = None
    dask_scheduler: str | None = None

    @classmethod
    def from_mapping(cls, settings: Mapping[str, Any]) -> ScanResources:
        """The resources named by the keys ``workers``, ``chunk_mb``, ``memory_limit_gb``
        and ``dask_scheduler`` of ``settings`` (the defaults for those it lacks)."""
        return cls(**{key: settings[key] for key in RESOURCE_KEYS if key in settings})

    def memory_limit_bytes(self) -> float:
        """The memory limit [bytes]: ``memory_limit_gb``, else 80 % of the machine's
        physical memory (the rest for the system)."""
        if self.memory_limit_gb:
            return self.memory_limit_gb * 2**30
        return 0.8 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")

    @contextmanager
    def scheduler(self) -> Iterator[None]:
        """Slabs computed by the dask.distributed cluster at ``dask_scheduler`` while the
        block runs, else by the job's own threads."""
        if self.dask_scheduler is None:
            yield
            return
        from distributed import Client

        with Client(self.dask_scheduler):
            log.info("dask scheduler %s", self.dask_scheduler)
            yield


ONE_WORKER = ScanResources()
"""The default resources: one worker, slabs of 64 MiB, 80 % of the machine's memory."""


@dataclass(frozen=True)
class PorositySettings:
    """Settings of :func:`imaging.ct.porosity.porosity_grid`.

    Attributes
    ----------
    grid_spacing : float
        Edge of a grid block [m] (:func:`grid_spacing`).
    calibration : mapping
        The ``imaging.calibration`` section (anchors, densities, porosity bounds).
    mask : mapping
        The ``imaging.mask`` section (mode ``threshold``, ``full`` or ``cylinder``).
    min_specimen_fraction : float
        Fraction of a block's voxels inside the specimen below which it is NaN [1].
    material : mapping
        ``dry_density_kg_m3`` and ``reference_porosity`` of ``materials.pellet``: the
        calibration maps the measured mean dry density to the reference porosity.
    store_scan : bool
        Whether the specimen image keeps the greyscale scan itself.
    sample : str
        The sample's name, in messages.
    """

    grid_spacing: float
    calibration: Mapping[str, Any]
    mask: Mapping[str, Any]
    min_specimen_fraction: float
    material: Mapping[str, Any]
    store_scan: bool = False
    sample: str = "scan"

    def __post_init__(self) -> None:
        if not self.grid_spacing > 0:
            raise ValueError(f"grid_spacing must be positive, got {self.grid_spacing}")
        if not 0 <= self.min_specimen_fraction <= 1:
            raise ValueError(f"min_specimen_fraction must lie in [0, 1], got "
                             f"{self.min_specimen_fraction}")
        if self.mask["mode"] not in _MASK_MODES:
            raise ValueError(f"mask mode must be one of {_MASK_MODES}, got {self.mask['mode']!r}")

    def record(self) -> dict[str, Any]:
        """The settings as plain values, as a file's provenance records them."""
        return {item.name: getattr(self, item.name) for item in fields(self) if item.name != "sample"}

    @classmethod
    def from_config(cls, sample: str, imaging: Mapping[str, Any], material: Mapping[str, Any],
                    micro_spacing: Sequence[float]) -> PorositySettings:
        """The settings of a sample from its validated imaging settings.

        Parameters
        ----------
        sample
            Sample name.
        imaging
            The sample's imaging settings (:func:`shared.config.sample_imaging`):
            ``calibration``, ``mask``, ``grid_spacing_m``, ``min_specimen_fraction`` and
            ``store_scan``.
        material
            ``dry_density_kg_m3`` and ``reference_porosity`` of ``materials.pellet``.
        micro_spacing
            ``(specimen_size_m, micro.n_points)`` of the smallest micro case on the
            sample, for the default grid spacing.
        """
        return cls(grid_spacing=grid_spacing(imaging["grid_spacing_m"], micro_spacing),
                   calibration=imaging["calibration"], mask=imaging["mask"],
                   min_specimen_fraction=imaging["min_specimen_fraction"],
                   material=material, store_scan=bool(imaging["store_scan"]), sample=sample)


@dataclass(frozen=True)
class RevSettings:
    """Settings of :func:`imaging.ct.rev.scan_rev`: the ``imaging.rev`` and
    ``imaging.chords`` sections (validated).

    Attributes
    ----------
    rev : mapping
        ``n_sizes``, ``n_positions``, ``tolerance``, ``max_window_fraction``,
        ``centred_n_sizes`` and ``seed``.
    chords : mapping
        ``pore_porosity_threshold`` [1] and ``include_edges``.
    sample : str
        The sample's name, in messages.
    """

    rev: Mapping[str, Any]
    chords: Mapping[str, Any]
    sample: str = "scan"

    def __post_init__(self) -> None:
        if not 0 < self.chords["pore_porosity_threshold"] < 1:
            raise ValueError("pore_porosity_threshold must lie in (0, 1), got "
                             f"{self.chords['pore_porosity_threshold']}")

    @property
    def n_windows(self) -> int:
        """REV windows held at once: ``n_sizes`` random sizes and one more, each at
        ``n_positions`` positions (the memory estimate counts them)."""
        return (self.rev["n_sizes"] + 1) * self.rev["n_positions"]
