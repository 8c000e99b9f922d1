"""Timing of the macro model: steps per second and wall time per phase.

``python -m benchmarks run macro_steps [--size STEPS]`` (or ``python -m benchmarks.macro``)
runs the default configuration's first macro case on a synthetic pellet permeability
table (water k from 1e-19 m2 at 0.1 MPa down by 0.8 decades per decade of suction) for
``STEPS`` coupled steps and reports the packing, the set-up time, the steps per second
and the seconds spent in each phase (remesh/geometry, transport, Newton-Raphson, DEM).
Timings are measured, never asserted.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from benchmarks.parameters import CONFIG
from shared.figures import new_figure, save_figure
from shared.io import write_dataset
from shared.upscaling import PermeabilityTable

if TYPE_CHECKING:
    from macro.model import MacroModel

OUT = Path("results/benchmarks")

__all__ = ["bench_macro_scaling", "bench_macro_scaling_fire_only", "bench_macro_steps", "synthetic_table"]


def synthetic_table() -> xr.Dataset:
    """A two-condition table on 12 suctions from 0.1 to 200 MPa."""
    suction = np.geomspace(1e5, 2e8, 12)
    water = 10.0 ** (-19.0 - 0.8 * (np.log10(suction) - 5.0))
    k = np.broadcast_to(water, (2, 2, 3, suction.size)).copy()
    tensor = np.zeros((2, 2, suction.size, 3, 3))
    for i in range(3):
        tensor[..., i, i] = k[:, :, i, :]
    attrs = {"units": "m2", "long_name": "synthetic"}
    return xr.Dataset(
        {
            "k": (("condition", "phase", "axis", "suction"), k, attrs),
            "k_tensor": (("condition", "phase", "suction", "i", "j"), tensor, attrs),
            "saturation": (("condition", "suction"), np.full((2, suction.size), 0.5), {"units": "1", "long_name": "s"}),
            "eps_v": (("condition", "suction"), np.zeros((2, suction.size)), {"units": "1", "long_name": "e"}),
        },
        coords={"condition": ["free", "confined"], "phase": ["water", "gas"], "axis": ["x", "y", "z"],
                "suction": ("suction", suction, {"units": "Pa", "long_name": "suction"})},
    )


def bench_macro_steps(steps: int = 100, pellet_radius: float | None = None, days: float = 0.0,
                      rigid_correction: bool = True) -> dict:
    """Steps per second and seconds per phase of the default macro case over its first
    ``steps`` coupled steps (optionally with another pellet radius [m], the container
    unchanged, and the relaxation's ``dem_rigid_correction``); ``step_rows`` holds each
    step's end time [s], force evaluations and wall time [s], continued until the model
    has simulated ``days`` days."""
    import copy

    from macro.run import build_model

    config = copy.deepcopy(CONFIG)
    if pellet_radius is not None:
        config["macro"]["pellet_radius_m"] = pellet_radius
    config["macro"]["numerics"]["dem_rigid_correction"] = rigid_correction
    case = sorted(config["macro"]["cases"])[0]
    with tempfile.TemporaryDirectory() as folder:
        path = write_dataset(synthetic_table(), Path(folder) / "table.nc", stage="upscaling", title="synthetic")
        start = time.perf_counter()
        model = build_model(config, case, PermeabilityTable.from_file(path, "free"))
        setup = time.perf_counter() - start
        model.step()  # compiles what the set-up did not
        for key in model.counters.phase_seconds:
            model.counters.phase_seconds[key] = 0.0
        start = time.perf_counter()
        rows = [_timed_step(model) for _ in range(steps)]
        wall = time.perf_counter() - start
        phase_s = dict(model.counters.phase_seconds)
        while model.time < 86400.0 * days:
            rows.append(_timed_step(model))
    packing = model.packing  # type: ignore[attr-defined]
    return {
        "case": case,
        "n_pellets": model.n_pellets,
        "n_cells": model.n_cells,
        "packing_fraction": packing.packing_fraction,
        "setup_s": setup,
        "steps": steps,
        "steps_per_s": steps / wall,
        "simulated_s": model.time,
        "phase_s": phase_s,
        "fire_steps_per_step": sum(row[1] for row in rows[:steps]) / steps,
        "newton_fallbacks": model.counters.newton_fallbacks,
        "remeshes": model.counters.remeshes,
        "step_rows": rows,
    }


def _timed_step(model: MacroModel) -> list[float]:
    """One coupled step: the model's time after it [s], its FIRE steps, its wall time [s]."""
    fire, clock = model.counters.dem_substeps, time.perf_counter()
    model.step()
    return [model.time, model.counters.dem_substeps - fire, time.perf_counter() - clock]


def bench_macro_scaling(steps: int = 100, radii: tuple[float, ...] = (5.99e-3, 4.73e-3, 3.65e-3, 3.0e-3),
                        days: float = 3.0, rigid_correction: bool = True) -> dict:
    """Cost per step against the pellet count (the Appendix .1 radii and a smaller one)
    and the exponent of a power-law fit, per phase, in total and of the FIRE steps per step,
    over the first ``steps`` steps; and over the steps of the first ``days`` days, the
    same stage of the hydration at every size (a smaller cell takes smaller time steps,
    so a fixed count of steps ends earlier in the larger columns)."""
    rows = [bench_macro_steps(steps, r, days, rigid_correction) for r in radii]
    count = np.array([r["n_pellets"] for r in rows], dtype=float)
    same_time = []
    for r in rows:
        table = np.array(r["step_rows"])
        within = table[table[:, 0] <= 86400.0 * days]
        same_time.append({"steps": int(within.shape[0]), "ms_per_step": 1e3 * float(within[:, 2].mean()),
                          "fire_steps_per_step": float(within[:, 1].mean())})

    def exponent(values: list[float]) -> float:
        return float(np.polyfit(np.log(count), np.log(values), 1)[0])

    fits = {}
    fig, axes = new_figure(1, 1, width=4.6, height=3.6)
    ax = axes[0][0]  # type: ignore[index]
    for phase in ("total", *rows[0]["phase_s"]):
        per_step = np.array([(1.0 / r["steps_per_s"]) if phase == "total" else r["phase_s"][phase] / steps
                             for r in rows])
        fits[phase] = exponent(list(per_step))
        name = f"total, first {steps} steps" if phase == "total" else phase
        ax.loglog(count, 1e3 * per_step, "o-" if phase == "total" else ".--", label=f"{name} (N^{fits[phase]:.2f})")
    same = [r["ms_per_step"] for r in same_time]
    ax.loglog(count, same, "s-", label=f"total, first {days:g} days (N^{exponent(same):.2f})")
    ax.set_xlabel("pellets")
    ax.set_ylabel("wall time per coupled step [ms]")
    ax.set_title("macro model: cost per step (2 cores)")
    ax.legend(fontsize=7)
    OUT.mkdir(parents=True, exist_ok=True)
    save_figure(fig, OUT / f"macro_scaling{'' if rigid_correction else '_fire_only'}.png")
    fire = np.array([r["fire_steps_per_step"] for r in rows])
    return {"dem_rigid_correction": rigid_correction, "runs": rows, "exponent_per_step": fits,
            "exponent_fire_steps_per_step": exponent(list(fire)),
            "same_time": {"days": days, "runs": same_time,
                          "exponent_per_step": exponent(same),
                          "exponent_fire_steps_per_step": exponent([r["fire_steps_per_step"] for r in same_time])}}


def bench_macro_scaling_fire_only(steps: int = 100) -> dict:
    """:func:`bench_macro_scaling` without the relaxation's rigid correction
    (``dem_rigid_correction`` false: FIRE alone)."""
    return bench_macro_scaling(steps, rigid_correction=False)


def main() -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.macro")
    parser.add_argument("steps", type=int, nargs="?", default=100)
    parser.add_argument("--output", type=Path, default=None)
    args = parser.parse_args()
    result = bench_macro_steps(args.steps)
    text = json.dumps(result, indent=1)
    print(text)
    if args.output is not None:
        args.output.parent.mkdir(parents=True, exist_ok=True)
        args.output.write_text(text)


if __name__ == "__main__":
    main()
