"""Pellet packing in the cylindrical container by radius growth (seeded).

Pellet radii are equal, or drawn uniformly within +-``spread`` of the mean radius (a
size distribution, ``macro.pellet_radius_spread``); the count fills the target packing
fraction with the mean pellet volume. Pellet centres start uniformly at random in the
cylinder with half their target radius;
the radii grow linearly to the target over the first half of the sweeps while an
overdamped relaxation moves each pellet by half of its overlaps with the other pellets,
the curved wall and the two plates; the second half relaxes at full size, then up to as
many sweeps again until no overlap exceeds 1e-4 of the radius. The packing
fraction is the pellets' volume over the container's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from macro import _kernels
from shared.dem import detect_contacts

__all__ = ["Packing", "pack_cylinder", "pellet_count"]

FloatArray = npt.NDArray[np.float64]


@dataclass
class Packing:
    """positions (n, 3) [m] (axis z, origin at the container's centre), radii (n,) [m],
    packing_fraction [1], largest_overlap [m] left after relaxation."""

    positions: FloatArray
    radii: FloatArray
    packing_fraction: float
    largest_overlap: float


def pellet_count(height: float, radius: float, pellet_radius: float, fraction: float,
                 spread: float = 0.0) -> int:
    """Number of pellets of a target packing fraction in the container (radii uniform
    within +-``spread`` of ``pellet_radius``: mean volume r^3 (1 + spread^2)).

    Raises
    ------
    ValueError
        Naming ``macro.pellet_radius_m`` when a pellet does not fit in the container.
    """
    if not 2.0 * pellet_radius * (1.0 + spread) < min(2.0 * radius, height):
        raise ValueError(
            f"macro.pellet_radius_m = {pellet_radius} m: a pellet of that radius does not fit in "
            f"the container (macro.cylinder_radius_m = {radius} m, macro.cylinder_height_m = {height} m)"
        )
    mean_volume = 4.0 / 3.0 * np.pi * pellet_radius**3 * (1.0 + spread**2)
    n = int(round(fraction * np.pi * radius**2 * height / mean_volume))
    if n < 5:
        raise ValueError(
            f"macro.pellet_radius_m = {pellet_radius} m gives {n} pellets in the container; "
            "the Delaunay mesh needs at least 5"
        )
    return n


def pack_cylinder(
    height: float, radius: float, pellet_radius: float, fraction: float,
    rng: np.random.Generator, sweeps: int, spread: float = 0.0,
) -> Packing:
    """Radius-growth packing of pellets in a cylinder (axis z, centred at 0).

    Parameters
    ----------
    height, radius
        Container height and radius [m].
    pellet_radius
        Pellet radius [m].
    fraction
        Target packing fraction [1] (sets the pellet count).
    rng
        Seeded generator.
    sweeps
        Relaxation sweeps.
    spread
        Radii uniform within +-spread of ``pellet_radius`` [1]; 0: equal pellets.
    """
    n = pellet_count(height, radius, pellet_radius, fraction, spread)
    target = pellet_radius * (1.0 + spread * rng.uniform(-1.0, 1.0, n)) if spread > 0.0 else np.full(n, pellet_radius)
    inner = radius - target
    rho = inner * np.sqrt(rng.uniform(0.0, 1.0, n))
    theta = rng.uniform(0.0, 2.0 * np.pi, n)
    z = rng.uniform(-0.5 * height + target, 0.5 * height - target, n)
    positions = np.column_stack([rho * np.cos(theta), rho * np.sin(theta), z])
    grow = max(sweeps // 2, 1)
    largest = np.inf
    pairs = np.empty((0, 2), dtype=np.int64)
    for sweep in range(sweeps):
        radii = target * min(1.0, 0.5 + 0.5 * (sweep + 1) / grow)
        if sweep % 5 == 0:
            pairs = detect_contacts(positions, radii, 1.0, 0.5 * pellet_radius)
        largest = _kernels.relax_overlaps(
            positions, radii, pairs, radius, -0.5 * height, 0.5 * height, 0.5
        )
    radii = target
    # relax at full size until the overlaps are below 1e-4 r (or the sweeps run out)
    for sweep in range(sweeps):
        if sweep % 5 == 0:
            pairs = detect_contacts(positions, radii, 1.0, 0.1 * pellet_radius)
        largest = _kernels.relax_overlaps(
            positions, radii, pairs, radius, -0.5 * height, 0.5 * height, 0.5
        )
        if largest < 1e-4 * pellet_radius:
            break
    pairs = detect_contacts(positions, radii, 1.0, 0.0)
    largest = _kernels.relax_overlaps(positions, radii, pairs, radius, -0.5 * height,
                                      0.5 * height, 0.0)
    volume = float((4.0 / 3.0 * np.pi * radii**3).sum())
    return Packing(positions, radii, volume / (np.pi * radius**2 * height), float(largest))
