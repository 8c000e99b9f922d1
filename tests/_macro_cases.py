"""Macro test inputs: a synthetic pellet permeability table and a small column configuration."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from shared.io import write_dataset
from tests._defaults import CONFIG

SUCTION = np.geomspace(1e5, 2e8, 12)


def synthetic_table(scale: float = 1.0) -> xr.Dataset:
    """Both conditions; water k rises as suction falls (times ``scale``), gas k peaks."""
    log_s = np.log10(SUCTION)
    water = scale * 10.0 ** (-19.0 - 0.8 * (log_s - 5.0))
    gas = 10.0 ** (-22 + 3 * np.exp(-((log_s - 7) ** 2)))
    k = np.empty((2, 2, 3, SUCTION.size))
    k[:, 0] = water
    k[:, 1] = gas
    k[1] *= 0.5
    tensor = np.zeros((2, 2, SUCTION.size, 3, 3))
    for i in range(3):
        tensor[..., i, i] = k[:, :, i, :]
    zeros = np.zeros((2, SUCTION.size))

    def var(dims: tuple[str, ...], values: np.ndarray, units: str) -> tuple[Any, ...]:
        return dims, values, {"units": units, "long_name": "synthetic"}

    return xr.Dataset(
        {
            "k": var(("condition", "phase", "axis", "suction"), k, "m2"),
            "k_tensor": var(("condition", "phase", "suction", "i", "j"), tensor, "m2"),
            "saturation": var(("condition", "suction"), zeros + 0.5, "1"),
            "eps_v": var(("condition", "suction"), zeros, "1"),
        },
        coords={
            "condition": ["free", "confined"], "phase": ["water", "gas"],
            "axis": ["x", "y", "z"],
            "suction": ("suction", SUCTION, {"units": "Pa", "long_name": "suction"}),
        },
    )


def write_table(path: Path, scale: float = 1.0) -> Path:
    write_dataset(synthetic_table(scale), path, stage="upscaling", title="synthetic table")
    return path


def small_config(**macro: Any) -> dict[str, Any]:
    """The default configuration with a small column (about 70 pellets of 4 mm, the packing
    fraction's mixture) and three
    sensors 10 mm from each end and at mid-height, each over one pellet diameter."""
    config = copy.deepcopy(CONFIG)
    config["macro"].update(
        cylinder_height_m=0.05, cylinder_radius_m=0.015, pellet_radius_m=4.0e-3,
        sensors={name: {"height_m": height, "band_width_m": 0.008}
                 for name, height in (("S10", 0.01), ("S25", 0.025), ("S40", 0.04))},
        cases={"small": {}},
    )
    config["macro"]["numerics"]["packing_iterations"] = 1500
    # the default's 80/20 needs a packing fraction no small column reaches
    config["macro"]["mixture"]["pellet_powder_dry_mass_ratio"] = None
    config["macro"].update(macro)
    return config


def swelling(suction):
    """Eq. 4.28 with the sign of docs/design.md §3, per Pa."""
    pellet = CONFIG["materials"]["mixture_pellet"]
    a, b, s0 = pellet["swelling_alpha_per_pa"], pellet["swelling_beta_per_pa"], pellet["initial_suction_pa"]
    return b / a * (np.exp(-a * suction) - np.exp(-a * s0))
