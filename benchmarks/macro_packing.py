"""The pellet packing: the mock-up's fraction, the highest fraction reached, the time.

``python -m benchmarks run macro_packing [--size ITERATIONS]`` packs the default
container (0.12 m x 0.03 m, :mod:`benchmarks.parameters`) with the mock-up's 7 mm
pellets (radius 3.5 mm) at its 80/20 pellet/powder dry mass (pellet packing fraction
0.5738), with the default radius 5.99 mm at 0.50, with radii within +-20 % of 3.5 mm and
with radius 2 mm at 0.60, each with the default iteration budget and three seeds; then
bisects, for 3.5 and 5.99 mm and each seed, the highest fraction that
:func:`macro.packing.pack_cylinder` packs with no overlap above its tolerance within
``ITERATIONS`` minimiser iterations. Wall times are measured on one core, never
asserted; docs/macro.md quotes the record (benchmarks/reference/macro_packing.json).
"""

from __future__ import annotations

import time

import numpy as np

from benchmarks.parameters import CONFIG

__all__ = ["bench_macro_packing"]

MOCK_UP_FRACTION = 1490.0 * 0.8 / (2770.0 * (1.0 - 0.25))
"""Pellet packing fraction of the mock-up's 80/20 mixture at 1490 kg/m3 [1]."""
SEEDS = (0, 1, 2)


def _pack(pellet_radius: float, fraction: float, seed: int, iterations: int, spread: float = 0.0) -> dict:
    """One packing of the default container: count, fraction, largest overlap [r], time [s]."""
    from macro.packing import pack_cylinder

    macro = CONFIG["macro"]
    start = time.perf_counter()
    packing = pack_cylinder(float(macro["cylinder_height_m"]), float(macro["cylinder_radius_m"]), pellet_radius,
                            fraction, np.random.default_rng(seed), iterations, spread)
    return {
        "n_pellets": int(packing.radii.size),
        "packing_fraction": packing.packing_fraction,
        "largest_overlap_r": packing.largest_overlap / pellet_radius,
        "wall_s": time.perf_counter() - start,
    }


def _packs(pellet_radius: float, fraction: float, seed: int, iterations: int) -> bool:
    """Whether the fraction packs within the tolerance of :mod:`macro.packing`."""
    from macro.packing import TOLERANCE

    return _pack(pellet_radius, fraction, seed, iterations)["largest_overlap_r"] <= TOLERANCE


def _limit(pellet_radius: float, low: float, high: float, seed: int, iterations: int, steps: int = 7) -> dict:
    """Bisect the highest fraction packed between ``low`` (packed) and ``high`` (not)."""
    start = time.perf_counter()
    if not _packs(pellet_radius, low, seed, iterations) or _packs(pellet_radius, high, seed, iterations):
        raise RuntimeError(f"bisection bounds {low}, {high} do not bracket the limit at r = {pellet_radius} m")
    for _ in range(steps):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if _packs(pellet_radius, middle, seed, iterations) else (low, middle)
    return {"pellet_radius_m": pellet_radius, "seed": seed, "packed": low, "not_packed": high,
            "bisection_s": time.perf_counter() - start}


def bench_macro_packing(iterations: int = 30000) -> dict:
    """Packings at the mock-up's and the default fraction, and the highest fraction reached."""
    budget = int(CONFIG["macro"]["numerics"]["packing_iterations"])
    cases = {"mock_up_3.5mm": (3.5e-3, MOCK_UP_FRACTION, 0.0), "default_5.99mm": (5.99e-3, 0.50, 0.0),
             "mock_up_3.5mm_spread_0.2": (3.5e-3, MOCK_UP_FRACTION, 0.2), "fine_2mm_0.60": (2e-3, 0.60, 0.0)}
    _pack(5.99e-3, 0.3, 0, budget)  # compiles the kernel outside the timings
    rows = {name: [_pack(r, fraction, seed, budget, spread) for seed in SEEDS]
            for name, (r, fraction, spread) in cases.items()}
    return {
        "iterations_default": budget,
        "target_fraction": MOCK_UP_FRACTION,
        "packings": rows,
        "limit_iterations": iterations,
        "limits": [_limit(r, low, 0.62, seed, iterations) for r, low in ((3.5e-3, 0.57), (5.99e-3, 0.50))
                   for seed in SEEDS],
    }
