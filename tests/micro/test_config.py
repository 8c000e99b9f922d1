"""The micro and upscaling sections of the configuration (micro.config): studies, scale
realizations, upscaling sources, and the config errors naming their keys."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from micro.config import case_n_points, check_studies, convergence_cases, scale_realizations, source_names
from shared.config import ConfigError, default_config, validate_config


def _config(studies: dict | None) -> dict:
    micro: dict = {"cases": {"het": {"porosity": "ct"},
                             "p125": {"porosity": "ct", "n_points": 125},
                             "hom": {"porosity": "homogeneous"}}}
    if studies is not None:
        micro["studies"] = studies
    config = {"samples": {"pellet": {"source": "phantom", "voxel_size_m": 3e-4}}, "micro": micro,
              "upscaling": {"conditions": {"free": "het", "confined": "het"}}}
    return dict(validate_config(config))


def test_studies_default_to_none():
    config = _config(None)
    assert config["micro"]["studies"]["convergence"] == []
    assert config["micro"]["studies"]["scale"]["reference"] is None
    check_studies(config)
    assert scale_realizations(config) == []


def test_declared_studies_pass_the_check():
    """The check accepts the studies, and what it read is what was declared: the cases'
    point counts (het takes micro.n_points = 1000) and 3 sub-cubes of a quarter of het's
    7 mm cube, inside it."""
    config = _config({"convergence": ["p125", "het"],
                      "scale": {"reference": "het", "fractions": [0.25], "realizations": 3}})
    check_studies(config)
    assert [case_n_points(config, name) for name in convergence_cases(config)] == [125, 1000]
    realizations = scale_realizations(config)
    assert [r.domain_fraction for r in realizations] == [0.25] * 3
    edge = 7e-3 * 0.25 ** (1 / 3)
    for r in realizations:
        assert r.edge_length == pytest.approx(edge, rel=1e-12)
        assert np.all(np.abs(r.offset) + edge / 2 <= 3.5e-3 * (1 + 1e-12))


@pytest.mark.parametrize(
    ("studies", "key"),
    [
        ({"convergence": ["p125", "absent"]}, "micro.studies.convergence"),
        ({"scale": {"reference": "absent", "fractions": [0.1]}}, "micro.studies.scale.reference"),
        ({"scale": {"fractions": [0.1]}}, "micro.studies.scale.reference"),
        ({"scale": {"reference": "het"}}, "micro.studies.scale.fractions"),
        ({"scale": {"reference": "hom", "fractions": [0.1]}}, "micro.studies.scale.reference"),
        ({"scale": {"reference": "het", "fractions": [1.0], "realizations": 2}},
         "micro.studies.scale.realizations"),
        ({"scale": {"reference": "het", "fractions": [0.5], "realizations": 28}},
         "micro.studies.scale.realizations"),
    ],
)
def test_a_bad_study_is_a_config_error_naming_the_key(studies, key):
    with pytest.raises(ConfigError, match=f"config key '{key}'"):
        check_studies(_config(studies))


def test_equal_point_counts_in_the_convergence_study_are_a_config_error():
    # het runs micro.n_points = 1000, like a case that sets it explicitly
    config = _config({"convergence": ["het"]})
    config["micro"]["cases"]["p1000"] = {"porosity": "ct", "n_points": 1000}
    config["micro"]["studies"]["convergence"].append("p1000")
    with pytest.raises(ConfigError, match="micro.studies.convergence.*same number of points"):
        check_studies(config)


@pytest.mark.parametrize("fraction", [0.0, 1.2, -0.1])
def test_a_fraction_outside_zero_one_is_a_schema_error(fraction):
    with pytest.raises(ConfigError, match=r"micro\.studies\.scale\.fractions"):
        _config({"scale": {"reference": "het", "fractions": [fraction]}})


def _realizations(**scale):
    return scale_realizations(_config({"scale": {"reference": "het", **scale}}))


def test_realizations_lie_inside_the_reference_distinct_and_reproducible():
    """7 mm reference of 1000 points (spacing 0.7 mm); a 1/8 sub-cube (3.5 mm) has
    floor(3.5 / 0.7) + 1 = 6 positions per axis, 216 in all."""
    realizations = _realizations(fractions=[0.125, 0.01], realizations=20, seed=3)
    assert len(realizations) == 40
    assert _realizations(fractions=[0.125, 0.01], realizations=20, seed=3) == realizations
    assert _realizations(fractions=[0.125, 0.01], realizations=20, seed=4) != realizations
    for fraction in (0.125, 0.01):
        group = [r for r in realizations if r.domain_fraction == fraction]
        edge = 7e-3 * fraction ** (1 / 3)
        offsets = np.array([r.offset for r in group])
        assert all(r.edge_length == pytest.approx(edge, rel=1e-12) for r in group)
        assert np.all(np.abs(offsets) + edge / 2 <= 3.5e-3 * (1 + 1e-12))
        assert len({tuple(np.round(o, 12)) for o in offsets}) == len(group)
        assert {r.n_points for r in group} == {max(64, round(1000 * fraction))}
    with pytest.raises(ConfigError, match="216 distinct positions"):
        _realizations(fractions=[0.125], realizations=217)


def test_more_realizations_keep_the_earlier_ones():
    """A realization's case (its params) is unchanged when others are added: only the new
    ones and the aggregate rerun."""
    few = _realizations(fractions=[0.25], realizations=3)
    more = _realizations(fractions=[0.25], realizations=5)
    assert more[:3] == few and len({r.name for r in more}) == 5


def test_an_unknown_study_key_is_a_schema_error():
    with pytest.raises(ConfigError, match="micro.studies.rev"):
        _config({"rev": ["het"]})


def test_config_names_unknown_sources_and_bad_ranges():
    config = default_config()
    bad = copy.deepcopy(config)
    bad["upscaling"]["conditions"]["confined"] = ["confined", "nowhere"]
    with pytest.raises(ConfigError, match=r"upscaling\.conditions\.confined.*'nowhere'"):
        validate_config(bad)
    bad = copy.deepcopy(config)
    bad["upscaling"]["suction_range_pa"] = [1e8, 1e6]
    with pytest.raises(ConfigError, match=r"upscaling\.suction_range_pa"):
        validate_config(bad)


def test_a_scale_fraction_source_is_that_fractions_realizations():
    config = copy.deepcopy(default_config())
    scale = config["micro"]["studies"]["scale"]
    config["upscaling"]["conditions"]["free"] = {"scale_fraction": 0.25}
    sources = source_names(validate_config(config))
    assert sources["free"] == [("realization", f"f0p25_r{k:02d}")
                               for k in range(scale["realizations"])]
    assert sources["confined"] == [("case", config["upscaling"]["conditions"]["confined"])]
    config["upscaling"]["conditions"]["free"] = {"scale_fraction": 0.5}
    with pytest.raises(ConfigError, match=r"upscaling\.conditions\.free\.scale_fraction"):
        validate_config(config)
