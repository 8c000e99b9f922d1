"""The local pressure-volume problem of each system (Caulk 2022, Sec. 4.3, Eqs. 4.39-4.51).

Given a system's water mass m_w, solid volume V_s, reference volume V_0 and largest
volume V_max, find its volume V [m3] and water pressure p [Pa] with

    f1 = S(V) - S_ret(p, phi(V)) - mu sum_p log c = 0   (retention, Eqs. 4.39, 4.41-4.43)
    f2 = V - V_t(-p, sigma) - mu sum_V log c = 0   (swelling, Eq. 4.40)

S(V) = m_w / (rho (V - V_s)), phi(V) = 1 - V_s / V, V_t the swelling target under the
confining stress sigma (:func:`macro.laws.confined_volume`), each equation with the
log-barriers of its own unknown's constraints. Barrier Newton-Raphson (Eqs. 4.44-4.50,
a numba kernel, :mod:`macro._newton_kernels`), checked against the equations without
barriers; a system that fails is solved by a bracketed search in log suction, and one
that neither solves raises :class:`NewtonError`. In full: docs/macro.md, "macro.newton".
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from macro import _newton_kernels
from macro.laws import MixtureParameters, suction
from shared.errors import NewtonError

__all__ = ["NewtonError", "NewtonSettings", "PVProblem", "constraints", "solve_pressure_volume"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class NewtonSettings:
    """tolerance (Eq. 4.51), max_iterations, barrier_start mu_0, barrier_decay,
    relaxation_start alpha_r at iteration 0, derivative_step h (relative)."""

    tolerance: float
    max_iterations: int
    barrier_start: float
    barrier_decay: float
    relaxation_start: float
    derivative_step: float


@dataclass
class PVProblem:
    """The data of n systems (arrays of shape (n,)); ``names`` label them in errors.

    water_mass [kg], solid_volume [m3], reference_volume V_0 [m3], max_volume [m3],
    density rho_w [kg/m3], max_suction s_max [Pa]; ``names`` a list or a function of the
    index (built only when an error needs it); ``retention_porosity`` the porosity of the
    retention curve's zeta and lambda, or None for the current 1 - V_s/V (Eqs. 4.42-4.43);
    ``stress`` the confining stress [Pa] and ``solid_mass`` [kg] of the confined swelling
    target (:func:`macro.laws.confined_volume`), None: free swelling (Eq. 4.28).
    """

    water_mass: FloatArray
    solid_volume: FloatArray
    reference_volume: FloatArray
    max_volume: FloatArray
    density: float
    max_suction: float
    names: list[str] | Callable[[int], str] | None = None
    retention_porosity: FloatArray | None = None
    stress: FloatArray | None = None
    solid_mass: FloatArray | None = None

    def porosity(self, volume: FloatArray, index: npt.NDArray[np.int64] | slice = slice(None)) -> FloatArray:
        """Porosity entering the retention curve: current (Eqs. 4.42-4.43) or fixed."""
        if self.retention_porosity is None:
            return 1.0 - self.solid_volume[index] / volume
        return self.retention_porosity[index] + 0.0 * volume

    def name(self, i: int) -> str:
        """The label of system ``i`` in error messages."""
        if self.names is None:
            return f"system {i}"
        return self.names(i) if callable(self.names) else self.names[i]


def constraints(problem: PVProblem, volume: FloatArray, pressure: FloatArray,
                index: npt.NDArray[np.int64] | slice = slice(None)) -> FloatArray:
    """The seven constraints c1..c7 (all must be >= 0), shape (7, n)."""
    vs = problem.solid_volume[index]
    sat = problem.water_mass[index] / (problem.density * (volume - vs))
    return np.stack([
        1.0 - vs / volume, vs / volume, 1.0 - volume / problem.max_volume[index],
        1.0 - sat, sat, -pressure / problem.max_suction, 1.0 + pressure / problem.max_suction,
    ])


def solve_pressure_volume(
    problem: PVProblem,
    material: MixtureParameters,
    settings: NewtonSettings,
    previous_volume: FloatArray,
    previous_suction: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, int, int]:
    """Solve every system's (V, p) (numba, one system at a time).

    Parameters
    ----------
    problem
        The systems' data.
    material
        Retention and swelling parameters.
    settings
        Newton-Raphson settings.
    previous_volume
        (n,) volumes of the previous step [m3] (Eqs. 4.47-4.48 start from them).
    previous_suction
        (n,) suctions of the previous step [Pa]: where Newton leaves a system unsolved,
        the bracketed search takes the root nearest to it (continuity of the state);
        None: the retention curve's suction at the previous volume.

    Returns
    -------
    volume, pressure
        (n,) [m3] and [Pa].
    iterations
        Newton-Raphson iterations summed over the systems.
    fallbacks
        Systems that the bracketed search solved.

    Raises
    ------
    NewtonError
        Naming the first system that has no feasible volume or no solution, with its
        state (m_w, V_s, V_0, V_max, the previous volume).
    """
    pb = problem
    previous_volume = np.asarray(previous_volume, dtype=np.float64)
    fixed = (np.full(previous_volume.size, np.nan) if pb.retention_porosity is None
             else np.asarray(pb.retention_porosity, dtype=np.float64))
    if previous_suction is None:
        sat = pb.water_mass / (pb.density * np.maximum(previous_volume - pb.solid_volume, 1e-300))
        estimate = suction(np.clip(sat, 1e-300, 1.0), pb.porosity(previous_volume), material)
        previous_suction = np.clip(np.nan_to_num(estimate, nan=0.5 * pb.max_suction),
                                   1e-6 * pb.max_suction, pb.max_suction)
    m = material
    law = np.array([m.retention_pressure_reference, m.retention_exponent_reference,
                    m.retention_pressure_porosity_factor, m.retention_exponent_porosity_factor,
                    m.reference_porosity, m.swelling_alpha, m.swelling_beta, m.initial_suction,
                    m.beta_v, m.alpha_v])
    n = previous_volume.size
    stress = np.zeros(n) if pb.stress is None else pb.stress
    solid_mass = np.zeros(n) if pb.solid_mass is None else pb.solid_mass
    volume, suction_, iterations, status = _newton_kernels.solve_systems(
        np.ascontiguousarray(pb.water_mass, dtype=np.float64),
        np.ascontiguousarray(pb.solid_volume, dtype=np.float64),
        np.ascontiguousarray(pb.reference_volume, dtype=np.float64),
        np.ascontiguousarray(stress, dtype=np.float64), np.ascontiguousarray(solid_mass, dtype=np.float64),
        np.ascontiguousarray(pb.max_volume, dtype=np.float64), fixed, previous_volume,
        np.asarray(previous_suction, dtype=np.float64), float(pb.density), float(pb.max_suction),
        settings.tolerance, settings.max_iterations, settings.barrier_start,
        settings.barrier_decay, settings.relaxation_start, settings.derivative_step, law)
    for code, why in ((_newton_kernels.INFEASIBLE, "no feasible volume (solid + water >= V_max)"),
                      (_newton_kernels.UNSOLVED, "neither Newton-Raphson nor the bracketed search "
                                                 "found a solution")):
        bad = np.flatnonzero(status == code)
        if bad.size:
            _fail(pb, int(bad[0]), previous_volume, why, bad.size)
    return volume, -suction_, int(iterations.sum()), int(np.count_nonzero(status == _newton_kernels.BRACKETED))


def _fail(problem: PVProblem, i: int, previous_volume: FloatArray, why: str, count: int) -> None:
    raise NewtonError(
        f"{problem.name(i)}: {why} (water mass m_w={problem.water_mass[i]:.6g} kg, "
        f"V_s={problem.solid_volume[i]:.6g} m3, V_0={problem.reference_volume[i]:.6g} m3, "
        f"V_max={problem.max_volume[i]:.6g} m3, previous V={previous_volume[i]:.6g} m3); "
        f"{count} such system(s)"
    )
