"""numba kernel of the macro packing: overdamped relaxation of overlaps in a cylinder.

Arrays in, arrays out; serial loops that scatter into per-pellet arrays (deterministic).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _pair_overlap(positions, radii, i, j):  # type: ignore[no-untyped-def]
    """Branch vector i -> j, centre distance and overlap r_i + r_j - distance [m]."""
    dx = positions[j, 0] - positions[i, 0]
    dy = positions[j, 1] - positions[i, 1]
    dz = positions[j, 2] - positions[i, 2]
    dist = np.sqrt(dx * dx + dy * dy + dz * dz)
    return dx, dy, dz, dist, radii[i] + radii[j] - dist


@njit(cache=True)
def relax_overlaps(positions, radii, pairs, cylinder_radius, z_low, z_high, fraction):
    """Move pellets apart by ``fraction`` of their overlaps (pairs, curved wall, plates).

    Overdamped (position-based) relaxation of a radius-growth packing. Returns the
    largest overlap found [m] before the move.
    """
    n = positions.shape[0]
    move = np.zeros((n, 3))
    largest = 0.0
    for k in range(pairs.shape[0]):
        i, j = pairs[k, 0], pairs[k, 1]
        dx, dy, dz, dist, overlap = _pair_overlap(positions, radii, i, j)
        if overlap <= 0.0 or dist == 0.0:
            continue
        largest = max(largest, overlap)
        s = 0.5 * fraction * overlap / dist
        move[i, 0] -= s * dx
        move[i, 1] -= s * dy
        move[i, 2] -= s * dz
        move[j, 0] += s * dx
        move[j, 1] += s * dy
        move[j, 2] += s * dz
    for i in range(n):
        rho = np.sqrt(positions[i, 0] ** 2 + positions[i, 1] ** 2)
        wall = rho + radii[i] - cylinder_radius
        if wall > 0.0 and rho > 0.0:
            largest = max(largest, wall)
            move[i, 0] -= fraction * wall * positions[i, 0] / rho
            move[i, 1] -= fraction * wall * positions[i, 1] / rho
        low = z_low + radii[i] - positions[i, 2]
        if low > 0.0:
            largest = max(largest, low)
            move[i, 2] += fraction * low
        high = positions[i, 2] + radii[i] - z_high
        if high > 0.0:
            largest = max(largest, high)
            move[i, 2] -= fraction * high
    for i in range(n):
        for c in range(3):
            positions[i, c] += move[i, c]
    return largest
