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

from macro.extrusion import mobility
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
