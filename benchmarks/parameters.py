"""The embedded default configuration's parameters: benchmarks time the model users run."""

from __future__ import annotations

from micro.run import hydration_settings
from shared.config import default_config
from shared.dem.parameters import dem_parameters
from shared.materials import clay_parameters

CONFIG = default_config()
CLAY = clay_parameters(CONFIG["materials"]["pellet"])
DEM = dem_parameters(CONFIG["materials"]["pellet"], CONFIG["micro"]["numerics"])
SETTINGS = hydration_settings(CONFIG["micro"]["numerics"], cracks=True)
