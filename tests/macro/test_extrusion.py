"""macro.extrusion: the powder as a conserved, mobile solid.

The implicit step against the explicit fluxes q = M A / L (P_i - P_j) it tends to for a
short step, conservation of solid, water and V_0 counted from the systems' states, dry
clay that does not move, the dry-density spread of a hydrating column falling faster
with extrusion than without, and the overflow of a squeezed cell.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from macro.extrusion import OVERFLOW_MARGIN, mobility
from macro.model import MacroModel
from macro.run import build_model
from shared.upscaling import PermeabilityTable
from tests._macro_cases import small_config


def _wetted(table_path, steps: int, **macro) -> MacroModel:
    model = build_model(small_config(**macro), "small", PermeabilityTable.from_file(table_path, "free"))
    for _ in range(steps):
        model.step()
    return model


def _totals(model: MacroModel) -> np.ndarray:
    active = ~model.inert
    return np.array([model.solid_volume[active].sum(), model.water_mass[active].sum(),
                     model.reference_volume[active].sum()])


@pytest.fixture(scope="module")
def wetted(tmp_path_factory):
    from tests._macro_cases import write_table

    table = write_table(tmp_path_factory.mktemp("table") / "table.nc")
    return table, _wetted(table, 30)


def test_mobility_ramps_from_the_granular_threshold_to_saturation(wetted):
    settings = wetted[1].settings.extrusion
    s_c = settings.mobile_saturation
    values = mobility([0.0, s_c, 0.5 * (1.0 + s_c), 1.0], settings)
    np.testing.assert_allclose(values, [0.0, 0.0, 0.5 * settings.mobility, settings.mobility], rtol=1e-12)


def test_short_step_moves_the_explicit_fluxes_and_conserves_solid_water_and_reference_volume(wetted):
    """For dt -> 0 the backward-Euler step is the explicit one: each cell's solid change
    is dt sum_j M_donor A / L (P_j - P_i), computed here from the exchanges by hand."""
    _, model = wetted
    model = dataclasses.replace(model)
    for name in ("solid_volume", "water_mass", "reference_volume", "volume", "max_volume"):
        setattr(model, name, getattr(model, name).copy())
    model.counters = dataclasses.replace(model.counters)
    before, solid = _totals(model), model.solid_volume.copy()
    pressure = model.extrusion_pressure()
    ex = model.cells.exchanges
    n_p = model.n_pellets
    pairs, kind = ex.pairs[ex.kind > 0], ex.kind[ex.kind > 0]
    i, j = pairs[:, 0], pairs[:, 1]
    donor = np.where(pressure[i] >= pressure[j], i, j)
    g = mobility(model.saturations(), model.settings.extrusion)[donor] * (ex.area / ex.length)[ex.kind > 0]
    g = np.where((kind == 2) | (pressure[i] > pressure[j]), g, 0.0)
    flux = g * (pressure[j] - pressure[i])
    expected = np.bincount(i, flux, minlength=solid.size) - np.bincount(j, flux, minlength=solid.size)
    assert np.abs(expected[n_p:]).max() > 0.0
    dt = 1e-3
    model.extrude(dt)
    change = (model.solid_volume - solid) / dt
    moving = np.abs(expected) > 1e-3 * np.abs(expected).max()
    np.testing.assert_allclose(change[moving], expected[moving], rtol=1e-3)
    np.testing.assert_allclose(_totals(model), before, rtol=1e-12)
    # pellets only give
    assert np.all(change[:n_p] <= 0.0)


def test_dry_clay_does_not_move(table_path):
    """Below the mobile saturation no clay flows (the ends held dry too): every state is
    unchanged."""
    model = build_model(small_config(boundary_suction_pa=1e8), "small",
                        PermeabilityTable.from_file(table_path, "free"))
    assert model.saturations()[~model.inert].max() < model.settings.extrusion.mobile_saturation
    solid = model.solid_volume.copy()
    model.extrude(3600.0)
    np.testing.assert_array_equal(model.solid_volume, solid)


@pytest.mark.parametrize("homogenisation", ["extrusion", "none"])
def test_hydrating_column_homogenises_by_extrusion_only(table_path, homogenisation):
    """The dry-density spread after 120 steps (4.7 days), relative to the start:
    extrusion spreads the clay into the looser cells (0.14 measured); without it the
    spread falls only by the pellets' swelling and levels off (0.55). The solid is
    conserved either way (from the states)."""
    model = build_model(small_config(homogenisation=homogenisation), "small",
                        PermeabilityTable.from_file(table_path, "free"))
    start, solid = model.dry_density_spread(), _totals(model)[0]
    for _ in range(120):
        model.step()
    assert _totals(model)[0] == pytest.approx(solid, rel=1e-12)
    ratio = model.dry_density_spread() / start
    if homogenisation == "extrusion":
        assert model.counters.extruded_volume_m3 > 0.0
        assert ratio < 0.25
    else:
        assert model.counters.extruded_volume_m3 == 0.0
        assert ratio > 0.45


def test_overflow_returns_a_squeezed_cell_within_its_void(wetted):
    """A cell whose void is set below its densest clay hands the excess to its
    neighbours: it ends within its void, and solid, water and V_0 are conserved."""
    _, model = wetted
    model = dataclasses.replace(model)
    for name in ("solid_volume", "water_mass", "reference_volume", "volume"):
        setattr(model, name, getattr(model, name).copy())
    model.cells = dataclasses.replace(model.cells, voids=model.cells.voids.copy())
    model.counters = dataclasses.replace(model.counters)
    n_p = model.n_pellets
    cell = int(np.flatnonzero(~model.inert[n_p:] & ~model.held[n_p:])[0])
    densest = float(model.densest_volume(np.array([n_p + cell]))[0])
    model.cells.voids[cell] = 0.5 * densest
    before = _totals(model)
    model.overflow()
    assert model.densest_volume(np.array([n_p + cell]))[0] <= model.cells.voids[cell] * (1.0 + 1e-9)
    np.testing.assert_allclose(_totals(model), before, rtol=1e-12)
    assert model.counters.overflowed_cell_steps > 0


def _squeezable(model: MacroModel) -> MacroModel:
    """A copy of ``model`` whose state and voids the test may change."""
    model = dataclasses.replace(model)
    for name in ("solid_volume", "water_mass", "reference_volume", "volume"):
        setattr(model, name, getattr(model, name).copy())
    model.cells = dataclasses.replace(model.cells, voids=model.cells.voids.copy())
    model.counters = dataclasses.replace(model.counters)
    return model


def test_overflow_routes_the_excess_past_full_neighbours_to_the_nearest_room(wetted):
    """A squeezed cell whose face neighbours are all full (void = their densest clay)
    hands its excess on to cells two face steps away or more: it ends within its void,
    its neighbours stay within theirs, and solid, water and V_0 are conserved."""
    model = _squeezable(wetted[1])
    n_p = model.n_pellets
    interior = ~model.inert[n_p:] & ~model.held[n_p:]
    neighbours = model.mesh.neighbours
    cell = next(int(c) for c in np.flatnonzero(interior)
                if (neighbours[c] >= 0).all() and interior[neighbours[c]].all())
    around = neighbours[cell]
    model.cells.voids[around] = model.densest_volume(n_p + around)
    model.cells.voids[cell] = 0.5 * float(model.densest_volume(np.array([n_p + cell]))[0])
    before, far = _totals(model), model.solid_volume[n_p:].copy()
    model.overflow()
    for c in (cell, *around):
        assert model.densest_volume(np.array([n_p + c]))[0] <= model.cells.voids[c] * (1.0 + 1e-9)
    np.testing.assert_allclose(_totals(model), before, rtol=1e-12)
    gained = np.flatnonzero(model.solid_volume[n_p:] > far * (1.0 + 1e-12))
    assert gained.size > 0 and not np.isin(gained, [cell, *around]).any()


def test_overflow_drains_a_held_cells_water_beyond_its_pore_space_through_the_boundary(wetted):
    """A held cell holding more water than its pore space gives the excess to the water
    supply, not to the interior: it ends with its pore space full (less the overflow's
    margin), and the interior's
    water and the boundary inflow end as they do without that excess."""
    plain, model = _squeezable(wetted[1]), _squeezable(wetted[1])
    n_p = model.n_pellets
    held = int(np.flatnonzero(model.held[n_p:] & ~model.inert[n_p:])[0])
    pore = model.cells.voids[held] / (1.0 + OVERFLOW_MARGIN) - model.solid_volume[n_p + held]
    model.water_mass[n_p + held] = 1.5 * model.settings.density * pore
    plain.overflow()
    model.overflow()
    assert model.water_mass[n_p + held] == pytest.approx(model.settings.density * pore, rel=1e-12)
    assert model.interior_water() == pytest.approx(plain.interior_water(), rel=1e-12)
    assert model.boundary_inflow == pytest.approx(plain.boundary_inflow, rel=1e-12, abs=1e-18)
