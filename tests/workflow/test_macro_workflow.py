"""The macro rules' DAG: a case's own materials and the seed ensembles, by dry runs.

No job runs: the outputs of a tiny configuration are made as empty files and ``snakemake
--touch --forceall`` records them as up to date with their params (as a finished run
would); then ``--list-changes params`` lists the outputs whose recorded params differ
from the current rules' after a config edit, i.e. the jobs that the edit itself reruns
(see test_workflow.py).
"""

from __future__ import annotations

import copy
import subprocess
from pathlib import Path

import pytest
import yaml

from tests.workflow._chain import edited_copy, listed
from tests.workflow._chain import snakemake as _snakemake
from tests.workflow._chain import workdir as _workdir

ROOT = Path(__file__).resolve().parents[2]
PRESET = "config/paper/macro_ensemble.yaml"

TINY = {
    "samples": {"pellet": {"source": "phantom", "voxel_size_m": 3.0e-4}},
    "micro": {"cases": {"het": {"porosity": "ct"}}},
    "upscaling": {"conditions": {"free": "het", "confined": "het"}},
    "macro": {
        "cases": {
            "a": {"materials": {"mixture_powder": {"retention_exponent_reference": 0.3}}},
            "b": {},
        },
        "ensembles": {"e": {"case": "b", "seeds": [1, 2]}},
    },
}


def _planned(result: subprocess.CompletedProcess, rule: str) -> list[str]:
    """The wildcards line of each job of ``rule`` in a dry run's plan."""
    jobs = result.stdout.split("rule ")[1:]
    return sorted(
        line.split("wildcards:")[1].strip()
        for job in jobs if job.startswith(f"{rule}:")
        for line in job.splitlines() if "wildcards:" in line
    )


@pytest.fixture(scope="module")
def touched(tmp_path_factory):
    """The tiny configuration as if run: its outputs as empty files, up to date."""
    workdir = _workdir(tmp_path_factory.mktemp("wf_macro"), TINY)
    for line in _snakemake(workdir, "-n").stdout.splitlines():
        if line.strip().startswith("output:"):
            for name in line.split("output:")[1].split(","):
                (workdir / name.strip()).parent.mkdir(parents=True, exist_ok=True)
                (workdir / name.strip()).touch()
    _snakemake(workdir, "--touch", "--forceall")
    assert "Nothing to be done" in _snakemake(workdir, "-n").stdout
    assert not listed(_snakemake(workdir, "--list-changes", "params"))
    return workdir


def _outputs(*cases: str) -> set[str]:
    return {f"results/macro/{case}.{suffix}" for case in cases for suffix in ("nc", "png")}


@pytest.mark.parametrize(
    ("edit", "changed"),
    [
        # a case's own value reruns that case alone
        (lambda c: c["macro"]["cases"]["a"]["materials"]["mixture_powder"].update(
            retention_exponent_reference=0.35), _outputs("a")),
        (lambda c: c["macro"]["cases"]["b"].update(
            materials={"mixture_pellet": {"friction_angle_deg": 25.0}}),
         _outputs("b", "e_s1", "e_s2")),
        # a top-level value reruns the cases that do not set their own
        (lambda c: c.setdefault("materials", {}).setdefault("mixture_powder", {}).update(
            retention_exponent_reference=0.3), _outputs("b", "e_s1", "e_s2")),
        (lambda c: c.setdefault("materials", {}).setdefault("mixture_pellet", {}).update(
            swelling_beta_per_pa=3.0e-8), _outputs("a", "b", "e_s1", "e_s2")),
        # an ensemble's settings rerun its statistics alone; a new ensemble reruns nothing
        (lambda c: c["macro"]["ensembles"]["e"].update(band_quantiles=[0.0, 1.0]),
         _outputs("ensemble_e")),
        (lambda c: c["macro"]["ensembles"].update(f={"case": "a", "seeds": [1, 2, 3]}), set()),
    ],
)
def test_a_macro_edit_changes_the_params_of_its_cases_only(touched, tmp_path, edit, changed):
    workdir = edited_copy(touched, tmp_path / "wf", edit)
    assert listed(_snakemake(workdir, "--list-changes", "params")) == changed


def test_a_cases_own_value_plans_that_case_alone(touched, tmp_path):
    """Of the cases, the dry run plans case a alone (the comparison reads it)."""
    def edit(config):
        config["macro"]["cases"]["a"]["materials"]["mixture_powder"]["reference_porosity"] = 0.3

    workdir = edited_copy(touched, tmp_path / "wf", edit)
    dry = _snakemake(workdir, "-n")
    assert _planned(dry, "macro_case") == ["macro_case=a"]
    assert _planned(dry, "macro_ensemble") == []


def test_the_ensemble_preset_plans_its_members_and_the_default_run_none(tmp_path):
    workdir = _workdir(tmp_path, None)
    seeds = yaml.safe_load((ROOT / PRESET).read_text())["macro"]["ensembles"]["weibull"]["seeds"]
    assert len(seeds) == 8
    dry = _snakemake(workdir, "-n", "--configfile", PRESET)
    members = [f"macro_case=weibull_s{seed}" for seed in seeds]
    assert _planned(dry, "macro_case") == sorted(["macro_case=weibull", *members])
    assert _planned(dry, "macro_ensemble") == ["ensemble=weibull"]
    ensemble_job = next(job for job in dry.stdout.split("rule ")[1:]
                        if job.startswith("macro_ensemble:"))
    inputs = ensemble_job.split("input:")[1].splitlines()[0].split(", ")
    assert sorted(i.strip() for i in inputs) == sorted(
        f"results/macro/weibull_s{seed}.nc" for seed in seeds)
    default = _snakemake(workdir, "-n")
    assert _planned(default, "macro_case") == ["macro_case=weibull"]
    assert _planned(default, "macro_ensemble") == []


def test_an_ensemble_of_an_unknown_case_is_refused_naming_the_key(tmp_path):
    config = copy.deepcopy(TINY)
    config["macro"]["ensembles"]["e"]["case"] = "nope"
    result = _snakemake(_workdir(tmp_path, config), "-n", ok=False)
    assert "config key 'macro.ensembles.e.case': 'nope' is not a case" in result.stderr
