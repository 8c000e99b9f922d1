"""The records of a macro run: what each step adds, the column's permeability when due,
the stop distance over the window, the thinning that keeps long runs bounded, and the
run's Dataset.

A record's quantities are named once, in :meth:`Records.record`; the rows of a new run
are created by the first record, and a resumed run's rows are its snapshot's.
:func:`records_dataset` gives each its variable of ``results/macro/<case>.nc``.
"""

from __future__ import annotations

import bisect
import logging
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
import xarray as xr

from macro.column_permeability import column_permeability
from macro.model import MacroModel
from macro.stopping import MONITORED, stop_distance

__all__ = ["INVARIANTS", "MEASUREMENT_ROWS", "PASSAGE_PRESSURE", "Records", "records_dataset"]

LOG = logging.getLogger("claychain.macro")
FloatArray = npt.NDArray[np.float64]

INVARIANTS = {
    "water_pellets": ("kg", "water mass in the pellets"),
    "water_powder": ("kg", "water mass in the powder of the free cells"),
    "water_held": ("kg", "water mass in the held end cells (the boundary's reservoir)"),
    "water_residual": ("kg", "interior water less the initial interior water and the boundary inflow (0: water conserved)"),
    "solid_water_fraction": ("1", "solids and water of pellets and powder over the container's volume (at most 1)"),
    "occupied_fraction": ("1", "pellets' clay volume with the powder's solids and water over the container's volume"),
    "largest_overfill": ("1", "largest powder solid and water volume over its cell's void, less 1 (> 0: a cell holds more than its void)"),
    "dry_density": ("kg m-3", "dry mass of pellets and powder over the container's volume"),
    "dry_density_spread": ("kg m-3", "volume-weighted standard deviation of the dry density of pellets and powder cells (0: homogeneous)"),
}
"""Invariants recorded at every record (:meth:`macro.model.MacroModel.invariants`): units, long name."""
MEASUREMENT_ROWS = ("permeability_time", "column_permeability", "passage")
"""Records of the column permeability, on their own time coordinate, and the first
passages (neither thinned nor picked)."""
PASSAGE_PRESSURE = 5e5
"""Pressure whose first passage by each sensor and plate is recorded at full time
resolution (Sec. 4.8 compares the order in which the sensors rise) [Pa]."""


class Records:
    """The rows of a run, one entry per record (``rows``), and the profiles' bin edges.

    Parameters
    ----------
    model
        The run's model (it carries its ``packing``): the bins of about one initial pellet
        diameter follow from the packing, not from the current state, so that a resumed
        run records as the uninterrupted one (finer bins alternate between pellets and
        powder).
    rows
        The rows of a resumed run; None for a new one.
    """

    def __init__(self, model: MacroModel, rows: dict[str, list[Any]] | None = None) -> None:
        s = model.settings
        bins = max(2, int(round(s.height / (2.0 * float(model.packing.radii.mean())))))
        self.edges: FloatArray = np.linspace(-0.5 * s.height, 0.5 * s.height, bins + 1, dtype=np.float64)
        self.new = rows is None
        self.rows: dict[str, list[Any]] = {key: [] for key in ("permeability_time", "column_permeability")} \
            if rows is None else rows
        self.rows.setdefault("passage", [])  # absent from the snapshots of earlier versions
        self._tolerances = np.array([s.stop_tolerance] * 2 + [s.stop_pressure_tolerance] * 3)

    def start(self, model: MacroModel) -> None:
        """The first entries of a new run (nothing for a resumed one): the initial state,
        its stop distance and the column's permeability at t = 0."""
        if self.new:
            self.record(model, 0.0)
            self.stop_distance(model)
            self.measure(model)

    def record(self, model: MacroModel, dt: float) -> None:
        """Append the model's state after a step of ``dt`` [s] (0 for the initial state)."""
        r = model.readings
        swell, suction = model.profiles(self.edges)
        entry = {
            "time": model.time, "sensors": r.sensors.copy(), "bands": r.bands.copy(),
            "axial_upper": r.axial_upper, "axial_lower": r.axial_lower,
            "suction": model.mean_suction(), "saturation": model.mean_saturation(),
            "swelling": swell, "suction_profile": suction,
            "pellet_suction": -model.pressure[: model.n_pellets].copy(),
            "unbalanced": r.unbalanced, "net_unbalanced": r.net_unbalanced, "dt": dt, "step": model.steps,
            "remeshes": model.counters.remeshes, **model.invariants(),
        }
        for name, value in entry.items():
            self.rows.setdefault(name, []).append(value)
        # first passage of PASSAGE_PRESSURE by the sensors, then the upper and lower plates
        readings = np.concatenate([r.sensors, [r.axial_upper, r.axial_lower]])
        if not self.rows["passage"]:
            self.rows["passage"].append(np.full(readings.size, np.nan))
        passage = self.rows["passage"][0]
        passage[np.isnan(passage) & (readings >= PASSAGE_PRESSURE)] = model.time

    def measure(self, model: MacroModel) -> None:
        """The column's permeability now (:func:`macro.column_permeability.column_permeability`)."""
        k = column_permeability(model).permeability
        self.rows["permeability_time"].append(model.time)
        self.rows["column_permeability"].append(k)
        LOG.info("column permeability along the axis %.4g m2 at t = %.4g s", k, model.time)

    def measure_due(self, model: MacroModel) -> bool:
        """Whether the run passed a measurement time since the last measurement."""
        times = np.asarray(model.settings.column_permeability_times)
        return bool(np.any((times > self.rows["permeability_time"][-1]) & (times <= model.time)))

    def stop_distance(self, model: MacroModel) -> tuple[float, int]:
        """The stop distance over the records of the window and the quantity setting it
        (:func:`macro.stopping.stop_distance`); recorded as ``stop_distance`` (NaN for the
        initial state)."""
        s, rows = model.settings, self.rows
        times = rows["time"]
        if len(times) == 1:
            rows.setdefault("stop_distance", []).append(float("nan"))
            return float("nan"), -1
        first = bisect.bisect_left(times, times[-1] * (1.0 - s.stop_window))
        monitored = np.column_stack([
            np.asarray(rows["saturation"][first:]), np.asarray(rows["sensors"][first:]).mean(axis=1),
            rows["axial_upper"][first:], rows["axial_lower"][first:]])
        gap, held_by = stop_distance(np.asarray(times[first:]), monitored, s.stop_window, self._tolerances)
        rows["stop_distance"].append(gap)
        return gap, held_by

    def thin(self, above: int) -> None:
        """Every other record (the first and last kept) once there are more than
        ``above``: memory and snapshots stay bounded over long runs."""
        if len(self.rows["time"]) > above:
            for key, values in self.rows.items():
                if key not in MEASUREMENT_ROWS:
                    values[:] = values[:-1:2] + values[-1:]


def _keep(steps: npt.NDArray[np.int64], wanted: int) -> npt.NDArray[np.int64]:
    """Indices of at most ``wanted`` records nearest to equally spaced step numbers, the
    first and last included (the records in memory are thinned unevenly)."""
    targets = np.linspace(steps[0], steps[-1], min(steps.size, wanted))
    nearest = np.clip(np.searchsorted(steps, targets), 1, steps.size - 1)
    nearest -= (targets - steps[nearest - 1]) < (steps[nearest] - targets)
    return np.unique(nearest)


def records_dataset(model: MacroModel, rows: Mapping[str, list[Any]], edges: FloatArray) -> xr.Dataset:
    """The Dataset of a run's records (:class:`Records`' ``rows`` and profile bin
    ``edges`` [m]): at most ``records`` of them at equal step spacing, the column
    permeabilities and first passages, the packing, and the run's counters as attributes."""
    s = model.settings
    keep = _keep(np.asarray(rows["step"]), s.records)
    pick = {k: np.asarray(v)[keep] for k, v in rows.items() if k not in MEASUREMENT_ROWS}
    balanced = np.maximum(pick["unbalanced"], pick["net_unbalanced"]) < s.dem_balance_tolerance
    z = 0.5 * (edges[:-1] + edges[1:]) + 0.5 * s.height
    packing = model.packing
    coords = {
        "time": ("time", pick["time"], {"units": "s", "long_name": "simulated time"}),
        "sensor": ("sensor", list(s.sensors.names), {"units": "1", "long_name": "radial pressure sensor (macro.sensors)"}),
        "sensor_height": ("sensor", s.sensors.heights, {"units": "m", "long_name": "height of the sensor's centre above the lower plate"}),
        "sensor_band_width": ("sensor", s.sensors.widths, {"units": "m", "long_name": "height of the wall band the sensor reads"}),
        "band": ("band", np.arange(len(s.bands.names)), {"units": "1", "long_name": "equal height band of the curved wall, from the bottom"}),
        "band_height": ("band", s.bands.heights, {"units": "m", "long_name": "height of the band's middle above the lower plate"}),
        "material": ("material", ["pellet", "powder"], {"units": "1", "long_name": "material"}),
        "z": ("z", z, {"units": "m", "long_name": "height above the lower plate"}),
        "pellet": ("pellet", np.arange(model.n_pellets), {"units": "1", "long_name": "pellet index"}),
        "xyz": ("xyz", ["x", "y", "z"], {"units": "1", "long_name": "axis"}),
        "plate": ("plate", ["upper", "lower"], {"units": "1", "long_name": "plate of the container"}),
        "permeability_time": ("permeability_time", np.asarray(rows["permeability_time"]),
                              {"units": "s", "long_name": "simulated time of a column permeability measurement"}),
    }
    data = {
        "sensor_pressure": (("time", "sensor"), pick["sensors"], {"units": "Pa", "long_name": "radial pressure read by each sensor: radial force in its band over 2 pi R w"}),
        "band_pressure": (("time", "band"), pick["bands"], {"units": "Pa", "long_name": "radial pressure on the curved wall per equal height band (Appendix .1 getPressure), force over 2 pi R dz"}),
        "axial_pressure_upper": (("time",), pick["axial_upper"], {"units": "Pa", "long_name": "axial pressure on the upper plate"}),
        "axial_pressure_lower": (("time",), pick["axial_lower"], {"units": "Pa", "long_name": "axial pressure on the lower plate"}),
        "mean_suction": (("time", "material"), pick["suction"], {"units": "Pa", "long_name": "volume-weighted mean suction"}),
        "mean_saturation": (("time", "material"), pick["saturation"], {"units": "1", "long_name": "pore-volume-weighted mean water saturation"}),
        "swelling_profile": (("time", "z"), pick["swelling"], {"units": "1", "long_name": "mean volumetric swelling strain V/V0 - 1 of pellets and powder along the axis"}),
        "suction_profile": (("time", "z"), pick["suction_profile"], {"units": "Pa", "long_name": "mean suction along the axis"}),
        "pellet_suction": (("time", "pellet"), pick["pellet_suction"], {"units": "Pa", "long_name": "suction of each pellet (field snapshots)"}),
        "stop_distance": (("time",), pick["stop_distance"], {"units": "1", "long_name": "largest relative rate of the monitored quantities over its tolerance (1 = stop; NaN: too few records in the window)"}),
        "unbalanced_force": (("time",), pick["unbalanced"], {"units": "1", "long_name": "mean resultant over mean contact force (over the powder's mean push while no contact carries)"}),
        "net_unbalanced_force": (("time",), pick["net_unbalanced"], {"units": "1", "long_name": "the pellets' net resultant over the plates' mean load"}),
        "time_step": (("time",), pick["dt"], {"units": "s", "long_name": "time step that ended at this record"}),
        "step": (("time",), pick["step"], {"units": "1", "long_name": "coupled steps so far"}),
        "remesh_count": (("time",), pick["remeshes"], {"units": "1", "long_name": "remeshes so far"}),
        "balanced": (("time",), balanced.astype(np.int8),
                     {"units": "1", "long_name": "1 if the reading is from a balanced state (unbalanced and net unbalanced force ratios below numerics.dem_balance_tolerance)"}),
        **{name: (("time",), pick[name], {"units": units, "long_name": long})
           for name, (units, long) in INVARIANTS.items()},
        "pellet_position": (("pellet", "xyz"), packing.positions, {"units": "m", "long_name": "initial pellet centre (origin at the container's centre)"}),
        "column_permeability": (("permeability_time",), np.asarray(rows["column_permeability"]), {"units": "m2", "long_name": "permeability of the whole column along its axis (steady flow between the plates, Appendix .1 emulatePermeability)"}),
        "sensor_passage_time": (("sensor",), rows["passage"][0][:-2], {"units": "s", "long_name": f"first time the sensor read {PASSAGE_PRESSURE:g} Pa (every step; NaN: never)"}),
        "axial_passage_time": (("plate",), rows["passage"][0][-2:], {"units": "s", "long_name": f"first time the plate read {PASSAGE_PRESSURE:g} Pa (every step; NaN: never)"}),
        "pellet_radius_final": (("pellet",), model.radii, {"units": "m", "long_name": "pellet radius at the end"}),
    }
    table = model.table
    attrs = {
        "n_pellets": model.n_pellets,
        "n_cells": model.n_cells,
        "packing_fraction": packing.packing_fraction,
        "packing_largest_overlap_m": packing.largest_overlap,
        "table_condition": s.table_condition,
        "table_lookups": table.looked_up,
        "table_clamped_lookups": table.clamped,
        **model.counters.attributes(),
        "steps": model.steps,
        "inert_void_fraction": model.neglected_void_fraction(),
        "boundary_inflow_kg": model.boundary_inflow,
        "dry_density_target_kg_m3": s.dry_density,
        "dry_density_initial_kg_m3": float(pick["dry_density"][0]),
        "dry_density_final_kg_m3": float(pick["dry_density"][-1]),
        "pellet_powder_dry_mass_ratio": model.dry_mass_ratio(),
        "powder_initial_porosity": model.powder_porosity,
        "balanced_fraction": float(np.mean(balanced)),
        "powder_heterogeneity": str(s.powder["heterogeneity"]),
        "powder_swelling_pressure": int(s.powder_pressure),
        "powder_pressure_on_walls": int(s.powder_on_walls),
        "sensor_area_convention": ("force / (2 pi R dz)" if s.sensors.area_share == 1.0
                                   else "force / (pi R dz), the thesis's getPressure"),
        "stop_monitored": ", ".join(MONITORED),
    }
    return xr.Dataset(data, coords=coords, attrs=attrs)
