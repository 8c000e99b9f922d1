"""A macro case's own material values (macro.cases.<case>.materials)."""

from __future__ import annotations

import copy
import json

import pytest

import macro.mock_up
import macro.run as macro_run
from macro.laws import case_materials, mixture_parameters
from shared.config import ConfigError, load_schema, validate_config
from shared.io import read_dataset
from shared.upscaling import PermeabilityTable
from tests._macro_cases import small_config

OWN = {"mixture_pellet": {"swelling_beta_per_pa": 3.0e-8},
       "mixture_powder": {"retention_exponent_reference": 0.3}}


def _two_cases():
    """Case ``own`` with its own values, case ``plain`` without."""
    config = small_config(cases={"own": {"materials": copy.deepcopy(OWN)}, "plain": {}})
    return validate_config(config)


def test_a_cases_own_values_reach_its_parameters_and_no_other_cases():
    config = _two_cases()
    powder = config["macro"]["powder"]
    own = mixture_parameters(case_materials(config["materials"], config["macro"]["cases"]["own"]),
                             powder)
    plain = mixture_parameters(
        case_materials(config["materials"], config["macro"]["cases"]["plain"]), powder)
    assert own.swelling_beta == 3.0e-8 and own.retention_exponent_reference == 0.3
    # the keys it does not set keep the defaults (the Appendix .1 script's alpha, beta;
    # Table 4.2), as the other case's
    assert own.swelling_alpha == plain.swelling_alpha == 2.4e-8
    assert own.retention_pressure_reference == plain.retention_pressure_reference == 4.026e6
    assert plain.swelling_beta == 1.6e-8 and plain.retention_exponent_reference == 0.26


def test_the_model_is_built_from_the_cases_own_values(table_path, monkeypatch):
    """build_model hands the case's materials to mixture_parameters (stopped right after)."""
    seen = {}

    class Built(Exception):
        pass

    def spy(materials, powder):
        seen.update(materials)
        raise Built

    monkeypatch.setattr(macro.mock_up, "mixture_parameters", spy)
    config = _two_cases()
    with pytest.raises(Built):
        macro_run.build_model(config, "own", PermeabilityTable.from_file(table_path, "free"))
    assert seen["mixture_pellet"]["swelling_beta_per_pa"] == 3.0e-8
    assert seen["mixture_pellet"]["swelling_alpha_per_pa"] == 2.4e-8
    assert seen["mixture_powder"]["retention_exponent_reference"] == 0.3


def test_the_run_records_the_cases_own_values(table_path, tmp_path):
    """The provenance (and the snapshot digest, hashed from the same section) holds the
    case's materials, merged over the top-level ones."""
    config = _two_cases()
    config["macro"]["numerics"]["max_steps"] = 2
    macro_run.run(config, "own", table_path, macro_run.CaseOutputs(tmp_path / "own.nc"))
    recorded = json.loads(read_dataset(tmp_path / "own.nc").attrs["config_json"])
    pellet = recorded["materials"]["mixture_pellet"]
    assert pellet["swelling_beta_per_pa"] == 3.0e-8 and pellet["poisson_ratio"] == 0.3
    assert recorded["materials"]["mixture_powder"]["retention_exponent_reference"] == 0.3


@pytest.mark.parametrize(
    ("own", "message"),
    [
        ({"mixture_pellet": {"swelling_gamma_per_pa": 1.0}},
         "unknown config key 'macro.cases.weibull.materials.mixture_pellet.swelling_gamma_per_pa'"),
        ({"mixture_sand": {}}, "unknown config key 'macro.cases.weibull.materials.mixture_sand'"),
        ({"pellet": {"poisson_ratio": 0.3}},
         "unknown config key 'macro.cases.weibull.materials.pellet'"),
        ({"mixture_powder": {"reference_porosity": 1.5}},
         "config key 'macro.cases.weibull.materials.mixture_powder.reference_porosity'"),
        ({"mixture_pellet": {"yield": "yes"}},
         "config key 'macro.cases.weibull.materials.mixture_pellet.yield'"),
    ],
)
def test_a_bad_own_value_is_refused_naming_the_key(own, message):
    config = small_config(cases={"weibull": {"materials": own}})
    with pytest.raises(ConfigError, match=message.replace(".", r"\.")):
        validate_config(config)


def _bare(schema):
    """A property schema without its description and default."""
    return {k: v for k, v in schema.items() if k not in ("description", "default")}


@pytest.mark.parametrize("section", ["mixture_pellet", "mixture_powder"])
def test_a_case_may_set_exactly_the_keys_of_the_sections_with_their_types(section):
    schema = load_schema()
    top = schema["properties"]["materials"]["properties"][section]["properties"]
    case = (schema["properties"]["macro"]["properties"]["cases"]["additionalProperties"]
            ["properties"]["materials"]["properties"][section]["properties"])
    assert {k: _bare(v) for k, v in top.items()} == {k: _bare(v) for k, v in case.items()}
