"""macro.settings: a case's settings over the macro section, and the mixture's make-up
(pellet fraction from the dry-mass ratio, powder porosity) against its mass balance."""

from __future__ import annotations

import pytest

from macro.settings import macro_settings, mixture_fractions, powder_porosity
from tests._macro_cases import small_config

GRAIN = 2770.0


def test_the_dry_mass_ratio_sets_the_pellets_share_of_the_dry_mass() -> None:
    """Pellets of porosity 0.25 (dry density 2077.5 kg/m3) at a 3:1 pellet/powder dry-mass
    ratio in a 1490 kg/m3 mixture: the pellets carry 3/4 of its dry mass, the powder 1/4."""
    fraction, dry_density = mixture_fractions(
        {"dry_density_kg_m3": 1490.0, "pellet_powder_dry_mass_ratio": 3.0, "packing_fraction": 0.5}, 0.25, GRAIN)
    assert dry_density == 1490.0
    pellets = fraction * GRAIN * 0.75
    assert pellets == pytest.approx(0.75 * 1490.0, rel=1e-14)
    assert pellets / (dry_density - pellets) == pytest.approx(3.0, rel=1e-12)
    # without a ratio, the packing fraction is taken as given
    assert mixture_fractions({"dry_density_kg_m3": 1490.0, "pellet_powder_dry_mass_ratio": None,
                              "packing_fraction": 0.45}, 0.25, GRAIN) == (0.45, 1490.0)


@pytest.mark.parametrize(
    ("mixture", "message"),
    [
        ({"dry_density_kg_m3": 1800.0, "pellet_powder_dry_mass_ratio": 9.0}, "cannot be packed at random"),
        ({"dry_density_kg_m3": 900.0, "pellet_powder_dry_mass_ratio": None, "packing_fraction": 0.5},
         "pellets alone .* are denser than macro.mixture.dry_density_kg_m3 = 900"),
    ],
)
def test_a_mixture_that_cannot_be_made_is_refused(mixture, message) -> None:
    with pytest.raises(ValueError, match="macro.mixture: .*" + message):
        mixture_fractions(mixture, 0.25, GRAIN)


def test_powder_porosity_is_the_unfilled_share_of_its_grain_mass() -> None:
    assert powder_porosity(0.3, 0.5) == pytest.approx(0.4, rel=1e-14)
    for dry_mass in (0.5, 0.6, 0.0, -0.1):
        with pytest.raises(ValueError, match="macro.mixture: the powder's dry mass"):
            powder_porosity(dry_mass, 0.5)


def test_a_cases_values_override_the_section_and_other_cases_keep_it() -> None:
    config = small_config(cases={"small": {}, "other": {
        "seed": 7, "pellet_radius_m": 3e-3, "heterogeneity": "homogeneous",
        "mixture": {"pellet_powder_dry_mass_ratio": 3.0}}})
    macro = config["macro"]
    plain, other = macro_settings(macro, "small"), macro_settings(macro, "other")
    assert (plain.seed, plain.pellet_radius) == (macro["seed"], macro["pellet_radius_m"])
    assert (other.seed, other.pellet_radius) == (7, 3e-3)
    assert other.powder["heterogeneity"] == "homogeneous"
    assert plain.packing_fraction == macro["mixture"]["packing_fraction"]
    pellet_density = macro["powder"]["grain_density_kg_m3"] * (1.0 - macro["pellet_porosity"])
    assert other.packing_fraction * pellet_density == pytest.approx(0.75 * other.dry_density, rel=1e-12)
    assert plain.sensors.names == tuple(macro["sensors"])
    with pytest.raises(KeyError, match="macro.cases has no case 'missing'"):
        macro_settings(macro, "missing")
