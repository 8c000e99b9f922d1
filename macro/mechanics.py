"""Forces on the pellets: the powder's swelling pressure on its cell contour (Eqs.
4.31-4.38), Hertz-Mindlin contacts between pellets and against the container, and the
quasi-static relaxation that balances them; the confining stress of each pellet.

The quasi-static DEM is a static solve by FIRE (:func:`shared.dem.fire_step`) with a
fictitious mass per pellet equal to its contact stiffness (time unit 1), so every step
is stable whatever the moduli (density scaling, as the thesis's script scales the
density by 1e10); it seeks the balanced state, it is not dynamics.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from macro._kernels import incidence, powder_push
from macro.geometry import VOID_FLOOR
from macro.laws import (
    free_volume,
    onset_ramp,
    saturation,
    swelling_pressure,
    yield_force,
    yield_pressure,
    young_modulus,
)
from macro.mixture import facet_angles
from macro.parts import Readings
from macro.state import ModelState
from shared.dem import (
    FireParameters,
    FireState,
    cylinder_contacts,
    detect_contacts,
    fire_step,
    pair_values,
    rigid_translation,
    yielding_hertz_mindlin,
)

FloatArray = npt.NDArray[np.float64]

MAX_STEP = 1e-3
"""Largest displacement of a pellet (and rotation times its radius) in one DEM step, in
radii: a pellet entering a contact stiffer than its mass moves at most this far."""
REMESHES = 2
"""Largest number of new meshes within one relaxation."""
FIRE = FireParameters(dt_start=1.0, alpha_start=0.25)
"""FIRE's constants for the relaxation: each row's mass is its own stiffness (frequency 1
per row), so the largest time step, 1, needs no ramp from Bitzek et al.'s dt_start 0.1;
alpha_start is FIRE 2.0's (Guenole et al. 2020). Bitzek's start takes half the FIRE steps,
but its readings at 0.01 and 0.001 differ by up to 3.5 % where these differ by 2.7 %
(docs/macro.md; benchmarks/reference/macro_fire.json)."""
CORRECTION_INTERVAL = 10
"""Fewest force evaluations between two rigid corrections of a relaxation."""
CORRECTION_STEP = 1e-5
"""Finite-difference step of the rigid correction's tangent, in mean pellet radii."""
MAX_OVERLAP_LOSS = 0.3
"""Largest fraction of a pellet's sphere that its overlaps may cut off."""


class Mechanics(ModelState):
    """Mechanics part of :class:`macro.model.MacroModel`."""

    READS: tuple[str, ...] = ("cells", "clay_radii", "contacts", "container", "counters", "densest_volume", "inert",
             "material", "mesh", "move_geometry", "n_cells", "n_pellets", "n_vertices",
             "occupied_loss", "overflow", "positions", "powder_wall_loads", "pressure", "radii",
             "reference_volume", "remesh", "retention_porosity", "settings", "solid_mass", "spins",
             "stress", "velocities", "vertex_radii")
    """What this part reads of the model's state and of its other parts."""

    def powder_pressure(self) -> tuple[FloatArray, FloatArray]:
        """Pressure of the powder on its cell contour [Pa] (Eqs. 4.31-4.35) and the
        magnitude of its derivative with respect to the cell's void [Pa/m3], both (n_c,).

        The powder swells freely until it fills its cell's void V_c; held there, it
        presses with the swelling pressure of its state (:func:`macro.laws.swelling_pressure`
        at m_s / V_c). Eq. 4.35's V / V_t is read as the powder's share of the void, 1
        whenever it presses. A cell squeezed below its solid and water presses at the dry
        density of its void, as drained (its water leaves at the next overflow: the
        consolidation of a cell takes seconds, :meth:`macro.extrusion.Extrusion.overflow`),
        so that the pellets meet a stiffening powder rather than a pressure that stops
        growing; below its solid at the smallest porosity it presses as at that state. With the
        pellets' yield (Eq. 4.4) on, at most the yield pressure of the cell's weakest
        pellet. The law is reached linearly over ``macro.numerics.powder_onset_strain``
        below V_f (:func:`macro.laws.onset_ramp`): the onset is set-valued, and a push
        that jumps at V_f leaves the pellets around such a cell no balanced state. Zero
        everywhere when ``macro.powder_swelling_pressure`` is off.
        """
        cells = slice(self.n_pellets, None)
        if not self.settings.powder_pressure:
            return np.zeros(self.n_cells), np.zeros(self.n_cells)
        held = np.maximum(self.cells.voids, self.densest_volume(cells, with_water=False))
        suction = -self.pressure[cells]
        solid_mass = self.solid_mass()[cells]
        free = free_volume(suction, self.reference_volume[cells], self.material)
        active = ~self.inert[cells] & (free > held)
        law = np.where(active, swelling_pressure(solid_mass / held, suction, self.retention_porosity()[cells],
                                                 self.material), 0.0)
        ramp = onset_ramp(held, free, self.settings.powder_onset_strain)
        pressure = law * ramp
        bound = self._pressure_bound()
        capped = pressure > bound
        pressure = np.where(capped, bound, pressure)
        # |dP/dV_c| of ramp S p'_vc(m_s / V_c)
        slope = pressure * self.material.alpha_v * solid_mass / held**2 \
            + np.where(ramp < 1.0, law / (self.settings.powder_onset_strain * free), 0.0)
        return pressure, np.where(active & ~capped, slope, 0.0)

    def _pressure_bound(self) -> FloatArray:
        """(n_c,) the largest push of each cell's powder [Pa]: the yield pressure of its
        weakest pellet (:func:`macro.laws.yield_pressure`: the pellets' surface gives way
        first); a cell with only container points is bounded by its neighbours' bounds
        (the powder around it gives way), inf without yield."""
        tet, n_p = self.mesh.tetrahedra, self.n_pellets
        strength = np.append(yield_pressure(-self.pressure[:n_p], self.radii, self.material), np.inf)
        bound = strength[np.where(tet < n_p, tet, n_p)].min(axis=1)
        if not np.isfinite(strength[:n_p]).any():
            return bound
        neighbours = self.mesh.neighbours
        for _ in range(4):
            unbounded = np.isinf(bound)
            if not unbounded.any():
                break
            # a missing neighbour (-1) reads the appended -inf
            around = np.append(bound, -np.inf)[neighbours]
            bound = np.where(unbounded, np.where(np.isfinite(around), around, -np.inf).max(axis=1), bound)
            bound[np.isneginf(bound)] = np.inf
        return bound

    def hydro_forces(self, cell_pressure: FloatArray) -> FloatArray:
        """(n_p, 3) forces of the cell pressures on the pellets [N] (Eqs. 4.34-4.38).

        A pellet's sector A_k = theta r^2 / 2 of each triangle is pushed by the pressure
        difference across it, A_k (P_i - P_j) n_ij (n_ij from cell i to j). The mesh's hull
        is made of container points, which have no sectors: no pellet is pushed there.
        """
        mesh = self.mesh
        verts, cells = mesh.facet_vertices, mesh.facet_cells
        sector = 0.5 * facet_angles(mesh.points, verts) * self.vertex_radii()[verts] ** 2
        jump = cell_pressure[cells[:, 0]] - cell_pressure[cells[:, 1]]
        vec = (sector * jump[:, None])[:, :, None] * mesh.facet_normals[:, None, :]
        forces = np.empty((self.n_vertices, 3))
        for c in range(3):
            forces[:, c] = np.bincount(verts.ravel(), vec[:, :, c].ravel(), minlength=self.n_vertices)
        return forces[:self.n_pellets]

    def relax(self, substeps: int) -> Readings:
        """Quasi-static DEM under the current radii, moduli and powder: FIRE steps
        (:func:`shared.dem.fire_step`) until both the unbalanced force ratio (mean
        resultant over mean contact force; over the powder's mean push while no contact
        carries, so that pushed pellets touching nothing are not balanced) and the net
        one (the pellets' net resultant over the plates' mean load; 0 while the plates
        carry nothing) are below
        ``dem_balance_tolerance``, at most ``substeps`` force evaluations (counted in
        ``dem_substeps_used``). The mean ratio alone is blind to a residual that points the
        same way along the column, which the plates read as a difference of loads.

        With ``dem_rigid_correction``, once the mean ratio is met and the net one is not, at
        most every ``CORRECTION_INTERVAL`` evaluations, a Newton step on the rigid
        translation of all the pellets (:func:`shared.dem.rigid_translation`, its 3 x 3
        tangent from finite differences of the whole force field, 4-8 evaluations)
        removes the net resultant: that mode is held only by the container and the
        powder, soft against the masses the contacts set, and FIRE alone takes hundreds of
        steps per relaxation for it in the longer columns (on by default; ``false``
        leaves the mode to FIRE, docs/macro.md).

        The contacts' slip and yield are committed when the relaxation ends, from its
        final positions (a return mapping): FIRE's steps are a solver's iterations, not
        a loading path, and the balanced state does not depend on how they got there
        (:func:`shared.dem.yielding_hertz_mindlin`). Committed at every FIRE step, the
        overshoots slid and yielded contacts, and readings at 0.01 and 0.001 differed by
        4 % (docs/macro.md).

        The degrees of freedom are the pellets' translations and their rotations times
        the radii, with one mass per pellet: its normal contact stiffness plus the
        powder's (time unit 1; the rotations' inertia m r^2). One power and one mixing
        act on both, so that the friction's torques and forces stay consistent. The
        powder's push is evaluated exactly at every step's positions (one numba pass over
        the cells and triangles, :meth:`push_field`), so a balanced state is balanced
        against the push of its own geometry. (Updating it only every 50 steps, with a
        linearised push in between, left 1/3 of the records unbalanced at 0.01: each
        update jolted the forces by a few per cent of the carried load, see
        docs/macro.md, "Quasi-static DEM and balanced readings".) When the pellets invert
        an active cell, the mesh is rebuilt at once (:meth:`remesh`, its overflow
        handed on), at most ``REMESHES`` times; beyond that the push stays linearised
        about the last positions it held, with the isotropic stiffness dP/dV_c A^2 over
        the pellet's cells. The container's friction (``wall_friction``) keeps its
        tangential forces per pellet and surface from one relaxation to the next, as
        the pairs keep theirs.

        FIRE rather than Newton or CG on the contact network: the force model (yield,
        Coulomb sliding, contacts that open and close, the powder's push) is
        non-smooth and history dependent, so its tangent matrix changes at every step,
        while FIRE needs only the forces the damped relaxation already computed, and its
        power test stops the motion whenever it turns uphill instead of overshooting.
        With the exact push and the rigid correction it balances the default case in 53
        force evaluations per coupled step on average (81 with FIRE alone;
        docs/macro.md), and FIRE has no damping coefficient to choose.
        """
        s = self.settings
        n_p = self.n_pellets
        young = young_modulus(-self.pressure[:n_p], self.material)
        strength = yield_force(-self.pressure[:n_p], self.material)
        nu = self.material.poisson_ratio
        z_lo, z_hi = -0.5 * s.height, 0.5 * s.height
        skin = 0.2 * float(self.radii.mean())
        # the contacts' committed history (the last relaxation's) and the tangential
        # displacement since; their trial forces are committed once this relaxation ends
        pairs = detect_contacts(self.positions, self.radii, 1.0, skin)
        shear: FloatArray = np.zeros((pairs.shape[0], 3))
        plastic: FloatArray = np.zeros(pairs.shape[0])
        history = self.contacts
        if history.pairs is not None and history.shear is not None and history.plastic is not None:
            shear, plastic = pair_values(pairs, history.pairs, history.shear), \
                pair_values(pairs, history.pairs, history.plastic)
        slip: FloatArray = np.zeros_like(shear)
        # the kernels overwrite every row of the trial arrays at each FIRE step
        trial_shear, trial_plastic = np.empty_like(shear), np.empty_like(plastic)
        wall_slip = np.zeros_like(self.contacts.wall_shear)
        wall_shear, wall_plastic = self.contacts.wall_shear.copy(), self.contacts.wall_plastic.copy()
        reference = self.positions.copy()
        # mass floor: the stiffness of a contact overlapping by 1e-3 r
        floor = 2.0 * young / (1.0 - nu * nu) * self.radii * np.sqrt(1e-3)
        # FIRE's rows: 0..n_p-1 the translations, n_p..2 n_p-1 the rotations times the radii [m]
        cap = np.tile(MAX_STEP * self.radii, 2)
        push = self.push_field()
        external, cell_pressure, powder_stiffness, frozen = push(self.positions)
        fire = FireState(FIRE)
        rates = np.zeros((2 * n_p, 3))
        # displacement and rotation of the last step (none before the first)
        moved: FloatArray = np.zeros((n_p, 3))
        turned: FloatArray = np.zeros((n_p, 3))
        anchor = self.positions.copy()
        k = remeshes = last_correction = 0
        still = np.zeros((n_p, 3))

        def contact_forces(positions: FloatArray, moved: FloatArray, turned: FloatArray, forces: FloatArray,
                           stiffness: FloatArray, slip: FloatArray,
                           wall_slip: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
            """Adds the contacts' forces, torques and stiffness at ``positions`` to ``forces``
            and ``stiffness``; the trial arrays written, ``slip`` and ``wall_slip`` advanced
            by the step ``moved``, ``turned``. Returns the torques and the normal forces of
            the pairs, on the curved wall and on the lower and upper plates [N]."""
            torques = np.zeros((n_p, 3))
            normal = yielding_hertz_mindlin(positions, moved, turned, self.radii, young, nu, self.material.friction,
                                            pairs, trial_shear, forces, torques, stiffness, strength, trial_plastic,
                                            shear, plastic, slip)
            radial, lower, upper = cylinder_contacts(
                positions, moved, turned, self.radii, young, nu, s.wall_friction, s.radius, z_lo, z_hi, forces,
                torques, stiffness, strength, wall_plastic, wall_shear, self.contacts.wall_plastic,
                self.contacts.wall_shear, wall_slip)
            return torques, normal, radial, lower, upper

        def translated(shift: FloatArray) -> tuple[FloatArray, float]:
            """The pellets' net resultant [N] and net ratio with all of them moved by
            ``shift`` (3,) [m] from where they are (infinite where the shift inverts an
            active cell); the slips are left as they were."""
            at, move = self.positions + shift, np.tile(shift, (n_p, 1))
            forces, _, _, inverted = push(at)
            if inverted:  # the shift inverts an active cell: refused
                return forces.sum(axis=0), np.inf
            lower, upper = contact_forces(at, move, still, forces, np.zeros(n_p), slip.copy(), wall_slip.copy())[3:]
            plates = 0.5 * float(lower.sum() + upper.sum())
            resultant = forces.sum(axis=0)
            return resultant, float(np.linalg.norm(resultant) / plates) if plates > 0.0 else np.inf

        while True:
            # the push follows the pellets (voids reopen as they move apart); where an
            # active cell has inverted, the mesh no longer holds the pellets' cells: a new
            # one (at most REMESHES per relaxation), else the push stays linearised about
            # the last positions it held
            if k and not frozen:
                trial = push(self.positions)
                if trial[3] and remeshes < REMESHES:
                    self.remesh()
                    if s.extrusion.enabled:
                        self.overflow()
                    remeshes += 1
                    push = self.push_field()
                    trial = push(self.positions)
                frozen = trial[3]
                if not frozen:
                    external, cell_pressure, powder_stiffness = trial[:3]
                    anchor = self.positions.copy()
            if 2.0 * np.sqrt(((self.positions - reference) ** 2).sum(axis=1)).max() > skin:
                found = detect_contacts(self.positions, self.radii, 1.0, skin)
                shear, plastic, slip = (pair_values(found, pairs, values) for values in (shear, plastic, slip))
                pairs, reference = found, self.positions.copy()
                trial_shear, trial_plastic = np.empty_like(shear), np.empty_like(plastic)
            # past an inversion, the push linearised about its last positions with the
            # isotropic stiffness k = sum dP/dV_c A^2, the bound of its rank-one terms
            forces = external - powder_stiffness[:, None] * (self.positions - anchor)
            stiffness = powder_stiffness.copy()
            torques, normal, radial, lower, upper = contact_forces(self.positions, moved, turned, forces, stiffness,
                                                                   slip, wall_slip)
            carried = np.concatenate([normal[normal > 0.0], radial[radial > 0.0],
                                      lower[lower > 0.0], upper[upper > 0.0]])
            resultant = np.sqrt((forces**2).sum(axis=1)).mean()
            if carried.size:
                unbalanced = float(resultant / carried.mean())
            else:  # no contact yet: balanced only where nothing pushes the pellets
                pushed = float(np.sqrt((external**2).sum(axis=1)).mean())
                unbalanced = float(resultant / pushed) if pushed > 0.0 else 0.0
            plates = 0.5 * float(lower.sum() + upper.sum())
            net = float(np.linalg.norm(forces.sum(axis=0)) / plates) if plates > 0.0 else 0.0
            if k >= substeps:
                break
            if unbalanced < s.dem_balance_tolerance and net < s.dem_balance_tolerance:
                break
            # balanced pellet by pellet but not as a whole: the residual that pushes all the
            # pellets one way is the column's soft rigid mode, solved by its own Newton step
            if (s.dem_rigid_correction and unbalanced < s.dem_balance_tolerance and not frozen
                    and k - last_correction >= CORRECTION_INTERVAL):
                shift, evaluations = rigid_translation(translated, forces.sum(axis=0), net,
                                                       CORRECTION_STEP * float(self.radii.mean()))
                k += evaluations
                last_correction = k
                if shift is not None:
                    moved, turned = np.tile(shift, (n_p, 1)), still
                    self.positions += shift
                    continue
            mass = np.tile(np.maximum(stiffness, floor), 2)
            step = fire_step(fire, rates, np.concatenate([forces, torques / self.radii[:, None]]), mass, cap)
            moved, turned = step[:n_p], step[n_p:] / self.radii[:, None]
            self.positions += moved
            k += 1
        self.velocities, self.spins = rates[:n_p], rates[n_p:] / self.radii[:, None]
        self.contacts.pairs, self.contacts.shear, self.contacts.plastic = pairs, trial_shear, trial_plastic
        self.contacts.wall_shear, self.contacts.wall_plastic = wall_shear, wall_plastic
        self.counters.dem_substeps += k
        self.cells.pressures = cell_pressure
        self.move_geometry()
        self._confine(pairs, normal, np.maximum(radial, 0.0) + np.maximum(lower, 0.0) + np.maximum(upper, 0.0))
        # radial loads on the curved wall at their contact's height above the lower plate
        heights, loads = self.positions[:, 2] + 0.5 * s.height, radial
        area = np.pi * s.radius**2
        upper_force, lower_force = float(upper.sum()), float(lower.sum())
        if s.powder_on_walls:
            wall_heights, wall_loads, extra_upper, extra_lower = self.powder_wall_loads()
            heights = np.concatenate([np.repeat(heights[:, None], 3, axis=1), wall_heights])
            loads = np.concatenate([loads, wall_loads])
            upper_force += extra_upper
            lower_force += extra_lower
        return Readings(s.sensors.pressures(heights, loads, s.radius),
                        s.bands.pressures(heights, loads, s.radius),
                        upper_force / area, lower_force / area, unbalanced, net)

    def push_field(self) -> Callable[[FloatArray], tuple[FloatArray, FloatArray, FloatArray, bool]]:
        """The powder's push as a function of the pellets' positions, for one relaxation:
        ``push(positions)`` is the push on the pellets (n_p, 3) [N], the cells' pressures
        [Pa], the push's stiffness per pellet, dP/dV_c A^2 over its cells [N/m], and
        whether an active cell is inverted at them (:func:`macro._kernels.powder_push`,
        the kernel of :meth:`powder_pressure` and :meth:`hydro_forces` fused).

        What the positions do not change within a relaxation (the radii, the suctions,
        the solid, the densest and free volumes, the yield bounds, each pellet's cells and
        triangles) is evaluated once here.
        """
        n_p, cells = self.n_pellets, slice(self.n_pellets, None)
        mesh, m = self.mesh, self.material
        suction = -self.pressure[cells]
        if self.settings.powder_pressure:
            candidate = ~self.inert[cells]
        else:
            candidate = np.zeros(self.n_cells, dtype=np.bool_)
        constants = (
            mesh.tetrahedra, mesh.facet_vertices, mesh.facet_cells, self.clay_radii(), self.vertex_radii(), n_p,
            self.solid_mass()[cells], self.densest_volume(cells, with_water=False),
            free_volume(suction, self.reference_volume[cells], m), candidate, self._pressure_bound(),
            m.beta_v * saturation(suction, self.retention_porosity()[cells], m), m.alpha_v,
            self.settings.powder_onset_strain, VOID_FLOOR,
            incidence(mesh.tetrahedra, n_p), incidence(mesh.facet_vertices, n_p))
        container = self.container

        def push(positions: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, bool]:
            forces, pressure, stiffness, inverted = powder_push(np.concatenate([positions, container]), *constants)
            return forces, pressure, stiffness, bool(inverted)

        return push

    def _confine(self, pairs: npt.NDArray[np.int64], normal: FloatArray, walls: FloatArray) -> None:
        """Confining stress of every pellet from the relaxed state, and the volume its
        sphere loses to overlaps.

        The mean stress on a sphere is the normal load over its surface,
        (sum of contact forces + sum_c P_c Omega_c r^2) / (4 pi r^2) (contacts, walls
        and the powder's push over the sphere's sectors in its cells); it enters the
        pellet's swelling target under-relaxed by ``stress_relaxation`` (the pellets'
        volumes and contacts are coupled explicitly, step by step). The overlaps' caps
        (with other pellets and the container) are the volume the sphere of a pellet
        loses, so that its radius keeps its clay volume (:meth:`step`).
        """
        assert self.stress is not None and self.cells.pressures is not None
        n_p, s = self.n_pellets, self.settings
        radii = self.radii
        load = walls + np.bincount(pairs[:, 0], normal, minlength=n_p) \
            + np.bincount(pairs[:, 1], normal, minlength=n_p)
        tet = self.mesh.tetrahedra
        surface = self.cells.pressures[:, None] * self.cells.solid_angles * self.vertex_radii()[tet] ** 2
        load += np.bincount(tet.ravel(), surface.ravel(), minlength=self.n_vertices)[:n_p]
        measured = load / (4.0 * np.pi * radii**2)
        self.stress[:n_p] += s.stress_relaxation * (measured - self.stress[:n_p])
        # caps cut off each sphere by its overlaps: pellets (plane of the lens) and container
        i, j = pairs[:, 0], pairs[:, 1]
        distance = np.linalg.norm(self.positions[j] - self.positions[i], axis=1)
        touching = radii[i] + radii[j] > distance
        i, j, distance = i[touching], j[touching], distance[touching]
        plane = (distance**2 + radii[i] ** 2 - radii[j] ** 2) / (2.0 * distance)
        lost = np.bincount(i, _cap_volume(radii[i], radii[i] - plane), minlength=n_p) \
            + np.bincount(j, _cap_volume(radii[j], radii[j] - (distance - plane)), minlength=n_p) + 0.0
        axis = np.hypot(self.positions[:, 0], self.positions[:, 1])
        for depth in (radii + axis - s.radius, radii - self.positions[:, 2] - 0.5 * s.height,
                      radii + self.positions[:, 2] - 0.5 * s.height):
            lost += _cap_volume(radii, np.maximum(depth, 0.0))
        self.occupied_loss = np.minimum(lost / (4.0 / 3.0 * np.pi * radii**3), MAX_OVERLAP_LOSS)


def _cap_volume(radius: FloatArray, height: FloatArray) -> FloatArray:
    """Volume of spherical caps pi h^2 (3 r - h) / 3 [m3]."""
    return np.pi * height**2 * (3.0 * radius - height) / 3.0
