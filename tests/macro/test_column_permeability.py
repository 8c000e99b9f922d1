"""The column's permeability: exact series and parallel means on a lattice, a uniform
medium on the model's network, conservation, scaling, Wiener bounds, no side effects,
and its records."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

import macro.hydraulics
from macro.column_permeability import column_permeability, network_permeability
from macro.run import build_model, simulate
from shared.upscaling import PermeabilityTable
from tests._macro_cases import small_config, write_table

DENSITY, VISCOSITY = 1000.0, 1.0e-3


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    return PermeabilityTable.from_file(write_table(tmp_path_factory.mktemp("table") / "table.nc"), "free")


@pytest.fixture(scope="module")
def model(table):
    return build_model(small_config(), "small", table)


def _lattice(shape, spacing):
    """Nodes at the centres of a box of cubes (x fastest), their neighbour pairs and axes."""
    nx, ny, nz = shape
    index = np.arange(nx * ny * nz).reshape(nz, ny, nx)
    pairs, axis = [], []
    for a, (lo, hi) in enumerate([(index[:, :, :-1], index[:, :, 1:]), (index[:, :-1], index[:, 1:]),
                                  (index[:-1], index[1:])]):
        pairs.append(np.column_stack([lo.ravel(), hi.ravel()]))
        axis.append(np.full(lo.size, a))
    z = (np.arange(nz) + 0.5) * spacing - 0.5 * nz * spacing
    position = np.repeat(z, nx * ny)
    return np.concatenate(pairs), np.concatenate(axis), position


def _lattice_permeability(shape, spacing, permeability):
    """network_permeability of a lattice whose exchange e has the permeability
    ``permeability[e]`` (two-point conductance rho k h^2 / (mu h))."""
    pairs, _, position = _lattice(shape, spacing)
    nx, ny, nz = shape
    conductance = DENSITY * permeability * spacing / VISCOSITY
    return network_permeability(pairs, conductance, position, np.ones(position.size, dtype=bool),
                                nz * spacing, nx * ny * spacing**2, spacing, -1.0e6, 1.0e5,
                                DENSITY, VISCOSITY)


def test_layers_in_series_give_the_harmonic_mean_of_the_exchanges():
    """Layers normal to the axis: the Dirichlet rows are the end rows of nodes, so the
    column is the nz - 1 exchanges in series between them, k = (nz - 1) / sum(1 / k_e)
    exactly (the layer's linear profile at the end rows drops dp (H - h) / H)."""
    shape, h = (3, 4, 6), 1e-3
    pairs, axis, position = _lattice(shape, h)
    layer_k = np.array([1e-18, 5e-20, 3e-19, 2e-18, 7e-19])  # between rows 0-1, ..., 4-5
    row = np.round((position[pairs[:, 0]] + 0.5 * shape[2] * h) / h - 0.5).astype(int)
    k = np.full(len(pairs), 1e-18)  # transverse exchanges carry nothing
    k[axis == 2] = layer_k[row[axis == 2]]
    flow = _lattice_permeability(shape, h, k)
    assert flow.permeability == pytest.approx(5.0 / np.sum(1.0 / layer_k), rel=1e-10, abs=0.0)
    assert flow.inflow == pytest.approx(flow.outflow, rel=1e-12, abs=0.0)


def test_columns_in_parallel_give_the_arithmetic_mean():
    """Each column of nodes along the axis at its own k: every column carries its linear
    profile (no transverse flux), k is the area-weighted arithmetic mean exactly."""
    shape, h = (4, 3, 5), 2e-3
    pairs, axis, _ = _lattice(shape, h)
    column_k = np.random.default_rng(3).uniform(1e-20, 1e-18, shape[0] * shape[1])
    k = np.where(axis == 2, column_k[pairs[:, 0] % (shape[0] * shape[1])], 1e-19)
    flow = _lattice_permeability(shape, h, k)
    assert flow.permeability == pytest.approx(column_k.mean(), rel=1e-10, abs=0.0)
    # the discrete maximum principle: every pressure between the plates' values
    assert np.all((flow.pressure >= -1.0e6 - 0.5e5) & (flow.pressure <= -1.0e6 + 0.5e5))


def _uniform(monkeypatch, model, k):
    """Every pellet and every powder cell (and so every exchange) at permeability k."""
    def same(values, *_, **__):
        return np.full(np.shape(values), k)

    monkeypatch.setattr(model.table, "permeability", same)
    monkeypatch.setattr(macro.hydraulics, "powder_permeability", same)


def test_uniform_medium_on_the_network(model, monkeypatch):
    """Every system at k: the column's k comes back within 25 %. The network's two-point
    fluxes on the Delaunay cells are not consistent (centroids, pellets conducting beside
    the powder): +19 % on this column, +14 % on the default mock-up. Doubling every k
    doubles the column's to round-off; inflow equals outflow to 1e-10."""
    _uniform(monkeypatch, model, 1e-18)
    flow = column_permeability(model)
    assert flow.permeability == pytest.approx(1e-18, rel=0.25, abs=0.0)
    assert flow.inflow == pytest.approx(flow.outflow, rel=1e-10, abs=0.0)
    _uniform(monkeypatch, model, 2e-18)
    assert column_permeability(model).permeability == pytest.approx(2.0 * flow.permeability, rel=1e-12, abs=0.0)


def test_flux_balance_and_definition_in_the_models_state(model):
    """The model's own conductances (four decades): inflow equals outflow to 1e-10, k is
    mu Q L / (rho A dp) with dp a tenth of the volume-weighted mean suction, and every
    pressure lies between the plates' (discrete maximum principle)."""
    flow = column_permeability(model)
    s = model.settings
    active = ~model.inert
    suction = np.average(-model.pressure[active], weights=model.volume[active])
    assert flow.drop == pytest.approx(0.1 * suction, rel=1e-12)
    assert flow.inflow > 0.0
    assert flow.inflow == pytest.approx(flow.outflow, rel=1e-10, abs=0.0)
    area = np.pi * s.radius**2
    assert flow.permeability == pytest.approx(
        s.viscosity * flow.inflow * s.height / (s.density * area * flow.drop), rel=1e-10, abs=0.0)
    solved = flow.pressure[np.isfinite(flow.pressure)]
    assert solved.size > 0.9 * np.count_nonzero(active)
    assert np.all((solved >= -suction - 0.5 * flow.drop) & (solved <= -suction + 0.5 * flow.drop))


def test_column_lies_within_the_wiener_bounds(model):
    """The column's k lies between the volume-weighted harmonic and arithmetic means of
    the active systems' permeabilities (series and parallel bounds)."""
    active = ~model.inert
    k = model.permeabilities()[active]
    volume = model.volume[active]
    harmonic = 1.0 / np.average(1.0 / k, weights=volume)
    arithmetic = np.average(k, weights=volume)
    assert harmonic < column_permeability(model).permeability < arithmetic


def _same(before, after, where="model"):
    """Assert two states equal field by field (arrays exactly, NaN equal to NaN)."""
    if isinstance(before, np.ndarray):
        np.testing.assert_array_equal(after, before, err_msg=where)
    elif dataclasses.is_dataclass(before) or isinstance(before, dict):
        items = vars(before) if dataclasses.is_dataclass(before) else before
        other = vars(after) if dataclasses.is_dataclass(after) else after
        assert set(items) == set(other), where
        for key, value in items.items():
            _same(value, other[key], f"{where}.{key}")
    else:
        assert after == before, where


def test_measurement_leaves_the_model_as_it_was(model):
    """Every field of the model (arrays, mesh, exchanges, counters, time, the table's
    look-up counters) is unchanged after a measurement."""
    table = model.table
    counters = (table.looked_up, table.clamped)
    state = {k: copy.deepcopy(v) for k, v in vars(model).items() if k != "table"}
    column_permeability(model)
    assert (table.looked_up, table.clamped) == counters
    _same(state, {k: v for k, v in vars(model).items() if k != "table"})


def test_records_on_their_own_time_coordinate(table):
    """Measured at the start, when the run first passes a listed time, and at the end;
    a run measured in between has the same records as one that is not, and its last
    value is the end state's."""
    config = small_config()
    config["macro"]["numerics"].update(max_steps=4, stop_tolerance=0.0)
    plain, _ = simulate(build_model(config, "small", table))  # the default times lie beyond
    times = plain["time"].values
    np.testing.assert_array_equal(plain["permeability_time"].values, times[[0, 4]])
    config["macro"]["column_permeability_times_s"] = [0.5 * (times[1] + times[2]), 1e9]
    model = build_model(config, "small", table)
    ds, _ = simulate(model)
    assert ds["column_permeability"].dims == ("permeability_time",)
    np.testing.assert_array_equal(ds["permeability_time"].values, times[[0, 2, 4]])
    np.testing.assert_array_equal(ds["column_permeability"].values[[0, 2]],
                                  plain["column_permeability"].values)
    assert ds["column_permeability"].values[-1] == column_permeability(model).permeability
    for name in ("sensor_pressure", "mean_suction", "swelling_profile", "time_step"):
        np.testing.assert_array_equal(ds[name].values, plain[name].values, err_msg=name)
