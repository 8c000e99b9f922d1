"""The local pressure-volume problem of each system (Caulk 2022, Sec. 4.3, Eqs. 4.39-4.51).

Given a system's water mass m_w, solid volume V_s, reference volume V_0 and largest
volume V_max (its cell's void for powder), find its volume V and water pressure p with

    f1 = S(V) - S_ret(p, phi(V)) - mu sum_p log c = 0   (retention, Eqs. 4.39, 4.41-4.43)
    f2 = V - V_0 (1 + eps(-p)) - mu sum_V log c = 0   (swelling, Eq. 4.40)

where S_ret is the retention curve (Eq. 4.24 read as S(s)), S(V) = m_w / (rho (V - V_s)), phi(V) = 1 - V_s / V,
and the log-barriers keep the constraints of Sec. 4.3 strictly positive:
c1 = 1 - V_s/V (phi >= 0), c2 = V_s/V (phi <= 1), c3 = 1 - V/V_max, c4 = 1 - S, c5 = S
(volume constraints, in f2) and c6 = -p/s_max (p <= 0), c7 = 1 + p/s_max (p >= -s_max)
(pressure constraints, in f1). The thesis prints one barrier sum in both equations; a
constraint that binds would then shift the other equation by a finite amount, so each
equation carries the barriers of its own unknown (our reading). Eq. 4.39 is written on
saturation, S(V) = S_ret(p), rather than on pressure, p = p_ret(V): the same root, but a
bounded function (p_ret has infinite slopes at S -> 0 and S -> 1, where Newton steps
overshoot). f2 is made dimensionless by V_0.

Newton-Raphson (Eqs. 4.44-4.50) with central-difference Jacobians (Eq. 4.46), the
barrier weight mu and the under-relaxation 1 - alpha_r decaying geometrically each
iteration, a fraction-to-boundary rule that keeps every iterate strictly feasible, and
a backtracking (Armijo) line search on |f|^2 that keeps Newton from cycling where the
swelling and retention curves bend.
Converged when the RMS relative update (Eq. 4.51) is below the tolerance, mu has
decayed below 1e-3 tolerance and both residuals are below the tolerance (or a
constraint is active). Systems where Newton stalls (|f| has local minima where the
porosity dependence of the retention curve bends the swelling target) are solved by a
bracketed bisection of the same equations and counted. All systems are solved at once (numpy, no loop over
systems); a system that does not converge raises :class:`NewtonError` naming it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from macro.laws import MixtureParameters, saturation, suction, swelling_strain

__all__ = [
    "NewtonError", "NewtonSettings", "PVProblem", "bracketed_solution", "constraints",
    "residuals", "solve_pressure_volume",
]

FloatArray = npt.NDArray[np.float64]


class NewtonError(RuntimeError):
    """A local pressure-volume system without solution or without convergence."""


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
    retention curve's zeta and lambda, or None for the current 1 - V_s/V (Eqs. 4.42-4.43).
    """

    water_mass: FloatArray
    solid_volume: FloatArray
    reference_volume: FloatArray
    max_volume: FloatArray
    density: float
    max_suction: float
    names: list[str] | Callable[[int], str] | None = None
    retention_porosity: FloatArray | None = None

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


def residuals(problem: PVProblem, material: MixtureParameters, volume: FloatArray,
              pressure: FloatArray, mu: float | FloatArray = 0.0,
              index: npt.NDArray[np.int64] | slice = slice(None)) -> tuple[FloatArray, FloatArray]:
    """Dimensionless f1 (retention) and f2 (swelling) of Eqs. 4.39-4.40 with barrier weight mu."""
    v0 = problem.reference_volume[index]
    c = constraints(problem, volume, pressure, index)
    with np.errstate(invalid="ignore", divide="ignore"):
        s_ret = saturation(-pressure, problem.porosity(volume, index), material)
        barrier_p = np.log(c[5]) + np.log(c[6])
        barrier_v = np.log(c[0]) + np.log(c[1]) + np.log(c[2]) + np.log(c[3]) + np.log(c[4])
    f1 = c[4] - s_ret - mu * barrier_p
    f2 = (volume - v0 * (1.0 + swelling_strain(-pressure, material))) / v0 - mu * barrier_v
    return f1, f2


def _feasible(c: FloatArray) -> npt.NDArray[np.bool_]:
    return np.all(c > 0.0, axis=0)


def initial_guess(problem: PVProblem, material: MixtureParameters,
                  volume: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Eqs. 4.47-4.48 from the previous volumes, moved strictly inside the constraints.

    Raises
    ------
    NewtonError
        If a system has no feasible volume: its water does not fit below V_max.
    """
    pb = problem
    low = np.maximum(pb.solid_volume + pb.water_mass / pb.density, pb.solid_volume)
    high = pb.max_volume
    bad = np.flatnonzero(~(low < high * (1.0 - 1e-12)))
    if bad.size:
        i = int(bad[0])
        raise NewtonError(
            f"{pb.name(i)}: no feasible volume (solid + water {low[i]:.6g} m3 >= V_max "
            f"{high[i]:.6g} m3; water mass {pb.water_mass[i]:.6g} kg); {bad.size} such system(s)"
        )
    gap = high - low
    volume = np.clip(volume, low + 1e-3 * gap, high - 1e-3 * gap)
    sat = pb.water_mass / (pb.density * (volume - pb.solid_volume))
    s = suction(np.clip(sat, 1e-300, 1.0), pb.porosity(volume), material)
    pressure = -np.clip(s, 1e-6 * pb.max_suction, (1.0 - 1e-6) * pb.max_suction)
    target = pb.reference_volume * (1.0 + swelling_strain(-pressure, material))
    volume = np.clip(target, low + 1e-3 * gap, high - 1e-3 * gap)
    return volume, pressure


def solve_pressure_volume(
    problem: PVProblem,
    material: MixtureParameters,
    settings: NewtonSettings,
    previous_volume: FloatArray,
) -> tuple[FloatArray, FloatArray, int, int]:
    """Solve every system's (V, p).

    Returns volumes [m3], pressures [Pa], the iterations used, and the number of systems
    that :func:`bracketed_solution` solved: those where Newton stalled, and those it
    left on a bound (checked for a root nearer their previous volume).

    Raises
    ------
    NewtonError
        Naming the first system that has no feasible volume or did not converge, with
        its state (V, p, m_w, V_s, V_max, last update).
    """
    volume, pressure = initial_guess(problem, material, np.asarray(previous_volume, dtype=float))
    n = volume.size
    active = np.arange(n)
    error = np.full(n, np.inf)
    mu = settings.barrier_start
    damping = 1.0 - settings.relaxation_start
    h = settings.derivative_step
    iterations = 0
    mu_done = 1e-3 * settings.tolerance
    for iterations in range(1, settings.max_iterations + 1):
        v, p = volume[active], pressure[active]
        # differences that never probe outside the constraints: central where the
        # constraints leave room, one-sided (shorter side) next to a bound
        low = problem.solid_volume[active] + problem.water_mass[active] / problem.density
        hv_up = np.minimum(h * v, 0.5 * (problem.max_volume[active] - v))
        hv_dn = np.minimum(h * v, 0.5 * (v - low))
        hp_up = np.minimum(h * np.abs(p), -0.5 * p)
        hp_dn = np.minimum(h * np.abs(p), 0.5 * (p + problem.max_suction))
        f1, f2 = residuals(problem, material, v, p, mu, active)
        a1, a2 = residuals(problem, material, v + hv_up, p, mu, active)
        b1, b2 = residuals(problem, material, v - hv_dn, p, mu, active)
        c1, c2 = residuals(problem, material, v, p + hp_up, mu, active)
        d1, d2 = residuals(problem, material, v, p - hp_dn, mu, active)
        with np.errstate(invalid="ignore", divide="ignore"):
            j11, j21 = (a1 - b1) / (hv_up + hv_dn), (a2 - b2) / (hv_up + hv_dn)
            j12, j22 = (c1 - d1) / (hp_up + hp_dn), (c2 - d2) / (hp_up + hp_dn)
            det = j11 * j22 - j12 * j21
            dv = (-f1 * j22 + f2 * j12) / det
            dp = (-f2 * j11 + f1 * j21) / det
        # pinned against a bound closer than the difference step can resolve: no update
        pinned = ~(np.isfinite(dv) & np.isfinite(dp))
        dv[pinned] = 0.0
        dp[pinned] = 0.0
        step = np.full(v.size, 1.0 - damping)
        # fraction to the boundary and backtracking: halve the step until every
        # constraint stays positive and the residual norm decreases (Armijo)
        norm = f1 * f1 + f2 * f2
        for _ in range(60):
            tv, tp = v + step * dv, p + step * dp
            trial = constraints(problem, tv, tp, active)
            ok = _feasible(trial) & np.isfinite(trial).all(axis=0)
            g1, g2 = residuals(problem, material, np.where(ok, tv, v), np.where(ok, tp, p), mu, active)
            ok &= g1 * g1 + g2 * g2 <= (1.0 - 1e-4 * step) * norm
            if ok.all():
                break
            step = np.where(ok, step, 0.5 * step)
        new_v, new_p = v + step * dv, p + step * dp
        with np.errstate(invalid="ignore", divide="ignore"):
            err = np.sqrt(0.5 * (((new_v - v) / v) ** 2 + ((new_p - p) / p) ** 2))
        volume[active], pressure[active] = new_v, new_p
        error[active] = err
        broken = pinned & ~_at_bound(problem, new_v, new_p, active)
        if broken.any():
            _fail(problem, active[np.flatnonzero(broken)[0]], volume, pressure, error, iterations,
                  "singular Jacobian away from the constraints")
        if mu <= mu_done:
            g1, g2 = residuals(problem, material, new_v, new_p, mu, active)
            bounds = constraints(problem, new_v, new_p, active) < 1e-8
            retention = np.abs(g1) < settings.tolerance
            solved = (err < settings.tolerance) & (
                (retention & (np.abs(g2) < settings.tolerance))
                | (retention & bounds[:5].any(axis=0))  # a volume bound replaces f2
                | bounds[5:].any(axis=0)  # a pressure bound replaces f1
            )
            active = active[~solved]
            if active.size == 0:
                break
        mu *= settings.barrier_decay
        damping *= settings.barrier_decay
    # h(V) can have several roots (and the bound V_max): a system that Newton left on a
    # bound, or that it did not solve, takes the root nearest its previous volume by the
    # bracketed bisection (counted)
    previous = np.asarray(previous_volume, dtype=float)
    at_bound = _at_bound(problem, volume, pressure, np.arange(n))
    # a powder that stays confined (on V_max before and after, swelling target beyond
    # it) keeps Newton's answer: the usual case of a confined cell, no search needed
    target = problem.reference_volume * (1.0 + swelling_strain(-pressure, material))
    stays = ((previous >= (1.0 - 1e-2) * problem.max_volume)
             & np.isclose(volume, problem.max_volume, rtol=1e-6) & (target >= volume))
    redo = np.union1d(active, np.flatnonzero(at_bound & ~stays)).astype(np.int64)
    if redo.size:
        v_b, p_b = bracketed_solution(problem, material, redo, previous[redo])
        volume[redo], pressure[redo] = v_b, p_b
    return volume, pressure, iterations, int(redo.size)



def bracketed_solution(problem: PVProblem, material: MixtureParameters,
                       index: npt.NDArray[np.int64],
                       previous_volume: FloatArray,
                       window: float | None = 0.03) -> tuple[FloatArray, FloatArray]:
    """Safeguarded solution of the same problem by bisection on V (vectorised).

    Eliminating p with the retention curve, p = -s(S(V), phi(V)), leaves
    h(V) = V - V_0 (1 + eps(s(V))) on (V_low, V_max), V_low the saturated volume. h can
    change sign more than once (the retention curve's porosity dependence); the sign
    change nearest to the previous volume is bisected (continuity of the state). Without a
    root, the system sits on the bound it moves into, nearest to its previous volume:
    V_max when its swelling target exceeds it (constraint c3 active), the edge of the
    admissible suctions s <= s_max (c7 active), or saturation (c4, c6 active) when it
    would shrink even saturated.

    Raises
    ------
    NewtonError
        If neither a root nor the bound V_max solves the system.
    """
    pb = problem
    vs, v0 = pb.solid_volume[index], pb.reference_volume[index]
    low = (vs + pb.water_mass[index] / pb.density) * (1.0 + 1e-12)
    high = pb.max_volume[index] * (1.0 - 1e-12)

    def h(v: FloatArray, rows: npt.NDArray[np.int64] | slice = slice(None)) -> tuple[FloatArray, FloatArray]:
        sat = pb.water_mass[index][rows] / (pb.density * (v - vs[rows]))
        s = np.maximum(suction(np.clip(sat, 1e-300, 1.0), pb.porosity(v, index[rows]), material), 0.0)
        # beyond the largest suction (c7) no root counts: NaN never changes sign
        value = np.where(s <= pb.max_suction, v - v0[rows] * (1.0 + swelling_strain(s, material)), np.nan)
        return value, -np.minimum(s, pb.max_suction)

    if window is not None:
        # first a narrow window around the previous volume: a root there is the nearest
        lo = np.clip(previous_volume * (1.0 - window), low, high)
        hi = np.clip(previous_volume * (1.0 + window), low, high)
        local = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, 9)[None, :]
        vals = np.stack([h(local[:, k])[0] for k in range(9)], axis=1)
        change = np.sign(vals[:, :-1]) * np.sign(vals[:, 1:]) <= 0.0
        mid = 0.5 * (local[:, :-1] + local[:, 1:])
        dist = np.where(change, np.abs(mid - previous_volume[:, None]), np.inf)
        pick = np.argmin(dist, axis=1)
        rows = np.arange(index.size)
        found = np.isfinite(dist[rows, pick])
        v = np.empty(index.size)
        p = np.empty(index.size)
        if found.any():
            f = np.flatnonzero(found)
            a, b = local[f, pick[f]], local[f, pick[f] + 1]
            sign_a = np.sign(vals[f, pick[f]])
            for _ in range(40):
                m = 0.5 * (a + b)
                left = np.sign(h(m, f)[0]) == sign_a
                a = np.where(left, m, a)
                b = np.where(left, b, m)
            v[f] = 0.5 * (a + b)
            p[f] = np.minimum(h(v[f], f)[1], -1e-9 * pb.max_suction)
        rest = np.flatnonzero(~found)
        if rest.size:
            v[rest], p[rest] = bracketed_solution(problem, material, index[rest], previous_volume[rest], None)
        return v, p

    grid = low[:, None] + (high - low)[:, None] * np.linspace(0.0, 1.0, 257)[None, :]
    values = np.stack([h(grid[:, k])[0] for k in range(grid.shape[1])], axis=1)
    valid = np.isfinite(values)
    # candidates between grid points k and k + 1: a root (sign change), or the edge of
    # the admissible suctions (c7) that the system moves into; at the last point, V_max
    root = np.sign(values[:, :-1]) * np.sign(values[:, 1:]) <= 0.0  # NaN compares False
    grow_edge = valid[:, :-1] & ~valid[:, 1:] & (values[:, :-1] < 0.0)
    shrink_edge = ~valid[:, :-1] & valid[:, 1:] & (values[:, 1:] > 0.0)
    kind = np.where(root, 1, np.where(grow_edge | shrink_edge, 2, 0))
    capped = valid[:, -1] & (values[:, -1] < 0.0)
    # a system that would shrink even when saturated sits saturated (c4 and c6 active)
    saturated = valid[:, 0] & (values[:, 0] > 0.0)
    kind[:, 0] = np.where(saturated & (kind[:, 0] == 0), 3, kind[:, 0])
    centre = 0.5 * (grid[:, :-1] + grid[:, 1:])
    # a root (both equations hold) wins over a bound; among equals, the nearest to the
    # previous volume (continuity of the state)
    distance = np.abs(centre - previous_volume[:, None]) + np.where(kind >= 2, 1e3 * high[:, None], 0.0)
    distance = np.where(kind > 0, distance, np.inf)
    best = np.argmin(distance, axis=1)
    rows = np.arange(index.size)
    best_distance = distance[rows, best]
    use_cap = capped & (np.abs(high - previous_volume) + 1e3 * high < best_distance)
    bad = np.flatnonzero(~np.isfinite(best_distance) & ~use_cap)
    if bad.size:
        i = int(index[bad[0]])
        k = bad[0]
        raise NewtonError(f"{pb.name(i)}: no solution of the pressure-volume problem between "
                          f"V_low={low[k]:.6g} and V_max={high[k]:.6g} m3 (m_w={pb.water_mass[i]:.6g} kg, "
                          f"V_s={pb.solid_volume[i]:.6g} m3, V_0={pb.reference_volume[i]:.6g} m3; "
                          f"h over the range: {np.array2string(values[k, ::32], precision=3)})")
    a, b = grid[rows, best], grid[rows, best + 1]
    is_root = kind[rows, best] == 1
    sign_a = np.sign(values[rows, best])
    valid_a = valid[rows, best]
    for _ in range(40):
        mid = 0.5 * (a + b)
        hm, _ = h(mid)
        # roots: keep the sign change; edges: keep the admissible side
        left = np.where(is_root, np.sign(hm) == sign_a, np.isfinite(hm) == valid_a)
        a = np.where(left, mid, a)
        b = np.where(left, b, mid)
    v = np.where(valid_a | is_root, a, b)
    v = np.where(is_root, 0.5 * (a + b), v)
    v = np.where(kind[rows, best] == 3, low, v)
    v = np.where(use_cap, high, v)
    _, p = h(v)
    return v, np.minimum(p, -1e-9 * pb.max_suction)


def _at_bound(problem: PVProblem, volume: FloatArray, pressure: FloatArray,
              index: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
    """Systems with a constraint within 1e-8 of its bound (an active constraint)."""
    return np.any(constraints(problem, volume, pressure, index) < 1e-8, axis=0)


def _fail(problem: PVProblem, i: int, volume: FloatArray, pressure: FloatArray,
          error: FloatArray, iterations: int, why: str) -> None:
    raise NewtonError(
        f"{problem.name(i)}: Newton-Raphson failed ({why}) after {iterations} iterations: "
        f"V={volume[i]:.6g} m3, p={pressure[i]:.6g} Pa, m_w={problem.water_mass[i]:.6g} kg, "
        f"V_s={problem.solid_volume[i]:.6g} m3, V_0={problem.reference_volume[i]:.6g} m3, "
        f"V_max={problem.max_volume[i]:.6g} m3, RMS update={error[i]:.3g}"
    )
