"""Pellet packing in the cylindrical container by soft-sphere energy minimisation (seeded).

Pellet radii are equal, or drawn uniformly within +-``spread`` of the mean radius (a
size distribution, ``macro.pellet_radius_spread``); the count fills the target packing
fraction with the mean pellet volume. The method is the zero-temperature jamming
protocol of O'Hern, Silbert, Liu and Nagel (2003, Phys. Rev. E 68, 011306): the centres
start uniformly at random in the cylinder at the full radii, and the harmonic overlap
energy of the pellets with each other, the curved wall and the two plates
(:func:`macro._kernels.overlap_energy`) is minimised by L-BFGS (scipy) with its analytic
gradient. Below the jamming fraction of the container the minimum has zero energy, a
packing without overlaps; the jamming fraction is that of random close packing (0.64 in
bulk) lowered by the walls' ordered layers (in the default container 0.585-0.589 with
radius 3.5 mm, 0.548-0.550 with 5.99 mm: benchmarks/reference/macro_packing.json).

Why this method: the minimiser moves all pellets at once along the energy's curvature,
so it reaches fractions near random close packing (the mock-up's 0.574 in 770-900
iterations with pellets of radius 3.5 mm, where radius growth with local overlap
relaxation left overlaps of 1e-2 r after 3000 sweeps), and the overlap left is a
convergence criterion, not a sweep count; the optimiser is a maintained library's.

The energy's radii are inflated by ``INFLATION``, so that the pellets are apart once the
energy nears zero. Pairs come from a Verlet list (``SKIN`` radii beyond contact); the
minimiser is stopped by its callback when a pellet has moved half the skin from where
the list was built, and restarted on a new list. The packing ends when no overlap
exceeds ``TOLERANCE`` of the radius, when the minimiser converges with overlaps left
(the fraction is beyond the container's jamming fraction) or when the iterations run
out. The packing fraction is the pellets' volume over the container's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import OptimizeResult, minimize
from threadpoolctl import threadpool_limits

from macro import _kernels
from shared.dem import detect_contacts
from shared.errors import ConfigError

__all__ = ["Packing", "pack_cylinder", "pellet_count"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
TOLERANCE = 1e-4
"""Largest overlap that ends the minimisation, as a fraction of the mean pellet radius."""
INFLATION = 1e-3
"""Relative inflation of the radii in the minimised energy."""
SKIN = 1.0
"""Verlet margin of the pair list, in mean pellet radii."""


@dataclass
class Packing:
    """positions (n, 3) [m] (axis z, origin at the container's centre), radii (n,) [m],
    packing_fraction [1], largest_overlap [m] left after the minimisation."""

    positions: FloatArray
    radii: FloatArray
    packing_fraction: float
    largest_overlap: float


@dataclass(frozen=True)
class _Container:
    """The cylinder in mean pellet radii: its radius and the heights of its plates."""

    radius: float
    z_low: float
    z_high: float

    def energy(self, positions: FloatArray, radii: FloatArray, pairs: IntArray) -> tuple[float, float, FloatArray]:
        """Overlap energy [r^2], largest overlap [r] and gradient (n, 3) [r]."""
        gradient = np.empty_like(positions)
        energy, largest = _kernels.overlap_energy(positions, radii, pairs, self.radius, self.z_low,
                                                  self.z_high, gradient)
        return float(energy), float(largest), gradient

    def largest_overlap(self, positions: FloatArray, radii: FloatArray) -> float:
        """Largest overlap of any pair, the wall or a plate [r], every pair detected."""
        return self.energy(positions, radii, detect_contacts(positions, radii, 1.0, 0.0))[1]


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
        raise ConfigError(
            f"macro.pellet_radius_m = {pellet_radius} m: a pellet of that radius does not fit in "
            f"the container (macro.cylinder_radius_m = {radius} m, macro.cylinder_height_m = {height} m)"
        )
    mean_volume = 4.0 / 3.0 * np.pi * pellet_radius**3 * (1.0 + spread**2)
    n = int(round(fraction * np.pi * radius**2 * height / mean_volume))
    if n < 5:
        raise ConfigError(
            f"macro.pellet_radius_m = {pellet_radius} m gives {n} pellets in the container; "
            "the Delaunay mesh needs at least 5"
        )
    return n


def pack_cylinder(
    height: float, radius: float, pellet_radius: float, fraction: float,
    rng: np.random.Generator, sweeps: int, spread: float = 0.0,
) -> Packing:
    """Random packing of pellets in a cylinder (axis z, centred at 0) by minimising their
    overlap energy.

    Parameters
    ----------
    height, radius
        Container height and radius [m].
    pellet_radius
        Mean pellet radius [m].
    fraction
        Target packing fraction [1] (sets the pellet count).
    rng
        Seeded generator.
    sweeps
        Iterations of the minimiser, all restarts together.
    spread
        Radii uniform within +-spread of ``pellet_radius`` [1]; 0: equal pellets.
    """
    n = pellet_count(height, radius, pellet_radius, fraction, spread)
    radii = 1.0 + spread * rng.uniform(-1.0, 1.0, n) if spread > 0.0 else np.ones(n)
    container = _Container(radius / pellet_radius, -0.5 * height / pellet_radius, 0.5 * height / pellet_radius)
    positions, largest = _minimise(_random_centres(container, radii, rng), radii, container, sweeps)
    volume = float((4.0 / 3.0 * np.pi * (pellet_radius * radii) ** 3).sum())
    return Packing(pellet_radius * positions, pellet_radius * radii, volume / (np.pi * radius**2 * height),
                   pellet_radius * largest)


def _random_centres(container: _Container, radii: FloatArray, rng: np.random.Generator) -> FloatArray:
    """Centres uniform in the cylinder that keeps each pellet inside (n, 3) [r]."""
    n = radii.size
    rho = (container.radius - radii) * np.sqrt(rng.uniform(0.0, 1.0, n))
    theta = rng.uniform(0.0, 2.0 * np.pi, n)
    z = rng.uniform(container.z_low + radii, container.z_high - radii, n)
    return np.column_stack([rho * np.cos(theta), rho * np.sin(theta), z])


def _minimise(positions: FloatArray, radii: FloatArray, container: _Container,
              iterations: int) -> tuple[FloatArray, float]:
    """Minimise the overlap energy of the inflated radii from ``positions`` [r]; returns
    the positions [r] and the largest overlap of the true radii [r]."""
    inflated = (1.0 + INFLATION) * radii
    used = 0
    # one BLAS thread: the minimiser's vector work is small, and threads only contend
    with threadpool_limits(limits=1, user_api="blas"):
        while True:
            positions, done, restarted = _descend(positions, inflated, container, iterations - used)
            used += done
            largest = container.largest_overlap(positions, radii)
            if largest <= TOLERANCE or not restarted or used >= iterations:
                return positions, largest


def _descend(positions: FloatArray, radii: FloatArray, container: _Container,
             iterations: int) -> tuple[FloatArray, int, bool]:
    """L-BFGS on one Verlet list, at most ``iterations``; returns the positions [r], the
    iterations done (at least 1) and whether a pellet moved half the skin (the list is
    then stale and the minimisation goes on from a new one)."""
    pairs = detect_contacts(positions, radii, 1.0, SKIN)
    start = positions.copy()
    stale = False

    def objective(flat: FloatArray) -> tuple[float, FloatArray]:
        energy, _, gradient = container.energy(flat.reshape(-1, 3), radii, pairs)
        return energy, gradient.ravel()

    def stop_when_stale(intermediate_result: OptimizeResult) -> None:
        nonlocal stale
        moved = intermediate_result.x.reshape(-1, 3) - start
        if float(np.einsum("ij,ij->i", moved, moved).max()) > (0.5 * SKIN) ** 2:
            stale = True
            raise StopIteration

    # ftol 0: stop on the gradient alone, the energy's decrease near zero being tiny
    result = minimize(objective, positions.ravel(), jac=True, method="L-BFGS-B", callback=stop_when_stale,
                      options={"maxiter": max(iterations, 1), "ftol": 0.0, "gtol": 1e-10})
    return result.x.reshape(-1, 3), max(int(result.nit), 1), stale
