"""Figure of the pellet permeability table: the curves the macro model will read."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from shared.figures import new_figure, outside_legend, save_figure
from shared.upscaling import PermeabilityTable

__all__ = ["table_figure"]

_PHASE_COLOUR = {"water": "tab:blue", "gas": "tab:red"}
_AXIS_STYLE = {"x": "-", "y": "--", "z": ":"}


def table_figure(table: xr.Dataset, path: str | Path) -> Path:
    """Per condition: k(suction) per phase and axis at the nodes, the interpolated
    geometric mean between them, and the ensemble band (+-1 std of log10 k) if any;
    below, saturation and strain against suction."""
    conditions = [str(c) for c in table["condition"].values]
    fig, axes = new_figure(2, len(conditions), width=6.0)
    fig.suptitle(f"pellet permeability table ({', '.join(conditions)}): what the macro model reads",
                 fontsize="medium")
    suction = table["suction"].values
    fine = np.geomspace(suction[0], suction[-1], 200)
    for column, condition in enumerate(conditions):
        view = table.sel(condition=condition)
        curve = PermeabilityTable(table, condition)
        ax = axes[0, column]
        for phase in [str(p) for p in table["phase"].values]:
            colour = _PHASE_COLOUR.get(phase, "k")
            for axis in [str(a) for a in table["axis"].values]:
                k = view["k"].sel(phase=phase, axis=axis).values
                ax.plot(suction, k, _AXIS_STYLE.get(axis, "-"), color=colour, marker="o", ms=3,
                        alpha=0.6, label=f"{phase} {axis}")
                spread = view["k_log10_std"].sel(phase=phase, axis=axis).values
                if np.isfinite(spread).all():
                    ax.fill_between(suction, k / 10**spread, k * 10**spread, color=colour, alpha=0.1)
            ax.plot(fine, curve.permeability(fine, phase), color=colour, lw=2,
                    label=f"{phase}, interpolated mean")
        ax.set(xscale="log", yscale="log", xlabel="suction [Pa]", ylabel="permeability [m2]",
               title=f"{condition} pellet (n = {int(view['n_realizations'])})")
        outside_legend(ax)
        low = axes[1, column]
        low.plot(suction, view["saturation"].values, "k-o", ms=3, label="saturation")
        low.plot(suction, view["eps_v"].values, "g-s", ms=3, label="eps_v")
        low.set(xscale="log", xlabel="suction [Pa]", ylabel="saturation, volumetric strain [-]",
                title="saturation and swelling")
        outside_legend(low)
    return save_figure(fig, path)
