"""Summary figure of a packing: profiles, rocking curve and voxel slices (cf. paper Fig. 9)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

from imaging.packing.voxels import VoxelImage  # noqa: E402
from shared.figures import outside_legend, save_figure  # noqa: E402

__all__ = ["packing_figure"]


def packing_figure(ds: xr.Dataset, image: VoxelImage, path: str | Path) -> Path:
    """Write a PNG with the porosity and order profiles (z_min, z_max marked), the
    rocking curve, and a vertical and a horizontal slice of the voxel image.

    Parameters
    ----------
    ds : xarray.Dataset
        The packing dataset (:func:`imaging.packing.dataset.packing_dataset`).
    image : VoxelImage
        Its voxel image.
    path : str or Path
        Target PNG.

    Returns
    -------
    Path
    """
    path = Path(path)
    micron = 1e6
    z = ds["zbin"].values * micron
    fig, axes = plt.subplots(2, 2, figsize=(10, 8), constrained_layout=True)
    fig.suptitle(f"packing {path.stem}: {ds.sizes.get('particle', 0)} elliptic disks", fontsize="medium")
    ax = axes[0, 0]
    ax.plot(ds["porosity_profile"].values, z, "o-", ms=3, label="porosity")
    ax.plot(ds["order_profile"].values, z, "s-", ms=3,
            label="S_part = <P2(cos theta)>, order\n(1: disks flat, 0: random)")
    for name in ("z_min", "z_max"):
        ax.axhline(float(ds[name]) * micron, color="grey", ls="--")
    ax.plot([], [], color="grey", ls="--", label="z_min, z_max: the analysed zone\n(away from floor and top)")
    ax.set(xlabel="porosity, S_part [-]", ylabel="z [um]",
           title=f"porosity {float(ds['porosity']):.3f}, S_part {float(ds['S_part']):.3f}")
    outside_legend(ax)
    ax = axes[0, 1]
    ax.plot(np.degrees(ds["theta"].values), ds["rocking_curve"].values, "o", ms=3)
    ax.set(xlabel="theta, disk normal from z [degree]", ylabel="I_c, orientation density [1/sr]",
           yscale="log", title=f"rocking curve; f_o = {float(ds['overlap_fraction']):.1e}\n"
                               "(f_o: solid voxels in 2 or more disks)")
    solid = image.solid
    extent_xy = (0.0, solid.shape[2] * image.voxel_size * micron)
    z_top = image.z_origin + solid.shape[0] * image.voxel_size
    axes[1, 0].imshow(solid[:, solid.shape[1] // 2, :], origin="lower", cmap="gray_r",
                      extent=extent_xy + (image.z_origin * micron, z_top * micron), aspect="auto")
    axes[1, 0].set(xlabel="x [um]", ylabel="z [um]", title="voxel slice y = w/2 (solid dark)")
    axes[1, 1].imshow(solid[solid.shape[0] // 2], origin="lower", cmap="gray_r",
                      extent=extent_xy + extent_xy)
    axes[1, 1].set(xlabel="x [um]", ylabel="y [um]", title="voxel slice at mid-height (solid dark)")
    path.parent.mkdir(parents=True, exist_ok=True)
    return save_figure(fig, path)  # labelled log ticks (shared.figures.log_ticks)
