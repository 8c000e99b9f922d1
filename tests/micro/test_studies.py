"""Convergence and scale studies: stacking, statistics, config checks, and the DAG."""

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

from micro.studies import check_studies, convergence_dataset, scale_dataset
from shared.config import ConfigError, validate_config
from shared.io import read_dataset, write_dataset

ROOT = Path(__file__).resolve().parents[2]
SUCTIONS = np.array([132.0e6, 1.0e6, 1.0e3])


def _case(rng: np.random.Generator, n_points: int, suctions: np.ndarray = SUCTIONS) -> xr.Dataset:
    """A tiny micro output with the contracted dims and random values."""
    n = suctions.size
    scalar = {"units": "1", "long_name": "a per-checkpoint scalar"}
    data = {
        "saturation": ("checkpoint", rng.uniform(0.3, 1.0, n), scalar),
        "eps_v": ("checkpoint", rng.normal(0.0, 0.1, n), scalar),
        "crack_count": ("checkpoint", rng.integers(0, 50, n).astype(float), scalar),
        "suction": ("checkpoint", suctions.copy(), {"units": "Pa", "long_name": "boundary suction"}),
        "permeability": (("checkpoint", "phase", "axis"), 10.0 ** rng.uniform(-24, -19, (n, 2, 3)),
                         {"units": "m2", "long_name": "permeability"}),
        "crack_fabric": (("checkpoint", "i", "j"), rng.uniform(0, 1e-8, (n, 3, 3)),
                         {"units": "m2", "long_name": "crack fabric"}),
        "porosity_hist": (("checkpoint", "bin"), rng.dirichlet(np.ones(4), n),
                          {"units": "1", "long_name": "porosity histogram"}),
    }
    coords = {
        "checkpoint": ("checkpoint", np.arange(n), {"units": "1", "long_name": "checkpoint index"}),
        "phase": ("phase", np.array(["water", "gas"]), {"long_name": "fluid phase"}),
        "axis": ("axis", np.array(["x", "y", "z"]), {"long_name": "direction"}),
        "i": ("i", np.arange(3), {"units": "1", "long_name": "tensor row"}),
        "j": ("j", np.arange(3), {"units": "1", "long_name": "tensor column"}),
        "bin": ("bin", np.array([0.125, 0.375, 0.625, 0.875]), {"units": "1", "long_name": "bin"}),
    }
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update(n_points=n_points, n_cells=6 * n_points, wall_time_s=0.01 * n_points)
    return ds


VARIABLES = ("saturation", "eps_v", "crack_count", "permeability", "crack_fabric", "porosity_hist")


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
    assert ds["suction"].dims == ("checkpoint",)


def test_convergence_refuses_equal_point_counts_and_other_checkpoints(rng):
    with pytest.raises(ValueError, match="same n_points"):
        convergence_dataset({"a": _case(rng, 125), "b": _case(rng, 125)})
    with pytest.raises(ValueError, match="checkpoint suctions"):
        convergence_dataset({"a": _case(rng, 125), "b": _case(rng, 343, SUCTIONS * 2)})


def test_scale_mean_and_std_match_numpy_over_the_realizations(rng):
    octants = {f"oct_{k}": _case(rng, 125) for k in range(4)}
    sixteenths = {f"six_{k}": _case(rng, 27) for k in range(3)}
    reference = _case(rng, 1000)
    cases = {"ref": reference, **octants, **sixteenths}
    edges = {"ref": 7e-3, **{n: 3.5e-3 for n in octants}, **{n: 1.75e-3 for n in sixteenths}}
    ds = scale_dataset(cases, edges, "ref")
    np.testing.assert_allclose(ds["domain_fraction"].values, [1 / 64, 1 / 8, 1.0], rtol=1e-12)
    np.testing.assert_array_equal(ds["n_realizations"].values, [3, 4, 1])
    np.testing.assert_allclose(ds["specimen_size_m"].values, [1.75e-3, 3.5e-3, 7e-3])
    for index, group in enumerate([sixteenths, octants]):
        for var in VARIABLES:
            values = np.stack([group[name][var].values for name in group])
            # independent reference: the mean as a sum, the std from its definition
            mean = values.sum(axis=0) / len(group)
            std = np.sqrt(((values - mean) ** 2).sum(axis=0) / (len(group) - 1))
            np.testing.assert_allclose(ds[f"{var}_mean"].isel(domain_fraction=index).values, mean,
                                       rtol=1e-12)
            np.testing.assert_allclose(ds[f"{var}_std"].isel(domain_fraction=index).values, std,
                                       rtol=1e-10)
    for var in VARIABLES:
        np.testing.assert_array_equal(ds[f"{var}_mean"].isel(domain_fraction=2).values,
                                      reference[var].values)
        assert np.isnan(ds[f"{var}_std"].isel(domain_fraction=2).values).all()
        assert ds[f"{var}_mean"].attrs["units"] == reference[var].attrs["units"]


def test_scale_refuses_a_case_larger_than_the_reference(rng):
    cases = {"ref": _case(rng, 125), "big": _case(rng, 1000)}
    with pytest.raises(ValueError, match="larger than the reference"):
        scale_dataset(cases, {"ref": 3.5e-3, "big": 7e-3}, "ref")
    with pytest.raises(ValueError, match="not among the cases"):
        scale_dataset(cases, {"ref": 3.5e-3, "big": 7e-3}, "other")


def test_study_datasets_meet_the_writer_contract_and_round_trip(rng, tmp_path):
    convergence = convergence_dataset({"a": _case(rng, 125), "b": _case(rng, 343)})
    scale = scale_dataset({"ref": _case(rng, 1000), "o0": _case(rng, 125), "o1": _case(rng, 125)},
                          {"ref": 7e-3, "o0": 3.5e-3, "o1": 3.5e-3}, "ref")
    for name, ds in (("convergence", convergence), ("scale", scale)):
        path = write_dataset(ds, tmp_path / f"{name}.nc", stage="studies", title=name,
                             config={"study": name})
        back = read_dataset(path)
        xr.testing.assert_allclose(back, ds)
        assert back.attrs["stage"] == "studies"
        assert back.attrs["study"] == name


# ------------------------------------------------------------------------------ config


def _config(studies: dict | None) -> dict:
    micro: dict = {"cases": {"het": {"porosity": "ct"},
                             "p125": {"porosity": "ct", "n_points": 125},
                             "oct": {"porosity": "ct", "specimen_size_m": 3.5e-3}}}
    if studies is not None:
        micro["studies"] = studies
    config = {"samples": {"pellet": {"source": "phantom", "voxel_size_m": 3e-4}}, "micro": micro}
    return dict(validate_config(config))


def test_studies_default_to_none():
    config = _config(None)
    assert config["micro"]["studies"] == {"convergence": [], "scale": {"reference": None, "cases": []}}
    check_studies(config)


def test_declared_studies_pass_the_check():
    check_studies(_config({"convergence": ["p125", "het"],
                           "scale": {"reference": "het", "cases": ["oct"]}}))


@pytest.mark.parametrize(
    ("studies", "key"),
    [
        ({"convergence": ["p125", "absent"]}, "micro.studies.convergence"),
        ({"scale": {"reference": "het", "cases": ["oct", "absent"]}}, "micro.studies.scale.cases"),
        ({"scale": {"reference": "absent", "cases": ["oct"]}}, "micro.studies.scale.reference"),
        ({"scale": {"cases": ["oct"]}}, "micro.studies.scale.reference"),
        ({"scale": {"reference": "oct", "cases": ["het"]}}, "micro.studies.scale.cases"),
    ],
)
def test_a_bad_study_is_a_config_error_naming_the_key(studies, key):
    with pytest.raises(ConfigError, match=f"config key '{key}'"):
        check_studies(_config(studies))


def test_equal_point_counts_in_the_convergence_study_are_a_config_error():
    # het runs micro.n_points = 1000, like a case that sets it explicitly
    config = _config({"convergence": ["het"]})
    config["micro"]["cases"]["p1000"] = {"porosity": "ct", "n_points": 1000}
    config["micro"]["studies"]["convergence"].append("p1000")
    with pytest.raises(ConfigError, match="micro.studies.convergence.*same number of points"):
        check_studies(config)


def test_an_unknown_study_key_is_a_schema_error():
    with pytest.raises(ConfigError, match="micro.studies.rev"):
        _config({"rev": ["het"]})


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
    # 4 default cases + 5 convergence + 8 octants
    assert jobs["micro_case"] == 17
    (tmp_path / "default").mkdir()
    result = _dry_run(tmp_path / "default")
    assert result.returncode == 0, result.stderr[-3000:]
    jobs = _job_counts(result)
    assert "micro_convergence" not in jobs and "micro_scale" not in jobs


def test_dry_run_refuses_a_study_naming_an_unknown_case(tmp_path):
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump({"micro": {"studies": {"convergence": ["nope"]}}}))
    result = _dry_run(tmp_path, "--configfile", str(tmp_path / "bad.yaml"))
    assert result.returncode != 0
    assert "micro.studies.convergence" in result.stderr and "'nope'" in result.stderr
