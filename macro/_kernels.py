"""numba kernel of the macro packing: soft-sphere overlap energy in a cylinder.

Arrays in, arrays out; serial loops that scatter into per-pellet arrays (deterministic).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def overlap_energy(positions, radii, pairs, cylinder_radius, z_low, z_high, gradient):  # type: ignore[no-untyped-def]
    """Harmonic overlap energy of spheres in a closed cylinder (axis z), its gradient.

    E = sum over the listed pairs of (r_i + r_j - d_ij)^2 / 2, plus (rho_i + r_i - R)^2 / 2
    for the curved wall and (z_low + r_i - z_i)^2 / 2, (z_i + r_i - z_high)^2 / 2 for
    the plates, each term only where it overlaps. Lengths in any one unit; the energy
    is in that unit squared.

    Parameters
    ----------
    positions
        (n, 3) sphere centres.
    radii
        (n,) sphere radii.
    pairs
        (m, 2) candidate pairs (i, j).
    cylinder_radius, z_low, z_high
        The container's radius and the heights of its plates.
    gradient
        (n, 3) output: dE/dpositions (overwritten).

    Returns
    -------
    energy, largest
        The energy and the largest overlap (0 when none; same unit as the lengths).
    """
    n = positions.shape[0]
    gradient[:] = 0.0
    energy = 0.0
    largest = 0.0
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        dx = positions[j, 0] - positions[i, 0]
        dy = positions[j, 1] - positions[i, 1]
        dz = positions[j, 2] - positions[i, 2]
        dist = np.sqrt(dx * dx + dy * dy + dz * dz)
        overlap = radii[i] + radii[j] - dist
        if overlap <= 0.0 or dist == 0.0:
            continue
        largest = max(largest, overlap)
        energy += 0.5 * overlap * overlap
        # dE/dx_i = overlap (x_j - x_i) / d, and the opposite for j
        s = overlap / dist
        gradient[i, 0] += s * dx
        gradient[i, 1] += s * dy
        gradient[i, 2] += s * dz
        gradient[j, 0] -= s * dx
        gradient[j, 1] -= s * dy
        gradient[j, 2] -= s * dz
    for i in range(n):
        rho = np.sqrt(positions[i, 0] ** 2 + positions[i, 1] ** 2)
        wall = rho + radii[i] - cylinder_radius
        if wall > 0.0 and rho > 0.0:
            largest = max(largest, wall)
            energy += 0.5 * wall * wall
            gradient[i, 0] += wall * positions[i, 0] / rho
            gradient[i, 1] += wall * positions[i, 1] / rho
        low = z_low + radii[i] - positions[i, 2]
        if low > 0.0:
            largest = max(largest, low)
            energy += 0.5 * low * low
            gradient[i, 2] -= low
        high = positions[i, 2] + radii[i] - z_high
        if high > 0.0:
            largest = max(largest, high)
            energy += 0.5 * high * high
            gradient[i, 2] += high
    return energy, largest
