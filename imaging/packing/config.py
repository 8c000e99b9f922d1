"""Configuration section of the packing stage: defaults, validation and conversion.

Keys (SI units in the key name; angles in degrees as the paper gives them):

=========================== ============== ===============================================
key                         default        meaning
=========================== ============== ===============================================
n_particles                 300            number of disks N_p
box_width_m                 4.0e-6         box width w [m]
basal_surface_median_m2     7.853982e-13   median basal surface pi l_a l_b [m^2] (d = 1 um)
basal_surface_sigma         0.0            log-normal sigma of the basal surface
basal_surface_max_m2        null           truncation of the basal surface law [m^2]
aspect_ratio_median         0.1            median R = h / (2 sqrt(l_a l_b))
aspect_ratio_sigma          0.0            log-normal sigma of R
axis_ratio_median           1.0            median l_a / l_b (>= 1)
axis_ratio_sigma            0.0            log-normal sigma of l_a / l_b
contact_distance_m          5.0e-10        d_cont [m]
theta_initial_deg           90.0           theta_max: entry tilt of the normal [deg]
theta_initial_mode          "random"       "random": uniform in (0, theta_max); "fixed"
slide_amplitude_m           5.0e-6         A_slide [m]
swivel_amplitude_deg        80.0           A_swiv [deg]
rotation_amplitude_deg      80.0           A_rot [deg] (elliptic disks only)
n_cycles                    3              cycles of move attempts
attempts_per_cycle          800            attempts per cycle
amplitude_reduction         0.5            amplitude factor between cycles
slide_direction             "steepest"     "steepest": away from the contact; "random"
swivel_axis                 "steepest"     "steepest": fastest descent; "random" (horiz.)
two_contact_swivel          "line"         two contacts: swivel about the line through them
                                           ("line") or about the steepest horizontal axis
                                           through the foot of the altitude ("point")
seed                        0              seed of the numpy Generator
voxel_resolution            256            voxels across w (image of the linear zone)
profile_bin_width_m         null           slice thickness dz [m]; null: d / 2
z_min_m, z_max_m            null           linear-zone bounds [m]; null: detected
zone_tolerance              null           porosity band of the detection; null: auto
rocking_curve_bins          45             bins of theta on [0, 90 deg]
contact_grid_m              null           delta_m of Eq. 11 [m]; null: d / 40
density_kg_m3               2180.0         particle density (hydrated vermiculite)
log_interval_s              30.0           seconds between progress log lines
store_voxel_image           false          also write the solid image (uint8) to the file
image_analyses              true           REV and chord lengths of the image (imaging.rev,
                                           imaging.chords)
=========================== ============== ===============================================

d is the equivalent diameter of the median basal surface, 2 sqrt(S_median / pi).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from imaging.deposition.deposition import DepositionParameters
from imaging.deposition.population import Population

__all__ = ["DEFAULTS", "resolve", "population_of", "parameters_of"]

DEFAULTS: dict[str, Any] = {
    "n_particles": 300,
    "box_width_m": 4.0e-6,
    "basal_surface_median_m2": math.pi / 4.0 * 1.0e-12,
    "basal_surface_sigma": 0.0,
    "basal_surface_max_m2": None,
    "aspect_ratio_median": 0.1,
    "aspect_ratio_sigma": 0.0,
    "axis_ratio_median": 1.0,
    "axis_ratio_sigma": 0.0,
    "contact_distance_m": 5.0e-10,
    "theta_initial_deg": 90.0,
    "theta_initial_mode": "random",
    "slide_amplitude_m": 5.0e-6,
    "swivel_amplitude_deg": 80.0,
    "rotation_amplitude_deg": 80.0,
    "n_cycles": 3,
    "attempts_per_cycle": 800,
    "amplitude_reduction": 0.5,
    "slide_direction": "steepest",
    "swivel_axis": "steepest",
    "two_contact_swivel": "line",
    "seed": 0,
    "voxel_resolution": 256,
    "profile_bin_width_m": None,
    "z_min_m": None,
    "z_max_m": None,
    "zone_tolerance": None,
    "rocking_curve_bins": 45,
    "contact_grid_m": None,
    "density_kg_m3": 2180.0,
    "log_interval_s": 30.0,
    "store_voxel_image": False,
    "image_analyses": True,
}

_POSITIVE = (
    "box_width_m", "basal_surface_median_m2", "aspect_ratio_median", "contact_distance_m",
    "density_kg_m3", "log_interval_s",
)
_NON_NEGATIVE = (
    "basal_surface_sigma", "aspect_ratio_sigma", "axis_ratio_sigma", "slide_amplitude_m",
    "swivel_amplitude_deg", "rotation_amplitude_deg",
)
_POSITIVE_INTEGERS = (
    "n_particles", "n_cycles", "attempts_per_cycle", "voxel_resolution", "rocking_curve_bins",
)
_OPTIONAL_POSITIVE = (
    "basal_surface_max_m2", "profile_bin_width_m", "contact_grid_m", "zone_tolerance",
)


def _check_numbers(section: Mapping[str, Any]) -> None:
    for key in _POSITIVE_INTEGERS:
        value = section[key]
        if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
            raise ValueError(f"{key}: must be a positive integer, got {value!r}")
    for key in _POSITIVE:
        if not section[key] > 0.0:
            raise ValueError(f"{key}: must be > 0, got {section[key]!r}")
    for key in _NON_NEGATIVE:
        if not section[key] >= 0.0:
            raise ValueError(f"{key}: must be >= 0, got {section[key]!r}")
    for key in _OPTIONAL_POSITIVE:
        if section[key] is not None and not section[key] > 0.0:
            raise ValueError(f"{key}: must be > 0 or null, got {section[key]!r}")
    seed = section["seed"]
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    for key in ("store_voxel_image", "image_analyses"):
        if not isinstance(section[key], bool):
            raise ValueError(f"{key}: must be true or false, got {section[key]!r}")
    if not 0.0 < section["amplitude_reduction"] <= 1.0:
        raise ValueError("amplitude_reduction: must be in (0, 1]")
    if not 0.0 <= section["theta_initial_deg"] <= 90.0:
        raise ValueError(
            f"theta_initial_deg: must be in [0, 90], got {section['theta_initial_deg']!r}")
    if section["axis_ratio_median"] < 1.0:
        raise ValueError("axis_ratio_median: l_a / l_b must be >= 1 (l_a is the semi-major axis)")


def resolve(section: Mapping[str, Any] | None) -> dict[str, Any]:
    """The section with defaults filled in, validated.

    Parameters
    ----------
    section : mapping or None
        User keys (see the module docstring).

    Returns
    -------
    dict
        Every key of :data:`DEFAULTS`.

    Raises
    ------
    ValueError
        Naming the offending key: unknown key, wrong sign or range, l_a < l_b, a box
        narrower than the median particle or than the largest particle when the laws bound
        it (see :func:`_largest_semi_major_axis`), or zone bounds in the wrong order. Other
        size laws are checked against the sampled particles by
        :func:`imaging.deposition.run.run`.
    """
    section = dict(section or {})
    unknown = sorted(set(section) - set(DEFAULTS))
    if unknown:
        raise ValueError(f"{unknown[0]}: unknown key of the packing section")
    out = {**DEFAULTS, **section}
    _check_numbers(out)
    if out["theta_initial_mode"] not in ("random", "fixed"):
        raise ValueError("theta_initial_mode: must be 'random' or 'fixed'")
    for key in ("slide_direction", "swivel_axis"):
        if out[key] not in ("steepest", "random"):
            raise ValueError(f"{key}: must be 'steepest' or 'random', got {out[key]!r}")
    if out["two_contact_swivel"] not in ("line", "point"):
        raise ValueError("two_contact_swivel: must be 'line' or 'point', "
                         f"got {out['two_contact_swivel']!r}")
    population = population_of(out)
    semi_major = population.median_semi_major_axis
    if out["box_width_m"] <= 2.0 * semi_major:
        raise ValueError(
            f"box_width_m: {out['box_width_m']!r} m is not wider than the median particle "
            f"(2 l_a = {2.0 * semi_major:.3g} m)")
    largest = _largest_semi_major_axis(out)
    if largest is not None and out["box_width_m"] <= 2.0 * largest:
        raise ValueError(
            f"box_width_m: {out['box_width_m']!r} m is not wider than the largest particle the "
            f"size law allows (2 l_a = {2.0 * largest:.3g} m); widen it or lower "
            "basal_surface_max_m2")
    thickness = population.aspect_ratio_median * population.median_diameter
    if out["contact_distance_m"] >= 0.5 * thickness:
        raise ValueError(
            f"contact_distance_m: {out['contact_distance_m']!r} m is not small against the "
            f"median particle thickness ({thickness:.3g} m)")
    bound = out["basal_surface_max_m2"]
    if bound is not None and bound <= out["basal_surface_median_m2"]:
        raise ValueError("basal_surface_max_m2: must exceed basal_surface_median_m2")
    z_min, z_max = out["z_min_m"], out["z_max_m"]
    if z_min is not None and z_max is not None and z_min >= z_max:
        raise ValueError("z_min_m: must be below z_max_m")
    return out


def _largest_semi_major_axis(section: Mapping[str, Any]) -> float | None:
    """Largest l_a [m] the size laws allow, or None when they do not bound it.

    l_a = sqrt(S e / pi) with S the basal surface and e = l_a / l_b: bounded when S is
    (sigma 0, or ``basal_surface_max_m2`` set) and e is fixed (``axis_ratio_sigma`` 0; the
    law of e has no upper cut).
    """
    if section["axis_ratio_sigma"] > 0.0:
        return None
    if section["basal_surface_sigma"] > 0.0:
        surface = section["basal_surface_max_m2"]
        if surface is None:
            return None
    else:
        surface = section["basal_surface_median_m2"]
    return math.sqrt(surface * section["axis_ratio_median"] / math.pi)


def population_of(section: Mapping[str, Any]) -> Population:
    """Population of a resolved section."""
    return Population(
        basal_surface_median=float(section["basal_surface_median_m2"]),
        basal_surface_sigma=float(section["basal_surface_sigma"]),
        aspect_ratio_median=float(section["aspect_ratio_median"]),
        aspect_ratio_sigma=float(section["aspect_ratio_sigma"]),
        axis_ratio_median=float(section["axis_ratio_median"]),
        axis_ratio_sigma=float(section["axis_ratio_sigma"]),
        basal_surface_max=section["basal_surface_max_m2"],
    )


def parameters_of(section: Mapping[str, Any]) -> DepositionParameters:
    """Deposition parameters of a resolved section (angles converted to radians)."""
    return DepositionParameters(
        box_width=float(section["box_width_m"]),
        contact_distance=float(section["contact_distance_m"]),
        theta_max=math.radians(section["theta_initial_deg"]),
        theta_random=section["theta_initial_mode"] == "random",
        slide_amplitude=float(section["slide_amplitude_m"]),
        swivel_amplitude=math.radians(section["swivel_amplitude_deg"]),
        rotation_amplitude=math.radians(section["rotation_amplitude_deg"]),
        n_cycles=int(section["n_cycles"]),
        attempts_per_cycle=int(section["attempts_per_cycle"]),
        amplitude_reduction=float(section["amplitude_reduction"]),
        steepest_slide=section["slide_direction"] == "steepest",
        steepest_swivel=section["swivel_axis"] == "steepest",
        contact_line_swivel=section["two_contact_swivel"] == "line",
        log_interval=float(section["log_interval_s"]),
    )


def check_packings(config: Mapping[str, Any]) -> None:
    """Check every entry of ``packings``; the error names ``packings.<name>.<key>``."""
    from shared.config import ConfigError

    for name, section in config["packings"].items():
        try:
            resolve(section)
        except ValueError as err:
            raise ConfigError(f"config key 'packings.{name}.{err}") from err
