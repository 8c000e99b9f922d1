"""Figures of the CT stage: what a user looks at before reading numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib.ticker import MaxNLocator

from shared.figures import new_figure, outside_legend, save_figure

__all__ = ["porosity_figure", "rev_figure"]


def _mid(n: int) -> int:
    return n // 2


def porosity_figure(image: xr.Dataset, porosity: xr.Dataset, path: str | Path) -> Path:
    """Grey (the stored preview) and porosity slices (xy and xz through the centre) and the
    porosity and density histograms."""
    fig, axes = new_figure(2, 3)
    spacing_mm = float(porosity.attrs.get("grid_spacing", np.nan)) * 1e3
    fig.suptitle(f"CT sample {Path(path).stem}: porosity grid of {spacing_mm:.3g} mm blocks",
                 fontsize="medium")
    grey = image["grey_preview"].rename(z_preview="z", y_preview="y", x_preview="x")
    phi = porosity["porosity"]
    mm = 1e3
    panels = [
        (axes[0, 0], grey.isel(z=_mid(grey.sizes["z"])), "x", "y", "grey, xy (mid z)", "gray", "grey value [-]"),
        (axes[0, 1], grey.isel(y=_mid(grey.sizes["y"])), "x", "z", "grey, xz (mid y)", "gray", "grey value [-]"),
        (axes[1, 0], phi.isel(z=_mid(phi.sizes["z"])), "x", "y", "porosity, xy (mid z)", "viridis", "porosity [-]"),
        (axes[1, 1], phi.isel(y=_mid(phi.sizes["y"])), "x", "z", "porosity, xz (mid y)", "viridis", "porosity [-]"),
    ]
    for ax, field, h, v, title, cmap, unit in panels:
        extent = [field[h].min() * mm, field[h].max() * mm, field[v].min() * mm, field[v].max() * mm]
        shown = ax.imshow(np.asarray(field.transpose(v, h)), origin="lower", extent=extent, cmap=cmap)
        fig.colorbar(shown, ax=ax, shrink=0.8, label=unit)
        ax.set(title=title, xlabel=f"{h} [mm]", ylabel=f"{v} [mm]")
    values = phi.values[np.isfinite(phi.values)]
    axes[1, 2].hist(values, bins=40, color="tab:blue")
    axes[1, 2].axvline(values.mean(), color="k", ls="--", label=f"mean {values.mean():.3f}")
    axes[1, 2].set(title="porosity of grid blocks", xlabel="porosity [-]", ylabel="number of blocks")
    outside_legend(axes[1, 2])
    density = porosity["density"].values
    axes[0, 2].hist(density[np.isfinite(density)], bins=40, color="tab:brown")
    axes[0, 2].set(title="block dry density", xlabel="density [kg/m3]", ylabel="number of blocks")
    for ax in (axes[0, 2], axes[1, 2]):
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    return save_figure(fig, path)


def rev_figure(rev: xr.Dataset, path: str | Path) -> Path:
    """REV curves (random windows mean +- std, band clipped at 0, and the centred window;
    the calibrated porosity beside the binary one) and chord-length distributions r f(r)."""
    fig, axes = new_figure(2, 2, width=6.0)
    fig.suptitle(f"CT sample {Path(path).stem}: REV and chord lengths", fontsize="medium")
    window_mm = rev["window"].values * 1e3
    centred_mm = rev["window_centred"].values * 1e3
    for ax, name, unit in ((axes[0, 0], "porosity", "-"), (axes[0, 1], "interface", "1/m")):
        mean, std = rev[f"{name}_mean"].values, rev[f"{name}_std"].values
        label = "binary image" if name == "porosity" else "random windows"
        ax.fill_between(window_mm, np.maximum(mean - std, 0.0), mean + std, alpha=0.3,
                        label=f"{label}, +-1 std")
        ax.plot(window_mm, mean, "o-", label=f"{label}, mean")
        ax.plot(centred_mm, rev[f"{name}_centred"].values, "s--", ms=3, label="centred window")
        if name == "porosity":
            ax.plot(window_mm, rev["calibrated_porosity_mean"].values, "^-", color="tab:gray",
                    label="calibrated porosity, mean")
        tolerance = float(rev.attrs.get("rev_tolerance", np.nan))
        total = float(rev[f"{name}_total"]) if f"{name}_total" in rev else np.nan
        if np.isfinite(tolerance) and np.isfinite(total):
            ax.axhspan(total * (1 - tolerance), total * (1 + tolerance), color="k", alpha=0.08,
                       label=f"whole cube +-{100 * tolerance:.3g} % (REV tolerance)")
        w_rev = float(rev[f"w_rev_{name}_centred"])
        if np.isfinite(w_rev):
            ax.axvline(w_rev * 1e3, color="k", ls=":", label=f"REV (centred) {w_rev * 1e3:.2g} mm")
        ax.set(xscale="log", xlabel="window edge [mm]", ylabel=f"{name} [{unit}]", title=f"REV: {name}")
        ax.set_ylim(bottom=0.0)
        outside_legend(ax)
    # chords in mm as the windows: one length unit across the figure
    length_mm = rev["length"].values * 1e3
    for ax, phase in ((axes[1, 0], "pore"), (axes[1, 1], "solid")):
        for direction in rev["direction"].values:
            f = rev[f"chord_{phase}"].sel(direction=direction).values
            ax.plot(length_mm, rev["length"].values * f, label=f"{direction}")
        ratio = float(rev["R_p" if phase == "pore" else "R_s"])
        ax.set(xscale="log", xlabel="chord length r [mm]", ylabel="r f(r) [-]",
               title=f"{phase} chords (R = {ratio:.3g})")
        outside_legend(ax, title="direction")
    return save_figure(fig, path)
