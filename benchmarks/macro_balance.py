"""The quasi-static DEM's balance (issue fire): the default macro case at two balance
tolerances.

``python -m benchmarks run macro_balance [--size DAYS]`` runs the default configuration's
first macro case on the synthetic table of :mod:`benchmarks.macro` for ``DAYS``
simulated days (20 by default: the whole 91-day case at two tolerances does not fit a
shared two-core machine) at ``dem_balance_tolerance`` 0.01 and 0.001 and reports, per
tolerance, the fraction of balanced steps (both the mean and the net unbalanced force
ratio below it), the FIRE steps per coupled step (each with
its exact powder push), the wall and CPU time per step and of the DEM phase, and the readings
(sensors and both plates) at the end and at the record times, with their relative
difference between the two tolerances. At each record of the 0.01 run a copy of its
state is balanced further to 0.001 and read as well: its difference to the 0.01
reading is the balance error at the record, its difference to the 0.001 run's reading
the path's (each run's contacts slide and yield along its own sequence of balanced
states). A control run at 0.0099, the same tolerance but for 1 %, measures how far two
paths of one packing drift apart when nothing but where each relaxation stops differs:
the scale the tolerances' difference is read against. Timings are measured, never
asserted.
"""

from __future__ import annotations

import copy
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.macro import synthetic_table
from benchmarks.parameters import CONFIG
from shared.io import write_dataset
from shared.upscaling import PermeabilityTable

__all__ = ["bench_macro_balance", "bench_macro_balance_fire_only", "bench_macro_balance_seeds"]

DAY = 86400.0
TOLERANCES = (0.01, 0.001)
CONTROL = 0.0099
"""The control run's tolerance: 0.01 but for 1 %."""
RECORDS = 20
"""Equally spaced simulated times (the end included) at which the readings are kept."""
SUBSTEPS_AT_TIGHTEST = 2000
"""``dem_substeps`` (the cap) of the run at 0.001."""


def _run(days: float, tolerance: float, substeps: int, rebalance: float | None = None,
         rigid_correction: bool = True, seed: int | None = None) -> dict:
    """One run of the default case to ``days`` at ``tolerance`` (with the relaxation's
    ``dem_rigid_correction`` as given, and another packing ``seed`` if given); with
    ``rebalance``, a copy of the model at each
    record balanced further to that tolerance (at most ``SUBSTEPS_AT_TIGHTEST`` force
    evaluations) is read too: the same state, a tighter balance, and the run goes on from
    the original."""
    from macro.run import build_model

    config = copy.deepcopy(CONFIG)
    config["macro"]["numerics"]["dem_balance_tolerance"] = tolerance
    config["macro"]["numerics"]["dem_substeps"] = substeps
    config["macro"]["numerics"]["dem_rigid_correction"] = rigid_correction
    if seed is not None:
        config["macro"]["seed"] = seed
    case = sorted(config["macro"]["cases"])[0]
    with tempfile.TemporaryDirectory() as folder:
        path = write_dataset(synthetic_table(), Path(folder) / "table.nc", stage="upscaling", title="synthetic")
        model = build_model(config, case, PermeabilityTable.from_file(path, "free"))
    marks = np.linspace(days * DAY / RECORDS, days * DAY, RECORDS)
    ratios, nets, used, readings, rebalanced = [], [], [], [], []
    wall = cpu = 0.0
    while model.time < days * DAY * (1.0 - 1e-12):
        before = model.counters.dem_substeps
        start, start_cpu = time.perf_counter(), time.process_time()
        model.step(max_dt=float(marks[len(readings)] - model.time))
        wall += time.perf_counter() - start
        cpu += time.process_time() - start_cpu
        ratios.append(model.readings.unbalanced)
        nets.append(model.readings.net_unbalanced)
        used.append(model.counters.dem_substeps - before)
        if model.time >= marks[len(readings)] * (1.0 - 1e-12):
            r = model.readings
            readings.append([*map(float, r.sensors), r.axial_upper, r.axial_lower])
            if rebalance is not None:
                probe = copy.deepcopy(model)
                probe.settings = replace(probe.settings, dem_balance_tolerance=rebalance)
                r = probe.relax(SUBSTEPS_AT_TIGHTEST)
                rebalanced.append([*map(float, r.sensors), r.axial_upper, r.axial_lower, r.unbalanced,
                                   r.net_unbalanced])
    ratio, net = np.asarray(ratios), np.asarray(nets)
    steps = ratio.size
    return {
        "tolerance": tolerance,
        "dem_substeps": substeps,
        "steps": steps,
        "days": model.time / DAY,
        "balanced_fraction": float(np.mean(np.maximum(ratio, net) < tolerance)),
        "unbalanced_quantiles_50_95_max": [float(q) for q in np.quantile(ratio, [0.5, 0.95, 1.0])],
        "net_unbalanced_quantiles_50_95_max": [float(q) for q in np.quantile(net, [0.5, 0.95, 1.0])],
        "fire_steps_per_step": float(np.mean(used)),
        "fire_steps_per_step_max": int(np.max(used)),
        "wall_s_per_step": wall / steps,
        "cpu_s_per_step": cpu / steps,
        "dem_wall_s_per_step": model.counters.phase_seconds["dem"] / steps,
        "reading_names": [*model.settings.sensors.names, "upper", "lower"],
        "record_days": [float(t) / DAY for t in marks],
        "readings_mpa": (np.asarray(readings) * 1e-6).tolist(),
        **({"rebalance_tolerance": rebalance,
            "readings_rebalanced_mpa": (np.asarray(rebalanced)[:, :-2] * 1e-6).tolist(),
            "rebalanced_unbalanced": np.asarray(rebalanced)[:, -2].tolist(),
            "rebalanced_net_unbalanced": np.asarray(rebalanced)[:, -1].tolist()} if rebalance is not None else {}),
    }


def _relative_difference(readings: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """|readings - reference| relative to the reference, per record and reading."""
    return np.abs(readings - reference) / np.maximum(np.abs(reference), 1e-12)


def bench_macro_balance(days: int = 20, rigid_correction: bool = True) -> dict:
    """The default case at dem_balance_tolerance 0.01 and 0.001, and the control at
    0.0099: balance, cost, readings."""
    cap = int(CONFIG["macro"]["numerics"]["dem_substeps"])
    runs = [_run(float(days), TOLERANCES[0], cap, TOLERANCES[1], rigid_correction),
            _run(float(days), TOLERANCES[1], SUBSTEPS_AT_TIGHTEST, None, rigid_correction),
            _run(float(days), CONTROL, cap, None, rigid_correction)]
    loose, tight, control = (np.asarray(r["readings_mpa"]) for r in runs)
    rebalanced = np.asarray(runs[0]["readings_rebalanced_mpa"])
    late = np.asarray(runs[0]["record_days"]) >= 5.0

    difference, drift = _relative_difference(loose, tight), _relative_difference(loose, control)
    return {
        "macro_case": sorted(CONFIG["macro"]["cases"])[0],
        "dem_rigid_correction": rigid_correction,
        "runs": runs,
        "relative_difference_final": difference[-1].tolist(),
        "relative_difference_max_over_records": difference.max(axis=0).tolist(),
        "relative_difference_max_from_day_5": difference[late].max(axis=0).tolist(),
        # the balance error at a record (the 0.01 run's states balanced to 0.001) against
        # the path's (the 0.001 run against those same states at 0.001)
        "relative_difference_rebalanced_max_over_records": _relative_difference(loose, rebalanced)
        .max(axis=0).tolist(),
        "relative_difference_rebalanced_to_tight_max_over_records": _relative_difference(rebalanced, tight)
        .max(axis=0).tolist(),
        # two paths at (nearly) one tolerance: 0.01 against 0.0099
        "control_difference_final": drift[-1].tolist(),
        "control_difference_max_over_records": drift.max(axis=0).tolist(),
        "control_difference_max_from_day_5": drift[late].max(axis=0).tolist(),
    }


def bench_macro_balance_fire_only(days: int = 20) -> dict:
    """:func:`bench_macro_balance` without the relaxation's rigid correction
    (``dem_rigid_correction`` false: FIRE alone)."""
    return bench_macro_balance(days, rigid_correction=False)


def bench_macro_balance_seeds(days: int = 20, seeds: tuple[int, ...] = (1, 2)) -> dict:
    """The tolerances' gap of :func:`bench_macro_balance` over other packings (seeds of
    the packing and the powder field), without its rebalanced copies and control run."""
    members = []
    for seed in seeds:
        loose, tight = (_run(float(days), tolerance, substeps, seed=seed) for tolerance, substeps in
                        ((TOLERANCES[0], int(CONFIG["macro"]["numerics"]["dem_substeps"])),
                         (TOLERANCES[1], SUBSTEPS_AT_TIGHTEST)))
        difference = _relative_difference(np.asarray(loose["readings_mpa"]), np.asarray(tight["readings_mpa"]))
        members.append({"seed": seed, "balanced_fraction": [loose["balanced_fraction"], tight["balanced_fraction"]],
                        "fire_steps_per_step": [loose["fire_steps_per_step"], tight["fire_steps_per_step"]],
                        "reading_names": loose["reading_names"],
                        "relative_difference_max_over_records": difference.max(axis=0).tolist(),
                        "record_day_of_max": (np.asarray(loose["record_days"])[difference.argmax(axis=0)]).tolist(),
                        "relative_difference_final": difference[-1].tolist()})
    return {"macro_case": sorted(CONFIG["macro"]["cases"])[0], "days": days, "members": members}

