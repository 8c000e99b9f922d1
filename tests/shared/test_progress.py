"""Progress lines and phase clocks against closed forms, on a simulated clock."""

from __future__ import annotations

import logging
import math
import types

import pytest

from shared import progress
from shared.progress import ConvergenceProgress, PhaseClock, Progress

LOG = logging.getLogger("test.progress")


@pytest.fixture
def clock(monkeypatch):
    """A settable clock standing for both ``time.monotonic`` and ``time.perf_counter``."""
    now = {"t": 1000.0}
    fake = types.SimpleNamespace(monotonic=lambda: now["t"], perf_counter=lambda: now["t"])
    monkeypatch.setattr(progress, "time", fake)
    return now


def test_eta_of_a_resumed_loop_uses_the_rate_since_the_restart(clock):
    """9 of 14 units were done before the restart; 1 more in 100 s, then 1 in 100 s:
    the rate 0.01 units/s is known from the second report on, and 3 left take 300 s."""
    bar = Progress(14, "run", LOG, done_before=9, interval=0.0)
    clock["t"] += 100.0
    bar.update(10)
    assert math.isnan(bar.eta(10))  # one rate: not yet known
    clock["t"] += 100.0
    bar.update(11)
    assert bar.eta(11) == pytest.approx(300.0)
    assert bar.eta(14) == 0.0


def test_eta_waits_for_the_rate_and_smooths_it(clock, caplog):
    """A first unit of 1000 s (the set-up), then units of 10 s: no ETA after the first
    report, then the exponential average 0.3 r_new + 0.7 r_old, not the mean rate."""
    bar = Progress(100, "loop", LOG, interval=0.0)
    with caplog.at_level(logging.INFO, logger=LOG.name):
        clock["t"] += 1000.0
        bar.update(1)
        assert "ETA not yet known" in caplog.records[-1].message
        clock["t"] += 10.0
        bar.update(2)
    smoothed = 0.3 * 0.1 + 0.7 * 0.001
    assert bar.eta(2) == pytest.approx(98 / smoothed)
    assert f"ETA {98 / smoothed:.1f} s" in caplog.records[-1].message
    clock["t"] += 10.0
    bar.update(3)
    assert bar.eta(3) == pytest.approx(97 / (0.3 * 0.1 + 0.7 * smoothed))
    # the mean rate (3 units in 1020 s) would have said 32 300 s
    assert bar.eta(3) < 0.1 * 97 * 1020 / 3


def test_trend_eta_extrapolates_growing_durations(clock):
    """Units of 10, 20, 30 s (after 2 of 7 done before a restart): the next two take 40
    and 50 s, 90 s in all, where the mean rate would say 40 s. A fourth unit of 1 s: the
    least-squares line through (2.5, 10), (3.5, 20), (4.5, 30), (5.5, 1) is
    22.05 - 1.7 x: 11 s for the last unit (midpoint 6.5)."""
    bar = Progress(7, "run", LOG, done_before=2, interval=0.0, trend=True)
    for done, seconds in ((3, 10.0), (4, 20.0), (5, 30.0)):
        clock["t"] += seconds
        bar.update(done)
    assert bar.eta(5) == pytest.approx(90.0)
    clock["t"] += 1.0
    bar.update(6)
    assert bar.eta(6) == pytest.approx(11.0)


def test_convergence_eta_extrapolates_a_geometric_decay(clock, caplog):
    """A plateau at 1, then r = exp(-(t - t1) / 10 s): from e^-2 to a target e^-4 takes
    20 s more, measured from where the decay began (below half the first residual)."""
    bar = ConvergenceProgress(math.exp(-4.0), "balance", LOG, interval=0.0)
    assert math.isnan(bar.eta(float("inf")))  # no finite residual yet
    assert math.isnan(bar.eta(1.0))
    clock["t"] += 30.0
    assert math.isnan(bar.eta(0.9))  # still on the plateau
    clock["t"] += 10.0
    assert math.isnan(bar.eta(math.exp(-1.0)))  # the decay starts the clock
    clock["t"] += 10.0
    assert bar.eta(math.exp(-2.0)) == pytest.approx(20.0)
    clock["t"] += 5.0
    assert math.isnan(bar.eta(1.0))  # rose again: no estimate
    assert bar.eta(math.exp(-5.0)) == 0.0
    with caplog.at_level(logging.INFO, logger="test.progress"):
        bar.update(7, math.exp(-3.0))
        bar.update(8, 1.0)
    assert "step 7" in caplog.text and "ETA" in caplog.text and "not yet known" in caplog.text
    with pytest.raises(ValueError, match="target"):
        ConvergenceProgress(0.0, "balance", LOG)


def test_phase_clock_partitions_and_resumes(clock):
    """Blocks add up per phase, an exception still counts, and totals carry over."""
    timer = PhaseClock({"flow": 2.0})
    with timer.phase("flow"):
        clock["t"] += 3.0
    with pytest.raises(RuntimeError), timer.phase("relaxation"):
        clock["t"] += 0.5
        raise RuntimeError("diverged")
    timer.add("relaxation", 1.0)
    assert timer.seconds == {"flow": 5.0, "relaxation": 1.5}
