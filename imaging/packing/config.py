"""A packing entry of the configuration: the checks across its keys, and its conversion.

Every key of ``packings.<name>``, its type, bounds, default and meaning is in the JSON
schema (``workflow/schemas/config.schema.yaml``), which validates the entry and fills in
its defaults. This module holds what the schema cannot express: checks across keys
(:func:`check_packings`), and the conversion of a validated entry into the parameters of
the deposition (:func:`population_of`, :func:`parameters_of`). :func:`packing_settings`
makes a validated entry from a few keys, as a notebook needs one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from imaging.packing.population import Population
from shared.config import DEFAULT_CONFIG_PATH, ConfigError, read_config_file, validate_config

if TYPE_CHECKING:
    from imaging.packing.deposition import DepositionParameters

__all__ = ["check_packing", "check_packings", "packing_settings", "population_of", "parameters_of"]


def check_packings(config: Mapping[str, Any]) -> None:
    """Check every entry of ``config["packings"]`` across its keys (:func:`check_packing`).

    Parameters
    ----------
    config : mapping
        The configuration, validated against the schema (defaults filled in).

    Raises
    ------
    ConfigError
        Naming ``packings.<name>.<key>``.
    """
    for name, section in config.get("packings", {}).items():
        check_packing(name, section)


def packing_settings(entry: Mapping[str, Any] | None = None, name: str = "packing"
                     ) -> dict[str, Any]:
    """A packing entry as the workflow hands it to the stage: validated against the schema
    with its defaults filled in, and checked across keys (:func:`check_packings`).

    The entry replaces the packings of the default configuration, which is validated as a
    whole, so errors read as the workflow's: ``config key 'packings.<name>.<key>': ...``.

    Parameters
    ----------
    entry : mapping, optional
        Keys of ``packings.<name>`` (the schema's defaults for the others).
    name : str
        The entry's name, in messages.

    Raises
    ------
    ConfigError
        Naming ``packings.<name>.<key>``.
    """
    config = read_config_file(DEFAULT_CONFIG_PATH)
    config["packings"] = {name: dict(entry or {})}
    validate_config(config)
    check_packings(config)
    return config["packings"][name]


def check_packing(name: str, section: Mapping[str, Any]) -> None:
    """Checks of one packing entry that the schema cannot express.

    Parameters
    ----------
    name : str
        The entry's name (a key of ``packings``), for the message.
    section : mapping
        The entry, validated against the schema (defaults filled in).

    Raises
    ------
    ConfigError
        Naming ``packings.<name>.<key>``: a box not wider than the median particle, or
        than the largest particle when the size laws bound it (see
        :func:`_largest_semi_major_axis`); a contact distance not small against the
        median particle thickness; a truncation of the basal surface law at or below its
        median; zone bounds in the wrong order. Size laws without a bound are checked
        against the sampled particles by :func:`imaging.packing.dataset.packed_bed`.
    """

    def fail(key: str, reason: str) -> ConfigError:
        return ConfigError(f"config key 'packings.{name}.{key}': {reason}")

    bound = section["basal_surface_max_m2"]
    if bound is not None and bound <= section["basal_surface_median_m2"]:
        raise fail("basal_surface_max_m2", "must exceed basal_surface_median_m2")
    population = population_of(section)
    width = section["box_width_m"]
    semi_major = population.median_semi_major_axis
    if width <= 2.0 * semi_major:
        raise fail("box_width_m", f"{width!r} m is not wider than the median particle "
                   f"(2 l_a = {2.0 * semi_major:.3g} m)")
    largest = _largest_semi_major_axis(section)
    if largest is not None and width <= 2.0 * largest:
        raise fail("box_width_m", f"{width!r} m is not wider than the largest particle the "
                   f"size law allows (2 l_a = {2.0 * largest:.3g} m); widen it or lower "
                   "basal_surface_max_m2")
    thickness = population.aspect_ratio_median * population.median_diameter
    if section["contact_distance_m"] >= 0.5 * thickness:
        raise fail("contact_distance_m", f"{section['contact_distance_m']!r} m is not small "
                   f"against the median particle thickness ({thickness:.3g} m)")
    z_min, z_max = section["z_min_m"], section["z_max_m"]
    if z_min is not None and z_max is not None and z_min >= z_max:
        raise fail("z_min_m", "must be below z_max_m")


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
    """Population of a validated packing entry."""
    bound = section["basal_surface_max_m2"]
    return Population(
        basal_surface_median=float(section["basal_surface_median_m2"]),
        basal_surface_sigma=float(section["basal_surface_sigma"]),
        aspect_ratio_median=float(section["aspect_ratio_median"]),
        aspect_ratio_sigma=float(section["aspect_ratio_sigma"]),
        axis_ratio_median=float(section["axis_ratio_median"]),
        axis_ratio_sigma=float(section["axis_ratio_sigma"]),
        basal_surface_max=None if bound is None else float(bound),
    )


def parameters_of(section: Mapping[str, Any]) -> DepositionParameters:
    """Deposition parameters of a validated packing entry (angles converted to radians)."""
    # imported here: the checks above serve the workflow's DAG, which compiles no kernel
    from imaging.packing.deposition import DepositionParameters

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
        scan_points=int(section["scan_points"]) if section["contact_mode"] == "scan" else 0,
    )
