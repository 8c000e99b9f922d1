"""The stop criterion relative to the current levels, its time estimate and the progress line."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from macro.stopping import MONITORED, RunProgress, progress_line, stop_distance, stop_time_estimate
from tests._defaults import CONFIG

DAY = 86400.0
NUMERICS = CONFIG["macro"]["numerics"]
WINDOW = NUMERICS["stop_window_fraction"]
TOLERANCES = np.array([NUMERICS["stop_tolerance"]] * 2 + [NUMERICS["stop_pressure_tolerance"]] * 3)
TIMES = np.linspace(0.0, 200.0 * DAY, 2001)


def _series(pellet_saturation):
    """The monitored columns: the given pellet saturation, a levelled powder saturation,
    and levelled pressures of 1-2 MPa."""
    flat = np.ones_like(TIMES)
    return np.column_stack([pellet_saturation, 0.85 * flat, 1.3e6 * flat, 2.0e6 * flat, 1.8e6 * flat])


def _window_span():
    """Span of the records in the window [s] (the window's duration unless rounding leaves
    out the record at its start)."""
    inside = TIMES[TIMES >= (1.0 - WINDOW) * TIMES[-1]]
    return inside[-1] - inside[0]


def test_defaults_the_tests_read():
    """The tests below read the defaults: saturations within 1 % of their value over a
    fifth of the elapsed time, pressures within 5 %."""
    assert WINDOW == 0.2 and NUMERICS["stop_tolerance"] == 0.01
    assert NUMERICS["stop_pressure_tolerance"] == 0.05


@pytest.mark.parametrize("since", [0.9, 0.5])
def test_saturation_still_rising_does_not_stop(since):
    """Flat, then rising linearly by 1.5 % of its final value per tenth of the elapsed
    time from ``since`` of it on (over the last tenth only, or steadily). The trend of a
    rise h over the last L of a window W, written out: the least-squares slope times W is
    h (3 L / W - 2 L^2 / W^2) (h once the rise covers the window); the distance is that
    over the tolerance, 1.5 at least for a window of a tenth or a fifth."""
    end, total = 0.8, TIMES[-1]
    rise = end * 0.015 * (1.0 - since) / 0.1
    rising = end - rise + rise * np.clip((TIMES - since * total) / ((1.0 - since) * total), 0.0, None)
    distance, column = stop_distance(TIMES, _series(rising), WINDOW, TOLERANCES)
    span = _window_span()
    last = min((1.0 - since) * total, span)
    ramp = end * 0.015 * last / (0.1 * total)
    expected = ramp * (3.0 * last / span - 2.0 * last**2 / span**2) / end / TOLERANCES[0]
    assert distance == pytest.approx(expected, rel=1e-2)
    assert distance >= 1.5 * (1.0 - 1e-2)
    assert MONITORED[column] == "pellet saturation"


def test_levelled_series_stops():
    """Saturation levelling off exponentially (time constant a fifth of the run) and
    constant pressures: the distance is the saturation's relative rate over the tolerance,
    its least-squares slope over the window of half-width h written out (the derivative
    at the window's middle times 3 (a cosh a - sinh a) / a^3, a = h / tau), below 1."""
    tau, amplitude = TIMES[-1] / 5.0, 0.3
    saturation = 0.9 - amplitude * np.exp(-TIMES / tau)
    distance, column = stop_distance(TIMES, _series(saturation), WINDOW, TOLERANCES)
    window = TIMES[TIMES >= (1.0 - WINDOW) * TIMES[-1]]
    a = 0.5 * (window[-1] - window[0]) / tau
    slope = amplitude / tau * np.exp(-window.mean() / tau) * 3.0 * (a * np.cosh(a) - np.sinh(a)) / a**3
    expected = slope * (window[-1] - window[0]) / saturation[-1] / TOLERANCES[0]
    assert distance == pytest.approx(expected, rel=1e-3)
    assert distance < 0.5 and column == 0


def test_a_large_initial_value_does_not_let_a_falling_quantity_pass():
    """The old rule's case: a suction falling from 132 MPa to 5 MPa, still falling by 1 MPa
    (20 % of its value) over the last tenth. Measured against its largest magnitude its
    fall over the last half (5 MPa) is below 5 % of 132 MPa (the old rule stopped);
    against its current value, over a window of a tenth or a fifth along the straight last
    stretch, it falls 1 MPa per tenth, tens of times the tolerance."""
    suction = np.interp(TIMES / TIMES[-1], [0.0, 0.3, 0.5, 0.7, 1.0], [132e6, 20e6, 10e6, 8e6, 5e6])
    half = TIMES >= 0.5 * TIMES[-1]
    assert np.ptp(suction[half]) < 0.05 * 132e6
    distance, _ = stop_distance(TIMES, suction[:, None], WINDOW, np.array([0.01]))
    span = _window_span()
    assert distance == pytest.approx(1e6 / 5e6 * span / (0.1 * TIMES[-1]) / 0.01, rel=1e-9)


def test_fluctuating_pressures_stop_unless_they_drift():
    """Pressures fluctuating by 10 % around their level from record to record stop; a
    drift of three times the tolerance over the window under the same noise does not."""
    noise = 0.1 * np.random.default_rng(0).standard_normal((TIMES.size, 3))
    level = np.column_stack([np.full(TIMES.size, 0.9), np.full(TIMES.size, 0.85)])
    drift = 3.0 * TOLERANCES[2] * TIMES / (WINDOW * TIMES[-1])
    steady = np.hstack([level, 1e6 * (1.0 + noise)])
    drifting = np.hstack([level, 1e6 * (1.0 + noise + drift[:, None])])
    assert stop_distance(TIMES, steady, WINDOW, TOLERANCES)[0] < 1.0
    assert stop_distance(TIMES, drifting, WINDOW, TOLERANCES)[0] > 1.0


def test_too_few_records_zero_levels_and_zero_tolerance():
    """Fewer than ten records in the window: unknown. A quantity constant at zero has no
    rate; one moving off a zero level an infinite one; a zero tolerance never stops."""
    flat = _series(np.full(TIMES.size, 0.9))
    assert np.isnan(stop_distance(TIMES[:9], flat[:9], WINDOW, TOLERANCES)[0])
    zero = flat.copy()
    zero[:, 4] = 0.0
    assert stop_distance(TIMES, zero, WINDOW, TOLERANCES)[0] == 0.0
    zero[-1, 4] = 1.0e3
    assert stop_distance(TIMES, zero, WINDOW, TOLERANCES)[0] > 1.0
    off = TOLERANCES.copy()
    off[0] = 0.0
    assert stop_distance(TIMES, flat, WINDOW, off)[0] == np.inf


def test_stop_time_follows_the_distance_s_power_law():
    """A distance falling as (t / 140 d)^-2 reaches 1 at 140 days, read at 100; a
    distance that does not fall gives no estimate."""
    times = np.linspace(1.0, 100.0, 500) * DAY
    assert stop_time_estimate(times, (times / (140.0 * DAY)) ** -2.0) == pytest.approx(140.0 * DAY, rel=1e-9)
    assert np.isnan(stop_time_estimate(times, 3.0 + 0.0 * times))
    assert np.isnan(stop_time_estimate(times[:5], (times[:5] / (140.0 * DAY)) ** -2.0))


def test_progress_line_reads_days_distance_and_eta():
    """At 100 days, one wall second per simulated day, a stop expected at 140 days: 40 s
    to go; without a pace the ETA is unknown; without a stop estimate the guard bounds it."""
    common = dict(label="macro", simulated=100.0 * DAY, step=800, distance=3.4, held_by=1,
                  saturation=(0.61, 0.72), guard_time=347.0 * DAY, guard="max_time_s guard")
    line = progress_line(**common, stop_time=140.0 * DAY, seconds_per_simulated=1.0 / DAY)
    assert line.startswith("macro: t = 100 d, step 800, stop distance 3.4 (1 = stop; powder saturation), "
                           "mean saturation pellets 0.610 powder 0.720, ETA 40 s (stop near 140 d")
    no_pace = progress_line(**common, stop_time=140.0 * DAY, seconds_per_simulated=np.nan)
    assert no_pace.endswith("ETA unknown")
    unknown = progress_line(**common, stop_time=np.nan, seconds_per_simulated=60.0 / DAY)
    assert unknown.endswith("ETA unknown (the stop distance is not falling yet), at most 4.1 h "
                            "(the max_time_s guard at 347 d)")
    late = progress_line(**common, stop_time=400.0 * DAY, seconds_per_simulated=1.0 / DAY)
    assert "ETA 4.1 min (the max_time_s guard at 347 d, before the stop near 400 d" in late


def test_run_progress_logs_simulated_days(caplog):
    """A forced line names the simulated time in days and the stop distance."""
    progress = RunProgress("macro test", logging.getLogger("test.progress"), 347.0 * DAY, 30000)
    times = np.linspace(0.0, 12.3 * DAY, 50)
    distances = np.full(times.size, 3.4)
    with caplog.at_level(logging.INFO, logger="test.progress"):
        progress.update(12.3 * DAY, 800, (0.61, 0.72), times, distances, 0, force=True)
    assert "macro test: t = 12.3 d, step 800, stop distance 3.4 (1 = stop; pellet saturation)" in caplog.text


def test_run_progress_before_stop_after_names_it(caplog, monkeypatch):
    """Below the threshold before stop_after_s: the stop comes at stop_after_s (once the
    pace is known, after two lines)."""
    import macro.stopping

    clock = iter([0.0, 30.0, 60.0])
    monkeypatch.setattr(macro.stopping.time, "monotonic", lambda: next(clock))
    progress = RunProgress("macro test", logging.getLogger("test.progress"), 347.0 * DAY, 30000,
                           stop_after=10.0 * DAY)
    times = np.linspace(0.0, 5.0 * DAY, 50)
    progress.update(4.0 * DAY, 250, (0.5, 0.6), times, np.full(times.size, 0.5), 2, force=True)
    with caplog.at_level(logging.INFO, logger="test.progress"):
        progress.update(5.0 * DAY, 300, (0.5, 0.6), times, np.full(times.size, 0.5), 2, force=True)
    assert "stop distance 0.5 (1 = stop; mean sensor pressure)" in caplog.text
    assert "(stop near 10 d along the distance's trend" in caplog.text


def test_run_progress_eta_waits_for_two_paces_and_smooths_them(caplog, monkeypatch):
    """The pace behind the ETA: unknown on the first line, then the exponential average
    of the paces between lines (weight 0.3 on the latest), so a slow stretch moves the
    ETA by 30 % of its change, not all of it."""
    import macro.stopping

    clock = iter([0.0, 50.0, 100.0, 150.0])
    monkeypatch.setattr(macro.stopping.time, "monotonic", lambda: next(clock))
    progress = RunProgress("macro test", logging.getLogger("test.progress"), 347.0 * DAY, 30000)
    times = np.linspace(0.0, 100.0 * DAY, 50)
    distances = np.full(times.size, 3.4)  # not falling: the guard bounds the ETA
    lines = []
    with caplog.at_level(logging.INFO, logger="test.progress"):
        # a simulated day per 50 s, twice, then a third of a day in 50 s
        for day in (1.0, 2.0, 2.0 + 1.0 / 3.0):
            caplog.clear()
            progress.update(day * DAY, int(day * 10), (0.5, 0.5), times, distances, 0)
            lines.append(caplog.text)
    assert lines[0].rstrip().endswith("ETA unknown")
    # the max_time_s guard 345 d away at 50 s per day
    assert "at most 4.8 h" in lines[1]
    # the pace 150 s/d folded in: 0.3 x 150 + 0.7 x 50 = 80 s/d (the last pace alone: 14.4 h)
    assert f"at most {(347.0 - 7.0 / 3.0) * 80.0 / 3600.0:.1f} h" in lines[2]
