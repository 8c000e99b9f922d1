"""Progress of long loops: a periodic log line with the fraction done and an ETA, and
the cumulative wall time of a run's phases."""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager

import numpy as np

__all__ = ["ConvergenceProgress", "PhaseClock", "Progress", "SMOOTHING", "MIN_RATE_SAMPLES"]


SMOOTHING = 0.3
"""Weight of the latest rate in the smoothed rate (tqdm's default ``smoothing``)."""

MIN_RATE_SAMPLES = 2
"""Rates measured between reports before an ETA is given: the first unit of a loop
carries its set-up (numba compiling its kernels), so one sample says little."""


class Progress:
    """Log ``label: k/n (p %), elapsed, ETA`` at most every ``interval`` seconds.

    The ETA divides the work left by a smoothed rate: an exponential moving average
    (weight :data:`SMOOTHING` on the latest) of the rates between successive reports,
    as tqdm smooths its rate. Until :data:`MIN_RATE_SAMPLES` rates are known it reads
    "not yet known". tqdm itself redraws one terminal line; our jobs log to files, one
    line per report, so the lines are ours.

    Parameters
    ----------
    total
        Number of units of work.
    label
        Name of the loop in the log line.
    log
        Where the lines go.
    interval
        Minimum time between lines [s].
    done_before
        Units finished before this process started (a resumed run): the rates are
        those of the units done since.
    trend
        For units that take longer and longer (the micro checkpoints: 1 to 7 minutes
        each at 150k points), extrapolate the linear trend of the units' durations
        instead of their smoothed rate, once three have been reported (each unit lasting
        at least the shortest so far).
    """

    def __init__(self, total: float, label: str, log: logging.Logger, interval: float = 10.0,
                 done_before: float = 0.0, trend: bool = False):
        self.total = float(total)
        self.label = label
        self.log = log
        self.interval = interval
        self.done_before = float(done_before)
        self.trend = trend
        self.start = time.monotonic()
        self._last = -float("inf")
        self._logged: float | None = None
        self._reports: list[tuple[float, float]] = [(self.done_before, self.start)]
        self._rate: float | None = None
        self._samples = 0

    def _observe(self, done: float, now: float) -> None:
        """Fold the rate since the previous report into the smoothed rate."""
        last_done, last_time = self._reports[-1]
        if done <= last_done or now <= last_time:
            return
        rate = (done - last_done) / (now - last_time)
        self._rate = rate if self._rate is None else SMOOTHING * rate + (1.0 - SMOOTHING) * self._rate
        self._samples += 1
        self._reports.append((done, now))

    def eta(self, done: float) -> float:
        """Seconds left once ``done`` units are finished [s]: the work left at the
        smoothed rate, or along the durations' trend (see ``trend``); NaN while the
        rate is not known yet, 0 when nothing is left."""
        if done >= self.total:
            return 0.0
        if self.trend and len(self._reports) >= 4:
            units, times = np.array(self._reports).T
            middles = 0.5 * (units[1:] + units[:-1])
            durations = np.diff(times) / np.diff(units)
            slope, intercept = np.polyfit(middles, durations, 1)
            remaining = np.arange(done, math.ceil(self.total)) + 0.5
            return float(np.maximum(intercept + slope * remaining, durations.min()).sum())
        if self._rate is None or self._samples < MIN_RATE_SAMPLES or self._rate <= 0.0:
            return float("nan")
        return (self.total - done) / self._rate

    def update(self, done: float, force: bool = False) -> None:
        """Report ``done`` units finished; logs only when the interval has elapsed.

        ``force`` logs regardless of the interval, unless the last line logged already
        reported ``done`` (a final forced report right after the first update of a
        one-chunk pass would print the same line twice).
        """
        now = time.monotonic()
        self._observe(done, now)
        if force and self._logged == done:
            return
        if not force and now - self._last < self.interval:
            return
        self._last = now
        self._logged = done
        fraction = min(max(done / self.total, 0.0), 1.0) if self.total > 0 else 1.0
        eta = self.eta(done)
        self.log.info(
            "%s: %g/%g (%.0f %%), elapsed %.1f s, ETA %s",
            self.label, done, self.total, 100.0 * fraction, now - self.start,
            f"{eta:.1f} s" if math.isfinite(eta) else "not yet known",
        )


class ConvergenceProgress:
    """Log ``label: step k, residual r (target t), elapsed, ETA`` at most every
    ``interval`` seconds, for an iteration that drives a residual down to a target.

    The ETA extrapolates a geometric decay: (ln r - ln t) over the rate of fall of ln r
    per second since the residual first fell below half its first finite value. A
    largest departure often stays on a plateau before it decays (the farthest cell of a
    diffusion front has not moved yet); until it leaves it, and while it does not fall,
    there is no estimate.

    Parameters
    ----------
    target
        Residual at which the iteration stops [1], > 0.
    label, log, interval
        As for :class:`Progress`.
    """

    def __init__(self, target: float, label: str, log: logging.Logger, interval: float = 60.0):
        if not target > 0.0:
            raise ValueError(f"target must be > 0, got {target}")
        self.target = float(target)
        self.label = label
        self.log = log
        self.interval = interval
        self.start = time.monotonic()
        self._first: float | None = None
        self._decaying: tuple[float, float] | None = None
        self._last = time.monotonic()

    def eta(self, residual: float) -> float:
        """Seconds left to the target at the residual's rate of fall [s]; NaN if unknown."""
        now = time.monotonic()
        if not math.isfinite(residual) or residual <= 0.0:
            return float("nan")
        if residual <= self.target:
            return 0.0
        if self._first is None:
            self._first = residual
        if self._decaying is None:
            if residual <= 0.5 * self._first:
                self._decaying = (now, residual)
            return float("nan")
        since, first = self._decaying
        fall = (math.log(first) - math.log(residual)) / (now - since) if now > since else 0.0
        return (math.log(residual) - math.log(self.target)) / fall if fall > 0 else float("nan")

    def update(self, step: int, residual: float) -> None:
        """Report the residual after ``step`` iterations; logs only when the interval
        has elapsed."""
        eta = self.eta(residual)
        now = time.monotonic()
        if now - self._last < self.interval:
            return
        self._last = now
        self.log.info("%s: step %d, residual %.3g (target %.3g), elapsed %.1f s, ETA %s",
                      self.label, step, residual, self.target, now - self.start,
                      f"{eta:.1f} s" if math.isfinite(eta) else "not yet known")


class PhaseClock:
    """Cumulative wall time of the named phases of a run [s], carried over a restart.

    Parameters
    ----------
    seconds
        Totals so far per phase [s] (those of an interrupted run to resume).
    """

    def __init__(self, seconds: Mapping[str, float] | None = None):
        self.seconds: dict[str, float] = {k: float(v) for k, v in (seconds or {}).items()}

    def add(self, name: str, seconds: float) -> None:
        """Count ``seconds`` [s] to phase ``name``."""
        self.seconds[name] = self.seconds.get(name, 0.0) + seconds

    @contextmanager
    def phase(self, name: str) -> Iterator[None]:
        """Count the wall time of the ``with`` block to phase ``name``."""
        start = time.perf_counter()
        try:
            yield
        finally:
            self.add(name, time.perf_counter() - start)
