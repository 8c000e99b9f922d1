"""VTK snapshots for ParaView: round trip through meshio, the collection, the run hook, config."""

from __future__ import annotations

import copy
import dataclasses
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
import xarray as xr

from micro import run as micro_run
from micro import vtk
from micro.hydration import update_cracks
from micro.pellet import SpecimenSpec, initial_state
from shared.config import ConfigError, validate_config
from shared.io import write_dataset
from tests._defaults import CLAY, DEM

SMALL = SpecimenSpec(edge_length=4e-3, n_points=125, seed=3)


@pytest.fixture()
def state(rng):
    """A small pellet with non-uniform cell fields and two fake cracks on mesh edges."""
    state = initial_state(SMALL, None, None, CLAY, DEM)
    n = state.mesh.n_cells
    state.pressure = -rng.uniform(1e5, 1e8, n)
    state.pressure[:5] = rng.uniform(0.0, 1e3, 5)  # a few cells above atmospheric pressure
    state.saturation = rng.uniform(0.3, 1.0, n)
    state.porosity = rng.uniform(0.1, 0.5, n)
    state.dem.radii[:] *= rng.uniform(1.0, 1.1, state.dem.n_points)
    update_cracks(state, CLAY)
    tetra = state.mesh.tetrahedra
    pairs = np.sort(np.array([tetra[0, [0, 1]], tetra[7, [2, 3]]]), axis=1)
    state.cracks = dataclasses.replace(state.cracks, pairs=pairs,
                                       apertures=np.array([2e-6, 5e-7]),
                                       imbibed=np.array([False, True]))
    return state


def _tetra_volumes(points: np.ndarray, tetra: np.ndarray) -> np.ndarray:
    a, b, c, d = (points[tetra[:, k]] for k in range(4))
    return np.abs(np.linalg.det(np.stack([b - a, c - a, d - a], axis=1))) / 6.0


def test_snapshot_round_trip(state, tmp_path):
    path = vtk.write_snapshot(tmp_path / "snap.vtu", state)
    assert [p.name for p in tmp_path.iterdir()] == ["snap.vtu"]  # no temporary file left
    back = meshio.read(path)
    mesh = state.mesh
    np.testing.assert_array_equal(back.points, state.dem.positions)
    tetra = back.cells_dict["tetra"]
    assert back.points.shape[0] == state.dem.n_points == mesh.points.shape[0]
    assert tetra.shape == (mesh.n_cells, 4)
    # volume from the file's points and cells, against the mesh's own cell volumes
    volume = _tetra_volumes(back.points, tetra).sum()
    assert volume == pytest.approx(mesh.volumes.sum(), rel=1e-12, abs=0.0)
    cells = {name: blocks[0] for name, blocks in back.cell_data.items()}
    np.testing.assert_array_equal(cells["pressure_Pa"], state.pressure)
    np.testing.assert_array_equal(cells["suction_Pa"], np.maximum(-state.pressure, 0.0))
    np.testing.assert_array_equal(cells["saturation"], state.saturation)
    np.testing.assert_array_equal(cells["porosity"], state.porosity)
    assert np.isnan(cells["crack_aperture_m"]).all() and (cells["crack_imbibed"] == -1).all()
    np.testing.assert_array_equal(back.point_data["radius_m"], state.dem.radii)


def test_point_suction_is_volume_weighted_mean_of_incident_cells(state, tmp_path):
    back = meshio.read(vtk.write_snapshot(tmp_path / "snap.vtu", state))
    mesh = state.mesh
    suction = np.maximum(-state.pressure, 0.0)
    weight = np.zeros(state.dem.n_points)
    weighted = np.zeros(state.dem.n_points)
    for k in range(4):
        np.add.at(weight, mesh.tetrahedra[:, k], mesh.volumes)
        np.add.at(weighted, mesh.tetrahedra[:, k], mesh.volumes * suction)
    assert (weight > 0).all()
    np.testing.assert_allclose(back.point_data["suction_Pa"], weighted / weight, rtol=1e-12)


def test_cracks_are_line_cells_with_aperture_and_imbibed_flag(state, tmp_path):
    back = meshio.read(vtk.write_snapshot(tmp_path / "snap.vtu", state))
    assert [block.type for block in back.cells] == ["tetra", "line"]
    np.testing.assert_array_equal(back.cells_dict["line"], state.cracks.pairs)
    np.testing.assert_array_equal(back.cell_data["crack_aperture_m"][1], [2e-6, 5e-7])
    np.testing.assert_array_equal(back.cell_data["crack_imbibed"][1], [0, 1])
    for name in ("pressure_Pa", "suction_Pa", "saturation", "porosity"):
        assert np.isnan(back.cell_data[name][1]).all()
    without = meshio.read(vtk.write_snapshot(tmp_path / "plain.vtu", state, cracks=False))
    assert [block.type for block in without.cells] == ["tetra"]


def test_collection_lists_the_snapshots_in_order_and_a_fresh_run_clears_them(state, tmp_path):
    directory = tmp_path / "case_vtk"
    for index in (0, 1, 2):
        vtk.write_checkpoint_snapshot(directory, "case", index, state)
    root = ET.parse(directory / "case.pvd").getroot()
    assert root.get("type") == "Collection"
    entries = [(float(d.get("timestep")), d.get("file")) for d in root.iter("DataSet")]
    assert entries == [(0.0, "checkpoint_00.vtu"), (1.0, "checkpoint_01.vtu"),
                       (2.0, "checkpoint_02.vtu")]
    for _, name in entries:
        assert meshio.read(directory / name).cells_dict["tetra"].shape[0] == state.mesh.n_cells
    # a rewrite of an earlier checkpoint (resumed run) lists only up to it
    vtk.write_checkpoint_snapshot(directory, "case", 1, state)
    root = ET.parse(directory / "case.pvd").getroot()
    assert [d.get("file") for d in root.iter("DataSet")] == ["checkpoint_00.vtu",
                                                             "checkpoint_01.vtu"]
    vtk.clear_snapshots(directory, "case")
    assert not any(directory.iterdir())


def test_collection_times_are_the_decades_of_suction_relieved(state, tmp_path):
    """With the checkpoint suctions, time step i is log10(s_0 / s_i): increasing."""
    directory = tmp_path / "case_vtk"
    suctions = [132.0e6, 13.2e6, 1.32e6]
    for index in (0, 1, 2):
        vtk.write_checkpoint_snapshot(directory, "case", index, state, suctions)
    root = ET.parse(directory / "case.pvd").getroot()
    times = [float(d.get("timestep")) for d in root.iter("DataSet")]
    np.testing.assert_allclose(times, [0.0, 1.0, 2.0], atol=1e-12)
    assert np.all(np.diff(times) > 0)


def _config(**micro):
    config = {"samples": {"p": {"source": "phantom", "voxel_size_m": 3e-4}},
              "micro": {"sample": "p", **micro}}
    if "cases" in micro:
        case = next(iter(micro["cases"]))
        config["upscaling"] = {"conditions": {"free": case, "confined": case}}
    return config


def test_config_key_defaults_to_false_and_must_be_boolean():
    assert validate_config(_config())["micro"]["vtk_snapshots"] is False
    assert validate_config(_config(vtk_snapshots=True))["micro"]["vtk_snapshots"] is True
    with pytest.raises(ConfigError, match=r"micro\.vtk_snapshots"):
        validate_config(_config(vtk_snapshots="yes"))


def test_run_writes_one_snapshot_per_checkpoint_only_when_asked(tmp_path):
    config = validate_config(_config(
        sample="p", specimen_size_m=4e-3, n_points=64,
        checkpoints_suction_pa=[132.0e6, 80.0e6], cases={"c": {"porosity": "ct"}},
    ))
    rng = np.random.default_rng(0)
    values = np.clip(0.25 + 0.03 * rng.standard_normal((14, 14, 14)), 0.05, 0.6)
    grid = xr.DataArray(values, dims=("z", "y", "x"),
                        coords={axis: np.arange(14) * 4e-4 for axis in "zyx"},
                        attrs={"units": "1", "long_name": "porosity"})
    ds = grid.to_dataset(name="porosity")
    for axis in "zyx":
        ds[axis].attrs.update(units="m", long_name=axis)
    porosity = tmp_path / "porosity.nc"
    write_dataset(ds, porosity, stage="imaging", title="test grid")

    micro_run.run(config, "c", porosity, micro_run.CaseOutputs(tmp_path / "off.nc", tmp_path / "off.png"))
    assert not (tmp_path / "off_vtk").exists()
    on = copy.deepcopy(config)
    on["micro"]["vtk_snapshots"] = True
    result = micro_run.run(on, "c", porosity, micro_run.CaseOutputs(tmp_path / "on.nc", tmp_path / "on.png"))
    directory = tmp_path / "on_vtk"
    assert sorted(p.name for p in directory.iterdir()) == [
        "checkpoint_00.vtu", "checkpoint_01.vtu", "on.pvd"]
    last = meshio.read(directory / "checkpoint_01.vtu")
    assert last.cells_dict["tetra"].shape[0] == result.attrs["n_cells"]
    assert last.points.shape[0] == result.attrs["n_points"]
    # the snapshot's porosity is the state the netCDF measured
    tetra = last.cells_dict["tetra"]
    volumes = _tetra_volumes(last.points, tetra)
    porosity_mean = (last.cell_data["porosity"][0] * volumes).sum() / volumes.sum()
    assert porosity_mean == pytest.approx(float(result["porosity_mean"][-1]), rel=1e-12)
