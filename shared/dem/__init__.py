"""DEM core shared by the micro and macro models: points, contacts, Hertz-Mindlin, walls,
and the FIRE static solver.

Typical use in a coupled loop::

    parameters = dem_parameters(config["materials"]["pellet"], config["micro"]["numerics"])
    state = new_state(*cube_points(15000, rng), parameters)
    walls = walls_around(state.positions, state.radii, active=False)  # free swelling
    dt = min(stable_time_step(state, parameters, walls=walls), parameters.time_step)
    report = step(state, dt, parameters, external_forces=hydro_forces, walls=walls)
    state.radii = swollen_radius(state.reference_radii, eps_v)  # stiffness follows

The names below are imported from their submodule on first use (PEP 562), so that
importing a light submodule (:mod:`.parameters` for the workflow's key lists) does not
import numba.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from shared.lazy import lazy_getattr

if TYPE_CHECKING:
    from shared.dem.contacts import (
        bond_pairs,
        contacts_need_update,
        detect_contacts,
        held_points,
        pair_values,
        point_bins,
        update_contacts,
    )
    from shared.dem.fire import FireParameters, FireState, fire_step
    from shared.dem.hertz import bond_stretches, bond_tension, contact_forces
    from shared.dem.integrator import (
        StepReport,
        integrate,
        limit_speed,
        stable_time_step,
        step,
        unbalanced_force,
    )
    from shared.dem.parameters import DEMParameters
    from shared.dem.points import cube_points
    from shared.dem.state import ContactList, DEMState, new_state
    from shared.dem.walls import (
        WallLoads,
        Walls,
        servo_walls,
        wall_forces,
        walls_around,
    )
    from shared.dem.yielding import cylinder_contacts, hertz_yield, yielding_hertz_mindlin

__all__ = [
    "dem_parameters",
    "ContactList",
    "DEMParameters",
    "DEMState",
    "StepReport",
    "WallLoads",
    "Walls",
    "bond_pairs",
    "bond_stretches",
    "bond_tension",
    "contact_forces",
    "contacts_need_update",
    "point_bins",
    "cube_points",
    "detect_contacts",
    "integrate",
    "new_state",
    "pair_values",
    "held_points",
    "servo_walls",
    "stable_time_step",
    "step",
    "unbalanced_force",
    "update_contacts",
    "wall_forces",
    "walls_around",
    "limit_speed",
    "cylinder_contacts",
    "FireParameters",
    "FireState",
    "fire_step",
    "hertz_yield",
    "yielding_hertz_mindlin",
]

# public name -> its submodule
_EXPORTS = {
    "bond_pairs": "contacts",
    "contacts_need_update": "contacts",
    "detect_contacts": "contacts",
    "held_points": "contacts",
    "pair_values": "contacts",
    "point_bins": "contacts",
    "update_contacts": "contacts",
    "bond_stretches": "hertz",
    "bond_tension": "hertz",
    "contact_forces": "hertz",
    "StepReport": "integrator",
    "integrate": "integrator",
    "limit_speed": "integrator",
    "stable_time_step": "integrator",
    "step": "integrator",
    "unbalanced_force": "integrator",
    "DEMParameters": "parameters",
    "dem_parameters": "parameters",
    "cube_points": "points",
    "ContactList": "state",
    "DEMState": "state",
    "new_state": "state",
    "WallLoads": "walls",
    "Walls": "walls",
    "servo_walls": "walls",
    "wall_forces": "walls",
    "walls_around": "walls",
    "FireParameters": "fire",
    "FireState": "fire",
    "fire_step": "fire",
    "cylinder_contacts": "yielding",
    "hertz_yield": "yielding",
    "yielding_hertz_mindlin": "yielding",
}


__getattr__ = lazy_getattr(__name__, _EXPORTS, globals())
