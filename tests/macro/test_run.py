"""The macro stage end to end on a small column: contract, symmetry, trends, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

from macro.laws import mixture_parameters
from macro.model import MacroModel
from macro.packing import Packing, pack_cylinder
from macro.run import CaseOutputs, build_model, case_parameters, mock_up, run
from macro.settings import macro_settings
from shared.io import OutputError, write_dataset
from shared.provenance import file_sha256
from shared.upscaling import PermeabilityTable
from tests._figures import check_figure, kept_figures  # noqa: F401
from tests._macro_cases import small_config, swelling, synthetic_table, write_table


def test_run_writes_the_contract(tmp_path, table_path, kept_figures):  # noqa: F811
    config = small_config()
    config["macro"]["numerics"]["max_steps"] = 4
    out = tmp_path / "small.nc"
    run(config, "small", table_path, CaseOutputs(out, tmp_path / "small.png"))
    ds = xr.load_dataset(out)
    assert ds["sensor_pressure"].dims == ("time", "sensor")
    assert list(ds["sensor"].values) == ["S10", "S25", "S40"]
    np.testing.assert_allclose(ds["sensor_height"].values, [0.01, 0.025, 0.04])
    assert ds["band_pressure"].dims == ("time", "band")
    assert ds.sizes["band"] == config["macro"]["sensor_bands"]
    np.testing.assert_allclose(ds["band_height"].values, [0.005, 0.015, 0.025, 0.035, 0.045])
    for name in ("axial_pressure_upper", "axial_pressure_lower", "mean_suction", "mean_saturation",
                 "swelling_profile", "stop_distance"):
        assert name in ds.variables
    # four steps leave too few records for a trend
    assert np.isnan(ds["stop_distance"].values).all()
    assert ds.sizes["time"] == 5 and list(ds["material"].values) == ["pellet", "powder"]
    inputs = json.loads(ds.attrs["inputs"])
    assert file_sha256(table_path) in json.dumps(inputs)
    assert ds.attrs["table_lookups"] > 0 and "table_clamped_lookups" in ds.attrs
    assert 0.4 < ds.attrs["packing_fraction"] < 0.6
    assert (tmp_path / "small.png").stat().st_size > 0
    assert {"time [d]", "pressure [MPa]", "height above the lower plate [cm]"} <= check_figure(kept_figures[-1])


def test_mock_up_in_memory_equals_what_run_writes(tmp_path, table_path, monkeypatch):
    """The library function reads and writes no file, and its records are the file's,
    bit for bit (the run's snapshots and output are its only additions)."""
    config = small_config()
    config["macro"]["numerics"]["max_steps"] = 3
    config["macro"]["vtk_snapshots"] = 0
    settings, material = case_parameters(config, "small")
    table = PermeabilityTable.from_file(table_path, settings.table_condition)
    written = tmp_path / "written"
    written.mkdir()
    run(config, "small", table_path, CaseOutputs(written / "small.nc"))
    monkeypatch.chdir(tmp_path)
    before = sorted(tmp_path.rglob("*"))
    ds = mock_up(table, settings, material)
    assert sorted(tmp_path.rglob("*")) == before
    on_file = xr.load_dataset(written / "small.nc")
    assert set(ds.data_vars) == set(on_file.data_vars)
    for name in ds.data_vars:
        np.testing.assert_array_equal(ds[name].values, on_file[name].values, err_msg=name)
    assert ds.attrs["stop_reason"] == on_file.attrs["stop_reason"] == "max_steps"


def _mirrored_model(table_path):
    """A column whose lower half is a packing and whose upper half its mirror image
    (jittered by 1e-3 r so that Delaunay has no cospherical sets), homogeneous powder."""
    config = small_config(cases={"small": {"heterogeneity": "homogeneous", "powder_pressure_on_walls": True}})
    settings = macro_settings(config["macro"], "small")
    material = mixture_parameters(config["materials"], settings.powder)
    half = pack_cylinder(settings.height / 2, settings.radius, settings.pellet_radius,
                         settings.packing_fraction, np.random.default_rng(0), settings.packing_sweeps)
    lower = half.positions - [0.0, 0.0, settings.height / 4]
    positions = np.vstack([lower, lower * [1.0, 1.0, -1.0]])
    positions += np.random.default_rng(1).normal(0.0, 1e-3 * settings.pellet_radius, positions.shape)
    packing = Packing(positions, np.full(len(positions), settings.pellet_radius),
                      half.packing_fraction, half.largest_overlap)
    return MacroModel.create(settings, material, PermeabilityTable.from_file(table_path, "free"), packing)


def _half_water(model: MacroModel) -> np.ndarray:
    """Water of the free systems (pellets and active cells not held) whose centre lies
    below and above mid-height [kg]."""
    z = np.concatenate([model.positions[:, 2], model.mesh.centroids[:, 2]])
    free = ~model.held & ~model.inert
    return np.array([model.water_mass[free & (z < 0.0)].sum(), model.water_mass[free & (z > 0.0)].sum()])


def test_column_loaded_from_both_ends_is_mirror_symmetric(table_path):
    """Hydraulics: the suction profile is its own mirror image within 10 % of s0 (the
    mesh of the jittered mirror packing is not symmetric: its held and inert cells
    differ between the ends; about 7 % measured at the steepest bin), and the two halves
    gain the same water from their ends within 10 % (their states' sums; 4.7 %
    measured). Mechanics: the two plates carry the same pressure within a factor 2. The
    powder pushes on the container too: early on, the wetted powder of the end cells
    pushes the pellets off the plates, which then carry only that push."""
    model = _mirrored_model(table_path)
    edges = np.linspace(-0.5 * model.settings.height, 0.5 * model.settings.height, 11)
    start = _half_water(model)
    upper, lower = [], []
    while model.time < 3000.0:
        model.step(max_dt=3000.0 - model.time)
        upper.append(model.readings.axial_upper)
        lower.append(model.readings.axial_lower)
    _, suction = model.profiles(edges)
    s0 = model.material.initial_suction
    assert np.abs(suction - suction[::-1]).max() < 0.1 * s0
    assert suction[:2].min() < 0.9 * s0  # the ends did hydrate, the middle not yet
    assert suction[4:6].min() > 0.95 * s0
    assert 0.5 < np.mean(upper) / np.mean(lower) < 2.0
    lower_gain, upper_gain = _half_water(model) - start
    assert lower_gain > 0.0 and upper_gain == pytest.approx(lower_gain, rel=0.1)


def test_larger_pellet_permeability_gives_a_faster_pressure_rise(tmp_path):
    """Same column, pellet permeability table x10: over the same 400 s the pellets are
    wetter and the mean wall pressure is higher."""
    results = {}
    for scale in (1.0, 10.0):
        table = write_table(tmp_path / f"table_{scale}.nc", scale)
        config = small_config()
        config["macro"]["numerics"].update(max_time_s=400.0, max_steps=2000, stop_tolerance=0.0)
        ds = run(config, "small", table, CaseOutputs(tmp_path / f"run_{scale}.nc"))
        assert ds["time"].values[-1] == pytest.approx(400.0)
        wall = ds["sensor_pressure"].mean("sensor") + ds["axial_pressure_upper"]
        results[scale] = (float(ds["mean_suction"].sel(material="pellet")[-1]), float(wall.mean()))
    assert results[10.0][0] < results[1.0][0]
    assert results[10.0][1] > results[1.0][1]


def test_missing_or_malformed_table_is_named(tmp_path):
    config = small_config()
    with pytest.raises(OutputError, match="nowhere.nc: no such file"):
        run(config, "small", tmp_path / "nowhere.nc", CaseOutputs(tmp_path / "out.nc"))
    broken = synthetic_table().drop_vars("k_tensor")
    path = tmp_path / "broken.nc"
    broken.to_netcdf(path)
    with pytest.raises(OutputError, match="broken.nc: missing variable"):
        run(config, "small", path, CaseOutputs(tmp_path / "out.nc"))
    assert not (tmp_path / "out.nc").exists()


def test_pellets_larger_than_the_container_are_named(table_path, tmp_path):
    config = small_config(pellet_radius_m=0.02)
    with pytest.raises(ValueError, match="macro.pellet_radius_m = 0.02 m: a pellet of that radius does not fit"):
        run(config, "small", table_path, CaseOutputs(tmp_path / "out.nc"))


def test_unknown_case_is_named(table_path, tmp_path):
    with pytest.raises(KeyError, match="macro.cases has no case 'nope'"):
        run(small_config(), "nope", table_path, CaseOutputs(tmp_path / "out.nc"))


def test_powder_presses_eq_4_31_at_its_dry_density_once_it_fills_its_void(table_path):
    """Eqs. 4.31-4.33 as read in MacroModel.powder_pressure: a cell whose free swelling
    volume V_0 (1 + eps(s)) stays inside its void presses with nothing; wetted past the
    confinement it presses S_w beta_v exp(alpha_v m_s / V_c) (S_w of Table 4.2's
    retention curve at the cell's suction), reached linearly over the onset strain
    (min(1, (V_f - V_c) / (0.01 V_f))), written out here, and its push only grows as it
    wets. The cells free in the balanced packing at the initial suction (the others are
    squeezed by the balance's pellets)."""
    config = small_config()
    model = build_model(config, "small", PermeabilityTable.from_file(table_path, "free"))
    powder = config["macro"]["powder"]
    curve = config["materials"]["mixture_powder"]
    onset = config["macro"]["numerics"]["powder_onset_strain"]
    n_p = model.n_pellets
    cells = np.flatnonzero(~model.inert[n_p:] & ~model.held[n_p:])
    free_volume = model.reference_volume[n_p + cells] * (1 + swelling(-model.pressure[n_p + cells]))
    cells = cells[free_volume < model.max_volume[n_p + cells]]
    assert cells.size > 0.5 * (~model.inert[n_p:] & ~model.held[n_p:]).sum()
    assert np.all(model.powder_pressure()[0][cells] == 0.0)
    void = model.max_volume[n_p + cells]
    solid_mass = powder["grain_density_kg_m3"] * model.solid_volume[n_p + cells]
    pushes = []
    for suction in np.geomspace(1.3e8, 1e6, 30):
        model.pressure[n_p + cells] = -suction
        push = model.powder_pressure()[0][cells]
        pushes.append(push)
        sat = (1.0 + (suction / curve["retention_pressure_reference_pa"])
               ** (1.0 / (1.0 - curve["retention_exponent_reference"]))) ** -curve["retention_exponent_reference"]
        free = model.reference_volume[n_p + cells] * (1 + swelling(suction))
        line = sat * powder["swelling_beta_v_pa"] * np.exp(powder["swelling_alpha_v_m3_per_kg"] * solid_mass / void) \
            * np.minimum(1.0, (free - void) / (onset * free))
        confined = free > void
        np.testing.assert_allclose(push[confined], line[confined], rtol=1e-9)
        assert np.all(push[~confined] == 0.0)
    pushes = np.array(pushes)
    assert pushes[-1].max() > 0.0
    assert np.all(np.diff(pushes, axis=0) >= 0.0)


def test_powder_push_is_bounded_by_the_pellets_yield_pressure(table_path):
    """Pellets and powder wetted to 1 MPa: every cell with a pellet pushes at most the mean
    contact pressure at which its weakest pellet yields against a flat, written out here
    from Eqs. 4.3-4.4 (F_y = 3 (1 - 2 nu) B exp(alpha s) / beta, a_y^3 = 3 F_y r / (4 E*),
    p_y = F_y / (pi a_y^2)), with the yield on (an option, off by default)."""
    config = small_config()
    pellet = config["materials"]["mixture_pellet"]
    pellet["yield"] = True
    model = build_model(config, "small", PermeabilityTable.from_file(table_path, "free"))
    n_p = model.n_pellets
    model.pressure[:] = -1e6
    pushes = model.powder_pressure()[0]
    nu, alpha, beta = pellet["poisson_ratio"], pellet["swelling_alpha_per_pa"], pellet["swelling_beta_per_pa"]
    force = 3 * (1 - 2 * nu) * pellet["yield_area_m2"] * np.exp(alpha * 1e6) / beta
    young = np.clip(3 * (1 - 2 * nu) * np.exp(alpha * 1e6) / beta, *pellet["young_modulus_bounds_pa"])
    contact = (3 * force * model.radii * (1 - nu**2) / (4 * young)) ** (1 / 3)
    weakest = np.where(model.mesh.tetrahedra < n_p, (force / (np.pi * contact**2))[
        np.minimum(model.mesh.tetrahedra, n_p - 1)], np.inf).min(axis=1)
    with_pellet = np.isfinite(weakest)
    assert pushes[with_pellet].max() > 0.0
    assert np.all(pushes[with_pellet] <= weakest[with_pellet] * (1 + 1e-9))


def test_paraview_series_lists_its_snapshots(table_path, tmp_path):
    """The .pvd names every snapshot written, in time order, and each .vtu holds the
    pellets (then the container's points) as points and the cells as tetrahedra with
    their fields; every point of the container lies on its wall or plates."""
    import meshio

    config = small_config()
    config["macro"]["numerics"].update(max_steps=12, max_time_s=2000.0, stop_tolerance=0.0)
    config["macro"]["vtk_snapshots"] = 4
    ds = run(config, "small", table_path, CaseOutputs(tmp_path / "small.nc"))
    pvd = (tmp_path / "small_vtk" / "small.pvd").read_text()
    files = sorted((tmp_path / "small_vtk").glob("step_*.vtu"))
    assert 2 <= len(files) <= 5 and all(f.name in pvd for f in files)
    grid = meshio.read(files[-1])
    n_p = ds.sizes["pellet"]
    pellet = grid.point_data["is_pellet"] == 1
    assert pellet[:n_p].all() and not pellet[n_p:].any()
    assert grid.cells_dict["tetra"].shape[0] == ds.attrs["n_cells"]
    np.testing.assert_allclose(grid.point_data["radius_m"][:n_p], ds["pellet_radius_final"].values)
    macro = config["macro"]
    wall = grid.points[n_p:]
    on_side = np.isclose(np.hypot(wall[:, 0], wall[:, 1]), macro["cylinder_radius_m"], rtol=1e-9)
    on_plate = np.isclose(np.abs(wall[:, 2]), 0.5 * macro["cylinder_height_m"], rtol=1e-9)
    assert (on_side | on_plate).all()


@pytest.mark.parametrize(("spoil", "message"), [
    (lambda t: t["k"].values.__setitem__((0, 0, 0, 3), np.nan), "non-positive or NaN permeabilities"),
    (lambda t: t["k"].values.__setitem__((0, 0, 1, 2), -1e-19), "non-positive or NaN permeabilities"),
    (lambda t: t["k_tensor"].values.__setitem__((0, 0, 4, 0, 0), np.nan), "NaN in 'k_tensor'"),
    (lambda t: t.__setitem__("suction", t["suction"].values[::-1]), "strictly increasing"),
])
def test_spoiled_table_is_refused_naming_the_file(table_path, tmp_path, spoil, message):
    """NaN, non-positive k or a reversed suction axis: one error naming the file, no output."""
    table = synthetic_table()
    spoil(table)
    path = tmp_path / "spoiled.nc"
    table.to_netcdf(path)
    with pytest.raises(OutputError, match=f"spoiled.nc.*{message}"):
        run(small_config(), "small", path, CaseOutputs(tmp_path / "out.nc"))
    assert not (tmp_path / "out.nc").exists()


def test_clamped_table_lookups_are_counted(tmp_path):
    """A table covering only 1-10 MPa: the pellets at 132 MPa read beyond it, and every
    such look-up is counted in the output."""
    table = synthetic_table().isel(suction=slice(6, 9))
    assert float(table["suction"].max()) < 1.32e8
    path = tmp_path / "narrow.nc"
    write_dataset(table, path, stage="upscaling", title="narrow table")
    config = small_config()
    config["macro"]["numerics"]["max_steps"] = 3
    ds = run(config, "small", path, CaseOutputs(tmp_path / "out.nc"))
    assert ds.attrs["table_clamped_lookups"] > 0
    assert ds.attrs["table_clamped_lookups"] <= ds.attrs["table_lookups"]


def test_jammed_packing_is_refused_naming_the_keys(table_path, tmp_path):
    """A packing fraction the minimiser cannot reach in its iterations leaves pellets
    overlapping the container or each other: refused, naming the key, nothing written."""
    config = small_config()
    config["macro"]["mixture"]["packing_fraction"] = 0.58
    config["macro"]["numerics"]["packing_iterations"] = 20
    with pytest.raises(ValueError, match=r"macro.mixture: a pellet packing fraction of 0.58: .*packing_iterations"):
        run(config, "small", table_path, CaseOutputs(tmp_path / "out.nc"))
    assert not (tmp_path / "out.nc").exists()


def test_records_are_thinned_and_picked_at_equal_step_spacing(table_path, tmp_path, monkeypatch):
    """Past THIN_ABOVE records in memory every other one is dropped; the written records
    are the nearest to equally spaced steps, first and last included."""
    import macro.mock_up
    import macro.records

    monkeypatch.setattr(macro.mock_up, "THIN_ABOVE", 10)
    config = small_config()
    config["macro"]["numerics"].update(max_steps=40, stop_tolerance=0.0, records=5)
    ds = run(config, "small", table_path, CaseOutputs(tmp_path / "small.nc"))
    assert 3 <= ds.sizes["time"] <= 5  # nearest records may coincide once thinned
    assert ds.attrs["steps"] == 40 and ds["time"].values[0] == 0.0
    assert ds["time_step"].values[-1] > 0.0
    keep = macro.records._keep(np.array([0, 4, 8, 16, 24, 32, 33, 34, 35, 36, 40]), 5)
    np.testing.assert_array_equal(keep, [0, 2, 4, 5, 10])  # steps 0, 8, 16/24 -> 24, 32, 40


def test_run_stops_once_the_recorded_distance_reaches_one(table_path, tmp_path):
    """Tolerances so loose that the first distance stops the run (stop_after_s 0): it stops
    near equilibrium at the first record whose distance is at most 1, and every recorded
    distance is the criterion evaluated on the written records (all of them are written:
    fewer steps than records) in the order of macro.stopping.MONITORED."""
    from macro.stopping import stop_distance

    config = small_config()
    config["macro"]["numerics"].update(max_steps=300, stop_after_s=0.0, stop_tolerance=10.0,
                                       stop_pressure_tolerance=10.0, records=400)
    ds = run(config, "small", table_path, CaseOutputs(tmp_path / "small.nc"))
    assert ds.attrs["stop_reason"] == "near_equilibrium" and ds.attrs["steps"] < 300
    distance = ds["stop_distance"].values
    assert distance[-1] <= 1.0 and not np.any(distance[:-1] <= 1.0)
    times = ds["time"].values
    monitored = np.column_stack([ds["mean_saturation"].values, ds["sensor_pressure"].mean("sensor").values,
                                 ds["axial_pressure_upper"].values, ds["axial_pressure_lower"].values])
    numerics = config["macro"]["numerics"]
    for k in range(1, times.size):
        expected = stop_distance(times[: k + 1], monitored[: k + 1], numerics["stop_window_fraction"],
                                 np.full(5, 10.0))[0]
        np.testing.assert_equal(distance[k], expected)
