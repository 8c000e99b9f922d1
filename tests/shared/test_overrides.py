"""Configuration values from the command line (shared.overrides)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from shared.config import ConfigError, load_schema
from shared.overrides import key_schema, main, overlay, parse_value

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = load_schema()


def test_values_take_the_type_of_their_key():
    values = overlay([
        "materials.pellet.swelling_beta_per_pa=2e-8",
        "micro.n_points=300",
        "imaging.store_scan=false",
        "upscaling.suction_range_pa=[60e6, 132e6]",
        "micro.cases.heterogeneous.porosity=homogeneous",
    ], SCHEMA)
    assert values["materials"]["pellet"]["swelling_beta_per_pa"] == 2e-8
    assert values["micro"]["n_points"] == 300 and isinstance(values["micro"]["n_points"], int)
    assert values["imaging"]["store_scan"] is False
    assert values["upscaling"]["suction_range_pa"] == [60e6, 132e6]
    assert values["micro"]["cases"]["heterogeneous"]["porosity"] == "homogeneous"


def test_a_number_key_keeps_an_integer_literal_and_a_string_stays_text():
    node = key_schema(SCHEMA, "materials.pellet.swelling_beta_per_pa")
    assert parse_value("3", node, "k", SCHEMA) == 3
    assert parse_value("300", {"type": "string"}, "k") == "300"
    assert parse_value("null", {"type": ["number", "null"]}, "k") is None


def test_an_unknown_key_is_refused_naming_it():
    with pytest.raises(ConfigError, match=r"'materials\.pellet\.swelling_betta'.*'materials"
                                          r"\.pellet'.*swelling_beta_per_pa"):
        overlay(["materials.pellet.swelling_betta=2e-8"], SCHEMA)
    with pytest.raises(ConfigError, match="'nope.x'"):
        overlay(["nope.x=1"], SCHEMA)


def test_a_value_of_the_wrong_type_names_the_key():
    with pytest.raises(ConfigError, match=r"config key 'micro\.n_points': 'many' is not integer"):
        overlay(["micro.n_points=many"], SCHEMA)
    with pytest.raises(ConfigError, match="expected key=value"):
        overlay(["micro.n_points"], SCHEMA)


def test_the_overlay_merged_over_the_config_validates(tmp_path, capsys):
    out = tmp_path / "overlay.yaml"
    assert main(["--output", str(out), "--set", "micro.cases.heterogeneous.n_points=300",
                 "--set", "materials.pellet.swelling_beta_per_pa=2e-8"]) == 0
    assert yaml.safe_load(out.read_text()) == {
        "micro": {"cases": {"heterogeneous": {"n_points": 300}}},
        "materials": {"pellet": {"swelling_beta_per_pa": 2e-8}}}
    # typed right but out of the schema's bounds, once merged: refused, key named
    assert main(["--output", str(tmp_path / "bad.yaml"), "--set", "micro.n_points=-5"]) == 2
    assert "'micro.n_points': -5 is less than the minimum" in capsys.readouterr().err
    assert not (tmp_path / "bad.yaml").exists()
    # a new case lacks its required keys in the merged configuration
    assert main(["--output", str(out), "--set", "micro.cases.new.n_points=300"]) == 2
    assert "'micro.cases.new'" in capsys.readouterr().err


def test_the_module_runs_as_a_command(tmp_path):
    result = subprocess.run([sys.executable, "-m", "shared.overrides", "--output",
                             str(tmp_path / "o.yaml"), "--set", "micro.nn=1"],
                            capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert result.returncode == 2
    assert "unknown config key 'micro.nn'" in result.stderr


def test_main_names_each_changed_key_with_its_value_before_and_after(tmp_path, capsys):
    from shared.config import default_config

    before = default_config()["materials"]["pellet"]["swelling_beta_per_pa"]
    n_points = default_config()["micro"]["n_points"]
    assert main(["--output", str(tmp_path / "o.yaml"), "--set", "materials.pellet.swelling_beta_per_pa=2e-8",
                 "--set", f"micro.n_points={n_points}"]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert lines == [f"claychain: --set materials.pellet.swelling_beta_per_pa: {before!r} -> 2e-08",
                     f"claychain: --set micro.n_points: {n_points!r} (unchanged)"]
