"""When a macro run has levelled off, and its progress towards that in simulated days.

The run watches the mean saturation of the pellets and of the powder, the mean pressure
of the wall sensors and the axial pressures on both plates. Over the last
``stop_window_fraction`` of the elapsed time, each quantity's relative rate is its
least-squares trend times the window's duration over its current level (the trend's
value at the window's end). The stop distance is the largest ratio of a relative rate to
its tolerance (``stop_tolerance`` for the saturations, ``stop_pressure_tolerance`` for
the pressures): 1 is the threshold, the run stops at or below it. Relative to the current
level, not to the largest so far: a suction measured against its initial 132 MPa passes
any tolerance once it has fallen far enough, however fast it still falls. A trend rather
than the range: the wall readings of a quasi-static DEM fluctuate around their level.
Over a fraction of the elapsed time, the criterion bounds d ln x / d ln t by the
tolerance over the fraction: a quantity growing as a small power of time stops it too.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from shared.progress import MIN_RATE_SAMPLES, SMOOTHING

__all__ = ["DAY", "MONITORED", "RunProgress", "duration_text", "progress_line", "stop_distance",
           "stop_time_estimate"]

FloatArray = npt.NDArray[np.float64]

MONITORED = ("pellet saturation", "powder saturation", "mean sensor pressure",
             "upper plate pressure", "lower plate pressure")
"""The quantities the stop criterion watches, in the order of its columns."""
MIN_RECORDS = 10
"""Fewest records in the window for a trend."""
ESTIMATE_FRACTION = 0.5
"""Part of the elapsed time whose stop distances the stop time is extrapolated from."""
DAY = 86400.0
"""Seconds in a day [s]."""


def stop_distance(times: FloatArray, series: FloatArray, window: float,
                  tolerances: FloatArray) -> tuple[float, int]:
    """The stop distance and the column that sets it.

    Parameters
    ----------
    times
        (n,) simulated times of the records, increasing [s].
    series
        (n, k) the monitored quantities at those times (any units).
    window
        Part of the elapsed time ``times[-1]`` over which the trends are fitted [1].
    tolerances
        (k,) largest relative change over the window of each quantity [1]; 0: an
        infinite ratio, the run never stops early.

    Returns
    -------
    distance, column
        The largest ratio of relative rate to tolerance [1] (1 = at the threshold; NaN
        with fewer than ``MIN_RECORDS`` records in the window) and its column (-1 with NaN).
        A quantity constant at zero has no rate; one whose level is zero while it moves
        has an infinite one.
    """
    inside = times >= times[-1] * (1.0 - window)
    if np.count_nonzero(inside) < MIN_RECORDS:
        return float("nan"), -1
    t, y = times[inside], series[inside]
    centred = t - t.mean()
    slope = centred @ (y - y.mean(axis=0)) / (centred @ centred)
    level = np.abs(y.mean(axis=0) + slope * centred[-1])
    change = np.abs(slope) * (t[-1] - t[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = np.where(change == 0.0, 0.0, change / level)
        ratio = np.where(tolerances > 0.0, np.where(rate == 0.0, 0.0, rate / tolerances), np.inf)
    column = int(np.argmax(ratio))
    return float(ratio[column]), column


def stop_time_estimate(times: FloatArray, distances: FloatArray) -> float:
    """Simulated time at which the stop distance's trend reaches 1 [s]; NaN when unknown.

    A power law fitted to the finite distances of the last ``ESTIMATE_FRACTION`` of the
    elapsed time (ln d linear in ln t): a saturation or pressure levelling off as a power
    of time keeps its distance falling as one, and a faster decay makes the estimate late
    rather than early. Unknown while the distance does not fall along the fit.

    Parameters
    ----------
    times
        (n,) simulated times of the records [s].
    distances
        (n,) stop distance at those times [1] (NaN before it can be estimated).
    """
    keep = (times >= times[-1] * (1.0 - ESTIMATE_FRACTION)) & np.isfinite(distances) \
        & (distances > 0.0) & (times > 0.0)
    if np.count_nonzero(keep) < MIN_RECORDS:
        return float("nan")
    log_t, log_d = np.log(times[keep]), np.log(distances[keep])
    centred = log_t - log_t.mean()
    slope = centred @ (log_d - log_d.mean()) / (centred @ centred)
    if not slope < 0.0:
        return float("nan")
    # ln d = mean + slope (ln t - mean ln t) = 0
    return float(max(np.exp(log_t.mean() - log_d.mean() / slope), times[-1]))


def duration_text(seconds: float) -> str:
    """A wall-clock duration in the unit that suits it: ``40 s``, ``4.2 min``, ``3.1 h``."""
    if seconds < 90.0:
        return f"{seconds:.0f} s"
    if seconds < 5400.0:
        return f"{seconds / 60.0:.1f} min"
    return f"{seconds / 3600.0:.1f} h"


def progress_line(label: str, simulated: float, step: int, distance: float, held_by: int,
                  saturation: Sequence[float], stop_time: float, guard_time: float,
                  guard: str, seconds_per_simulated: float) -> str:
    """The progress line of a macro run.

    Parameters
    ----------
    label
        Names the run.
    simulated
        Simulated time now [s].
    step
        Steps done.
    distance
        Stop distance now [1] (NaN: not estimated yet).
    held_by
        Index in ``MONITORED`` of the quantity that sets the distance (-1: none).
    saturation
        Mean saturation of the pellets and of the powder [1].
    stop_time
        Simulated time of the stop along the distance's trend [s] (NaN: unknown).
    guard_time
        Simulated time at which the first guard ends the run at the current pace [s].
    guard
        Names that guard (``max_time_s guard``, ``max_steps guard``).
    seconds_per_simulated
        Wall time per simulated second at the current pace [s/s] (NaN: unknown).
    """
    known = f"{distance:.3g} (1 = stop; {MONITORED[held_by]})" if held_by >= 0 else "unknown yet"
    head = (f"{label}: t = {simulated / DAY:.4g} d, step {step}, stop distance {known}, "
            f"mean saturation pellets {saturation[0]:.3f} powder {saturation[1]:.3f}, ")
    if not math.isfinite(seconds_per_simulated):
        return head + "ETA unknown"
    guard_eta = duration_text(max(guard_time - simulated, 0.0) * seconds_per_simulated)
    guard_part = f"the {guard} at {guard_time / DAY:.4g} d"
    if not math.isfinite(stop_time):
        return head + (f"ETA unknown (the stop distance is not falling yet), at most {guard_eta} "
                       f"({guard_part})")
    if stop_time >= guard_time:
        return head + (f"ETA {guard_eta} ({guard_part}, before the stop near {stop_time / DAY:.4g} d "
                       "along the distance's trend)")
    eta = duration_text((stop_time - simulated) * seconds_per_simulated)
    return head + f"ETA {eta} (stop near {stop_time / DAY:.4g} d along the distance's trend; {guard_part})"


class RunProgress:
    """Log :func:`progress_line` at most every ``interval`` seconds of wall time.

    The pace (wall time per simulated second) is smoothed over the lines as
    :class:`shared.progress.Progress` smooths its rate (weight ``SMOOTHING`` on the pace
    since the previous line), and unknown until ``MIN_RATE_SAMPLES`` paces are measured:
    the first lines carry the kernels' compilation, and the time step grows by orders of
    magnitude over a run. The steps' guard follows the steps' pace since the last line.

    Parameters
    ----------
    label
        Names the run in the log line.
    log
        Where the lines go.
    max_time
        Guard on simulated time [s].
    max_steps
        Guard on the number of steps.
    stop_after
        No stop before this simulated time [s].
    simulated, step
        Simulated time [s] and steps at the start (a resumed run starts past 0).
    interval
        Least wall time between two lines [s].
    """

    def __init__(self, label: str, log: logging.Logger, max_time: float, max_steps: int,
                 stop_after: float = 0.0, simulated: float = 0.0, step: int = 0, interval: float = 30.0):
        self.label = label
        self.log = log
        self.max_time = float(max_time)
        self.max_steps = int(max_steps)
        self.stop_after = float(stop_after)
        self.interval = interval
        self._last = (time.monotonic(), float(simulated), int(step))
        self._pace: float | None = None
        self._paces = 0

    def update(self, simulated: float, step: int, saturation: Sequence[float],
               times: Sequence[float], distances: Sequence[float], held_by: int,
               force: bool = False) -> None:
        """Report the state after ``step`` steps; logs only when the interval has elapsed.

        Parameters
        ----------
        simulated
            Simulated time [s].
        step
            Steps done.
        saturation
            Mean saturation of the pellets and of the powder [1].
        times, distances
            Simulated times [s] of the records and their stop distances [1].
        held_by
            Index in ``MONITORED`` of the quantity that sets the last distance (-1: none).
        force
            Log whatever the interval.
        """
        now = time.monotonic()
        wall, earlier, steps_before = self._last
        if not force and now - wall < self.interval:
            return
        self._last = (now, simulated, step)
        if simulated > earlier:
            pace = (now - wall) / (simulated - earlier)
            self._pace = pace if self._pace is None else SMOOTHING * pace + (1.0 - SMOOTHING) * self._pace
            self._paces += 1
        per_simulated = self._pace if self._pace is not None and self._paces >= MIN_RATE_SAMPLES else float("nan")
        # the first guard at the current pace: simulated time, or the steps' worth of it
        guard_time, guard = self.max_time, "max_time_s guard"
        if step > steps_before:
            at_max_steps = simulated + (self.max_steps - step) * (simulated - earlier) / (step - steps_before)
            if at_max_steps < guard_time:
                guard_time, guard = at_max_steps, "max_steps guard"
        # below the threshold before stop_after: the stop comes at stop_after
        if distances[-1] <= 1.0:
            trend = simulated
        else:
            trend = stop_time_estimate(np.asarray(times), np.asarray(distances))
        stop_time = max(trend, self.stop_after) if math.isfinite(trend) else trend
        self.log.info("%s", progress_line(self.label, simulated, step, distances[-1], held_by, saturation,
                                          stop_time, guard_time, guard, per_simulated))
