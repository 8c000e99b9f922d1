"""Explicit leapfrog of translations and spins with Cundall damping; stable step; balance."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from shared.dem import _kernels
from shared.dem.contacts import update_contacts
from shared.dem.hertz import bond_tension, contact_forces
from shared.dem.parameters import DEMParameters
from shared.dem.state import DEMState
from shared.dem.walls import WallLoads, Walls, servo_walls, wall_forces

__all__ = [
    "StepReport",
    "stable_time_step",
    "integrate",
    "unbalanced_force",
    "step",
    "limit_speed",
]

FloatArray = npt.NDArray[np.float64]


@dataclass
class StepReport:
    """What one :func:`step` computed.

    Attributes
    ----------
    forces
        (n, 3) total undamped force per point [N] (contacts + walls + external).
    torques
        (n, 3) total contact torque per point [N m].
    normal_forces
        (n_contacts,) normal force per candidate contact [N], aligned with
        ``state.contacts.pairs`` as it was during the step.
    wall_loads
        Wall forces and stiffnesses, or None without walls.
    contacts_rebuilt
        Whether the contact list was rebuilt this step.
    """

    forces: FloatArray
    torques: FloatArray
    normal_forces: FloatArray
    wall_loads: WallLoads | None
    contacts_rebuilt: bool


def stable_time_step(
    state: DEMState,
    parameters: DEMParameters,
    walls: Walls | None = None,
    safety: float | None = None,
) -> float:
    """Largest stable leapfrog time step, times a safety factor [s].

    Parameters
    ----------
    state
        Assembly (current overlaps set the tangent stiffnesses).
    parameters
        Moduli [Pa, 1] and ``time_step_safety`` [1].
    walls
        Active walls add their contact stiffness; None for no walls.
    safety
        Overrides ``parameters.time_step_safety`` [1]; 1 returns the bound itself.

    Returns
    -------
    float
        safety 2 / sqrt(lambda), lambda a bound on the largest eigenvalue of M^-1 K
        over translations and rotations [s]; inf if no free point is loaded (cap it,
        e.g. by ``parameters.time_step``).

    Notes
    -----
    Leapfrog is stable for dt < 2 / omega_max. lambda is the largest block-Gershgorin
    row sum of M^-1/2 K M^-1/2 (K the tangent stiffness of the contacts, see
    ``_kernels.gershgorin_rates``), so omega_max^2 <= lambda. For a uniform chain
    loaded along its axis, the translational row gives 4 k / m, the exact limit
    of its shortest wave; the rotational rows make the bound stricter by about 1.7
    for Hertz-Mindlin spheres with nu = 0.3.
    """
    safety = parameters.time_step_safety if safety is None else safety
    rates = np.zeros((state.n_points, 2))
    _kernels.gershgorin_rates(
        state.positions, state.radii, state.contacts.pairs, state.masses, state.inertia,
        parameters.effective_modulus, parameters.shear_coefficient, rates,
    )
    rates[:, 0] += _bond_rates(state, parameters)
    if walls is not None:
        wall_stiffness = np.zeros(state.n_points)
        wall_forces(state, walls, np.zeros((state.n_points, 3)), parameters, wall_stiffness)
        rates[:, 0] += wall_stiffness / state.masses
    largest = rates[~state.fixed].max(initial=0.0)
    if largest == 0.0:
        return float("inf")
    return float(safety * 2.0 / np.sqrt(largest))


def _bond_rates(state: DEMState, parameters: DEMParameters) -> FloatArray:
    """Gershgorin row sums of the intact bonds' tension springs, per point [1/s^2].

    Without tensile strength a bond breaks at its first stretch and never acts as a
    spring; otherwise every intact bond counts, stretched or not (conservative).
    """
    if state.bonds.shape[0] == 0 or parameters.bond_tensile_strength == 0.0:
        return np.zeros(state.n_points)
    return _kernels.bond_rates(state.bonds, state.bond_broken, state.radii, state.masses,
                               parameters.effective_modulus)


def integrate(
    state: DEMState,
    forces: FloatArray,
    torques: FloatArray,
    time_step: float,
    damping: float,
) -> None:
    """Advance velocities, spins and positions of the free points by one leapfrog step.

    Parameters
    ----------
    state
        Assembly, updated in place (``time`` included).
    forces
        (n, 3) total force per point [N].
    torques
        (n, 3) total torque per point [N m].
    time_step
        Time step [s].
    damping
        Cundall damping coefficient [1], applied to forces and torques; 0 for
        conservative dynamics.
    """
    n = state.n_points
    if forces.shape != (n, 3) or torques.shape != (n, 3):
        raise ValueError(f"forces and torques must have shape ({n}, 3)")
    leapfrog = _kernels.sized(_kernels.leapfrog, _kernels.leapfrog_serial, n)
    leapfrog(
        state.positions, state.velocities, forces, state.masses, state.fixed,
        float(damping), float(time_step),
    )
    leapfrog(
        np.empty((0, 3)), state.spins, torques, state.inertia, state.fixed,
        float(damping), float(time_step),
    )
    state.time += time_step


def unbalanced_force(
    forces: FloatArray, normal_forces: FloatArray, fixed: npt.NDArray[np.bool_] | None = None
) -> float:
    """Mean resultant force on free points over mean contact normal force [1].

    Parameters
    ----------
    forces
        (n, 3) total force per point [N].
    normal_forces
        (n_contacts,) contact normal forces [N]; zeros (separated pairs) are skipped.
    fixed
        (n,) points to leave out, or None.

    Returns
    -------
    float
        Yade's unbalancedForce ratio (normal forces only in the denominator); inf
        when no contact carries force.
    """
    resultant = np.sqrt((forces**2).sum(axis=1))
    if fixed is not None:
        resultant = resultant[~fixed]
    carried = normal_forces[normal_forces > 0.0]
    if carried.size == 0:
        return float("inf")
    return float(resultant.mean() / carried.mean())


def step(
    state: DEMState,
    time_step: float,
    parameters: DEMParameters,
    external_forces: FloatArray | None = None,
    walls: Walls | None = None,
    damping: float | None = None,
) -> StepReport:
    """One DEM step: contact list, Hertz-Mindlin, bond and wall forces, leapfrog, servo.

    Parameters
    ----------
    state
        Assembly, advanced in place.
    time_step
        Time step [s]; keep it below :func:`stable_time_step`.
    parameters
        DEM parameters.
    external_forces
        (n, 3) extra forces, e.g. hydro-mechanical ones [N], or None.
    walls
        Wall box (moved in place if servo-controlled), or None.
    damping
        Overrides ``parameters.damping`` [1].

    Returns
    -------
    StepReport
    """
    rebuilt = update_contacts(state, parameters)
    # + 0.0 turns -0.0 into 0.0: the same array as zeros plus the external forces
    forces = np.zeros((state.n_points, 3)) if external_forces is None else external_forces + 0.0
    forces, torques, normal_forces = contact_forces(state, time_step, parameters, forces)
    if state.bonds.shape[0]:
        bond_tension(state, parameters, forces)
    loads = None if walls is None else wall_forces(state, walls, forces, parameters)
    integrate(
        state, forces, torques, time_step,
        parameters.damping if damping is None else damping,
    )
    if walls is not None and loads is not None:
        servo_walls(walls, loads, time_step, parameters)
    return StepReport(forces, torques, normal_forces, loads, rebuilt)


def limit_speed(state: DEMState, max_speed: float) -> None:
    """Scale down velocities above ``max_speed`` [m/s] (kinetic limiter of quasi-static runs).

    A relaxation only seeks the balanced state; a point that a burst of elastic energy
    has launched would otherwise travel far before damping catches it, and a nearly
    unconfined swollen assembly can then fall apart.
    """
    _kernels.sized(_kernels.cap_speed, _kernels.cap_speed_serial,
                   state.velocities.shape[0])(state.velocities, max_speed)
