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
import numba. Each submodule's ``__all__`` is exported whole.

The ``if TYPE_CHECKING:`` block is the one list of names: type checkers and IDEs read it,
and ``shared.lazy.lazy_package`` reads it from this file to build ``__all__`` and the lazy map.
"""

# the block's names are this package's exports, not unused imports (ruff reads no derived __all__)
# ruff: noqa: F401

from __future__ import annotations

from typing import TYPE_CHECKING

from shared.lazy import lazy_package

if TYPE_CHECKING:
    from shared.dem.coarse import rigid_translation
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
    from shared.dem.parameters import DEM_MATERIAL_KEYS, DEMParameters, dem_parameters
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

__all__, __getattr__ = lazy_package(globals())
