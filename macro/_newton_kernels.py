"""numba kernels of the local pressure-volume problem (see :mod:`macro.newton`).

One loop over the systems, each solved on its own (results do not depend on the order
or the thread count). Unknowns per system: volume V [m3] and suction s = -p [Pa].
Material constants come in one array ``law``: zeta_0 [Pa], lambda_0, a, b, phi_0 of the
retention curve (:mod:`shared.retention`, scalar here), alpha [1/Pa], beta [1/Pa],
s_0 [Pa] of the swelling law (:mod:`shared.swelling`) and beta_v [Pa], alpha_v [m3/kg]
of the consolidation line (Eq. 4.31). Per system: the confining stress [Pa] and the
solid mass [kg] of the confined swelling (:func:`macro.laws.confined_volume`).

Status per system: 0 solved by Newton-Raphson, 1 by the bracketed search, 2 no feasible
volume, 3 no solution found, 4 drier than the retention curve allows at s_max,
5 confined at V_max. The statuses in full: docs/macro.md, "macro._newton_kernels".
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

NEWTON, BRACKETED, INFEASIBLE, UNSOLVED, DRIEST, CONFINED = 0, 1, 2, 3, 4, 5
BOUND = 1e-6
"""A constraint within this relative distance of its bound is active."""
GRID = 512
"""Points of the log-suction grid of the bracketed search."""


@njit(cache=True)
def _retention(suction, porosity, law):
    """S(s, phi) [1] (Eqs. 4.24-4.26)."""
    shift = law[4] - porosity
    zeta = law[0] * np.exp(law[2] * shift)
    lam = law[1] * np.exp(law[3] * shift)
    if suction <= 0.0:
        return 1.0
    return (1.0 + (suction / zeta) ** (1.0 / (1.0 - lam))) ** (-lam)


@njit(cache=True)
def _inverse_retention(saturation, porosity, law):
    """s(S, phi) = zeta (S^(-1/lambda) - 1)^(1 - lambda) [Pa] (Eq. 4.24)."""
    shift = law[4] - porosity
    zeta = law[0] * np.exp(law[2] * shift)
    lam = law[1] * np.exp(law[3] * shift)
    return zeta * max(saturation ** (-1.0 / lam) - 1.0, 0.0) ** (1.0 - lam)


@njit(cache=True)
def _target(suction, v0, stress, solid_mass, fixed, law):
    """Swelling volume under the confining stress [m3] (:func:`macro.laws.confined_volume`):
    the free swelling V_f = V_0 (1 + eps(s)) (Eq. 4.28) while the stress is below the
    swelling pressure S_ret(s) p'_vc(m_s / V_f), else the volume where it meets it."""
    alpha, beta, s0 = law[5], law[6], law[7]
    free = v0 * (1.0 + beta / alpha * (np.exp(-alpha * suction) - np.exp(-alpha * s0)))
    if not stress > 0.0:
        return free
    beta_v, alpha_v = law[8], law[9]
    line = stress / (_retention(suction, fixed if fixed == fixed else law[4], law) * beta_v)
    if not line > 1.0:
        return free
    return min(free, alpha_v * solid_mass / np.log(line))


@njit(cache=True)
def _porosity(volume, solid, fixed):
    return fixed if fixed == fixed else 1.0 - solid / volume


@njit(cache=True)
def _residuals(v, s, mu, m, vs, v0, st, ms, vmax, fixed, rho, smax, law):
    """(f1, f2, feasible) of Eqs. 4.39-4.40 with barrier weight mu (see macro.newton)."""
    if not (vs < v < vmax and 0.0 < s < smax):
        return 0.0, 0.0, False
    sat = m / (rho * (v - vs))
    if not 0.0 < sat < 1.0:
        return 0.0, 0.0, False
    f1 = sat - _retention(s, _porosity(v, vs, fixed), law)
    f2 = (v - _target(s, v0, st, ms, fixed, law)) / v0
    if mu > 0.0:
        f1 -= mu * (np.log(s / smax) + np.log(1.0 - s / smax))
        f2 -= mu * (np.log(1.0 - vs / v) + np.log(vs / v) + np.log(1.0 - v / vmax)
                    + np.log(1.0 - sat) + np.log(sat))
    return f1, f2, True


@njit(cache=True)
def _admissible(v, s, m, vs, v0, st, ms, vmax, fixed, rho, smax, tol, law, suction_bounds):
    """Whether (V, s) solves the problem: both equations, or one with its bound active.

    The suction bounds (drier than the curve allows at s_max, saturated) are accepted
    only with ``suction_bounds``: from the bracketed search, which takes them only when
    no root exists (Newton may stop on them beside a root)."""
    low = vs + m / rho
    f1, f2, ok = _residuals(v, s, 0.0, m, vs, v0, st, ms, vmax, fixed, rho, smax, law)
    if not ok:
        return False
    capped = v >= vmax * (1.0 - tol) and f2 <= tol  # confined: swelling target beyond V_max
    driest = suction_bounds and s >= smax * (1.0 - BOUND) and f1 <= tol  # too dry even at s_max
    wettest = suction_bounds and v <= low * (1.0 + BOUND) and f2 >= -tol  # saturated above its target
    retention = abs(f1) < tol or driest or wettest
    return retention and (abs(f2) < tol or capped or driest or wettest)


@njit(cache=True)
def _newton(m, vs, v0, st, ms, vmax, fixed, rho, smax, v, s, tol, max_iter, mu0, decay, relax0, h, law):
    """Barrier Newton-Raphson of one system from (v, s); returns (v, s, iterations)."""
    low = vs + m / rho
    mu = mu0
    damping = 1.0 - relax0
    mu_done = 1e-3 * tol
    for it in range(1, max_iter + 1):
        f1, f2, _ = _residuals(v, s, mu, m, vs, v0, st, ms, vmax, fixed, rho, smax, law)
        # central differences (Eq. 4.46), one-sided near a bound, never outside
        hv_up = min(h * v, 0.5 * (vmax - v))
        hv_dn = min(h * v, 0.5 * (v - low))
        hs_up = min(h * s, 0.5 * (smax - s))
        hs_dn = min(h * s, 0.5 * s)
        a1, a2, _ = _residuals(v + hv_up, s, mu, m, vs, v0, st, ms, vmax, fixed, rho, smax, law)
        b1, b2, _ = _residuals(v - hv_dn, s, mu, m, vs, v0, st, ms, vmax, fixed, rho, smax, law)
        c1, c2, _ = _residuals(v, s + hs_up, mu, m, vs, v0, st, ms, vmax, fixed, rho, smax, law)
        d1, d2, _ = _residuals(v, s - hs_dn, mu, m, vs, v0, st, ms, vmax, fixed, rho, smax, law)
        j11, j21 = (a1 - b1) / (hv_up + hv_dn), (a2 - b2) / (hv_up + hv_dn)
        j12, j22 = (c1 - d1) / (hs_up + hs_dn), (c2 - d2) / (hs_up + hs_dn)
        det = j11 * j22 - j12 * j21
        if not (det != 0.0 and np.isfinite(det)):
            return v, s, it
        dv = (-f1 * j22 + f2 * j12) / det
        ds = (-f2 * j11 + f1 * j21) / det
        # relaxation (Eq. 4.50), fraction to the boundary and Armijo backtracking
        step = 1.0 - damping
        norm = f1 * f1 + f2 * f2
        accepted = False
        for _ in range(60):
            g1, g2, ok = _residuals(v + step * dv, s + step * ds, mu, m, vs, v0, st, ms, vmax, fixed, rho, smax, law)
            if ok and g1 * g1 + g2 * g2 <= (1.0 - 1e-4 * step) * norm:
                accepted = True
                break
            step *= 0.5
        if not accepted:
            return v, s, it
        err = np.sqrt(0.5 * ((step * dv / v) ** 2 + (step * ds / s) ** 2))  # Eq. 4.51
        v += step * dv
        s += step * ds
        if mu <= mu_done and err < tol:
            return v, s, it
        mu *= decay
        damping *= decay
    return v, s, max_iter


@njit(cache=True)
def _clipped_volume(s, m, vs, v0, st, ms, vmax, fixed, rho, law):
    """V(s): the swelling target within [saturated volume, V_max] (complementarity)."""
    low = vs + m / rho
    return min(max(_target(s, v0, st, ms, fixed, law), low * (1.0 + 1e-12)), vmax * (1.0 - 1e-12))


@njit(cache=True)
def _gap(s, m, vs, v0, st, ms, vmax, fixed, rho, law):
    """g(s) = S(V(s)) - S_ret(s, phi(V(s))): p eliminated, V on its constraints."""
    v = _clipped_volume(s, m, vs, v0, st, ms, vmax, fixed, rho, law)
    return min(m / (rho * (v - vs)), 1.0) - _retention(s, _porosity(v, vs, fixed), law)


@njit(cache=True)
def _bracketed(m, vs, v0, st, ms, vmax, fixed, rho, smax, previous, law):
    """Root of g: with a fixed retention porosity g is monotone and bisected over the
    whole log-suction range; otherwise the sign change on a log-suction grid nearest the
    previous suction (roots with V inside its bounds first) is bisected. Without a root,
    the suction bound (too dry: s_max; too wet: the range's smallest suction)."""
    lo_log, hi_log = np.log(1e-9 * smax), np.log(smax * (1.0 - 1e-9))
    if fixed == fixed:
        # fixed retention porosity: g increases with s (V(s) shrinks, S_ret falls), one
        # root at most, bisected over the whole range
        return _bisected(lo_log, hi_log, m, vs, v0, st, ms, vmax, fixed, rho, law)
    best, best_dist = -1, np.inf
    prev_log = np.log(min(max(previous, 1e-9 * smax), smax))
    g_prev = _gap(np.exp(lo_log), m, vs, v0, st, ms, vmax, fixed, rho, law)
    g_first = g_prev
    for k in range(1, GRID):
        x = lo_log + (hi_log - lo_log) * k / (GRID - 1)
        g = _gap(np.exp(x), m, vs, v0, st, ms, vmax, fixed, rho, law)
        if g_prev * g <= 0.0:
            mid = x - 0.5 * (hi_log - lo_log) / (GRID - 1)
            # a root where both equations hold wins over one on a volume bound
            target = _target(np.exp(mid), v0, st, ms, fixed, law)
            clipped = target >= vmax or target <= vs + m / rho
            dist = abs(mid - prev_log) + (1e3 if clipped else 0.0)
            if dist < best_dist:
                best, best_dist = k, dist
        g_prev = g
    if best < 0:
        # no sign change: g > 0 everywhere is a saturated system (S = 1 > S_ret),
        # g < 0 everywhere one drier than the retention curve allows (s_max)
        s = 1e-9 * smax if g_first > 0.0 else smax * (1.0 - 1e-9)
        return _clipped_volume(s, m, vs, v0, st, ms, vmax, fixed, rho, law), s
    a = lo_log + (hi_log - lo_log) * (best - 1) / (GRID - 1)
    b = lo_log + (hi_log - lo_log) * best / (GRID - 1)
    return _bisected(a, b, m, vs, v0, st, ms, vmax, fixed, rho, law)


@njit(cache=True)
def _bisected(a, b, m, vs, v0, st, ms, vmax, fixed, rho, law):
    """(V, s) at the sign change of g in log-suction [a, b]; the end of the interval
    that g approaches zero from when it does not change sign (a suction bound)."""
    ga = _gap(np.exp(a), m, vs, v0, st, ms, vmax, fixed, rho, law)
    gb = _gap(np.exp(b), m, vs, v0, st, ms, vmax, fixed, rho, law)
    if ga > 0.0 and gb > 0.0:  # saturated: S = 1 > S_ret everywhere
        return _clipped_volume(np.exp(a), m, vs, v0, st, ms, vmax, fixed, rho, law), np.exp(a)
    if ga < 0.0 and gb < 0.0:  # drier than the curve allows at s_max
        return _clipped_volume(np.exp(b), m, vs, v0, st, ms, vmax, fixed, rho, law), np.exp(b)
    for _ in range(60):
        c = 0.5 * (a + b)
        gc = _gap(np.exp(c), m, vs, v0, st, ms, vmax, fixed, rho, law)
        if (gc <= 0.0) == (ga <= 0.0):
            a, ga = c, gc
        else:
            b = c
    s = np.exp(0.5 * (a + b))
    return _clipped_volume(s, m, vs, v0, st, ms, vmax, fixed, rho, law), s


@njit(cache=True, parallel=True)
def solve_systems(water, solid, v0, stress, msolid, vmax, fixed, previous_volume, previous_suction,
                  rho, smax, tol, max_iter, mu0, decay, relax0, h, law):
    """Volume [m3], suction [Pa], iterations and status of every system.

    Newton starts from Eqs. 4.47-4.48: the suction of the new water at the previous
    volume, then the swelling volume at that suction, both moved inside the constraints;
    a system that Newton leaves unsolved gets the bracketed search from its previous
    suction. ``fixed`` is the retention curve's porosity per system (NaN: current).
    """
    n = water.size
    volume = np.empty(n)
    suction = np.empty(n)
    iterations = np.zeros(n, dtype=np.int64)
    status = np.zeros(n, dtype=np.int64)
    # every system is independent: one per thread, the same results in any order
    for i in prange(n):
        m, vs, vm = water[i], solid[i], vmax[i]
        low = vs + m / rho
        if not low < vm * (1.0 - 1e-12):
            status[i] = INFEASIBLE
            volume[i], suction[i] = previous_volume[i], previous_suction[i]
            continue
        gap = vm - low
        v = min(max(previous_volume[i], low + 1e-3 * gap), vm - 1e-3 * gap)
        s = previous_suction[i]
        # Eq. 4.47: suction from the retention curve at the previous volume (Eq. 4.24
        # inverted in closed form at that porosity)
        sat = min(m / (rho * (v - vs)), 1.0)
        s = min(max(_inverse_retention(sat, _porosity(v, vs, fixed[i]), law), 1e-6 * smax),
                (1.0 - 1e-6) * smax)
        driest = smax * (1.0 - 1e-9)
        if fixed[i] == fixed[i] and _gap(driest, m, vs, v0[i], stress[i], msolid[i], vm, fixed[i], rho, law) < 0.0:
            s = smax * (1.0 - 1e-9)
            volume[i], suction[i] = _clipped_volume(s, m, vs, v0[i], stress[i], msolid[i], vm, fixed[i], rho, law), s
            status[i] = DRIEST
            continue
        if fixed[i] == fixed[i]:
            top = vm * (1.0 - 1e-12)
            s_top = _inverse_retention(min(m / (rho * (top - vs)), 1.0), fixed[i], law)
            if 0.0 < s_top < smax and _target(s_top, v0[i], stress[i], msolid[i], fixed[i], law) >= top:
                volume[i], suction[i] = top, s_top
                status[i] = CONFINED
                continue
        # Eq. 4.48
        v = min(max(_target(s, v0[i], stress[i], msolid[i], fixed[i], law), low + 1e-3 * gap), vm - 1e-3 * gap)
        v, s, iterations[i] = _newton(m, vs, v0[i], stress[i], msolid[i], vm, fixed[i], rho, smax, v, s, tol,
                                      max_iter, mu0, decay, relax0, h, law)
        if not _admissible(v, s, m, vs, v0[i], stress[i], msolid[i], vm, fixed[i], rho, smax, tol, law, False):
            v, s = _bracketed(m, vs, v0[i], stress[i], msolid[i], vm, fixed[i], rho, smax, previous_suction[i], law)
            status[i] = BRACKETED if _admissible(v, s, m, vs, v0[i], stress[i], msolid[i], vm, fixed[i], rho, smax,
                                                 tol, law, True) else UNSOLVED
        volume[i], suction[i] = v, s
    return volume, suction, iterations, status
