"""Fixtures of the packing tests: a small deposited bed, shared by the test modules, and
packing entries completed through the configuration schema."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest

from imaging.packing import DepositionParameters, Packing, Population, deposit, sample_semi_axes
from imaging.packing.config import packing_settings

DIAMETER = 1.0e-6


def packing_section(section: Mapping[str, Any] | None = None, name: str = "tiny") -> dict[str, Any]:
    """A packing entry as the workflow hands it to the stage
    (:func:`imaging.packing.config.packing_settings`)."""
    return packing_settings(section, name)


def small_bed(seed: int, n: int = 40, box_diameters: float = 3.0, theta_max: float = np.pi / 2,
              axis_ratio: float = 1.0, attempts: int = 800, size_sigma: float = 0.0,
              steepest: bool = True, scan_points: int = 0) -> Packing:
    """A bed of R = 0.1 disks of median equivalent diameter 1 um, high freedom (Table II
    series 2); ``size_sigma`` is the log-normal sigma of the basal surface, ``steepest``
    the direction rule of slides and swivels, ``scan_points`` the contact scan's n_sp (0:
    exact contacts)."""
    rng = np.random.default_rng(seed)
    population = Population(basal_surface_median=np.pi / 4 * DIAMETER**2,
                            basal_surface_sigma=size_sigma, aspect_ratio_median=0.1,
                            axis_ratio_median=axis_ratio)
    semi_axes = sample_semi_axes(population, n, rng)
    params = DepositionParameters(
        box_width=box_diameters * DIAMETER, contact_distance=5e-4 * DIAMETER, theta_max=theta_max,
        theta_random=True, slide_amplitude=5 * DIAMETER, swivel_amplitude=np.radians(80),
        rotation_amplitude=np.radians(80), attempts_per_cycle=attempts, steepest_slide=steepest,
        steepest_swivel=steepest, scan_points=scan_points)
    return deposit(semi_axes, params, rng)


@pytest.fixture(scope="session")
def elliptic_bed() -> Packing:
    """40 elliptic disks (l_a / l_b = 1.5) in a 3 d box."""
    return small_bed(seed=7, axis_ratio=1.5)


@pytest.fixture(scope="session")
def scanned_bed() -> Packing:
    """The elliptic bed's particles deposited with the paper's contact scan (n_sp = 150)."""
    return small_bed(seed=7, axis_ratio=1.5, scan_points=150)


@pytest.fixture(scope="session")
def polydisperse_bed() -> Packing:
    """60 disks, basal surface log-normal with sigma 0.8 (both grids of the bed index used),
    moved in random directions."""
    return small_bed(seed=8, n=60, box_diameters=5.0, attempts=200, size_sigma=0.8,
                     steepest=False)
