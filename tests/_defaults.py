"""The embedded default configuration's parameters, for tests: they test the model users run.

Tests change single values with :func:`clay`, :func:`dem` and :func:`settings`.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from micro.hydration import HydrationSettings
from micro.run import hydration_settings
from shared.config import default_config
from shared.dem.parameters import DEMParameters, dem_parameters
from shared.materials import ClayParameters, clay_parameters

CONFIG = default_config()
CLAY = clay_parameters(CONFIG["materials"]["pellet"])
DEM = dem_parameters(CONFIG["materials"]["pellet"], CONFIG["micro"]["numerics"])
SETTINGS = hydration_settings(CONFIG["micro"]["numerics"], cracks=True)


def clay(**changes: Any) -> ClayParameters:
    """The default clay parameters with some fields changed."""
    return dataclasses.replace(CLAY, **changes)


def dem(**changes: Any) -> DEMParameters:
    """The default DEM parameters with some fields changed."""
    return dataclasses.replace(DEM, **changes)


def settings(**changes: Any) -> HydrationSettings:
    """The default hydration settings with some fields changed."""
    return dataclasses.replace(SETTINGS, **changes)
