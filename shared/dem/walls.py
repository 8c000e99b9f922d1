"""Six axis-aligned rigid walls: off (free swelling), fixed, or servo-controlled stress.

The servo follows Yade's TriaxialStressController as used in Sec. 3.5.4 of Caulk (2022):
each active wall moves along its normal by a fraction of the displacement its contact
stiffness predicts to reach the target stress, at most ``wall_max_velocity`` per time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from shared.dem import _kernels
from shared.dem.parameters import DEMParameters
from shared.dem.state import DEMState

__all__ = ["Walls", "WallLoads", "walls_around", "wall_forces", "servo_walls"]

FloatArray = npt.NDArray[np.float64]


@dataclass
class Walls:
    """Box of six walls; wall w = 2 axis + side (side 0 at ``lower``, 1 at ``upper``).

    Attributes
    ----------
    lower, upper
        (3,) wall plane coordinates [m].
    active
        (6,) walls that push on points; all False means free swelling.
    servo
        Whether active walls move to impose ``target_stress``; if False they stay put.
    target_stress
        (3,) compressive stress to impose on the two walls of each axis [Pa].
    """

    lower: FloatArray
    upper: FloatArray
    active: npt.NDArray[np.bool_]
    servo: bool
    target_stress: FloatArray

    def face_areas(self) -> FloatArray:
        """(6,) current areas of the walls [m2], from the box dimensions."""
        size = self.upper - self.lower
        per_axis = np.array([size[1] * size[2], size[0] * size[2], size[0] * size[1]])
        return np.repeat(per_axis, 2)


@dataclass
class WallLoads:
    """Forces of the points on the walls.

    Attributes
    ----------
    force
        (6,) compressive force on each wall [N].
    stiffness
        (6,) summed tangent contact stiffness of each wall [N/m].
    """

    force: FloatArray
    stiffness: FloatArray


def walls_around(
    positions: npt.ArrayLike,
    radii: npt.ArrayLike,
    target_stress: float | npt.ArrayLike = 0.0,
    active: bool = True,
    servo: bool = True,
) -> Walls:
    """Walls on the bounding box of the spheres (touching the outermost points).

    Parameters
    ----------
    positions
        (n, 3) point centres [m].
    radii
        (n,) interaction radii [m].
    target_stress
        Compressive stress per axis [Pa], scalar or (3,).
    active
        Whether the walls push on the points (False: free swelling).
    servo
        Whether the walls move to impose ``target_stress``.
    """
    positions = np.asarray(positions, dtype=np.float64)
    radii = np.asarray(radii, dtype=np.float64)
    return Walls(
        lower=(positions - radii[:, None]).min(axis=0),
        upper=(positions + radii[:, None]).max(axis=0),
        active=np.full(6, active, dtype=np.bool_),
        servo=servo,
        target_stress=np.broadcast_to(np.asarray(target_stress, dtype=np.float64), (3,)).copy(),
    )


def wall_forces(
    state: DEMState,
    walls: Walls,
    forces: FloatArray,
    parameters: DEMParameters,
    stiffness: FloatArray | None = None,
) -> WallLoads:
    """Add frictionless Hertz wall forces on the points (rigid wall, R* = r).

    Parameters
    ----------
    state
        Assembly.
    walls
        Wall box.
    forces
        (n, 3) forces the wall forces are added to [N], in place.
    parameters
        Young's modulus [Pa] and Poisson ratio [1]; E* = E / (1 - nu^2).
    stiffness
        (n,) per-point tangent stiffness to add the wall stiffness to [N/m], or None.

    Returns
    -------
    WallLoads
        Compressive force [N] and contact stiffness [N/m] per wall.
    """
    per_point = np.zeros(state.n_points) if stiffness is None else stiffness
    force, wall_stiffness = _kernels.wall_contacts(
        state.positions, state.radii, walls.lower, walls.upper, walls.active,
        parameters.wall_effective_modulus, forces, per_point,
    )
    return WallLoads(force=force, stiffness=wall_stiffness)


def servo_walls(
    walls: Walls,
    loads: WallLoads,
    time_step: float,
    parameters: DEMParameters,
) -> None:
    """Move active servo walls towards ``target_stress`` (in place).

    Parameters
    ----------
    walls
        Wall box, moved in place.
    loads
        Current wall forces and stiffnesses.
    time_step
        Time step [s]; bounds the move to ``wall_max_velocity`` time_step.
    parameters
        ``wall_gain`` [1] and ``wall_max_velocity`` [m/s].

    Notes
    -----
    Excess force F - sigma A pushes a wall outwards by gain (F - sigma A) / k_wall.
    A wall without contact moves inwards at full speed to find the specimen.
    """
    if not walls.servo:
        return
    max_step = parameters.wall_max_velocity * time_step
    excess = loads.force - np.repeat(walls.target_stress, 2) * walls.face_areas()
    with np.errstate(divide="ignore", invalid="ignore"):
        move = np.where(
            loads.stiffness > 0.0,
            parameters.wall_gain * excess / loads.stiffness,
            -max_step,
        )
    move = np.where(walls.active, np.clip(move, -max_step, max_step), 0.0)
    walls.lower -= move[0::2]
    walls.upper += move[1::2]
