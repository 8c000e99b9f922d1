"""The macro mixture read against the mock-up: ``python -m benchmarks run macro_mixture``
(or ``python -m benchmarks.macro_mixture [PATH]``).

Reads a macro result (``results/macro/weibull.nc`` by default) and reports what Sec. 4.8
and the mock-up's apparent homogeneity at about 100 days are compared with: each
sensor's and plate's time to 0.5 MPa and its plateau (the mean over the last fifth of
the run), the time the dry-density spread halves, the plateau against Eq. 4.31 at the
global dry density times the boundary's saturation, the plates' agreement, the balanced
fraction of the records at the run's tolerance, and the run's cap and overflow counters.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import xarray as xr

from benchmarks.parameters import CONFIG
from macro.laws import mixture_parameters, swelling_pressure

__all__ = ["bench_macro_mixture", "mixture_record"]

RESULT = Path("results/macro/weibull.nc")
DAY = 86400.0
PASSAGE = 5e5
"""The pressure whose first passage is compared with Sec. 4.8's order [Pa]."""


def _plateau(time: np.ndarray, values: np.ndarray) -> float:
    """Mean over the last fifth of the elapsed time."""
    late = time >= 0.8 * time[-1]
    return float(values[late].mean())


def homogenised_pressure(dry_density: float, config: dict = CONFIG) -> float:
    """Eq. 4.31 at ``dry_density`` [kg/m3] times the retention curve's saturation at the
    boundary suction (Eq. 4.33): the wall pressure of the homogenised column [Pa]."""
    material = mixture_parameters(config["materials"], config["macro"]["powder"])
    return float(swelling_pressure(dry_density, config["macro"]["boundary_suction_pa"],
                                   material.reference_porosity, material))


def mixture_record(path: str | Path = RESULT) -> dict:
    """The numbers of the module docstring from one macro result."""
    ds = xr.open_dataset(path)
    time = ds["time"].values
    readings = {str(name): ds["sensor_pressure"].sel(sensor=name).values for name in ds["sensor"].values}
    readings.update(upper_plate=ds["axial_pressure_upper"].values, lower_plate=ds["axial_pressure_lower"].values)
    spread = ds["dry_density_spread"].values
    halved = np.flatnonzero(spread <= 0.5 * spread[0])
    dry_density = float(ds["dry_density"].values[-1])
    target = homogenised_pressure(dry_density)
    plateaus = {name: _plateau(time, values) for name, values in readings.items()}
    passage = {}
    for name, values in readings.items():
        above = np.flatnonzero(values >= PASSAGE)
        passage[name] = float(time[above[0]] / DAY) if above.size else None
    mean_plateau = float(np.mean(list(plateaus.values())))
    record = {
        "result": str(path),
        "pellets": int(ds.sizes["pellet"]),
        "end_time_days": float(time[-1] / DAY),
        "stop_reason": ds.attrs.get("stop_reason"),
        "steps": int(ds.attrs["steps"]),
        "runtime_s": float(ds.attrs["runtime_s"]),
        "dry_density_kg_m3": dry_density,
        "homogenised_pressure_pa": target,
        "passage_days": passage,
        "plateau_pa": plateaus,
        "mean_plateau_over_homogenised": mean_plateau / target,
        "plates_ratio": plateaus["upper_plate"] / plateaus["lower_plate"],
        "spread_kg_m3": {"start": float(spread[0]), "end": float(spread[-1])},
        "spread_halves_days": float(time[halved[0]] / DAY) if halved.size else None,
        "balanced_fraction": float(ds["balanced"].mean()),
        "largest_unbalanced_ratio": float(ds["unbalanced_force"].max()),
        "largest_net_unbalanced_ratio": float(ds["net_unbalanced_force"].max()),
        "largest_overfill": float(ds["largest_overfill"].max()),
        "pellets_below_boundary_suction_at_end": int((ds["pellet_suction"].values[-1]
                                                       < 0.999 * CONFIG["macro"]["boundary_suction_pa"]).sum()),
    }
    record.update({key: int(ds.attrs[key]) for key in ("capped_cell_steps", "overflowed_cell_steps",
                                                        "extrusion_limited_steps") if key in ds.attrs})
    return record


def bench_macro_mixture(path: str | Path = RESULT) -> dict:
    """The default macro result against Sec. 4.8 and the homogenised limit."""
    return mixture_record(path)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.macro_mixture", description=__doc__.splitlines()[0])
    parser.add_argument("path", nargs="?", default=str(RESULT), help="a macro result (default %(default)s)")
    print(json.dumps(mixture_record(parser.parse_args(argv).path), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
