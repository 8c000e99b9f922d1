"""FIRE's constants in the macro relaxation: the relaxation's own
(:data:`macro.mechanics.FIRE`: a start at the largest time step with FIRE 2.0's
alpha_start 0.25) against Bitzek et al.'s standard start, from the same state of the
default case.

``python -m benchmarks run macro_fire [--size STEPS]`` runs the default configuration's
first macro case on the synthetic table of :mod:`benchmarks.macro` for 100 coupled steps
with :data:`macro.mechanics.FIRE`, then ``STEPS`` (100) more from that state with each set
of constants, and reports the FIRE steps per coupled step, the balanced fraction and the
readings at the end, with their relative difference. Timings are measured, never asserted.
"""

from __future__ import annotations

import copy
import tempfile
import time
from pathlib import Path

import numpy as np

import macro.mechanics
from benchmarks.macro import synthetic_table
from benchmarks.parameters import CONFIG
from shared.dem import FireParameters
from shared.io import write_dataset
from shared.upscaling import PermeabilityTable

__all__ = ["bench_macro_fire"]

WARM_UP = 100
"""Coupled steps before the comparison (the pellets press each other and the powder)."""
CONSTANTS = {"relaxation": macro.mechanics.FIRE, "bitzek": FireParameters()}


def _steps(model: macro.model.MacroModel, steps: int) -> dict:
    """``steps`` coupled steps of ``model``: FIRE steps, balance, CPU time, readings."""
    before, ratios = model.counters.dem_substeps, []
    cpu = time.process_time()
    for _ in range(steps):
        model.step(model.settings.max_time_step)
        ratios.append(max(model.readings.unbalanced, model.readings.net_unbalanced))
    r = model.readings
    return {
        "fire_steps_per_step": (model.counters.dem_substeps - before) / steps,
        "balanced_fraction": float(np.mean(np.asarray(ratios) < model.settings.dem_balance_tolerance)),
        "cpu_s": time.process_time() - cpu,
        "readings_mpa": [float(v) * 1e-6 for v in (*r.sensors, r.axial_upper, r.axial_lower)],
    }


def bench_macro_fire(steps: int = 100) -> dict:
    """The two sets of FIRE constants from one state of the default case."""
    from macro.run import build_model

    config = copy.deepcopy(CONFIG)
    case = sorted(config["macro"]["cases"])[0]
    with tempfile.TemporaryDirectory() as folder:
        path = write_dataset(synthetic_table(), Path(folder) / "table.nc", stage="upscaling", title="synthetic")
        model = build_model(config, case, PermeabilityTable.from_file(path, "free"))
    for _ in range(WARM_UP):
        model.step(model.settings.max_time_step)
    runs = {}
    for name, constants in CONSTANTS.items():
        macro.mechanics.FIRE = constants
        try:
            runs[name] = _steps(copy.deepcopy(model), steps)
        finally:
            macro.mechanics.FIRE = CONSTANTS["relaxation"]
    reference, other = (np.asarray(runs[name]["readings_mpa"]) for name in CONSTANTS)
    return {
        "macro_case": case,
        "pellets": model.n_pellets,
        "warm_up_steps": WARM_UP,
        "days_at_start": model.time / 86400.0,
        "constants": {name: vars(c) for name, c in CONSTANTS.items()},
        "runs": runs,
        "fire_steps_ratio": runs["relaxation"]["fire_steps_per_step"] / runs["bitzek"]["fire_steps_per_step"],
        "readings_relative_difference_max": float(np.max(np.abs(other - reference) / np.abs(reference))),
    }
