"""Confinement-limited swelling and the invariants of the macro model.

The pressure-volume kernel against the confined swelling law (macro.laws; the law itself
is tested in test_laws.py), and a small column's water and volume
balances and dry density against their definitions.
"""

from __future__ import annotations

import numpy as np
import pytest

from macro.laws import confined_pressure, confined_volume
from macro.newton import NewtonSettings, PVProblem, solve_pressure_volume
from macro.run import CaseOutputs, build_model, run
from shared.upscaling import PermeabilityTable
from tests._macro_cases import small_config, swelling
from tests.macro._material import CONFIG, MATERIAL, PHI0, pellet

NEWTON = NewtonSettings(tolerance=1e-8, max_iterations=80, barrier_start=0.1, barrier_decay=0.3,
                        relaxation_start=0.5, derivative_step=1e-7)


def _solve(suction: float, stress: float) -> tuple[float, float, float, float]:
    """The kernel's (V, s) of a pellet whose water is that of the law's state at
    ``suction`` under ``stress``; also the law's volume."""
    v0, vs, ms = pellet(suction)
    volume = float(confined_volume(suction, stress, ms, v0, PHI0, MATERIAL))
    zeta, lam = MATERIAL.retention_pressure_reference, MATERIAL.retention_exponent_reference
    sat = (1.0 + (suction / zeta) ** (1.0 / (1.0 - lam))) ** -lam
    water = 1000.0 * sat * (volume - vs)
    problem = PVProblem(np.array([water]), np.array([vs]), np.array([v0]), np.array([10.0 * v0]),
                        1000.0, 1.38e8, None, np.array([PHI0]), np.array([stress]), np.array([ms]))
    v, p, _, _ = solve_pressure_volume(problem, MATERIAL, NEWTON, np.array([v0]), np.array([1.3e8]))
    return float(v[0]), float(-p[0]), volume, v0


@pytest.mark.parametrize("suction", [1e6, 3e7])
def test_free_pellet_reaches_the_free_swelling_of_eq_4_28(suction):
    volume, found, _, v0 = _solve(suction, 0.0)
    assert found == pytest.approx(suction, rel=1e-3)
    assert volume / v0 - 1.0 == pytest.approx(swelling(suction), rel=1e-2)


@pytest.mark.parametrize("stress", [2e6, 8e6])
def test_pressure_volume_kernel_balances_the_swelling_pressure_against_the_stress(stress):
    """The numba kernel's confined target and macro.laws' are two implementations."""
    volume, found, law_volume, v0 = _solve(2e6, stress)
    _, _, ms = pellet(2e6)
    assert volume == pytest.approx(law_volume, rel=1e-4)
    assert confined_pressure(volume, found, ms, v0, PHI0, MATERIAL) == pytest.approx(stress, rel=1e-2)


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    table = tmp_path_factory.mktemp("table") / "table.nc"
    from tests._macro_cases import write_table

    write_table(table)
    config = small_config()
    config["macro"]["numerics"].update(max_steps=60, stop_tolerance=0.0)
    return run(config, "small", table, CaseOutputs(tmp_path_factory.mktemp("run") / "small.nc")), table


def test_water_is_conserved_at_every_record(small_run):
    ds, _ = small_run
    total = ds["water_pellets"] + ds["water_powder"] + ds["water_held"]
    assert float(ds.attrs["boundary_inflow_kg"]) > 0.0
    assert np.all(np.abs(ds["water_residual"].values) <= 1e-9 * total.values)


def test_solids_and_water_fit_the_container_at_every_record(small_run):
    ds, _ = small_run
    assert np.all(ds["solid_water_fraction"].values < 1.0)
    assert np.all(ds["occupied_fraction"].values < 1.0)


def test_mixture_holds_its_target_dry_density(small_run):
    ds, _ = small_run
    target = CONFIG["macro"]["mixture"]["dry_density_kg_m3"]
    assert ds.attrs["dry_density_initial_kg_m3"] == pytest.approx(target, rel=1e-9)
    # the dry mass stays (remeshes move powder between cells, conserving it)
    np.testing.assert_allclose(ds["dry_density"].values, target, rtol=1e-9)


def test_closed_column_keeps_its_water(small_run, monkeypatch):
    """No held cells: nothing enters, the water stays to round-off."""
    import macro.geometry

    _, table = small_run
    monkeypatch.setattr(macro.geometry, "end_cells", lambda mesh, on_plate: np.zeros(mesh.n_cells, dtype=bool))
    config = small_config()
    model = build_model(config, "small", PermeabilityTable.from_file(table, "free"))
    assert not model.held.any()
    before = model.water_mass.sum()
    for _ in range(10):
        model.step()
    assert model.boundary_inflow == 0.0
    assert model.water_mass.sum() == pytest.approx(before, rel=1e-12)


def test_first_passages_are_the_first_records_above_half_a_megapascal(tmp_path_factory):
    """The passage times, tracked at every step, against the records kept at every step
    (records = max_steps + 1: none thinned or dropped)."""
    from tests._macro_cases import write_table

    table = write_table(tmp_path_factory.mktemp("table") / "table.nc")
    config = small_config()
    config["macro"]["numerics"].update(max_steps=40, records=41, stop_tolerance=0.0)
    ds = run(config, "small", table, CaseOutputs(tmp_path_factory.mktemp("run") / "small.nc"))
    readings = np.column_stack([ds["sensor_pressure"].values, ds["axial_pressure_upper"].values,
                                ds["axial_pressure_lower"].values])
    passages = np.concatenate([ds["sensor_passage_time"].values, ds["axial_passage_time"].values])
    assert ds.sizes["time"] == 41
    for column, passage in zip(readings.T, passages, strict=True):
        above = np.flatnonzero(column >= 5e5)
        expected = ds["time"].values[above[0]] if above.size else np.nan
        np.testing.assert_equal(passage, expected)
    assert np.isfinite(passages).any()


def test_a_compressed_pellet_is_wetter_than_the_water_it_took_in():
    """The mechanism that puts pellets below the boundary suction: a pellet that took in
    its water at 1 MPa without stress (free, V_f(1 MPa)), then confined by 5 MPa with the
    same water, is compressed until its water fills its pores (V = V_s + m_w / rho, by
    hand): saturated, at a suction near zero (the pore water would be pressed; it leaves by
    transport in the next steps), and still larger than the confined volume at that
    suction, which it cannot reach without draining."""
    v0, vs, ms = pellet(1e6)
    free = v0 * (1.0 + swelling(1e6))
    zeta, lam = MATERIAL.retention_pressure_reference, MATERIAL.retention_exponent_reference
    sat = (1.0 + (1e6 / zeta) ** (1.0 / (1.0 - lam))) ** -lam
    water = 1000.0 * sat * (free - vs)
    problem = PVProblem(np.array([water]), np.array([vs]), np.array([v0]), np.array([10.0 * v0]),
                        1000.0, 1.38e8, None, np.array([PHI0]), np.array([5e6]), np.array([ms]))
    v, p, _, _ = solve_pressure_volume(problem, MATERIAL, NEWTON, np.array([free]), np.array([1e6]))
    volume, suction = float(v[0]), float(-p[0])
    assert volume == pytest.approx(vs + water / 1000.0, rel=1e-5)
    assert volume < free
    assert suction < 1e3
    assert volume > float(confined_volume(suction, 5e6, ms, v0, PHI0, MATERIAL))


def test_records_balance_and_cells_hold_their_powder_after_the_first_steps(small_run):
    """The quasi-static balance (issue: at least 95 % of the records at 0.01): every
    record, the initial one included, is balanced at the default tolerance, per pellet
    and for the pellets' net resultant. (Before the packing was balanced ahead of the
    hydration and the powder's onset was regularised, the first seven were not: mean
    ratios of 0.016-0.024 as the loose packing settled, net ones of 0.26 and 0.03 when
    the pellets first touched the plates.) No cell is capped, and no cell's powder
    exceeds its void by more than half at a record (48 times it before the push
    stiffened as drained)."""
    ds, _ = small_run
    ratio = np.maximum(ds["unbalanced_force"], ds["net_unbalanced_force"]).values
    tolerance = CONFIG["macro"]["numerics"]["dem_balance_tolerance"]
    assert np.all(ratio < tolerance)
    np.testing.assert_array_equal(ds["balanced"].values, ratio < tolerance)
    assert ds.attrs["capped_cell_steps"] == 0
    assert ds["largest_overfill"].max() < 0.5


def test_records_count_the_steps_and_remeshes_as_the_run_does(small_run):
    """The records' step and remesh count, kept per step, end at the run's own counters
    (the attributes) and never decrease."""
    ds, _ = small_run
    step, remeshes = ds["step"].values, ds["remesh_count"].values
    assert step[0] == 0 and step[-1] == ds.attrs["steps"] and np.all(np.diff(step) > 0)
    assert remeshes[-1] == ds.attrs["remeshes"] and np.all(np.diff(remeshes) >= 0)
