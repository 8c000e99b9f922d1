"""macro.config: seed ensembles' members as cases, and the checks of macro.ensembles."""

from __future__ import annotations

import pytest

from macro.config import check_ensembles, ensemble_cases, ensemble_members, member_name
from shared.config import ConfigError, validate_config
from tests._macro_cases import small_config


def test_members_become_cases_with_their_seeds():
    config = validate_config(small_config(
        cases={"small": {"heterogeneity": "homogeneous"}},
        ensembles={"het": {"case": "small", "seeds": [3, 5]}}))
    assert ensemble_cases(config["macro"]) == {
        "het_s3": {"heterogeneity": "homogeneous", "seed": 3},
        "het_s5": {"heterogeneity": "homogeneous", "seed": 5},
    }
    assert config["macro"]["ensembles"]["het"]["band_quantiles"] == [0.1, 0.9]
    assert ensemble_members(config["macro"], "het") == ["het_s3", "het_s5"] == [
        member_name("het", 3), member_name("het", 5)]


@pytest.mark.parametrize(
    ("ensembles", "cases", "message"),
    [
        ({"e": {"case": "nope", "seeds": [1, 2]}}, {"small": {}},
         "config key 'macro.ensembles.e.case': 'nope' is not a case"),
        ({"e": {"case": "small", "seeds": [1, 2]}}, {"small": {}, "e_s2": {}},
         "config key 'macro.ensembles.e.seeds': member 'e_s2' is also a case"),
        ({"e": {"case": "small", "seeds": [1, 2]}}, {"small": {}, "ensemble_e": {}},
         "config key 'macro.ensembles.e': the case ensemble_e"),
        ({"e": {"case": "small", "seeds": [1, 2], "band_quantiles": [0.9, 0.1]}},
         {"small": {}}, "config key 'macro.ensembles.e.band_quantiles'"),
        ({"e": {"case": "small", "seeds": [1]}}, {"small": {}},
         "config key 'macro.ensembles.e.seeds'"),
        ({"e": {"case": "small", "seeds": [1, 2], "members": 2}}, {"small": {}},
         "unknown config key 'macro.ensembles.e.members'"),
    ],
)
def test_a_bad_ensemble_is_refused_naming_the_key(ensembles, cases, message):
    config = small_config(cases=cases, ensembles=ensembles)
    with pytest.raises(ConfigError, match=message.replace(".", r"\.")):
        validate_config(config, checks=[check_ensembles])
