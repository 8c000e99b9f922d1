"""A killed macro run resumes from its last snapshot and ends bit for bit as an
uninterrupted one; a snapshot of another configuration is ignored, a broken one named."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from tests._macro_cases import small_config

from macro.model import MacroModel
from macro.run import run
from shared.io import OutputError


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


def test_resume_after_a_kill_is_bit_identical(table_path, tmp_path, monkeypatch):
    steps = 10
    whole = run(_config(steps), "small", table_path, tmp_path / "whole.nc")
    original = _kill_at(monkeypatch, 6)
    out = tmp_path / "resumed.nc"
    with pytest.raises(KeyboardInterrupt):
        run(_config(steps), "small", table_path, out)
    snapshot = tmp_path / ".resumed.snapshot.pkl"
    assert snapshot.is_file() and not out.exists()
    monkeypatch.setattr(MacroModel, "step", original)
    resumed = run(_config(steps), "small", table_path, out)
    assert resumed.attrs["resumed"] == 1 and not snapshot.exists()
    for name, variable in whole.data_vars.items():
        np.testing.assert_array_equal(resumed[name].values, variable.values, err_msg=name)
    for key in ("remeshes", "newton_iterations", "newton_fallbacks", "steps", "boundary_inflow_kg"):
        assert resumed.attrs[key] == whole.attrs[key], key
    assert xr.load_dataset(out).sizes["time"] == whole.sizes["time"]


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
