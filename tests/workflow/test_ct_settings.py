"""The CT rules' imaging settings: the keys the entry points read are those of the one
list (imaging/ct_keys.py) that the rules take their params from; the machine resources
are the jobs' threads and resources, so that changing them reruns nothing while a
science key reruns the CT jobs (dry runs of a finished run, as tests/workflow/
test_workflow.py does)."""

from __future__ import annotations

import ast
import copy
import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from imaging.ct import run as ct_run
from imaging.ct.io import write_tiff_stack
from imaging.ct.phantom import pellet_phantom
from imaging.ct.settings import RevSettings, ScanResources
from imaging.ct_keys import POROSITY_KEYS, RESOURCE_KEYS, REV_KEYS, job_resources, resource_value
from shared.config import ConfigError, default_config
from tests.workflow._chain import ROOT, edited_copy, snakemake, workdir

CONFIG = default_config()
VOXEL = 3e-4


class _Recording(dict):
    """A settings mapping that records the keys read from it (a copy for the provenance,
    ``dict(settings)``, reads none)."""

    def __init__(self, *args: Any) -> None:
        super().__init__(*args)
        self.read: set[str] = set()

    def __getitem__(self, key: str) -> Any:
        self.read.add(key)
        return super().__getitem__(key)

    def get(self, key: str, default: Any = None) -> Any:
        self.read.add(key)
        return super().get(key, default)


def test_the_entry_points_read_the_listed_keys(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The porosity settings and the resources read the porosity keys and the resource keys,
    the REV route the REV keys and the resources, and neither reads any other imaging key:
    the rules' params lack nothing."""
    monkeypatch.setattr("imaging.ct.run.figures.porosity_figure", lambda *args: None)
    monkeypatch.setattr("imaging.ct.run.figures.rev_figure", lambda *args: None)
    spec = ct_run.phantom_spec(dict(CONFIG["phantom"], shape=[24, 24, 24], seed=3),
                               CONFIG["imaging"]["calibration"], VOXEL)
    scan = write_tiff_stack(pellet_phantom(spec)[0], tmp_path / "p.tif")
    imaging = copy.deepcopy(CONFIG["imaging"])
    imaging["rev"].update(n_positions=8, n_sizes=3)
    entry = {"source": "tiff", "path": str(scan), "voxel_size_m": VOXEL}
    porosity = _Recording(imaging)
    outputs = ct_run.PorosityOutputs(tmp_path / "image.nc", tmp_path / "porosity.nc", tmp_path / "porosity.png")
    ct_run.porosity({"sample": entry, "imaging": porosity, "material": CONFIG["materials"]["pellet"],
                     "micro_spacing": (4e-3, 64)}, "p", scan, outputs,
                    resources=ScanResources.from_mapping(porosity))
    rev = _Recording(imaging)
    ct_run.rev({"sample": entry, "settings": rev}, "p", ct_run.RevInputs(scan, *outputs[:2]),
               ct_run.RevOutputs(tmp_path / "rev.nc", tmp_path / "rev.png"),
               resources=ScanResources.from_mapping(rev))
    assert porosity.read == {*POROSITY_KEYS, *RESOURCE_KEYS}
    assert rev.read == {*REV_KEYS, *RESOURCE_KEYS}
    # the REV settings hold the listed keys and the sample's name
    assert {f.name for f in dataclasses.fields(RevSettings)} == {*REV_KEYS, "sample"}
    # every imaging key is read by one of them (the schema's section has no dead key)
    assert set(imaging) == {*POROSITY_KEYS, *REV_KEYS, *RESOURCE_KEYS}


TARGET = "results/rev/pellet.nc"
# the outputs of the jobs that TARGET needs
OUTPUTS = ("results/phantom/pellet.tif", "results/images/pellet.nc", "results/porosity/pellet.nc",
           "results/porosity/pellet.png", TARGET, "results/rev/pellet.png")


@pytest.fixture(scope="module")
def ct_run_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The default config with its CT jobs recorded as run (``--touch``: Snakemake records
    their params and code as a run does, without running them; the scripts themselves
    run in tests/workflow/test_workflow.py), so that a dry run plans nothing."""
    work = workdir(tmp_path_factory.mktemp("ct"), yaml.safe_load((ROOT / "config/config.yaml").read_text()))
    for output in OUTPUTS:
        (work / output).parent.mkdir(parents=True, exist_ok=True)
        (work / output).touch()
    snakemake(work, "--touch", "--forceall", TARGET)
    assert "Nothing to be done" in snakemake(work, "-n", TARGET).stdout
    return work


def _recorded_params(folder: Path, rule: str) -> list[Any]:
    """The params Snakemake recorded for the job of ``rule`` (its metadata, one record per
    output file, all with the job's params)."""
    records = [json.loads(p.read_text()) for p in (folder / ".snakemake/metadata").iterdir()]
    (params,) = {tuple(r["params"]) for r in records if r["rule"] == rule}
    return [ast.literal_eval(value) for value in params]


def test_the_rules_params_hold_the_listed_science_keys(ct_run_folder: Path) -> None:
    porosity = [p for p in _recorded_params(ct_run_folder, "imaging_porosity")
                if isinstance(p, dict) and "calibration" in p]
    rev = [p for p in _recorded_params(ct_run_folder, "imaging_rev") if isinstance(p, dict) and "rev" in p]
    assert [set(p) for p in porosity] == [set(POROSITY_KEYS)]
    assert [set(p) for p in rev] == [set(REV_KEYS)]


def _planned(folder: Path, tmp: Path, edit: dict[str, Any]) -> str:
    """What a dry run (``snakemake -n``) prints after ``edit`` (imaging key -> value) of
    the recorded run's config, on a copy of it."""
    def apply(config: dict) -> None:
        config["imaging"].update(edit)
    copy = edited_copy(folder, tmp / "wf", apply)
    return snakemake(copy, "-n", TARGET).stdout


@pytest.mark.parametrize("edit", [{"workers": 1}, {"chunk_mb": 0.01, "memory_limit_gb": 64.0,
                                                   "dask_scheduler": "tcp://10.0.0.5:8786"}])
def test_changing_a_resource_reruns_nothing(ct_run_folder: Path, tmp_path: Path, edit: dict[str, Any]) -> None:
    assert "Nothing to be done" in _planned(ct_run_folder, tmp_path, edit)


def test_changing_a_science_key_reruns_the_ct_jobs(ct_run_folder: Path, tmp_path: Path) -> None:
    planned = _planned(ct_run_folder, tmp_path, {"min_specimen_fraction": 0.6})
    jobs = {line.split()[0] for line in planned.split("Job stats:")[1].split("total")[0].splitlines()[3:]
            if line.strip()}
    assert jobs == {"imaging_porosity", "imaging_rev"}


@pytest.mark.parametrize(("chunk_mb", "limit"), [(32, None), (2 * 48 * 48 * 2 / 2**20, 64.0), (0.1 + 0.2, 1e-3)])
def test_a_resource_reaches_the_job_as_the_config_wrote_it(chunk_mb: float, limit: float | None) -> None:
    """Snakemake rounds a float resource: the CT resources travel as strings, and come
    back as the config's numbers (the provenance's config_sha256 is the config's)."""
    written = {key: resource_value(value) for key, value in
               (("chunk_mb", chunk_mb), ("memory_limit_gb", limit), ("dask_scheduler", None))}
    resources = {key: value for key, value in written.items() if value is not None}  # null: unset
    settings = job_resources(3, resources)
    assert settings == {"workers": 3, "chunk_mb": chunk_mb, "memory_limit_gb": limit, "dask_scheduler": None}
    assert type(settings["chunk_mb"]) is type(chunk_mb)
    with pytest.raises(ConfigError, match="got '0'"):
        job_resources(1, {"chunk_mb": "0"})
