"""Upscaling: micro permeability curves -> the pellet permeability table macro reads.

``table`` condenses micro results (pure: :func:`upscale`), ``run`` is the stage's entry point (files,
CSV export, figure). The reader and interpolator live in :mod:`shared.upscaling`.
"""

from micro.upscaling.table import (
    SOURCE_VARIABLES,
    UpscalingSettings,
    table_rows,
    upscale,
    upscaling_table,
)

__all__ = ["SOURCE_VARIABLES", "UpscalingSettings", "table_rows", "upscale", "upscaling_table"]
