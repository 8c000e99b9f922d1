"""A packing entry of the configuration: the schema holds its keys, the checks name them."""

from __future__ import annotations

import copy

import pytest

from imaging.packing.config import check_packings
from shared.config import ConfigError, default_config, load_schema, validate_config

from .conftest import packing_section


@pytest.fixture(scope="module")
def config() -> dict:
    return default_config()


@pytest.mark.parametrize(
    ("entry", "key"),
    [
        ({"colour": "red"}, "colour"),  # unknown key
        ({"n_particles": 0}, "n_particles"),  # below the minimum
        ({"theta_initial_deg": 95.0}, "theta_initial_deg"),  # above the maximum
        ({"amplitude_reduction": 1.5}, "amplitude_reduction"),
        ({"rev_tolerance": 0.0}, "rev_tolerance"),
        ({"swivel_axis": "sideways"}, "swivel_axis"),  # not in the enum
        ({"seed": 1.5}, "seed"),  # not an integer
    ],
)
def test_schema_rejects_a_bad_packing_key(config: dict, entry: dict, key: str) -> None:
    bad = copy.deepcopy(config)
    bad["packings"]["flat"] = entry
    with pytest.raises(ConfigError, match=rf"'packings\.flat\.{key}'"):
        validate_config(bad)


def test_every_packing_key_is_documented_with_its_default() -> None:
    """The schema is the one place of the keys: each has a description and a default."""
    entry = load_schema()["properties"]["packings"]["additionalProperties"]
    assert entry["additionalProperties"] is False
    for key, schema in entry["properties"].items():
        assert schema.get("description"), key
        assert "default" in schema, key
        assert "type" in schema or "enum" in schema, key


def test_defaults_come_from_the_schema(config: dict) -> None:
    entry = load_schema()["properties"]["packings"]["additionalProperties"]["properties"]
    filled = config["packings"]["monodisperse_small"]
    assert set(filled) == set(entry)
    assert filled["voxel_resolution"] == entry["voxel_resolution"]["default"]
    # the packings' REV tolerance is their own (the paper's 1 %), not the CT's imaging.rev
    assert filled["rev_tolerance"] == 0.01
    assert config["imaging"]["rev"]["tolerance"] == 0.05


def test_an_empty_entry_passes_the_checks_across_keys(config: dict) -> None:
    check_packings(config)
    assert packing_section({})["n_particles"] == 300


@pytest.mark.parametrize(
    ("entry", "key"),
    [
        ({"box_width_m": 0.5e-6}, "box_width_m"),
        ({"contact_distance_m": 1e-7}, "contact_distance_m"),
        ({"basal_surface_max_m2": 1e-13}, "basal_surface_max_m2"),
        ({"z_min_m": 2e-6, "z_max_m": 1e-6}, "z_min_m"),
    ],
)
def test_checks_across_keys_name_the_key(config: dict, entry: dict, key: str) -> None:
    bad = copy.deepcopy(config)
    bad["packings"] = {"flat": entry}
    validate_config(bad)
    with pytest.raises(ConfigError, match=rf"'packings\.flat\.{key}'"):
        check_packings(bad)
