"""A long run's restart file: resume from it, save to it at a wall-clock cadence, remove it.

The one checkpointer of the micro and macro runs. It owns the file (written atomically
as a :mod:`shared.snapshot`: data only, checked before use), the digest that decides
whether a file is this run's (the configuration, the input files and the code the run
imports: a file of another is ignored), the cadence of the saves (``interval`` seconds
of wall time since the last one; :meth:`Checkpointer.due`) and the wall time of the
killed runs before, in all and per phase, which the saves carry over. What a file holds
is the stage's: it hands :meth:`Checkpointer.save` its state as plain metadata and
arrays, and :meth:`Checkpointer.resume` a function that rebuilds it from them
(micro/checkpoint.py, macro/checkpoint.py).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from shared.progress import PhaseClock
from shared.provenance import config_sha256, file_sha256, module_sha256
from shared.snapshot import read_meta, read_snapshot, write_snapshot

__all__ = ["Checkpointer", "run_digest", "saved_wall_time"]

T = TypeVar("T")


def run_digest(config: Mapping[str, Any], code: str | Path, inputs: Iterable[str | Path] = ()) -> str:
    """The hash of what decides a run: its configuration section, the sha256 of its input
    files and the sources of ``code`` and of the modules it imports
    (:func:`shared.provenance.module_sha256`): a restart file of another is not resumed."""
    return config_sha256({**config, "code": module_sha256(code),
                          "inputs": [file_sha256(path) for path in inputs]})


def saved_wall_time(path: Path) -> tuple[float, dict[str, float]]:
    """The wall time [s] a run had taken when it wrote the restart file ``path``, in all
    and per phase (empty for a file without phases)."""
    meta = read_meta(path)
    return float(meta.get("wall_time", 0.0)), dict(meta.get("phase_seconds", {}))


@dataclass
class Checkpointer:
    """A run's restart file and the cadence of its saves.

    Attributes
    ----------
    path
        The restart file.
    digest
        The hash of what decides the run (:func:`run_digest`).
    interval
        Wall time between two saves [s] (:meth:`due`); infinite: only the saves the
        stage asks for.
    log
        Where the line of a file ignored or set aside goes.
    started
        ``time.monotonic()`` at the run's start.
    earlier
        Wall time of the killed runs before, up to their last save [s].
    clock
        The wall time per phase, the earlier runs' included.
    last_save
        ``time.monotonic()`` at the last save (or since the cadence started).
    resumed
        Whether :meth:`resume` found this run's file.
    """

    path: Path
    digest: str
    interval: float = math.inf
    log: logging.Logger = field(default_factory=lambda: logging.getLogger("claychain"))
    started: float = field(default_factory=time.monotonic)
    earlier: float = 0.0
    clock: PhaseClock = field(default_factory=PhaseClock)
    last_save: float = field(default_factory=time.monotonic)
    resumed: bool = False

    def resume(self, restore: Callable[[dict[str, Any], dict[str, np.ndarray]], T]) -> T | None:
        """What ``restore(meta, arrays)`` rebuilds from the file, or None (no file, one of
        another digest, or one that fails its checks: :func:`shared.snapshot.read_snapshot`);
        resuming carries the earlier runs' wall time over."""
        state = read_snapshot(self.path, self.digest, restore, self.log)
        if state is not None:
            self.resumed = True
            self.earlier, phases = saved_wall_time(self.path)
            self.clock = PhaseClock(phases)
        return state

    def wall_time(self) -> float:
        """The run's wall time so far [s], the earlier runs' included."""
        return self.earlier + time.monotonic() - self.started

    def restart_cadence(self) -> None:
        """Count the interval to the next save from now (the run's set-up done)."""
        self.last_save = time.monotonic()

    def due(self, intervals: float = 1.0) -> bool:
        """Whether ``intervals`` times ``interval`` have passed since the last save."""
        return time.monotonic() - self.last_save >= intervals * self.interval

    def save(self, meta: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
        """Write the stage's state (plain ``meta``, ``arrays``) with the wall time so far,
        in all and per phase, atomically (:func:`shared.snapshot.write_snapshot`)."""
        write_snapshot(self.path, self.digest, {**meta, "wall_time": self.wall_time(),
                                                "phase_seconds": dict(self.clock.seconds)}, arrays)
        self.last_save = time.monotonic()

    def finish(self) -> None:
        """Remove the file: the run has written its outputs."""
        self.path.unlink(missing_ok=True)
