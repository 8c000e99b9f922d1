"""Convergence and scale studies: stacking, statistics, and the DAG."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from micro.config import (
    Realization,
)
from micro.studies import convergence_dataset, scale_dataset
from shared.io import read_dataset, write_dataset

ROOT = Path(__file__).resolve().parents[2]
SUCTIONS = np.array([132.0e6, 1.0e6, 1.0e3])


def _case(rng: np.random.Generator, n_points: int, suctions: np.ndarray = SUCTIONS) -> xr.Dataset:
    """A tiny micro output with the contracted dims and random values."""
    n = suctions.size
    scalar = {"units": "1", "long_name": "a per-checkpoint scalar"}
    data = {
        "saturation": ("suction", rng.uniform(0.3, 1.0, n), scalar),
        "eps_v": ("suction", rng.normal(0.0, 0.1, n), scalar),
        "crack_count": ("suction", rng.integers(0, 50, n), scalar),
        "crack_volume": ("suction", rng.uniform(0, 1e-12, n), {"units": "m3", "long_name": "V_c"}),
        "permeability": (("suction", "phase", "axis"), 10.0 ** rng.uniform(-24, -19, (n, 2, 3)),
                         {"units": "m2", "long_name": "permeability"}),
        "crack_fabric": (("suction", "i", "j"), rng.uniform(0, 1e-8, (n, 3, 3)),
                         {"units": "m2", "long_name": "crack fabric"}),
        "porosity_hist": (("suction", "bin"), rng.dirichlet(np.ones(4), n),
                          {"units": "1", "long_name": "porosity histogram"}),
    }
    coords = {
        "checkpoint": ("suction", np.arange(n), {"units": "1", "long_name": "checkpoint index"}),
        "suction": ("suction", suctions.copy(), {"units": "Pa", "long_name": "boundary suction"}),
        "phase": ("phase", np.array(["water", "gas"]), {"long_name": "fluid phase"}),
        "axis": ("axis", np.array(["x", "y", "z"]), {"long_name": "direction"}),
        "i": ("i", np.arange(3), {"units": "1", "long_name": "tensor row"}),
        "j": ("j", np.arange(3), {"units": "1", "long_name": "tensor column"}),
        "bin": ("bin", np.array([0.125, 0.375, 0.625, 0.875]), {"units": "1", "long_name": "bin"}),
    }
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update(n_points=n_points, n_cells=6 * n_points, wall_time_s=0.01 * n_points)
    return ds


VARIABLES = ("saturation", "eps_v", "crack_count", "permeability", "crack_fabric", "porosity_hist",
             "crack_volume")


def test_convergence_stacks_the_cases_sorted_by_n_points(rng):
    cases = {"mid": _case(rng, 343), "fine": _case(rng, 1000), "coarse": _case(rng, 125)}
    ds = convergence_dataset(cases)
    np.testing.assert_array_equal(ds["n_points"].values, [125, 343, 1000])
    assert json.loads(ds.attrs["cases"]) == ["coarse", "mid", "fine"]
    for index, name in enumerate(["coarse", "mid", "fine"]):
        for var in VARIABLES:
            assert ds[var].dims == ("n_points", *cases[name][var].dims)
            np.testing.assert_array_equal(ds[var].isel(n_points=index).values, cases[name][var].values)
            assert ds[var].attrs == cases[name][var].attrs
        assert float(ds["n_cells"].isel(n_points=index)) == 6 * cases[name].attrs["n_points"]
    np.testing.assert_array_equal(ds["suction"].values, SUCTIONS)
    assert "wall_time_phase" not in ds


def test_convergence_stacks_the_phase_times_that_cases_record(rng):
    """A case run before phases were timed gets NaN; the phases are the union."""
    cases = {"old": _case(rng, 125), "new": _case(rng, 343), "newer": _case(rng, 1000)}
    cases["new"].attrs.update(wall_time_flow_s=2.0, wall_time_relaxation_s=3.0)
    cases["newer"].attrs.update(wall_time_flow_s=5.0, wall_time_remesh_s=1.0)
    ds = convergence_dataset(cases)
    assert list(ds["run_phase"].values) == ["flow", "relaxation", "remesh"]
    np.testing.assert_array_equal(ds["wall_time_phase"].values,
                                  [[np.nan] * 3, [2.0, 3.0, np.nan], [5.0, np.nan, 1.0]])
    assert ds["suction"].dims == ("suction",) and "suction" in ds.indexes


def test_convergence_refuses_equal_point_counts_and_other_checkpoints(rng):
    with pytest.raises(ValueError, match="same n_points"):
        convergence_dataset({"a": _case(rng, 125), "b": _case(rng, 125)})
    with pytest.raises(ValueError, match="checkpoint suctions"):
        convergence_dataset({"a": _case(rng, 125), "b": _case(rng, 343, SUCTIONS * 2)})


def test_convergence_relative_change_against_numpy(rng):
    cases = {"a": _case(rng, 125), "b": _case(rng, 343), "c": _case(rng, 1000)}
    ds = convergence_dataset(cases)
    for var in ("saturation", "eps_v", "permeability", "crack_count"):
        values = np.stack([cases[name][var].values for name in ("a", "b", "c")])
        change = ds[f"{var}_relative_change"].values
        assert np.isnan(change[0]).all()
        np.testing.assert_allclose(change[1:], np.abs(values[1:] - values[:-1]) / np.abs(values[1:]),
                                   rtol=1e-12)


def _realization(name, fraction, edge=7e-3):
    return Realization(name, fraction, edge * fraction ** (1 / 3), 125, (0.0, 0.0, 0.0))


def test_scale_per_realization_values_and_mean_and_std_match_numpy(rng):
    eighths = [(_realization(f"e{k}", 1 / 8), _case(rng, 125)) for k in range(4)]
    hundredths = [(_realization(f"h{k}", 0.01), _case(rng, 27)) for k in range(3)]
    reference = _case(rng, 1000)
    ds = scale_dataset(("ref", reference), 7e-3, eighths + hundredths)
    np.testing.assert_allclose(ds["domain_fraction"].values, [0.01, 1 / 8, 1.0], rtol=1e-12)
    np.testing.assert_array_equal(ds["n_realizations"].values, [3, 4, 1])
    np.testing.assert_allclose(ds["specimen_size_m"].values,
                               7e-3 * np.array([0.01, 1 / 8, 1.0]) ** (1 / 3), rtol=1e-12)
    assert list(ds["realization"].values) == ["ref", "e0", "e1", "e2", "e3", "h0", "h1", "h2"]
    np.testing.assert_array_equal(ds["saturation"].sel(realization="h1").values,
                                  hundredths[1][1]["saturation"].values)
    for index, group in enumerate([hundredths, eighths]):
        for var in VARIABLES:
            values = np.stack([case[var].values for _, case in group])
            # independent reference: the mean as a sum, the std from its definition
            mean = values.sum(axis=0) / len(group)
            std = np.sqrt(((values - mean) ** 2).sum(axis=0) / (len(group) - 1))
            np.testing.assert_allclose(ds[f"{var}_mean"].isel(domain_fraction=index).values, mean,
                                       rtol=1e-12)
            np.testing.assert_allclose(ds[f"{var}_std"].isel(domain_fraction=index).values, std,
                                       rtol=1e-10)
        k = np.stack([case["permeability"].values for _, case in group])
        geometric = np.prod(k, axis=-1) ** (1 / 3)
        np.testing.assert_allclose(ds["permeability_geomean_mean"].isel(domain_fraction=index),
                                   geometric.mean(axis=0), rtol=1e-10)
        volume = group[0][0].edge_length ** 3
        crack = np.stack([case["crack_volume"].values for _, case in group]) / volume
        np.testing.assert_allclose(ds["crack_volume_fraction_std"].isel(domain_fraction=index),
                                   crack.std(axis=0, ddof=1), rtol=1e-10)
    for var in VARIABLES:
        np.testing.assert_array_equal(ds[f"{var}_mean"].isel(domain_fraction=2).values,
                                      reference[var].values)
        assert np.isnan(ds[f"{var}_std"].isel(domain_fraction=2).values).all()
        assert ds[f"{var}_mean"].attrs["units"] == reference[var].attrs["units"]


def test_scale_refuses_a_realization_larger_than_the_reference(rng):
    with pytest.raises(ValueError, match="larger than the reference"):
        scale_dataset(("ref", _case(rng, 125)), 7e-3, [(_realization("big", 1.5), _case(rng, 125))])


def test_study_datasets_meet_the_writer_contract_and_round_trip(rng, tmp_path):
    convergence = convergence_dataset({"a": _case(rng, 125), "b": _case(rng, 343)})
    scale = scale_dataset(("ref", _case(rng, 1000)), 7e-3,
                          [(_realization(f"o{k}", 1 / 8), _case(rng, 125)) for k in range(2)])
    for name, ds in (("convergence", convergence), ("scale", scale)):
        path = write_dataset(ds, tmp_path / f"{name}.nc", stage="studies", title=name,
                             config={"study": name})
        back = read_dataset(path)
        xr.testing.assert_allclose(back, ds)
        assert back.attrs["stage"] == "studies"
        assert back.attrs["study"] == name


# ------------------------------------------------------------------------------ workflow


def _dry_run(tmp: Path, *args: str) -> subprocess.CompletedProcess:
    shutil.copy(ROOT / "Snakefile", tmp / "Snakefile")
    shutil.copytree(ROOT / "workflow", tmp / "workflow")
    shutil.copytree(ROOT / "config", tmp / "config")
    return subprocess.run([sys.executable, "-m", "snakemake", "--cores", "2", "-n", *args],
                          cwd=tmp, capture_output=True, text=True, timeout=300)


def _job_counts(result: subprocess.CompletedProcess) -> dict[str, int]:
    table = (result.stdout + result.stderr).split("Job stats:")[1].split("total")[0]
    rows = [line.split() for line in table.splitlines()]
    return {row[0]: int(row[1]) for row in rows if len(row) == 2 and row[1].isdigit()}


def test_dry_run_with_the_presets_plans_the_study_jobs(tmp_path):
    (tmp_path / "presets").mkdir()
    result = _dry_run(tmp_path / "presets", "--configfile", "config/paper/micro_convergence.yaml",
                      "config/paper/micro_scale.yaml")
    assert result.returncode == 0, result.stderr[-3000:]
    jobs = _job_counts(result)
    assert jobs["micro_convergence"] == 1 and jobs["micro_scale"] == 1
    # 4 default cases + 6 convergence + the scale study's principal case
    assert jobs["micro_case"] == 11
    # the thesis's 6 domain fractions x 40 realizations
    assert jobs["micro_scale_realization"] == 240
    (tmp_path / "default").mkdir()
    result = _dry_run(tmp_path / "default")
    assert result.returncode == 0, result.stderr[-3000:]
    jobs = _job_counts(result)
    # the default's small scale study: 2 fractions x 2 realizations, no convergence study
    assert "micro_convergence" not in jobs
    assert jobs["micro_scale"] == 1 and jobs["micro_scale_realization"] == 4


def test_dry_run_refuses_a_study_naming_an_unknown_case(tmp_path):
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump({"micro": {"studies": {"convergence": ["nope"]}}}))
    result = _dry_run(tmp_path, "--configfile", str(tmp_path / "bad.yaml"))
    assert result.returncode != 0
    assert "micro.studies.convergence" in result.stderr and "'nope'" in result.stderr
