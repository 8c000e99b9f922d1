"""Progress of long loops: a periodic log line with the fraction done and an ETA."""

from __future__ import annotations

import logging
import time

__all__ = ["Progress"]


class Progress:
    """Log ``label: k/n (p %), elapsed, ETA`` at most every ``interval`` seconds.

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
    """

    def __init__(self, total: float, label: str, log: logging.Logger, interval: float = 10.0):
        self.total = float(total)
        self.label = label
        self.log = log
        self.interval = interval
        self.start = time.monotonic()
        self._last = -float("inf")

    def update(self, done: float, force: bool = False) -> None:
        """Report ``done`` units finished; logs only when the interval has elapsed."""
        now = time.monotonic()
        if not force and now - self._last < self.interval:
            return
        self._last = now
        elapsed = now - self.start
        fraction = min(max(done / self.total, 0.0), 1.0) if self.total > 0 else 1.0
        eta = elapsed * (1.0 - fraction) / fraction if fraction > 0 else float("nan")
        self.log.info(
            "%s: %g/%g (%.0f %%), elapsed %.1f s, ETA %.1f s",
            self.label, done, self.total, 100.0 * fraction, elapsed, eta,
        )
