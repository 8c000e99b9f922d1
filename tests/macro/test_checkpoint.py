"""A macro run SIGKILLed in its own process resumes from its last snapshot and ends bit
for bit as an uninterrupted one, across remeshes; a snapshot of another configuration is
ignored; a broken, damaged, pickled or inconsistent one is moved aside, named in one log
line, and the case starts afresh; the model's whole state, attributes added later
included, goes through a snapshot."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from macro.checkpoint import load_snapshot, save_snapshot
from macro.model import MacroModel
from macro.run import CaseOutputs, case_parameters, run
from shared.checkpointer import Checkpointer
from shared.snapshot import read_meta
from shared.upscaling import PermeabilityTable
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
import macro.mock_up
import macro.run
from macro.model import MacroModel

config, table, output, kill_at, thin_above = sys.argv[1:]
macro.mock_up.THIN_ABOVE = int(thin_above)
step = MacroModel.step


def killed(self, max_dt=float("inf")):
    if self.steps == int(kill_at):
        os.kill(os.getpid(), signal.SIGKILL)
    return step(self, max_dt)


MacroModel.step = killed
macro.run.run(json.loads(open(config).read()), "small", table, macro.run.CaseOutputs(output))
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
    remesh = MacroModel.remesh
    steps = []

    def counted(self):
        steps.append(self.steps + 1)
        remesh(self)

    monkeypatch.setattr(MacroModel, "remesh", counted)
    run(config, "small", table_path, CaseOutputs(output))
    monkeypatch.setattr(MacroModel, "remesh", remesh)
    return xr.load_dataset(output), steps


def _snapshot_model(path):
    """The saved model's plain attributes (the file read as data, no checks)."""
    return read_meta(path)["model"]


def test_a_run_killed_three_times_resumes_to_the_uninterrupted_result(table_path, tmp_path,
                                                                     monkeypatch):
    """SIGKILLed in a process of its own before the first remesh, after it and halfway
    from there to the end, resumed each time: the result, its counters and its ParaView
    series are those of the uninterrupted run, bit for bit (records thinned in between).
    (The balanced pellets of FIRE remesh once in this run; the damped relaxation's
    drifting ones twice.)"""
    steps = 36
    config = _swelling_config(steps)
    # a packing that remeshes early and twice (steps 9 and 10); with most seeds this
    # loose column remeshes once or never in 36 steps
    config["macro"]["seed"] = 4
    monkeypatch.setattr("macro.mock_up.THIN_ABOVE", THIN_ABOVE)
    whole, remeshed = _remesh_steps(monkeypatch, table_path, config, tmp_path / "whole.nc")
    assert remeshed and remeshed[0] + 6 < steps, remeshed
    kills = (remeshed[0] // 2, remeshed[0] + 2, (remeshed[0] + 2 + steps) // 2)
    config_path = tmp_path / "config.json"
    config_path.write_text(json.dumps(config))
    script = tmp_path / "user.py"
    script.write_text(CHILD)
    out = tmp_path / "resumed.nc"
    snapshot = tmp_path / ".resumed.snapshot.npz"
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
        assert model["steps"] == kill_at
        remeshes.append(model["counters"]["object"]["remeshes"])
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


def _killed_run(monkeypatch, config, table_path, out, step=2):
    """Run until the kill at ``step``; the snapshot left behind."""
    original = _kill_at(monkeypatch, step)
    with pytest.raises(KeyboardInterrupt):
        run(config, "small", table_path, CaseOutputs(out))
    monkeypatch.setattr(MacroModel, "step", original)
    snapshot = out.with_name(f".{out.stem}.snapshot.npz")
    assert snapshot.is_file()
    return snapshot


def _runs_afresh_setting_aside(snapshot, config, table_path, out, caplog, why):
    """The rerun starts afresh, the file is moved aside and one log line says ``why``."""
    content = snapshot.read_bytes()
    with caplog.at_level("INFO", logger="claychain.macro"):
        assert run(config, "small", table_path, CaseOutputs(out)).attrs["resumed"] == 0
    aside = snapshot.with_name(snapshot.name + ".rejected")
    assert aside.read_bytes() == content and not snapshot.exists()
    lines = [r.getMessage() for r in caplog.records if "moved to" in r.getMessage()]
    assert len(lines) == 1 and str(snapshot) in lines[0] and why in lines[0], lines


@pytest.mark.parametrize("damage", ["garbage", "pickle", "checksum"])
def test_a_broken_snapshot_is_set_aside_and_the_case_starts_afresh(damage, table_path, tmp_path,
                                                                   monkeypatch, caplog):
    """Not a snapshot, a pickle (whose loading would run code: here it would create a
    file), and a snapshot whose array bytes were changed under an intact zip: none is
    resumed, each is moved aside with its reason."""
    out = tmp_path / "case.nc"
    snapshot = out.with_name(".case.snapshot.npz")
    marker = tmp_path / "code-ran"
    if damage == "garbage":
        snapshot.write_bytes(b"not a snapshot")
        why = "unreadable"
    elif damage == "pickle":
        import pickle

        class Payload:
            def __reduce__(self):
                return (Path.touch, (marker,))

        snapshot.write_bytes(pickle.dumps({"model": Payload()}))
        why = "unreadable"
    else:
        snapshot = _killed_run(monkeypatch, _config(3), table_path, out)
        with np.load(snapshot) as data:
            members = {k: data[k] for k in data.files}
        name = next(k for k, v in members.items() if v.dtype == float and v.size > 100)
        members[name] = members[name].copy()
        members[name].flat[7] += 1e-9
        np.savez(snapshot, **members)
        why = "does not match its checksum"
    _runs_afresh_setting_aside(snapshot, _config(3), table_path, out, caplog, why)
    assert not marker.exists()


def test_a_snapshot_of_another_configuration_is_ignored(table_path, tmp_path, monkeypatch):
    other = _config(3)
    other["macro"]["seed"] = 5
    out = tmp_path / "case.nc"
    _killed_run(monkeypatch, other, table_path, out)
    assert run(_config(3), "small", table_path, CaseOutputs(out)).attrs["resumed"] == 0


def test_a_snapshot_whose_records_differ_in_shape_is_set_aside(table_path, tmp_path, monkeypatch, caplog):
    out = tmp_path / "case.nc"
    config = _config(3)
    snapshot = _killed_run(monkeypatch, config, table_path, out)
    with np.load(snapshot) as data:
        digest = json.loads(str(data["header"]))["digest"]
    settings, material = case_parameters(config, "small")
    table = PermeabilityTable.from_file(table_path, settings.table_condition)
    checkpointer = Checkpointer(snapshot, digest)
    model, rows = load_snapshot(checkpointer, settings, material, table)
    rows["swelling"][-1] = rows["swelling"][-1][:-1]
    save_snapshot(checkpointer, model, rows)
    _runs_afresh_setting_aside(snapshot, config, table_path, out, caplog, "swelling differ in shape")


def _assert_same_state(a, b, where):
    """Bit for bit the same values, types and dtypes (the table: its counters)."""
    if isinstance(a, PermeabilityTable):
        assert (a.clamped, a.looked_up, a.condition) == (b.clamped, b.looked_up, b.condition), where
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and (a.dtype, a.shape) == (b.dtype, b.shape), where
        assert a.tobytes() == b.tobytes(), where
    elif hasattr(a, "__dict__"):
        assert type(a) is type(b) and list(vars(a)) == list(vars(b)), where
        for key in vars(a):
            _assert_same_state(vars(a)[key], vars(b)[key], f"{where}.{key}")
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for key in a:
            _assert_same_state(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, list | tuple):
        assert type(a) is type(b) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same_state(x, y, f"{where}[{i}]")
    else:
        assert type(a) is type(b) and (a == b or (a != a and b != b)), (where, a, b)


def test_the_whole_model_and_attributes_added_later_go_through_a_snapshot(model, table_path, tmp_path):
    """Every attribute after three steps, and an array, a float and a NaN that no
    snapshot code names, come back bit for bit; the next step too."""
    for _ in range(3):
        model.step()
    model.added_array = np.arange(5.0) / 3.0
    model.added_float = 0.1 + 0.2
    model.added_nan = float("nan")
    rows = {"time": [1.0, 2.5], "swelling": [np.zeros(3), np.ones(3) / 7.0]}
    path = tmp_path / "s.npz"
    saving = Checkpointer(path, "d")
    saving.wall_time = lambda: 12.5  # the wall time so far [s], as a run's checkpointer counts it
    save_snapshot(saving, model, rows)
    settings, material = case_parameters(small_config(), "small")
    table = PermeabilityTable.from_file(table_path, "free")
    loading = Checkpointer(path, "d")
    loaded, loaded_rows = load_snapshot(loading, settings, material, table)
    wall_time = loading.earlier
    assert wall_time == 12.5 and table.looked_up == 0 < loaded.table.looked_up == model.table.looked_up
    _assert_same_state(model, loaded, "model")
    _assert_same_state(rows, loaded_rows, "rows")
    model.step()
    loaded.step()
    model.counters.phase_seconds = loaded.counters.phase_seconds  # wall time, not state
    _assert_same_state(model, loaded, "model")


def test_an_attribute_a_snapshot_cannot_hold_is_an_error_naming_it(model, tmp_path):
    model.added_set = {1, 2}
    with pytest.raises(TypeError, match=r"model\.added_set: a builtins\.set cannot be saved"):
        save_snapshot(Checkpointer(tmp_path / "s.npz", "d"), model, {})
    assert not (tmp_path / "s.npz").exists()


def test_snapshot_of_other_code_is_ignored(table_path, tmp_path, monkeypatch, caplog):
    """An edit of the code macro.run imports between a kill and the rerun starts the case afresh."""
    import shared.checkpointer

    out = tmp_path / "case.nc"
    original = _kill_at(monkeypatch, 2)
    with pytest.raises(KeyboardInterrupt):
        run(_config(3), "small", table_path, CaseOutputs(out))
    monkeypatch.setattr(MacroModel, "step", original)
    assert (tmp_path / ".case.snapshot.npz").is_file()
    monkeypatch.setattr(shared.checkpointer, "module_sha256", lambda path: "edited")
    with caplog.at_level("INFO", logger="claychain.macro"):
        assert run(_config(3), "small", table_path, CaseOutputs(out)).attrs["resumed"] == 0
    assert "snapshot of another configuration or code" in caplog.text
