"""macro.transport: the stable step of Eq. 4.58 by hand, the implicit pressures against a
dense backward Euler solve, and the flux limiter's conservation."""

from __future__ import annotations

import numpy as np
import pytest

from macro.transport import CG_TOLERANCE, implicit_pressures, limited_rates, mass_rates, stable_time_step


def test_stable_step_of_eq_4_58_by_hand():
    """Three systems in a chain, G = 1e-12 and 3e-12 kg/(Pa s): alpha_i = sum G / (rho n V)."""
    pairs = np.array([[0, 1], [1, 2]])
    conductance = np.array([1e-12, 3e-12])
    pore = np.array([2e-9, 1e-9, 4e-9])
    slope = np.array([1e8, 5e7, 2e8])
    held = np.array([False, False, True])
    # system 0: 1e-12 / (1000 * 2e-9) * 1e8 = 50; system 1: 4e-12 / (1000 * 1e-9) * 5e7 = 200
    dt = stable_time_step(pairs, conductance, pore, slope, held, 1000.0, 0.6)
    assert dt == pytest.approx(0.6 * 2.0 / 200.0, rel=1e-12)


def test_implicit_pressures_are_the_dense_backward_euler_solution(rng):
    """A random graph of 30 systems, 5 held: the sparse solve (Jacobi-preconditioned CG)
    solves (C/dt + L_FF) p' = C/dt p + G_FH p_H assembled densely here to the row-wise
    backward error CG_TOLERANCE, max_i |r_i| / (|M_ii| max |p'| + |rhs_i|), and so lies
    within 10 times it of the dense solution."""
    n = 30
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n) if rng.uniform() < 0.2])
    conductance = rng.uniform(1e-13, 1e-12, len(pairs))
    pressure = -rng.uniform(1e6, 1e8, n)
    capacity = rng.uniform(1e-12, 1e-10, n)
    free = np.ones(n, dtype=bool)
    free[:5] = False
    dt = 50.0
    laplacian = np.zeros((n, n))
    for (i, j), g in zip(pairs, conductance, strict=True):
        laplacian[i, i] += g
        laplacian[j, j] += g
        laplacian[i, j] -= g
        laplacian[j, i] -= g
    f, h = np.flatnonzero(free), np.flatnonzero(~free)
    matrix = np.diag(capacity[f] / dt) + laplacian[np.ix_(f, f)]
    rhs = capacity[f] / dt * pressure[f] - laplacian[np.ix_(f, h)] @ pressure[h]
    expected = np.linalg.solve(matrix, rhs)
    got = implicit_pressures(pairs, conductance, pressure, capacity, dt, free)
    residual = np.abs(rhs - matrix @ got[f]) / (np.diag(matrix) * np.abs(got[f]).max() + np.abs(rhs))
    assert residual.max() <= CG_TOLERANCE
    np.testing.assert_allclose(got[f], expected, rtol=10.0 * CG_TOLERANCE)
    np.testing.assert_array_equal(got[h], pressure[h])


def test_flux_limiter_keeps_water_and_conserves_it(rng):
    """A tiny wet system between large dry ones over a long step: its outflows are scaled so
    that it keeps 1 % of its water; the rates still sum to zero; systems that are not
    limited get exactly the unlimited rates of Eq. 4.22."""
    n = 6
    pairs = np.array([[0, 1], [0, 2], [0, 3], [3, 4], [4, 5]])
    conductance = rng.uniform(1e-13, 1e-12, len(pairs))
    pressure = np.array([-1e6, -1e8, -1e8, -5e7, -5e7, -5e7])
    water = np.array([1e-9, 1.0, 1.0, 1.0, 1.0, 1.0])
    free = np.ones(n, dtype=bool)
    dt = 1e4
    rate, limited = limited_rates(pairs, conductance, pressure, water, dt, free, 0.01)
    plain = mass_rates(pairs, conductance, pressure, n)
    assert limited == 1 and -dt * plain[0] > water[0]
    assert -dt * rate[0] == pytest.approx(0.99 * water[0], rel=1e-12)
    assert rate.sum() == pytest.approx(0.0, abs=1e-12 * np.abs(plain).max())
    np.testing.assert_allclose(rate[4:], plain[4:], rtol=1e-12)
