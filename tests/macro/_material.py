"""The small column's mixture parameters and a pellet of them: shared by the law and
confinement tests."""

from __future__ import annotations

import numpy as np

from macro.laws import mixture_parameters
from tests._macro_cases import small_config

CONFIG = small_config()
MATERIAL = mixture_parameters(CONFIG["materials"], CONFIG["macro"]["powder"])
PHI0 = MATERIAL.reference_porosity


def pellet(suction: float) -> tuple[float, float, float]:
    """A 6 mm pellet of porosity 0.25: V_0 [m3], V_s [m3], m_s [kg]."""
    v0 = 4.0 / 3.0 * np.pi * 6e-3**3
    vs = 0.75 * v0
    return v0, vs, MATERIAL.grain_density * vs
