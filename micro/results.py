"""The Dataset of a micro case: one variable per record key, declared once here.

A checkpoint's record (:func:`micro.pellet.measure_checkpoint` and the diagnostics of
:func:`micro.hydration.advance_to_balance`) becomes one slice along ``suction`` of
``results/micro/<case>.nc`` (docs/design.md §2): :data:`SCALARS` are its scalar keys,
:data:`ARRAYS` its array keys, and the permeability tensor gives the tensor variables
with their principal values and directions (:func:`tensor_variables`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

import numpy as np
import xarray as xr

from micro.pellet import POROSITY_BINS
from micro.permeability import principal_permeability

__all__ = ["ARRAYS", "SCALARS", "records_dataset", "tensor_variables"]

log = logging.getLogger("micro")

SCALARS: dict[str, tuple[str, str, type]] = {
    # name: (units, long name, dtype): the counts are integers
    "saturation": ("1", "pore-volume weighted water saturation", float),
    "eps_v": ("1", "volumetric strain of the specimen from its state at 132 MPa", float),
    "porosity_mean": ("1", "volume-weighted mean porosity", float),
    "crack_count": ("1", "number of open bonds on mesh edges (cracks)", np.int64),
    "crack_count_imbibed": ("1", "number of water-filled cracks", np.int64),
    "crack_count_gas": ("1", "number of gas-filled cracks", np.int64),
    "crack_area": ("m2", "total crack area", float),
    "crack_area_imbibed": ("m2", "area of water-filled cracks", float),
    "crack_area_gas": ("m2", "area of gas-filled cracks", float),
    "crack_volume": ("m3", "total crack volume", float),
    "time": ("s", "simulated hydration time", float),
    "n_remesh": ("1", "number of Delaunay remeshes so far", np.int64),
    "flow_steps": ("1", "flow steps taken to reach the checkpoint", np.int64),
    "dem_steps": ("1", "DEM relaxation steps taken to reach the checkpoint", np.int64),
    "unbalanced_force": ("1", "unbalanced-force ratio at the end of the checkpoint", float),
    "suction_misfit": ("1", "largest relative departure of a cell's suction from the boundary's",
                       float),
    "balanced": ("1", "1 if hydraulic and mechanical balance were reached, else 0", np.int64),
}
"""The records' scalar keys: units, long name and stored type."""

_FABRIC = "crack fabric tensor (1/N) sum a_c n n of {} cracks"
ARRAYS: dict[str, tuple[tuple[str, ...], str, str]] = {
    # name: (dimensions after suction, units, long name)
    "permeability": (("phase", "axis"), "m2", "intrinsic x relative permeability, measured by a "
                                              "steady solve with a linear boundary pressure"),
    "crack_fabric": (("i", "j"), "m2", _FABRIC.format("all")),
    "crack_fabric_imbibed": (("i", "j"), "m2", _FABRIC.format("water-filled")),
    "crack_fabric_gas": (("i", "j"), "m2", _FABRIC.format("gas-filled")),
    "porosity_hist": (("bin",), "1", "volume fraction of cells per porosity bin"),
}
"""The records' array keys but the permeability tensor (:func:`tensor_variables`)."""


def records_dataset(records: Sequence[dict[str, Any]], checkpoints: np.ndarray) -> xr.Dataset:
    """The Dataset of a case's records, one per checkpoint suction [Pa] (the first
    ``len(records)`` of ``checkpoints``)."""
    suction = checkpoints[: len(records)]
    data: dict[str, Any] = {}
    for name, (units, long_name, dtype) in SCALARS.items():
        data[name] = ("suction", np.array([r[name] for r in records], dtype=dtype),
                      {"units": units, "long_name": long_name})
    for name, (dims, units, long_name) in ARRAYS.items():
        data[name] = (("suction", *dims), np.stack([r[name] for r in records]),
                      {"units": units, "long_name": long_name})
        if name == "permeability":
            data.update(tensor_variables(records))
    centres = 0.5 * (POROSITY_BINS[1:] + POROSITY_BINS[:-1])
    coords = {
        # suction indexes the checkpoints (ds.sel(suction=1e6)); the checkpoint's number
        # is a coordinate along it (the ParaView series' time step, micro/vtk.py)
        "suction": ("suction", suction, {"units": "Pa", "long_name": "boundary suction"}),
        "checkpoint": ("suction", np.arange(len(records)), {"units": "1", "long_name": "checkpoint index"}),
        "phase": ("phase", np.array(["water", "gas"]), {"long_name": "fluid phase"}),
        "axis": ("axis", np.array(["x", "y", "z"]), {"long_name": "direction (z: compaction axis)"}),
        "i": ("i", np.arange(3), {"units": "1", "long_name": "tensor row (x, y, z)"}),
        "j": ("j", np.arange(3), {"units": "1", "long_name": "tensor column (x, y, z)"}),
        "bin": ("bin", centres, {"units": "1", "long_name": "porosity bin centre"}),
        "principal": ("principal", np.arange(3),
                      {"units": "1", "long_name": "principal axis, by ascending principal value"}),
    }
    return xr.Dataset(data, coords=coords)



def tensor_variables(records: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The permeability tensors of the records [m2] and their principal values and
    directions, as Dataset variables.

    A record without a tensor (from a checkpoint file of an older version) gives NaN.
    """
    missing = np.full((2, 3, 3), np.nan)
    if any("permeability_tensor" not in r for r in records):
        log.warning("records without a permeability tensor (resumed from an older checkpoint "
                    "file): stored as NaN")
    tensor = np.stack([np.asarray(r.get("permeability_tensor", missing), dtype=float)
                       for r in records])
    derived = principal_permeability(tensor)
    how = ("linear pressure on all six walls along x, y and z in turn (one factorisation per "
           "phase), Darcy velocity averaged over the inner 80 % of the box")
    return {
        "permeability_tensor": (
            ("suction", "phase", "i", "j"), tensor,
            {"units": "m2", "long_name": "permeability tensor K_ij = -mu <v_i> / (grad p)_j, "
                                         f"{how}"},
        ),
        "permeability_tensor_symmetric": (
            ("suction", "phase", "i", "j"), derived.symmetric,
            {"units": "m2", "long_name": "symmetric part (K + K^T)/2 of the permeability tensor"},
        ),
        "permeability_principal": (
            ("suction", "phase", "principal"), derived.values,
            {"units": "m2", "long_name": "principal permeabilities: eigenvalues of the symmetric "
                                         "part, ascending"},
        ),
        "permeability_principal_direction": (
            ("suction", "phase", "i", "principal"), derived.directions,
            {"units": "1", "long_name": "principal directions: unit eigenvectors (components "
                                        "i = x, y, z) of the symmetric part, largest component "
                                        "positive"},
        ),
        "permeability_asymmetry": (
            ("suction", "phase"), derived.asymmetry,
            {"units": "1", "long_name": "relative asymmetry ||K - K^T||_F / ||K||_F of the "
                                        "permeability tensor"},
        ),
    }
