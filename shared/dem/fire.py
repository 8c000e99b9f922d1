"""FIRE, the Fast Inertial Relaxation Engine (Bitzek et al., PRL 97, 170201, 2006): a
damped inertial descent to the nearest static equilibrium of a force field.

The integrator is generic: rows of any (m, d) array of degrees of freedom with a mass
per row, e.g. the n translations of a packing stacked over its n rotations times the
radii (forces over torques / r, masses over inertias / r^2), so that one power and one
mixing act on both and the friction's torques stay consistent with the forces.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

__all__ = ["FireParameters", "FireState", "fire_step"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class FireParameters:
    """FIRE's constants, Bitzek et al.'s standard values by default.

    Attributes
    ----------
    dt_max
        Largest time step [time unit of the masses]; with each row's mass its diagonal
        stiffness (time unit 1), 1 keeps the semi-implicit Euler step stable.
    dt_start
        First time step, and the time step of :meth:`FireState.reset` [same unit].
    n_min
        Steps of positive power before the time step may grow [1].
    f_inc, f_dec
        Growth and cut factors of the time step [1].
    alpha_start, f_alpha
        First mixing coefficient and its decay per step of positive power [1].
    """

    dt_max: float = 1.0
    dt_start: float = 0.1
    n_min: int = 5
    f_inc: float = 1.1
    f_dec: float = 0.5
    alpha_start: float = 0.1
    f_alpha: float = 0.99


@dataclass
class FireState:
    """Time step, mixing coefficient and count of positive-power steps of one descent."""

    parameters: FireParameters = field(default_factory=FireParameters)
    dt: float = 0.0
    alpha: float = 0.0
    positive: int = 0

    def __post_init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Start over: ``dt_start``, ``alpha_start``, no positive steps."""
        self.dt = self.parameters.dt_start
        self.alpha = self.parameters.alpha_start
        self.positive = 0


def fire_step(state: FireState, velocities: FloatArray, forces: FloatArray, masses: FloatArray,
              max_displacement: FloatArray | None = None) -> FloatArray:
    """One FIRE step; updates ``velocities`` and ``state`` in place and returns the step's
    displacement of every row.

    The power P = F . v of the current forces decides first (F1-F4 of Bitzek et al.):
    P > 0 for more than ``n_min`` steps lets the time step grow by ``f_inc`` up to
    ``dt_max`` and ``alpha`` decay by ``f_alpha``; P <= 0 cuts the time step by ``f_dec``,
    resets ``alpha`` and stops every row (at rest, all velocities zero, there is no
    power to judge: nothing changes). Then a semi-implicit Euler step (Guénolé et
    al., Comput. Mater. Sci. 175, 109584, 2020): v += dt F / m, the velocity turned
    towards the acceleration, v = (1 - alpha) v + alpha |v| a / |a|, and x += dt v. The
    norms |v| and |a| are mass-weighted (sqrt(sum m v^2), sqrt(sum F^2 / m)): the mixing
    is FIRE's in the coordinates sqrt(m) x, where every mass is 1.

    Parameters
    ----------
    state
        The descent's time step, mixing and count, updated.
    velocities
        (m, d) velocities [length / time], updated.
    forces
        (m, d) forces at the current positions [force].
    masses
        (m,) mass of each row [force time^2 / length], positive.
    max_displacement
        (m,) largest length of a row's displacement in one step [length]: a row beyond
        it is scaled down, its velocity with it; None for no bound.

    Returns
    -------
    numpy.ndarray
        (m, d) displacement of the step [length].
    """
    p = state.parameters
    power = float(np.sum(forces * velocities))
    if power > 0.0:
        state.positive += 1
        if state.positive > p.n_min:
            state.dt = min(state.dt * p.f_inc, p.dt_max)
            state.alpha *= p.f_alpha
    elif velocities.any():
        state.positive = 0
        state.dt *= p.f_dec
        state.alpha = p.alpha_start
        velocities[:] = 0.0
    acceleration = forces / masses[:, None]
    velocities += state.dt * acceleration
    speed = np.sqrt(np.sum(masses[:, None] * velocities**2))
    drive = np.sqrt(np.sum(forces * acceleration))
    if drive > 0.0:
        velocities *= 1.0 - state.alpha
        velocities += state.alpha * speed / drive * acceleration
    displacement = state.dt * velocities
    if max_displacement is not None:
        length = np.sqrt(np.sum(displacement**2, axis=1))
        scale = np.minimum(1.0, max_displacement / np.maximum(length, 1e-300))[:, None]
        displacement *= scale
        velocities *= scale
    return displacement
