"""Where the default macro case stands against the homogenised limit (issue macro-physics).

``python -m benchmarks run macro_homogenised`` runs the default configuration's first
macro case on the synthetic table of :mod:`benchmarks.macro` to its stop and decomposes
its final state: the mixture's global dry density and Eq. 4.31's stress there; the
pellets' confining stress; the powder's push (Eq. 4.35) over the active cells, inside
and at the container; the share of the curved wall's hull held by inert slivers; the
wall readings with and without the powder's push on the container; and, for each
sensor, the suction at its height when it first passed 0.5 MPa. docs/macro.md quotes
the record (benchmarks/reference/macro_homogenised.json).
"""

from __future__ import annotations

import copy
import tempfile
from pathlib import Path

import numpy as np

from benchmarks.macro import synthetic_table
from benchmarks.parameters import CONFIG
from shared.io import write_dataset
from shared.upscaling import PermeabilityTable

__all__ = ["bench_macro_homogenised"]

MPA = 1e-6


def _quantiles(values: np.ndarray) -> list[float]:
    """10, 25, 50, 75 and 90 % quantiles [MPa]."""
    return [float(q) for q in np.percentile(values, [10, 25, 50, 75, 90]) * MPA]


def bench_macro_homogenised() -> dict:
    """The default case's final state against Eq. 4.31 at its global dry density."""
    from macro.laws import consolidation_pressure
    from macro.run import build_model, simulate

    config = copy.deepcopy(CONFIG)
    case = sorted(config["macro"]["cases"])[0]
    with tempfile.TemporaryDirectory() as folder:
        path = write_dataset(synthetic_table(), Path(folder) / "table.nc", stage="upscaling", title="synthetic")
        model = build_model(config, case, PermeabilityTable.from_file(path, "free"))
    ds, reason = simulate(model)
    s, n_p, mesh = model.settings, model.n_pellets, model.mesh
    container = np.pi * s.radius**2 * s.height
    global_density = float(model.solid_mass().sum() / container)
    active = ~model.inert[n_p:]
    push, volumes = model.cells.pressures, mesh.volumes
    on_container = (mesh.tetrahedra >= n_p).any(axis=1) & active
    side = np.abs(mesh.boundary_normals[:, 2]) <= np.sqrt(0.5)
    hull_cells, areas = mesh.boundary_cells[side], mesh.boundary_areas[side]
    # the same state read with the powder pushing on the container through the hull
    heights, loads, upper, lower = model.powder_wall_loads()
    area = np.pi * s.radius**2
    readings, powder = model.readings, s.sensors.pressures(heights, loads, s.radius)
    # the readings hold the powder's push where powder_pressure_on_walls is on (the default)
    on = 1.0 if s.powder_on_walls else 0.0
    contacts = readings.sensors - on * powder
    with_powder = contacts + powder
    plates = [readings.axial_upper - on * upper / area, readings.axial_lower - on * lower / area]
    time = ds["time"].values
    passage = {}
    for sensor, height in zip(ds["sensor"].values, ds["sensor_height"].values, strict=True):
        when = float(ds["sensor_passage_time"].sel(sensor=sensor))
        if np.isfinite(when):
            profile = ds["suction_profile"].isel(time=int(np.searchsorted(time, when)))
            at = float(profile.sel(z=height, method="nearest"))
            passage[str(sensor)] = {"day": when / 86400.0, "suction_at_height_mpa": at * MPA}
    return {
        "macro_case": case,
        "stop_reason": reason,
        "days": float(model.time / 86400.0),
        "global_dry_density_kg_m3": global_density,
        "eq_4_31_at_global_density_mpa": float(consolidation_pressure(global_density, model.material)) * MPA,
        "pellet_stress_median_mpa": float(np.median(model.stress[:n_p])) * MPA,
        "powder_push_volume_mean_mpa": float((push * volumes)[active].sum() / volumes[active].sum()) * MPA,
        "powder_push_quantiles_at_container_mpa": _quantiles(push[on_container]),
        "powder_push_quantiles_inside_mpa": _quantiles(push[active & ~on_container]),
        "void_over_tetrahedron_median_at_container": float(np.median((model.cells.voids / volumes)[on_container])),
        "void_over_tetrahedron_median_inside": float(np.median((model.cells.voids / volumes)[active & ~on_container])),
        "curved_wall_hull_inert_area_fraction": float(areas[model.inert[n_p:][hull_cells]].sum() / areas.sum()),
        "sensors": [str(v) for v in ds["sensor"].values],
        "sensor_pressure_contacts_mpa": [float(v) * MPA for v in contacts],
        "sensor_pressure_with_powder_on_walls_mpa": [float(v) * MPA for v in with_powder],
        "plates_contacts_mpa": [float(v) * MPA for v in plates],
        "plates_with_powder_on_walls_mpa": [(plates[0] + upper / area) * MPA, (plates[1] + lower / area) * MPA],
        "passage_of_0p5_mpa": passage,
    }
