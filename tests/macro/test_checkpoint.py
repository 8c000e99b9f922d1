"""A macro run SIGKILLed in its own process resumes from its last snapshot and ends bit
for bit as an uninterrupted one, across remeshes; a snapshot of another configuration is
ignored, a broken or inconsistent one named."""

from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import xarray as xr

from macro.model import MacroModel
from macro.run import run
from shared.io import OutputError
from tests._macro_cases import small_config

ROOT = Path(__file__).resolve().parents[2]


def _config(steps):
    config = small_config()
    config["macro"]["numerics"].update(max_steps=steps, stop_tolerance=0.0, snapshot_interval_s=1e-9)
    return config


def _kill_at(monkeypatch, step):
    """Make MacroModel.step raise KeyboardInterrupt (a kill) when it reaches ``step``."""
    original = MacroModel.step

    def killed(self, max_dt=float("inf")):
        if self.steps == step:
            raise KeyboardInterrupt("killed")
        return original(self, max_dt)

    monkeypatch.setattr(MacroModel, "step", killed)
    return original


CHILD = """\
import json, os, signal, sys
import macro.run
from macro.model import MacroModel

config, table, output, kill_at, thin_above = sys.argv[1:]
macro.run.THIN_ABOVE = int(thin_above)
step = MacroModel.step


def killed(self, max_dt=float("inf")):
    if self.steps == int(kill_at):
        os.kill(os.getpid(), signal.SIGKILL)
    return step(self, max_dt)


MacroModel.step = killed
macro.run.run(json.loads(open(config).read()), "small", table, output)
"""
"""A user's run in a process of its own, SIGKILLed when it is about to take step
``kill_at`` + 1 (after ``kill_at`` steps; -1: never), its records thinned above
``thin_above``."""
THIN_ABOVE = 16
"""Records in memory before thinning in the test runs: thinned before and after kills."""
VARYING = ("runtime_s", "resumed", "created", "history", "code_version", "source")
"""Attributes of a result that tell when, how fast and from which working tree it was
made (a tree edited during the run is "-dirty"), not what."""


def _swelling_config(steps):
    """The small column with a fast and coarse hydration of a loose mixture whose pellets
    swell as Table 4.1 reads (twice the script's free swelling): the pellets move far
    enough to remesh within a dozen steps."""
    config = small_config(cases={"small": {"conductivity_factor": 1000.0}})
    config["macro"]["mixture"].update(dry_density_kg_m3=1100.0, packing_fraction=0.4)
    config["materials"]["mixture_pellet"].update(swelling_alpha_per_pa=1.6e-8, swelling_beta_per_pa=2.4e-8)
    config["macro"]["numerics"].update(max_steps=steps, stop_tolerance=0.0, snapshot_interval_s=1e-9,
                                       max_saturation_change=1.0)
    return config


def _remesh_steps(monkeypatch, table_path, config, output):
    """Run uninterrupted in this process; the result and the steps that remeshed."""
    remesh = MacroModel._remesh
    steps = []

    def counted(self):
        steps.append(self.steps + 1)
        remesh(self)

    monkeypatch.setattr(MacroModel, "_remesh", counted)
    run(config, "small", table_path, output)
    monkeypatch.setattr(MacroModel, "_remesh", remesh)
    return xr.load_dataset(output), steps


def _snapshot_model(path):
    with open(path, "rb") as handle:
        return pickle.load(handle)["model"]


def test_a_run_killed_three_times_resumes_to_the_uninterrupted_result(table_path, tmp_path,
                                                                     monkeypatch):
    """SIGKILLed in a process of its own before the first remesh, after it and halfway
    from there to the end, resumed each time: the result, its counters and its ParaView
    series are those of the uninterrupted run, bit for bit (records thinned in between).
    (The balanced pellets of FIRE remesh once in this run; the damped relaxation's
    drifting ones twice.)"""
    steps = 36
    config = _swelling_config(steps)
    # a packing that remeshes early and often (steps 5, 8 and 18); with most seeds this
    # loose column remeshes once or never in 36 steps
    config["macro"]["seed"] = 14
    monkeypatch.setattr("macro.run.THIN_ABOVE", THIN_ABOVE)
    whole, remeshed = _remesh_steps(monkeypatch, table_path, config, tmp_path / "whole.nc")
    assert remeshed and remeshed[0] + 6 < steps, remeshed
    kills = (remeshed[0] // 2, remeshed[0] + 2, (remeshed[0] + 2 + steps) // 2)
    config_path = tmp_path / "config.json"
    config_path.write_text(json.dumps(config))
    script = tmp_path / "user.py"
    script.write_text(CHILD)
    out = tmp_path / "resumed.nc"
    snapshot = tmp_path / ".resumed.snapshot.pkl"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    remeshes = []
    for kill_at in (*kills, -1):
        arguments = (config_path, table_path, out, kill_at, THIN_ABOVE)
        done = subprocess.run([sys.executable, str(script), *map(str, arguments)], env=env, cwd=tmp_path,
                              capture_output=True, text=True, timeout=300)
        if kill_at < 0:
            assert done.returncode == 0, done.stderr
            break
        assert done.returncode == -signal.SIGKILL, done.stderr
        assert not out.exists()
        model = _snapshot_model(snapshot)
        assert model.steps == kill_at
        remeshes.append(model.remeshes)
    assert remeshes[0] == 0 < remeshes[1] <= remeshes[2] <= whole.attrs["remeshes"], remeshes
    assert not snapshot.exists()
    resumed = xr.load_dataset(out)
    assert resumed.attrs["resumed"] == 1 and whole.attrs["resumed"] == 0
    assert resumed.attrs["steps"] == steps
    for ds in (whole, resumed):
        for key in [k for k in ds.attrs if k in VARYING or k.startswith("seconds_")]:
            del ds.attrs[key]
    xr.testing.assert_identical(resumed, whole)
    series = {name: {p.name.replace(name, "case"): p.read_bytes()
                     for p in (tmp_path / f"{name}_vtk").iterdir()} for name in ("whole", "resumed")}
    assert len(series["whole"]) > 2 and series["resumed"] == series["whole"]


def test_snapshot_of_another_configuration_is_ignored_and_a_broken_one_named(table_path, tmp_path,
                                                                             monkeypatch):
    out = tmp_path / "case.nc"
    snapshot = tmp_path / ".case.snapshot.pkl"
    snapshot.write_bytes(b"not a snapshot")
    with pytest.raises(OutputError, match=r"\.case\.snapshot\.pkl: unreadable macro snapshot"):
        run(_config(3), "small", table_path, out)
    snapshot.unlink()
    other = _config(3)
    other["macro"]["seed"] = 5
    original = _kill_at(monkeypatch, 2)
    with pytest.raises(KeyboardInterrupt):
        run(other, "small", table_path, out)
    monkeypatch.setattr(MacroModel, "step", original)
    assert snapshot.is_file()
    assert run(_config(3), "small", table_path, out).attrs["resumed"] == 0


def test_a_snapshot_whose_records_differ_in_shape_is_named(table_path, tmp_path, monkeypatch):
    out = tmp_path / "case.nc"
    snapshot = tmp_path / ".case.snapshot.pkl"
    original = _kill_at(monkeypatch, 2)
    with pytest.raises(KeyboardInterrupt):
        run(_config(3), "small", table_path, out)
    monkeypatch.setattr(MacroModel, "step", original)
    payload = pickle.loads(snapshot.read_bytes())
    payload["rows"]["swelling"][-1] = payload["rows"]["swelling"][-1][:-1]
    snapshot.write_bytes(pickle.dumps(payload))
    with pytest.raises(OutputError, match=r"\.case\.snapshot\.pkl: .*swelling differ in shape.*afresh"):
        run(_config(3), "small", table_path, out)
    assert snapshot.is_file() and not out.exists()


def test_snapshot_of_other_code_is_ignored(table_path, tmp_path, monkeypatch, caplog):
    """An edit of the code macro.run imports between a kill and the rerun starts the case afresh."""
    import macro.run

    out = tmp_path / "case.nc"
    original = _kill_at(monkeypatch, 2)
    with pytest.raises(KeyboardInterrupt):
        run(_config(3), "small", table_path, out)
    monkeypatch.setattr(MacroModel, "step", original)
    assert (tmp_path / ".case.snapshot.pkl").is_file()
    monkeypatch.setattr(macro.run, "module_sha256", lambda path: "edited")
    with caplog.at_level("INFO", logger="claychain.macro"):
        assert run(_config(3), "small", table_path, out).attrs["resumed"] == 0
    assert "of another configuration, table or code" in caplog.text
