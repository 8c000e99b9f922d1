"""The coupled hydration loop: conservation, loads, resume, determinism and bad input."""

from __future__ import annotations

import copy
import dataclasses
import functools

import numpy as np
import pytest
import xarray as xr

import shared.checkpointer
from micro import case as micro_case
from micro import hydration
from micro import run as micro_run
from micro.forces import membrane_forces
from micro.hydration import (
    DivergenceError,
    FlowSystem,
    advance_to_balance,
    triangulate,
    update_geometry,
)
from micro.pellet import SpecimenSpec, centred_grid, initial_state, settle
from shared.config import ConfigError, validate_config
from shared.dem.integrator import step, unbalanced_force
from shared.dem.state import new_state
from shared.mesh import mesh_from_tetrahedra
from shared.retention import saturation as retention_saturation
from tests._defaults import CLAY, DEM, SETTINGS, settings

SMALL = SpecimenSpec(edge_length=4e-3, n_points=125, seed=3)


def _grid(values: np.ndarray, spacing: float = 5e-4) -> xr.DataArray:
    coords = {axis: np.arange(n) * spacing for axis, n in zip("zyx", values.shape, strict=True)}
    return xr.DataArray(values, dims=("z", "y", "x"), coords=coords)


def test_membrane_shares_each_face_load_among_its_outer_points(rng):
    """A jittered 10^3 lattice (spacing 1 mm) plus one point pushed 3 mm out of the x- face:
    each face's load goes whole to its outer layer, the stray point taking one share."""
    axis = np.arange(10) * 1e-3
    lattice = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    points = np.vstack([lattice + rng.uniform(-2e-5, 2e-5, lattice.shape), [[-3e-3, 4e-3, 4e-3]]])
    inward = np.repeat(np.eye(3), 2, axis=0) * np.array([1.0, -1.0] * 3)[:, None]
    loads = 405.0 * inward + rng.uniform(-1.0, 1.0, (6, 3))
    forces = membrane_forces(points, loads, layer=5e-4)
    np.testing.assert_allclose(forces.sum(axis=0), loads.sum(axis=0), atol=1e-9)
    low_x = points[:, 0] < 5e-4
    assert low_x.sum() == 101
    assert forces[-1] == pytest.approx(loads[0] / 101, rel=1e-12)


def test_pore_fluid_forces_have_no_net_resultant_on_a_heterogeneous_specimen():
    """Newton's third law for the whole specimen: with porosity rising 0.02 per mm, S p
    varies over the hull, and the facet forces plus the face loads still sum to zero
    (the face loads are the hull facets' own resultants, per face)."""
    x = np.arange(16) * 1e-3
    grid = _grid(np.broadcast_to(0.1 + 20.0 * x, (16, 16, 16)).copy(), 1e-3)
    state = initial_state(SMALL, grid, None, CLAY, DEM)
    bishop = state.saturation * state.pressure
    assert np.ptp(bishop[state.mesh.boundary_cells]) > 0.1 * np.abs(bishop).mean()
    _, forces = hydration.swell(state, CLAY)
    typical = np.linalg.norm(forces, axis=1).mean()
    assert np.linalg.norm(forces.sum(axis=0)) < 1e-10 * typical * state.dem.n_points


def test_a_fragment_that_left_the_specimen_is_not_its_main_body():
    """Three bonded points, two bonded points far away and a lone one: the main body is
    the three (the pair still touches a neighbour, but not the specimen)."""
    positions = np.array([[0, 0, 0], [1.8, 0, 0], [0, 1.8, 0],
                          [10, 0, 0], [11.8, 0, 0], [20, 20, 20]], dtype=float) * 1e-4
    dem = new_state(positions, np.full(6, 1e-4), DEM, stress_free_bonds=True)
    assert dem.bonds.shape[0] == 3  # 0-1, 0-2 and 3-4
    body = hydration._main_body(dem, np.zeros(dem.contacts.pairs.shape[0]))
    np.testing.assert_array_equal(body, [True, True, True, False, False, False])


def test_flat_tetrahedra_are_dropped(rng):
    cube = rng.random((60, 3))
    face = np.column_stack([rng.random(30), rng.random(30), np.full(30, 1.0)])
    points = np.vstack([cube * [1, 1, 0.98], face])
    tetrahedra, neighbours = triangulate(points)
    mesh = mesh_from_tetrahedra(points, tetrahedra, neighbours)
    assert mesh.volumes.min() > 1e-9 * mesh.volumes.mean()
    # what is dropped has no volume: the cells still fill the convex hull
    from scipy.spatial import ConvexHull

    assert mesh.volumes.sum() == pytest.approx(ConvexHull(points).volume, rel=1e-9)


def test_remesh_conserves_solid_and_water():
    """Solid and water of the moved cells (old connectivity) are both kept by a remesh."""
    state = initial_state(SMALL, None, None, CLAY, DEM)
    state.saturation = np.linspace(0.3, 0.7, state.mesh.n_cells)
    solid = state.solid_volume.sum()
    state.dem.positions[0] += 0.45 * (state.dem.positions[1] - state.dem.positions[0]) * 3
    corners = state.dem.positions[state.mesh.tetrahedra]
    moved = np.abs(np.linalg.det(corners[:, 1:] - corners[:, :1])) / 6
    water = float((np.clip(1 - state.solid_volume / moved, 1e-6, 1 - 1e-6) * moved * state.saturation).sum())
    remeshed = update_geometry(state, (1e-6, 1 - 1e-6), CLAY)
    assert remeshed and state.n_remesh == 1
    assert state.solid_volume.sum() == pytest.approx(solid, rel=1e-12)
    assert state.water_volume() == pytest.approx(water, rel=1e-10)


def test_initial_suction_gives_uniform_pressure_and_mechanical_balance():
    """Homogeneous specimen at 132 MPa: pressure stays uniform, the DEM reaches balance."""
    state = initial_state(SMALL, None, None, CLAY, DEM)
    system = FlowSystem.for_mesh(state.mesh)
    tight = settings(unbalanced_force_tolerance=1e-4, max_relaxation_steps=30000)
    system, report = advance_to_balance(state, system, 132e6, tight, CLAY, DEM)
    assert report["balanced"] == 1.0 and report["flow_steps"] == 1.0
    assert report["unbalanced_force"] < 1e-4
    np.testing.assert_allclose(state.pressure, -132e6, rtol=1e-12)
    np.testing.assert_allclose(state.dem.radii, state.dem.reference_radii, rtol=1e-12)


def test_a_checkpoint_relaxes_on_until_mechanical_balance():
    """Relaxations of 20 steps stop short of an unbalanced force of 1e-3; at hydraulic
    balance the final relaxations continue until it is met, which a fresh evaluation of
    the forces (a DEM step of 1e-15 s) confirms; without them the report says so."""
    reports = {}
    for final in (0, 100):
        state = initial_state(SMALL, None, None, CLAY, DEM)
        tuned = settings(unbalanced_force_tolerance=1e-3, max_relaxation_steps=20,
                         ramp_steps=10, final_relaxations=final)
        _, reports[final] = advance_to_balance(state, FlowSystem.for_mesh(state.mesh), 132e6,
                                               tuned, CLAY, DEM)
    assert reports[0]["unbalanced_force"] > 1e-3 and reports[0]["balanced"] == 0.0
    assert reports[100]["balanced"] == 1.0
    check = step(state.dem, 1e-15, DEM, state.hydraulic_forces, state.walls, 0.0)
    assert unbalanced_force(check.forces, check.normal_forces) < 1e-3


def test_a_long_relaxation_reports_its_unbalanced_force(monkeypatch, caplog):
    """With the report interval at 0 s, every force check of a relaxation logs its step
    and the ratio that it returns at the end."""
    monkeypatch.setattr(hydration, "ConvergenceProgress", functools.partial(
        hydration.ConvergenceProgress, interval=0.0))
    state = initial_state(SMALL, None, None, CLAY, DEM)
    tuned = settings(unbalanced_force_tolerance=1e-6, max_relaxation_steps=40, ramp_steps=10,
                     check_interval=10)
    with caplog.at_level("INFO", logger="micro.hydration"):
        steps, unbalanced = hydration.relax(state.dem, state.walls,
                                            np.zeros_like(state.dem.positions), tuned, DEM)
    lines = [r.getMessage() for r in caplog.records if "relaxation" in r.getMessage()]
    assert steps == 40 and len(lines) == 4
    assert lines[-1].startswith("relaxation: unbalanced force ratio: step 40, residual "
                                f"{unbalanced:.3g}")


def test_suction_front_moves_inwards_and_balances():
    state = initial_state(SMALL, None, None, CLAY, DEM)
    system = FlowSystem.for_mesh(state.mesh)
    saturation = state.mean_saturation()
    system, report = advance_to_balance(state, system, 60e6, SETTINGS, CLAY, DEM)
    assert report["balanced"] == 1.0
    np.testing.assert_allclose(-state.pressure, 60e6, rtol=0.02)
    # the pores filled (their volume shrank too: the Bishop stress S s compacts the
    # stress-free cloud, so the water volume itself may fall)
    assert state.mean_saturation() > saturation
    assert state.dem.radii.min() > state.dem.reference_radii.min()  # and the points swelled


def test_a_non_finite_field_or_solve_stops_hydration_with_a_divergence_error(monkeypatch):
    """A NaN field or a failed solve ends in a DivergenceError naming it (run() then keeps
    the last good checkpoint, ``test_killed_run_resumes_to_the_same_result``)."""
    state = initial_state(SMALL, None, None, CLAY, DEM)
    system = FlowSystem.for_mesh(state.mesh)
    state.porosity[state.mesh.n_cells // 2] = np.nan
    with pytest.raises(DivergenceError, match="porosity"):
        advance_to_balance(state, system, 60e6, SETTINGS, CLAY, DEM)
    state = initial_state(SMALL, None, None, CLAY, DEM)
    # a solve whose matrix is indefinite, as a negative conductance would make it
    monkeypatch.setattr(hydration, "conductances", lambda *args: -np.ones(state.mesh.n_facets))
    with pytest.raises(DivergenceError, match="flow solve failed"):
        advance_to_balance(state, FlowSystem.for_mesh(state.mesh), 60e6, SETTINGS, CLAY, DEM)


def test_grid_not_covering_the_specimen_is_refused():
    field = np.full((6, 6, 6), 0.25)
    field[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="outside the scanned pellet"):
        centred_grid(_grid(field, 1e-3), 4.5e-3)
    with pytest.raises(ValueError, match="does not span"):
        centred_grid(_grid(np.full((4, 4, 4), 0.25), 5e-4), 4e-3)


def test_offset_cube_reads_the_shifted_part_of_the_grid():
    """Porosity rising 0.02 per mm along x: a cube moved by +1 mm averages 0.02 more."""
    x = np.arange(16) * 1e-3
    grid = _grid(np.broadcast_to(0.1 + 20.0 * x, (16, 16, 16)).copy(), 1e-3)
    centred = centred_grid(grid, 4e-3)
    shifted = centred_grid(grid, 4e-3, (1e-3, -2e-3, 0.5e-3))
    inside = {axis: slice(0.0, 4e-3) for axis in "zyx"}
    difference = shifted.sel(inside).mean() - centred.sel(inside).mean()
    assert float(difference) == pytest.approx(0.02, rel=1e-9)


def test_the_settled_specimen_has_the_scanned_porosity_where_its_material_was_built():
    """settle(): balance at s0 compacts the stress-free cloud; the cells then take the grid
    porosity at their vertices' as-built mean (here 0.21 + 20 x, linear, so trilinear
    interpolation is exact), with solid volume (1 - porosity) V and S(s0)."""
    x = np.arange(16) * 1e-3
    grid = _grid(np.broadcast_to(0.1 + 20.0 * x, (16, 16, 16)).copy(), 1e-3)
    state = initial_state(SMALL, grid, None, CLAY, DEM)
    built = state.dem.positions.copy()
    built_volume = state.mesh.volumes.sum()
    system, report = settle(state, FlowSystem.for_mesh(state.mesh), SMALL, grid, None, SETTINGS,
                            CLAY, DEM)
    assert report["suction_misfit"] < SETTINGS.hydraulic_tolerance
    assert state.mesh.volumes.sum() < 0.97 * built_volume  # S s0 compacted the cloud
    expected = 0.21 + 20.0 * built[state.mesh.tetrahedra].mean(axis=1)[:, 0]
    np.testing.assert_allclose(state.porosity, expected, rtol=1e-12)
    np.testing.assert_allclose(state.solid_volume, (1.0 - expected) * state.mesh.volumes,
                               rtol=1e-12)
    np.testing.assert_allclose(state.pressure, -132e6)
    assert system.pattern.n_free > 0


def test_case_overrides_points_size_offset_and_bond_strength(micro_config):
    config, _ = micro_config
    study = copy.deepcopy(config)
    study["micro"]["cases"]["sub"] = {"porosity": "ct", "n_points": 64,
                                      "specimen_size_m": 2e-3, "offset_m": [5e-4, 0.0, 0.0],
                                      "materials": {"bond_tensile_strength_pa": 2e6}}
    study = validate_config(study)
    spec, _, _ = micro_run.case_settings(study, "sub")
    assert (spec.n_points, spec.edge_length, spec.offset) == (64, 2e-3, (5e-4, 0.0, 0.0))
    assert micro_run.case_parameters(study, "sub")[1].bond_tensile_strength == 2e6
    default, _, _ = micro_run.case_settings(study, "c")
    assert (default.n_points, default.edge_length, default.offset) == (125, 4e-3, (0.0, 0.0, 0.0))
    assert (micro_run.case_parameters(study, "c")[1].bond_tensile_strength
            == study["materials"]["pellet"]["bond_tensile_strength_pa"] == 2e7)


@pytest.mark.parametrize(("override", "key"), [
    ({"bond_strength": 1.0}, "micro.cases.c.materials.bond_strength"),
    ({"poisson_ratio": 0.7}, "micro.cases.c.materials.poisson_ratio"),
])
def test_bad_case_material_names_the_key(micro_config, override, key):
    config, _ = micro_config
    bad = copy.deepcopy(config)
    bad["micro"]["cases"]["c"]["materials"] = override
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        validate_config(bad)


@pytest.fixture()
def micro_config(tmp_path):
    config = validate_config({
        "samples": {"p": {"source": "phantom", "voxel_size_m": 3e-4}},
        "micro": {
            "sample": "p", "specimen_size_m": 4e-3, "n_points": 125,
            "checkpoints_suction_pa": [132.0e6, 80.0e6, 50.0e6],
            "cases": {"c": {"porosity": "ct"}},
        },
        "upscaling": {"conditions": {"free": "c", "confined": "c"}},
    })
    rng = np.random.default_rng(0)
    grid = _grid(np.clip(0.25 + 0.03 * rng.standard_normal((14, 14, 14)), 0.05, 0.6), 4e-4)
    path = tmp_path / "porosity.nc"
    from shared.io import write_dataset

    grid.attrs.update(units="1", long_name="porosity")
    ds = grid.to_dataset(name="porosity")
    for axis in "zyx":
        ds[axis].attrs.update(units="m", long_name=axis)
    write_dataset(ds, path, stage="imaging", title="test grid")
    return config, path


def test_checkpoints_must_decrease(micro_config):
    config, _ = micro_config
    bad = copy.deepcopy(config)
    bad["micro"]["checkpoints_suction_pa"] = [132.0e6, 140.0e6]
    with pytest.raises(ConfigError, match="micro.checkpoints_suction_pa"):
        validate_config(bad)


def test_killed_run_resumes_to_the_same_result(micro_config, tmp_path, monkeypatch):
    config, grid = micro_config
    reference = micro_run.run(config, "c", grid, micro_run.CaseOutputs(tmp_path / "a.nc", tmp_path / "a.png"))
    original = micro_case.advance_to_balance
    calls = {"n": 0}

    def dies_at_the_third(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 3:
            raise DivergenceError("simulated crash")
        return original(*args, **kwargs)

    monkeypatch.setattr(micro_case, "advance_to_balance", dies_at_the_third)
    with pytest.raises(DivergenceError, match="last good checkpoint is kept"):
        micro_run.run(config, "c", grid, micro_run.CaseOutputs(tmp_path / "b.nc", tmp_path / "b.png"))
    assert (tmp_path / "b.checkpoint.npz").exists() and not (tmp_path / "b.nc").exists()
    monkeypatch.setattr(micro_case, "advance_to_balance", original)
    resumed = micro_run.run(config, "c", grid, micro_run.CaseOutputs(tmp_path / "b.nc", tmp_path / "b.png"))
    assert not (tmp_path / "b.checkpoint.npz").exists()
    # the checkpoints before the crash come back from the file, the ones after it are
    # recomputed from the saved state: bit for bit either way
    for name in ("flow_steps", "dem_steps", "n_remesh", "time", "saturation", "eps_v",
                 "porosity_mean", "permeability", "porosity_hist", "crack_count"):
        np.testing.assert_array_equal(resumed[name].values, reference[name].values)


def test_a_checkpoint_of_other_code_is_not_resumed(micro_config, tmp_path, monkeypatch):
    """The checkpoint's digest holds the hash of the code micro.run imports: after an
    edit, the file left by a killed run is found and ignored, and the case starts afresh."""
    config, grid = micro_config
    original = micro_case.advance_to_balance

    def dies_at_the_second(*args, **kwargs):
        if dies_at_the_second.calls == 1:
            raise DivergenceError("simulated crash")
        dies_at_the_second.calls += 1
        return original(*args, **kwargs)

    dies_at_the_second.calls = 0
    monkeypatch.setattr(micro_case, "advance_to_balance", dies_at_the_second)
    with pytest.raises(DivergenceError):
        micro_run.run(config, "c", grid, micro_run.CaseOutputs(tmp_path / "b.nc", tmp_path / "b.png"))
    monkeypatch.setattr(micro_case, "advance_to_balance", original)
    loaded = []
    load = micro_case.load_checkpoint
    monkeypatch.setattr(micro_case, "load_checkpoint", lambda *a: loaded.append(load(*a)) or loaded[-1])
    monkeypatch.setattr(shared.checkpointer, "module_sha256", lambda path: "edited")
    micro_run.run(config, "c", grid, micro_run.CaseOutputs(tmp_path / "b.nc", tmp_path / "b.png"))
    assert loaded == [None] and not (tmp_path / "b.checkpoint.npz").exists()


def test_cracks_open_in_a_heterogeneous_specimen_only():
    """Thesis Sec. 3.5.5 (Fig. 3.12): same points, same bonds, same loading; the
    homogeneous specimen keeps every bond intact and the heterogeneous one cracks.

    The heterogeneity is a flaw, a 1.2 mm slab of porosity 0.5 in a 0.2 matrix, as the
    compaction planes of a CT scan; the homogeneous specimen has the same mean porosity.
    """
    parameters = DEM  # the default configuration's bonds
    spec = dataclasses.replace(SMALL, n_points=343)
    x = np.arange(11) * 5e-4
    field = np.broadcast_to(np.where(np.abs(x - 2e-3) < 6e-4, 0.5, 0.2), (11, 11, 11))
    tuned = settings(max_flow_steps=25)
    flawed = initial_state(spec, _grid(field.copy()), None, CLAY, parameters)
    mean = float((flawed.porosity * flawed.mesh.volumes).sum() / flawed.mesh.volumes.sum())
    counts = {}
    for name, state in (("homogeneous", initial_state(spec, None, mean, CLAY, parameters)),
                        ("heterogeneous", flawed)):
        system = FlowSystem.for_mesh(state.mesh)
        for suction in (132e6, 40e6, 10e6, 1e6):
            system, _ = advance_to_balance(state, system, suction, tuned, CLAY, parameters)
        counts[name] = (int(state.dem.bond_broken.sum()), state.cracks.bonds.size)
    assert counts["homogeneous"] == (0, 0)
    assert counts["heterogeneous"][1] > 0


def test_a_material_value_in_config_reaches_the_model(micro_config):
    """zeta_0 doubled in ``materials.pellet`` gives, at phi_0, the saturation of
    Eq. 3.15 with the doubled pressure, [1 + (s / 2 zeta_0)^(1 / (1 - lambda_0))]^-lambda_0."""
    config, _ = micro_config
    edited = copy.deepcopy(config)
    zeta = 2.0 * config["materials"]["pellet"]["retention_pressure_reference_pa"]
    edited["materials"]["pellet"]["retention_pressure_reference_pa"] = zeta
    material, _ = micro_run.case_parameters(validate_config(edited), "c")
    exponent = config["materials"]["pellet"]["retention_exponent_reference"]
    porosity = config["materials"]["pellet"]["reference_porosity"]
    suction = 5e6
    expected = (1.0 + (suction / zeta) ** (1.0 / (1.0 - exponent))) ** (-exponent)
    assert retention_saturation(suction, porosity, material) == pytest.approx(expected, rel=1e-12)
    default, _ = micro_run.case_parameters(config, "c")
    assert retention_saturation(suction, porosity, default) < 0.99 * expected
