"""Configuration validation: defaults filled in, errors that name the key."""

import copy

import pytest

from shared.config import ConfigError, load_config, validate_config


@pytest.fixture(scope="module")
def default_config():
    return load_config("config/config.yaml")


def test_defaults_are_filled_in(default_config):
    assert default_config["imaging"]["calibration"]["muscovite_density_kg_m3"] == 3900.0
    assert default_config["imaging"]["calibration"]["air_density_kg_m3"] == 1.13


@pytest.mark.parametrize(
    ("edit", "key"),
    [
        (lambda c: c["samples"]["pellet"].update(voxel_size_m=0.0), "samples.pellet.voxel_size_m"),
        (lambda c: c["samples"]["pellet"].update(voxel_size_m="big"), "samples.pellet.voxel_size_m"),
        (lambda c: c["imaging"]["rev"].update(n_positions=1.5), "imaging.rev.n_positions"),
        (lambda c: c["imaging"].update(colour="red"), "imaging.colour"),
        (lambda c: c["samples"]["pellet"].update(source="jpeg"), "samples.pellet.source"),
    ],
)
def test_errors_name_the_key(default_config, edit, key):
    config = copy.deepcopy(default_config)
    edit(config)
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        validate_config(config)


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="no such configuration file"):
        load_config(tmp_path / "absent.yaml")


def test_a_scan_without_path_is_refused_naming_the_key(default_config):
    config = copy.deepcopy(default_config)
    config["samples"]["scan"] = {"source": "tiff", "voxel_size_m": 1e-5}
    with pytest.raises(ConfigError, match=r"samples\.scan\.path.*tiff"):
        validate_config(config)


def _undescribed(node: object, path: str = "") -> list[str]:
    """The keys under a schema node that have no description."""
    if not isinstance(node, dict):
        return []
    missing = []
    for key, sub in node.get("properties", {}).items():
        name = f"{path}.{key}".lstrip(".")
        if isinstance(sub, dict) and "description" not in sub:
            missing.append(name)
        missing += _undescribed(sub, name)
    if isinstance(node.get("additionalProperties"), dict):
        missing += _undescribed(node["additionalProperties"], f"{path}.<name>")
    for key, sub in node.get("$defs", {}).items():
        missing += _undescribed(sub, f"$defs.{key}")
    return missing


def test_every_key_of_the_schema_has_a_description():
    from shared.config import load_schema

    assert _undescribed(load_schema()) == []
    # the walk finds a key without one
    assert _undescribed({"properties": {"a": {"properties": {"b": {"type": "number"}}}}}) == [
        "a", "a.b"]


def test_the_crack_switch_says_what_it_does():
    from shared.config import default_config, load_schema

    case = load_schema()["properties"]["micro"]["properties"]["cases"]["additionalProperties"]
    assert "cracks" not in case["properties"]
    assert "bonds still" in case["properties"]["crack_coupling"]["description"]
    assert default_config()["micro"]["cases"]["uncoupled_cracks"]["crack_coupling"] is False
