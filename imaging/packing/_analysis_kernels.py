"""Kernels of the bed analyses: voxel coverage and basal contact area, numba."""

from __future__ import annotations

import numpy as np
from numba import njit

from imaging.packing._contact_kernels import contains_point
from imaging.packing._grid_kernels import gather_levels


@njit(cache=True)
def voxel_coverage(centers, rots, axes, exts, z_origin, voxel_size, counts):
    """Count, per voxel, the particles that contain its centre (saturating at 255).

    ``counts`` has shape (nz, ny, nx) with nx * voxel_size = ny * voxel_size = box
    width (periodic in x and y); voxel (k, j, i) is centred at ((i + 1/2) l,
    (j + 1/2) l, z_origin + (k + 1/2) l) [m].
    """
    nz, ny, nx = counts.shape
    for p in range(centers.shape[0]):
        c = centers[p]
        e = exts[p]
        i0 = int(np.floor((c[0] - e[0]) / voxel_size - 0.5))
        i1 = int(np.ceil((c[0] + e[0]) / voxel_size - 0.5))
        j0 = int(np.floor((c[1] - e[1]) / voxel_size - 0.5))
        j1 = int(np.ceil((c[1] + e[1]) / voxel_size - 0.5))
        k0 = max(int(np.floor((c[2] - e[2] - z_origin) / voxel_size - 0.5)), 0)
        k1 = min(int(np.ceil((c[2] + e[2] - z_origin) / voxel_size - 0.5)), nz - 1)
        for k in range(k0, k1 + 1):
            z = z_origin + (k + 0.5) * voxel_size
            for j in range(j0, j1 + 1):
                y = (j + 0.5) * voxel_size
                for i in range(i0, i1 + 1):
                    if contains_point(c, rots[p], axes[p], (i + 0.5) * voxel_size, y, z):
                        cell = counts[k, j % ny, i % nx]
                        if cell < 255:
                            counts[k, j % ny, i % nx] = cell + 1


@njit(cache=True)
def _touches_basal_face(px, py, pz, center, rot, axes, d_cont):
    """True if a point is within d_cont [m] of a basal face of a particle, measured along
    its normal, and above or below the face's ellipse."""
    dx = px - center[0]
    dy = py - center[1]
    dz = pz - center[2]
    l0 = rot[0, 0] * dx + rot[1, 0] * dy + rot[2, 0] * dz
    l1 = rot[0, 1] * dx + rot[1, 1] * dy + rot[2, 1] * dz
    l2 = rot[0, 2] * dx + rot[1, 2] * dy + rot[2, 2] * dz
    if (l0 / axes[0]) ** 2 + (l1 / axes[1]) ** 2 > 1.0:
        return False
    return abs(abs(l2) - axes[2]) < d_cont


@njit(cache=True)
def basal_contact_points(selected, step, centers, rots, axes, exts, fine, coarse, link,
                         geometry, found, shifts):
    """Number of square centres of a grid of edge ``step`` [m] laid on the bottom basal
    face of each selected particle that lie within d_cont of another particle's basal
    face (Ferrage et al. 2015, Eq. 11). ``fine``, ``coarse``, ``link`` and ``geometry``
    describe the bed's grids (see :func:`._grid_kernels.gather_levels`)."""
    d_cont = geometry[1]
    lo = np.empty(3)
    hi = np.empty(3)
    total = 0
    for i in selected:
        a, b, c = axes[i]
        for k in range(3):  # element-wise: an array assignment compiles numba's error text
            lo[k] = centers[i, k] - exts[i, k] - d_cont
            hi[k] = centers[i, k] + exts[i, k] + d_cont
        count = gather_levels(lo, hi, centers, exts, fine, coarse, link, geometry, found, shifts)
        na = int(np.ceil(a / step))
        nb = int(np.ceil(b / step))
        for u in range(-na, na):
            x = (u + 0.5) * step
            for v in range(-nb, nb):
                y = (v + 0.5) * step
                if (x / a) ** 2 + (y / b) ** 2 > 1.0:
                    continue
                p = centers[i] + rots[i, :, 0] * x + rots[i, :, 1] * y - rots[i, :, 2] * c
                for k in range(count):
                    j = found[k]
                    if j == i and shifts[k, 0] == 0.0 and shifts[k, 1] == 0.0:
                        continue
                    cj = centers[j].copy()
                    cj[0] += shifts[k, 0]
                    cj[1] += shifts[k, 1]
                    if _touches_basal_face(p[0], p[1], p[2], cj, rots[j], axes[j], d_cont):
                        total += 1
                        break
    return total
