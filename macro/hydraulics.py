"""Water in the mixture: retention, permeabilities and conductances of the exchanges, the
held ends, and the explicit (Eq. 4.23, step of Eq. 4.58) or linearised implicit mass
update between pellets and powder cells (Sec. 4.4)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from macro.laws import free_volume, powder_permeability, saturation, suction_derivative
from macro.state import ModelState
from macro.transport import (
    conductances,
    harmonic_mean,
    implicit_pressures,
    limited_rates,
    mass_rates,
    stable_time_step,
)

FloatArray = npt.NDArray[np.float64]

PICARD_ITERATIONS = 3
"""Modified Picard iterations of an implicit step."""
IMPLICIT_LOSS = 0.99
"""Largest fraction of its water a system may lose in one implicit step (positivity)."""


class Hydraulics(ModelState):
    """Transport part of :class:`macro.model.MacroModel`."""

    READS: tuple[str, ...] = ("boundary_inflow", "cells", "counters", "densest_volume", "held", "inert", "material",
             "max_volume", "mesh", "n_pellets", "pellet_frames", "positions", "pressure",
             "reference_volume", "settings", "solid_volume", "swelling_volume", "table",
             "trial_time_step", "volume", "water_mass")
    """What this part reads of the model's state and of its other parts."""

    def hold_boundary(self) -> None:
        """Held cells at the boundary suction: S, V from the laws, V capped by their void
        (at least their solid at the smallest porosity). Called at every step: the held
        cells are the water supply's side, so the water a shrinking void squeezes out
        leaves through the boundary (it is not interior water)."""
        h = np.flatnonzero(self.held)
        s_b = self.settings.boundary_suction
        target = free_volume(s_b, self.reference_volume[h], self.material)
        densest = self.densest_volume(h, with_water=False)
        self.volume[h] = np.maximum(np.minimum(target, self.max_volume[h] * (1.0 - 1e-9)), densest)
        porosity = self.retention_porosity()[h]
        sat = saturation(s_b, porosity, self.material)
        self.water_mass[h] = self.settings.density * sat * (self.volume[h] - self.solid_volume[h])
        self.pressure[h] = -s_b


    def saturations(self) -> FloatArray:
        """(n,) water saturation m_w / (rho (V - V_s)) [1]."""
        return self.water_mass / (self.settings.density * (self.volume - self.solid_volume))

    def retention_porosity(self) -> FloatArray:
        """(n,) porosity of the retention curve: current (Eqs. 4.25-4.26, 4.42-4.43) or, with
        ``macro.retention_follows_porosity`` off, Table 4.2's reference porosity phi_0 (the
        curve as measured: pellets start at it; the loose powder would be much drier on the
        curve extrapolated to its porosity)."""
        if self.settings.retention_follows_porosity:
            return self.porosities()
        return np.full(self.volume.size, self.material.reference_porosity)

    def porosities(self) -> FloatArray:
        """(n,) porosity 1 - V_s / V [1]."""
        return 1.0 - self.solid_volume / self.volume

    def permeabilities(self) -> FloatArray:
        """(n,) permeability [m2]: the table's for pellets, the powder law for cells."""
        n_p = self.n_pellets
        k = np.empty(self.volume.size)
        k[:n_p] = self.table.permeability(-self.pressure[:n_p], "water")
        k[n_p:] = powder_permeability(self.saturations()[n_p:], self.porosities()[n_p:], self.material)
        return k

    def conductances(self) -> FloatArray:
        """Mass conductance of every exchange [kg/(Pa s)]."""
        ex = self.cells.exchanges
        assert ex is not None
        k = self.permeabilities()
        i, j = ex.pairs[:, 0], ex.pairs[:, 1]
        k_i, k_j = k[i], k[j]
        if self.pellet_frames is not None:
            k_i, k_j = self.directional_permeabilities(k_i, k_j)
        k_edge = harmonic_mean(k_i, k_j)
        cc = ex.kind == 2
        sat, por = self.saturations(), self.porosities()
        k_edge[cc] = powder_permeability(0.5 * (sat[i[cc]] + sat[j[cc]]),
                                         0.5 * (por[i[cc]] + por[j[cc]]), self.material)
        s = self.settings
        return conductances(ex.area, ex.length, k_edge, s.density, s.viscosity, s.conductivity_factor)

    def directional_permeabilities(self, k_i: FloatArray, k_j: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The pellet ends of the exchanges with the table's tensor (thesis Sec. 6.3): each
        pellet's tensor, rotated into the lab by its random frame (its compaction axis),
        read along the exchange, d^T R K R^T d (d the unit vector between the systems'
        centres); the cell ends keep the powder's."""
        assert self.cells.exchanges is not None and self.pellet_frames is not None
        n_p = self.n_pellets
        frames = self.pellet_frames
        tensor = frames @ self.table.tensor(-self.pressure[:n_p], "water") @ np.swapaxes(frames, 1, 2)
        centres = np.concatenate([self.positions, self.mesh.centroids])
        i, j = self.cells.exchanges.pairs[:, 0], self.cells.exchanges.pairs[:, 1]
        d = centres[j] - centres[i]
        d /= np.maximum(np.linalg.norm(d, axis=1), 1e-300)[:, None]
        k_i, k_j = k_i.copy(), k_j.copy()
        for k_end, end in ((k_i, i), (k_j, j)):
            pellet = end < n_p
            k_end[pellet] = np.einsum("ea,eab,eb->e", d[pellet], tensor[end[pellet]], d[pellet])
        return k_i, k_j

    def time_step(self, conductance: FloatArray) -> float:
        """Stable explicit step of Eq. 4.58 [s]."""
        assert self.cells.exchanges is not None
        # dp/dS grows without bound as S -> 1: no system is driven wetter than the
        # boundary, so the slope is taken no wetter than at half the boundary suction
        porosity = self.retention_porosity()
        wettest = saturation(0.5 * self.settings.boundary_suction, porosity, self.material)
        sat = np.clip(self.saturations(), 1e-12, wettest)
        slope = suction_derivative(sat, porosity, self.material)
        pore = self.volume - self.solid_volume
        return stable_time_step(self.cells.exchanges.pairs, conductance, pore, slope, self.held | self.inert,
                                self.settings.density, self.settings.chi)

    def saturation_limited_step(self, conductance: FloatArray) -> float:
        """Largest step in which no free system's saturation changes by more than
        ``max_saturation_change`` and none loses more than that fraction of its water
        [s]: the explicit update follows a retention curve
        whose slope changes by orders of magnitude, which Eq. 4.58's local slope misses
        (a dry cell next to a wet one would otherwise be drained below zero water)."""
        assert self.cells.exchanges is not None
        rate = mass_rates(self.cells.exchanges.pairs, conductance, self.pressure, self.volume.size)
        free = ~self.held & ~self.inert
        pore = (self.volume - self.solid_volume)[free]
        change = np.abs(rate[free]) / (self.settings.density * pore)
        # and no system loses more than that fraction of its own water (dry systems)
        loss = np.maximum(-rate[free], 0.0) / np.maximum(self.water_mass[free], 1e-300)
        largest = max(change.max(initial=0.0), loss.max(initial=0.0))
        return float(self.settings.max_saturation_change / largest) if largest > 0.0 else float("inf")

    def transport(self, dt: float, conductance: FloatArray) -> None:
        """Explicit mass update (Eq. 4.23); held systems keep their mass, their loss is inflow."""
        assert self.cells.exchanges is not None
        rate = mass_rates(self.cells.exchanges.pairs, conductance, self.pressure, self.volume.size)
        self.boundary_inflow -= float(dt * rate[self.held].sum())
        free = ~self.held
        self.water_mass[free] += dt * rate[free]

    def capacities(self) -> FloatArray:
        """(n,) dm/dp of every system at its current state [kg/Pa]: the retention
        curve's storage rho (V - V_s) dS/dp plus, where the system is not at V_max, the
        swelling's rho S dV/dp of the confined swelling target (central differences)."""
        m = self.material
        sat = np.clip(self.saturations(), 1e-12, 1.0 - 1e-12)
        slope = suction_derivative(sat, self.retention_porosity(), m)
        pore = self.volume - self.solid_volume
        suction = np.maximum(-self.pressure, 1.0)
        swelling = (self.swelling_volume(0.99 * suction) - self.swelling_volume(1.01 * suction)) / (0.02 * suction)
        confined = self.volume >= self.max_volume * (1.0 - 1e-3)
        return self.settings.density * (pore / slope + np.where(confined, 0.0, sat * np.maximum(swelling, 0.0)))

    def water_at(self, pressure: FloatArray) -> FloatArray:
        """(n,) water each system would hold at ``pressure`` [kg]: the local problem with p
        given, rho S_ret(s) (V(s) - V_s), V(s) its swelling volume (:meth:`swelling_volume`)."""
        suction = np.clip(-pressure, 0.0, self.settings.max_suction)
        volume = self.swelling_volume(suction)
        sat = saturation(suction, self.retention_porosity(), self.material)
        return self.settings.density * sat * np.maximum(volume - self.solid_volume, 0.0)

    def implicit_transport(self, conductance: FloatArray, max_dt: float) -> float:
        """Linearised backward-Euler mass update (see :mod:`macro.transport`); returns dt [s].

        The trial step doubles the last accepted one (the first is Eq. 4.58's), capped by
        ``max_time_step_s``; it shrinks until no free system's water changes by more than
        ``max_saturation_change`` of its pore volume (at least the median system's); the
        outflows of a system that would lose more than ``IMPLICIT_LOSS`` of its water are
        limited (:func:`macro.transport.limited_rates`, counted in ``limited_systems``).
        """
        assert self.cells.exchanges is not None
        s = self.settings
        pairs = self.cells.exchanges.pairs
        free = ~self.held & ~self.inert
        capacity = self.capacities()
        # a system smaller than the median counts as the median: tiny cells may swing
        # further within a step (the step is stable; they hold little of the water)
        pore = (self.volume - self.solid_volume)[free]
        pore = np.maximum(pore, np.median(pore))
        limit = s.max_saturation_change
        if self.trial_time_step <= 0.0:
            self.trial_time_step = self.time_step(conductance)
        dt = min(self.trial_time_step, s.max_time_step, max_dt)
        start = self.water_at(self.pressure)
        for _ in range(20):
            # modified Picard (Celia et al. 1990): the storage of each iterate from the
            # retention and swelling laws themselves, with the secant capacity between
            # the step's start and the iterate (the tangent one at first)
            pressure = self.pressure
            for _ in range(PICARD_ITERATIONS):
                stored = self.water_at(pressure) - start
                moved = pressure - self.pressure
                big = np.abs(moved) > 1e-9 * np.abs(self.pressure)
                secant = np.where(big, stored / np.where(big, moved, 1.0), capacity)
                secant = np.where(secant > 0.0, secant, capacity)
                effective = pressure - stored / secant
                pressure = np.clip(implicit_pressures(pairs, conductance, effective, secant, dt, free),
                                   -s.max_suction, 0.0)
            # a tiny cell draining into a large dry neighbour would lose all its water
            # in a long step: its outflows are limited (conservatively) instead
            rate, limited = limited_rates(pairs, conductance, pressure, self.water_mass, dt, free,
                                          1.0 - IMPLICIT_LOSS)
            change = np.abs(dt * rate[free]) / (s.density * pore)
            largest = change.max(initial=0.0)
            if largest <= limit:
                break
            dt *= 0.9 * limit / largest
        self.counters.flux_limited_system_steps += limited
        self.trial_time_step = 2.0 * dt if largest <= 0.5 * limit else dt
        self.boundary_inflow -= float(dt * rate[self.held].sum())
        self.water_mass[~self.held] += dt * rate[~self.held]
        return dt

