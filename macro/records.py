"""The records of a macro run: what each step adds, the column's permeability when due,
the stop distance over the window, and the thinning that keeps long runs bounded.

A record's quantities are named once, in :meth:`Records.record`; the rows of a new run
are created by the first record, and a resumed run's rows are its snapshot's.
"""

from __future__ import annotations

import bisect
import logging
from typing import Any

import numpy as np
import numpy.typing as npt

from macro.column_permeability import column_permeability
from macro.model import MacroModel
from macro.stopping import stop_distance

__all__ = ["INVARIANTS", "MEASUREMENT_ROWS", "PASSAGE_PRESSURE", "Records"]

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
            "unbalanced": r.unbalanced, "dt": dt, "step": model.steps, **model.invariants(),
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
