"""The local pressure-volume problem (Sec. 4.3): solutions, constraints, failures."""

from __future__ import annotations

import numpy as np
import pytest

from macro.laws import mixture_parameters
from macro.newton import NewtonError, NewtonSettings, PVProblem, constraints, solve_pressure_volume
from tests._defaults import CONFIG
from tests._macro_cases import swelling

MATERIAL = mixture_parameters(CONFIG["materials"], CONFIG["macro"]["powder"])
NUM = CONFIG["macro"]["numerics"]
SETTINGS = NewtonSettings(
    NUM["newton_tolerance"], NUM["newton_max_iterations"], NUM["newton_barrier_start"],
    NUM["newton_barrier_decay"], NUM["newton_relaxation_start"], NUM["newton_derivative_step"],
)
RHO, S_MAX = 1000.0, 1.38e8


def van_genuchten(suction, porosity):
    """Table 4.2's retention written out here: S = [1 + (s/zeta)^(1/(1-lambda))]^(-lambda)."""
    powder = CONFIG["materials"]["mixture_powder"]
    shift = powder["reference_porosity"] - porosity
    zeta = powder["retention_pressure_reference_pa"] * np.exp(powder["retention_pressure_porosity_factor"] * shift)
    lam = powder["retention_exponent_reference"] * np.exp(powder["retention_exponent_porosity_factor"] * shift)
    return (1.0 + (suction / zeta) ** (1.0 / (1.0 - lam))) ** (-lam)


def inverse_van_genuchten(sat, porosity):
    """s = zeta (S^(-1/lambda) - 1)^(1 - lambda)."""
    powder = CONFIG["materials"]["mixture_powder"]
    shift = powder["reference_porosity"] - porosity
    zeta = powder["retention_pressure_reference_pa"] * np.exp(powder["retention_pressure_porosity_factor"] * shift)
    lam = powder["retention_exponent_reference"] * np.exp(powder["retention_exponent_porosity_factor"] * shift)
    return zeta * (sat ** (-1.0 / lam) - 1.0) ** (1.0 - lam)


def random_states(rng, n, largest=1e8):
    """Admissible states built from a known solution (V*, s*): the water that fits it."""
    v0 = rng.uniform(1e-9, 1e-6, n)
    solid = (1.0 - rng.uniform(0.2, 0.35, n)) * v0
    s_star = 10 ** rng.uniform(6.2, np.log10(largest), n)
    v_star = v0 * (1.0 + swelling(s_star))
    water = RHO * van_genuchten(s_star, 1.0 - solid / v_star) * (v_star - solid)
    v_max = v_star * rng.uniform(1.02, 1.5, n)
    return PVProblem(water, solid, v0, v_max, RHO, S_MAX), v_star, s_star


def test_solution_satisfies_both_equations_and_every_constraint(rng):
    """From a previous volume within 5 % (a time step's change), as in the model."""
    problem, v_star, s_star = random_states(rng, 400)
    previous = v_star * rng.uniform(0.95, 1.05, v_star.size)
    volume, pressure, _, _ = solve_pressure_volume(problem, MATERIAL, SETTINGS, previous)
    assert np.all(constraints(problem, volume, pressure) >= 0.0)
    sat = problem.water_mass / (RHO * (volume - problem.solid_volume))
    porosity = 1.0 - problem.solid_volume / volume
    # retention (Eq. 4.39) and swelling (Eq. 4.40), evaluated here from the tables
    np.testing.assert_allclose(sat, van_genuchten(-pressure, porosity), atol=2e-3)
    np.testing.assert_allclose(volume, problem.reference_volume * (1.0 + swelling(-pressure)), rtol=2e-3)


def test_confined_systems_satisfy_retention_and_swelling_or_sit_on_the_bound(rng):
    """With V_max below the free solution, every system either solves both equations
    inside (another root: the porosity-dependent retention allows several) or sits on
    V_max with its swelling target beyond it; retention holds in both cases."""
    problem, v_star, _ = random_states(rng, 200, largest=3e7)
    problem.max_volume = 0.9 * v_star  # the free solution does not fit
    # keep the systems that the bound really confines: at V_max their water's suction is
    # admissible and their swelling target exceeds V_max
    sat = problem.water_mass / (RHO * (problem.max_volume - problem.solid_volume))
    s_cap = inverse_van_genuchten(sat, 1.0 - problem.solid_volume / problem.max_volume)
    keep = (s_cap < S_MAX) & (problem.reference_volume * (1 + swelling(s_cap)) > problem.max_volume)
    assert keep.sum() > 20
    problem = PVProblem(problem.water_mass[keep], problem.solid_volume[keep],
                        problem.reference_volume[keep], problem.max_volume[keep], RHO, S_MAX)
    volume, pressure, _, _ = solve_pressure_volume(problem, MATERIAL, SETTINGS, 0.88 * v_star[keep])
    assert np.all(constraints(problem, volume, pressure) >= 0.0)
    sat = problem.water_mass / (RHO * (volume - problem.solid_volume))
    np.testing.assert_allclose(sat, van_genuchten(-pressure, 1.0 - problem.solid_volume / volume), atol=2e-3)
    target = problem.reference_volume * (1.0 + swelling(-pressure))
    on_bound = np.isclose(volume, problem.max_volume, rtol=1e-6)
    assert on_bound.sum() >= keep.sum() // 2
    assert np.all(target[on_bound] >= volume[on_bound] * (1 - 1e-3))
    np.testing.assert_allclose(volume[~on_bound], target[~on_bound], rtol=2e-3)


def test_failure_names_the_system_and_its_state(rng):
    problem, _, _ = random_states(rng, 8)
    problem.names = [f"cell {i}" for i in range(8)]
    problem.water_mass[5] = RHO * problem.max_volume[5]  # more water than room
    with pytest.raises(NewtonError, match=r"cell 5: no feasible volume .*water mass"):
        solve_pressure_volume(problem, MATERIAL, SETTINGS, problem.reference_volume.copy())


def test_free_pellet_swells_as_eq_4_28():
    """A pellet wetted step by step from 132 to 1 MPa (its water at each step that of the
    free-swelling state) follows V0 (1 + eps(s)) and r0 (1 + eps)^(1/3) (Eqs. 4.28-4.30)."""
    r0 = 5.99e-3
    v0 = 4.0 / 3.0 * np.pi * r0**3
    solid = 0.75 * v0
    previous = np.array([v0])
    for s in np.geomspace(1.3e8, 1e6, 40):
        eps = swelling(s)
        volume = v0 * (1.0 + eps)
        water = RHO * van_genuchten(s, 1.0 - solid / volume) * (volume - solid)
        problem = PVProblem(np.array([water]), np.array([solid]), np.array([v0]),
                            np.array([10 * v0]), RHO, S_MAX)
        got, pressure, _, _ = solve_pressure_volume(problem, MATERIAL, SETTINGS, previous)
        # the radius follows Eqs. 4.28-4.30 at the suction the pellet takes (the
        # retention curve's porosity dependence allows more than one such suction
        # for one water mass)
        reached = swelling(-pressure[0])
        assert np.cbrt(3 * got[0] / (4 * np.pi)) == pytest.approx(r0 * (1 + reached) ** (1 / 3), rel=1e-3)
        previous = got
    assert -pressure[0] == pytest.approx(1e6, rel=1e-2)
    assert np.cbrt(3 * got[0] / (4 * np.pi)) == pytest.approx(r0 * (1 + swelling(1e6)) ** (1 / 3), rel=1e-3)
