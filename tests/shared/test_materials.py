"""shared.materials: the clay parameters read from materials.pellet (the published values
of its defaults), the key tables against the schema, and the checks of the dataclass."""

from __future__ import annotations

import dataclasses

import pytest

from shared.config import load_schema
from shared.materials import CLAY_CONFIG_KEYS, CLAY_LAW_KEYS, ClayLaws, ClayParameters, clay_parameters
from tests._defaults import CONFIG, clay


def test_every_field_has_a_key_of_materials_pellet() -> None:
    fields = [field.name for field in dataclasses.fields(ClayParameters)]
    assert sorted(CLAY_CONFIG_KEYS) == sorted(fields)
    pellet = load_schema()["properties"]["materials"]["properties"]["pellet"]["properties"]
    assert set(CLAY_CONFIG_KEYS.values()) <= set(pellet)
    assert len(set(CLAY_CONFIG_KEYS.values())) == len(CLAY_CONFIG_KEYS)


def test_the_mixture_sections_hold_each_law_key_once() -> None:
    """The macro mixture's material is a ClayLaws read from the same keys: each law key
    is in exactly one of materials.mixture_powder and materials.mixture_pellet (so that
    macro.laws.mixture_parameters may merge them), and the laws' fields are the clay's
    less the fluids' and the cracks'."""
    materials = load_schema()["properties"]["materials"]["properties"]
    powder, pellet = (set(materials[name]["properties"]) for name in ("mixture_powder", "mixture_pellet"))
    assert all((key in powder) + (key in pellet) == 1 for key in CLAY_LAW_KEYS.values())
    law_fields = {field.name for field in dataclasses.fields(ClayLaws)}
    assert set(CLAY_CONFIG_KEYS) - law_fields == {
        "water_viscosity", "gas_viscosity", "surface_tension", "crack_roughness_factor"}


def test_the_defaults_are_the_thesis_values() -> None:
    """Eqs. 3.15-3.20 and Sec. 3.5.1 of Caulk (2022), as the schema's defaults document them."""
    material = clay_parameters(CONFIG["materials"]["pellet"])
    assert (material.retention_pressure_reference, material.retention_exponent_reference) == (3.0e4, 0.08)
    assert (material.retention_pressure_porosity_factor, material.retention_exponent_porosity_factor) == (6.8, -1.5)
    assert material.reference_porosity == 0.25
    assert (material.intrinsic_permeability_reference, material.permeability_porosity_factor) == (1e-20, 2.0)
    assert (material.swelling_alpha, material.swelling_beta) == (2.102e-8, 8e-9)
    assert material.initial_suction == 1.32e8
    assert (material.gas_viscosity, material.surface_tension) == (1.8e-5, 0.0728)


def test_a_section_value_reaches_its_field_as_a_float() -> None:
    section = dict(CONFIG["materials"]["pellet"], initial_suction_pa=5, swelling_beta_per_pa="3e-9")
    material = clay_parameters(section)
    assert material.initial_suction == 5.0 and isinstance(material.initial_suction, float)
    assert material.swelling_beta == 3e-9


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"residual_saturation": 0.5, "saturated_saturation": 0.5}, "residual_saturation < saturated_saturation"),
        ({"saturated_saturation": 1.1}, "saturated_saturation <= 1"),
        ({"retention_exponent_reference": 1.0}, r"lambda_0\) must lie in \(0, 1\)"),
        ({"reference_porosity": 0.0}, r"phi_0\) must lie in \(0, 1\)"),
        ({"gas_viscosity": 0.0}, "gas_viscosity must be > 0"),
        ({"swelling_alpha": -1e-8}, "swelling_alpha must be > 0"),
    ],
)
def test_impossible_values_are_refused(changes, message) -> None:
    with pytest.raises(ValueError, match=message):
        clay(**changes)
