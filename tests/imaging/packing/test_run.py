"""Stage entry point: the written file, config checks of a packing entry, and the paper presets."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

from imaging.packing.config import population_of
from imaging.packing.population import sample_semi_axes
from imaging.packing.run import PackingOutputs, run
from shared.config import ConfigError
from shared.io import read_dataset
from tests._figures import check_figure, kept_figures  # noqa: F401

from .conftest import packing_section

PRESETS = sorted((Path(__file__).parents[3] / "config" / "paper").glob("packing_*.yaml"))
TINY = {"n_particles": 25, "box_width_m": 3e-6, "attempts_per_cycle": 150, "voxel_resolution": 64,
        "seed": 4, "log_interval_s": 0.5}
CONTRACT = ["center", "semi_axes", "euler", "normal", "porosity_profile", "order_profile",
            "porosity", "S_part", "S_vol", "eta", "beta", "A_B", "A_L", "A_T", "A_Bcont",
            "overlap_fraction", "rocking_curve"]


def test_run_writes_the_contract(tmp_path: Path, caplog: pytest.LogCaptureFixture,
                                 kept_figures) -> None:  # noqa: F811
    with caplog.at_level(logging.INFO, logger="imaging.packing"):
        ds = run(packing_section({**TINY, "store_voxel_image": True}), "tiny",
                 PackingOutputs(tmp_path / "tiny.nc", tmp_path / "tiny.png"))
    assert any("ETA" in record.message for record in caplog.records)
    back = read_dataset(tmp_path / "tiny.nc", required=CONTRACT)
    assert (tmp_path / "tiny.png").stat().st_size > 10_000
    assert {"z [um]", "I_c, orientation density [1/sr]"} <= check_figure(kept_figures[-1])
    for name, var in back.variables.items():
        if var.dtype.kind in "iuf":
            assert {"units", "long_name"} <= set(var.attrs), name
    xr.testing.assert_allclose(back[CONTRACT], ds[CONTRACT])
    assert back.attrs["stage"] == "packing" and back.attrs["seed"] == 4
    assert back.sizes["particle"] == 25
    assert np.allclose(np.linalg.norm(back["normal"].values, axis=1), 1.0)
    assert float(back["overlap_fraction"]) < 1e-4
    assert 0.2 < float(back["porosity"]) < 0.9
    solid_fraction = float(back["solid"].mean())
    assert solid_fraction == pytest.approx(1 - float(back["porosity"]), abs=0.1)
    for name in ("w_rev_porosity_centred", "w_rev_interface_centred"):
        assert "not reached" in back[name].attrs["missing_value_meaning"]
        assert back[name].attrs["tolerance"] == 0.01  # the schema's default rev_tolerance
        width = float(back[name])
        assert np.isnan(width) or 0.0 < width < float(back["window_centred"][-1])
    # the largest centred window, recomputed from the stored image
    solid = back["solid"].values
    k = round(float(back["window_centred"][-1] / back["voxel_size"]))
    lo = [(n - k) // 2 for n in solid.shape]
    window = solid[lo[0]:lo[0] + k, lo[1]:lo[1] + k, lo[2]:lo[2] + k]
    assert k == min(solid.shape)
    assert float(back["rev_porosity_centred"][-1]) == pytest.approx(1.0 - window.mean(), rel=1e-6)


@pytest.mark.parametrize(
    "key, value",
    [
        ("box_width_m", 0.5e-6),
        ("basal_surface_sigma", -0.2),
        ("axis_ratio_median", 0.7),
        ("n_particles", 0),
        ("theta_initial_deg", 95.0),
        ("theta_initial_mode", "sideways"),
        ("swivel_axis", "sideways"),
        ("two_contact_swivel", "hinge"),
        ("amplitude_reduction", 0.0),
        ("n_particle", 10),
        ("seed", -1),
        ("contact_distance_m", 1e-7),
        ("axis_ratio_sigma", -0.1),
        ("aspect_ratio_sigma", -0.1),
        ("theta_initial_deg", -5.0),
    ],
)
def test_invalid_config_names_the_key(key: str, value: object) -> None:
    """Refused by the schema (types, bounds, unknown keys) or by the checks across keys."""
    with pytest.raises(ConfigError, match=rf"'packings\.tiny\.{key}'"):
        packing_section({key: value})


@pytest.mark.parametrize(
    "section",
    [
        # log-normal basal surface capped at d = 3 um: the largest particle is known
        {"box_width_m": 2.9e-6, "basal_surface_sigma": 0.5,
         "basal_surface_max_m2": np.pi / 4 * 9e-12},
        # capped surface and l_a / l_b = 2: 2 l_a = 2 sqrt(2) um
        {"box_width_m": 2.8e-6, "basal_surface_sigma": 0.5, "axis_ratio_median": 2.0,
         "basal_surface_max_m2": np.pi / 4 * 4e-12},
    ],
)
def test_box_narrower_than_the_largest_possible_particle_fails_at_validation(
    section: dict
) -> None:
    """(Monodisperse beds: the largest particle is the median one, checked first.)"""
    packing_section({**section, "box_width_m": 3.0 * section["box_width_m"]})
    with pytest.raises(ConfigError, match=r"packings\.tiny\.box_width_m.*largest"):
        packing_section(section)


def _largest_sampled_diameter(section: dict, n: int = 1_000_000) -> float:
    """2 l_a of the largest of n particles drawn from the entry's laws [m]."""
    semi_axes = sample_semi_axes(population_of(section), n, np.random.default_rng(1))
    return float(2 * semi_axes[:, 0].max())


def test_unbounded_laws_are_left_to_the_sampled_check() -> None:
    """Without a cap (or with a spread axis ratio) the largest particle is not known before
    sampling: the configuration checks accept the box, and a large enough draw holds a
    particle wider than it (so only run's check on the sampled particles can refuse it).
    With the capped surface and a fixed axis ratio, the accepted box holds every draw."""
    for unbounded in ({"box_width_m": 2.9e-6, "basal_surface_sigma": 0.5},
                      {"box_width_m": 2.9e-6, "basal_surface_sigma": 0.5, "axis_ratio_sigma": 0.3,
                       "basal_surface_max_m2": np.pi / 4 * 9e-12}):
        section = packing_section(unbounded)
        assert section["box_width_m"] == unbounded["box_width_m"]
        assert _largest_sampled_diameter(section) > section["box_width_m"]
    capped = packing_section({"box_width_m": 3.1e-6, "basal_surface_sigma": 0.5,
                              "basal_surface_max_m2": np.pi / 4 * 9e-12})
    assert 2.5e-6 < _largest_sampled_diameter(capped) <= 3.0e-6 * (1 + 1e-12)


def test_box_narrower_than_the_largest_sampled_particle(tmp_path: Path) -> None:
    section = packing_section({**TINY, "basal_surface_sigma": 2.0, "n_particles": 200})
    with pytest.raises(ValueError, match="box_width_m"):
        run(section, "x", PackingOutputs(tmp_path / "x.nc", tmp_path / "x.png"))


@pytest.mark.parametrize("preset", PRESETS, ids=lambda p: p.stem)
def test_paper_presets_are_valid_and_fit_the_box(preset: Path) -> None:
    ((name, section),) = yaml.safe_load(preset.read_text())["packings"].items()
    section = packing_section(section, name)
    semi_axes = sample_semi_axes(population_of(section), section["n_particles"],
                                 np.random.default_rng(section["seed"]))
    assert 2 * semi_axes[:, 0].max() < section["box_width_m"]


def test_presets_cover_tables_two_and_three() -> None:
    assert len(PRESETS) == 6
