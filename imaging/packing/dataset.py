"""The packing stage's computation: sample a population, deposit it, measure the bed
(:mod:`.measures`) and analyse its voxel image (:mod:`imaging.morphology`), as the
Dataset of docs/design.md §2, with no file read or written.

:func:`build_packing` takes a validated packing entry (:func:`.config.packing_settings`)
and returns the Dataset; :func:`packed_bed` also returns the voxel image the figure draws.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np
import xarray as xr

from imaging.morphology import chord_lengths, rev_analysis
from imaging.packing.config import parameters_of, population_of
from imaging.packing.deposition import Packing, deposit
from imaging.packing.measures import PackingMeasures, measure_packing
from imaging.packing.population import sample_semi_axes
from imaging.packing.voxels import VoxelImage
from shared.errors import ConfigError

__all__ = ["PackedBed", "build_packing", "packed_bed", "packing_dataset"]

log = logging.getLogger("imaging.packing")


def _var(dims: tuple[str, ...], data: Any, units: str, long_name: str) -> xr.Variable:
    return xr.Variable(dims, np.asarray(data), {"units": units, "long_name": long_name})


def _particle_variables(packing: Packing, measures: PackingMeasures) -> dict[str, xr.Variable]:
    p = ("particle",)
    return {
        "center": _var(p + ("xyz",), packing.centers, "m", "particle barycentre"),
        "semi_axes": _var(p + ("abc",), packing.semi_axes, "m",
                          "semi-axes l_a, l_b and half thickness h/2"),
        "euler": _var(p + ("angle",), packing.euler, "rad", "ZZZ Euler angles (phi, theta, psi)"),
        "normal": _var(p + ("xyz",), packing.normals, "1", "upward unit normal of the basal faces"),
        "volume": _var(p, packing.volumes, "m3", "particle volume"),
        "in_zone": _var(p, measures.in_zone.astype(np.uint8), "1",
                        "1 if the barycentre lies in the linear zone (z_min, z_max]"),
        "accepted_moves": _var(p, packing.accepted_moves, "1", "accepted settling moves"),
        "settle_time": _var(p, packing.wall_time, "s", "wall time spent settling the particle"),
    }


def _measure_variables(measures: PackingMeasures) -> dict[str, xr.Variable]:
    scalars = {
        "porosity": (measures.porosity, "1", "porosity of the linear zone"),
        "S": (measures.S, "1", "scalar order parameter of the Q tensor"),
        "S_part": (measures.S_part, "1", "order parameter <P2(cos theta)> per particle"),
        "S_vol": (measures.S_vol, "1", "order parameter <P2(cos theta)> weighted by volume"),
        "eta": (measures.eta, "1", "biaxiality of the Q tensor"),
        "beta": (np.degrees(measures.beta), "degree", "angle between director and z axis"),
        "A_B": (measures.A_B, "m2 g-1", "specific basal surface area"),
        "A_L": (measures.A_L, "m2 g-1", "specific lateral surface area"),
        "A_T": (measures.A_T, "m2 g-1", "specific total surface area"),
        "A_Bcont": (measures.A_Bcont, "m2 g-1", "specific basal surface area in contact"),
        "overlap_fraction": (measures.overlap_fraction, "1",
                             "share of solid voxels covered by two or more particles"),
        "z_min": (measures.z_min, "m", "bottom of the linear zone"),
        "z_max": (measures.z_max, "m", "top of the linear zone"),
        "voxel_size": (measures.image.voxel_size, "m", "voxel edge of the image"),
    }
    out = {name: _var((), value, units, text) for name, (value, units, text) in scalars.items()}
    out["porosity_profile"] = _var(("zbin",), measures.porosity_profile, "1",
                                   "porosity per slice of barycentre altitude")
    out["order_profile"] = _var(("zbin",), measures.order_profile, "1",
                                "S_part per slice of barycentre altitude")
    out["orientation_distribution"] = _var(("theta",), measures.orientation_distribution, "rad-1",
                                           "volume orientation distribution F_v")
    out["rocking_curve"] = _var(("theta",), measures.rocking_curve, "sr-1",
                                "calculated rocking curve I_c with A = 1")
    return out


_NOT_REACHED = ("NaN: no window smaller than the image satisfies the criterion, so the REV "
                "is not reached inside the image")


def _image_analysis_variables(
    image: VoxelImage, section: Mapping[str, Any], rng: np.random.Generator
) -> tuple[dict[str, xr.Variable], dict[str, xr.Variable]]:
    """REV and chord-length analyses (:mod:`imaging.morphology`) of the pore image, as
    (data variables, coordinates), with the entry's ``rev_*`` and ``chords_*`` settings;
    empty when the image is too thin.

    Two REV criteria are stored: the spread of random windows (relative standard deviation
    below ``rev_tolerance``, windows up to ``rev_max_window_fraction`` of the image so that
    they can differ) and the paper's centred window (Sec. V C: a window centred in the
    image, grown in all directions, whose porosity or interface density stays within
    ``rev_tolerance`` of the whole image's for all larger windows, up to the whole image).
    """
    pore = ~image.solid
    if min(pore.shape) < 8:
        log.warning("REV and chord analyses skipped: image %s too thin", pore.shape)
        return {}, {}
    tolerance = float(section["rev_tolerance"])
    rev = rev_analysis(pore, image.voxel_size, rng, binary=pore, tolerance=tolerance,
                       n_sizes=int(section["rev_n_sizes"]),
                       n_positions=int(section["rev_n_positions"]),
                       max_window_fraction=float(section["rev_max_window_fraction"]),
                       n_centred_sizes=int(section["rev_centred_n_sizes"]))
    edges_c = rev.window_centred * image.voxel_size
    chords = chord_lengths(pore, image.voxel_size, bool(section["chords_include_edges"]))
    cd = ("direction", "chord_length")
    random_note = ("NaN: the relative standard deviation over random windows exceeds the "
                   "tolerance at the largest window (rev_max_window_fraction of the image)")
    out = {
        "rev_porosity_std": _var(("window",), rev.porosity_std, "1",
                                 "std of porosity over random windows"),
        "rev_interface_std": _var(("window",), rev.interface_std, "m-1",
                                  "std of interface density over random windows"),
        "w_rev_porosity": _var((), rev.w_rev_porosity, "m",
                               "REV edge for porosity, random-window criterion"),
        "w_rev_interface": _var((), rev.w_rev_interface, "m",
                                "REV edge for interface density, random-window criterion"),
        "rev_porosity_centred": _var(("window_centred",), rev.porosity_centred, "1",
                                     "porosity of the centred window"),
        "rev_interface_centred": _var(("window_centred",), rev.interface_centred, "m-1",
                                      "interface density of the centred window"),
        "w_rev_porosity_centred": _var((), rev.w_rev_porosity_centred, "m",
                                       "REV edge for porosity, centred-window criterion"),
        "w_rev_interface_centred": _var((), rev.w_rev_interface_centred, "m",
                                        "REV edge for interface density, centred-window "
                                        "criterion"),
        "chord_pore": _var(cd, chords.f_pore, "m-1", "pore chord length distribution"),
        "chord_solid": _var(cd, chords.f_solid, "m-1", "solid chord length distribution"),
        "mean_chord_pore": _var(("direction",), chords.mean_pore, "m", "mean pore chord"),
        "mean_chord_solid": _var(("direction",), chords.mean_solid, "m", "mean solid chord"),
        "R_p": _var((), chords.R_p, "1", "pore chord anisotropy l_z / l_xy"),
        "R_s": _var((), chords.R_s, "1", "solid chord anisotropy l_z / l_xy"),
    }
    for name in ("w_rev_porosity", "w_rev_interface"):
        out[name].attrs.update(tolerance=tolerance, missing_value_meaning=random_note)
    for name in ("w_rev_porosity_centred", "w_rev_interface_centred"):
        out[name].attrs.update(tolerance=tolerance, missing_value_meaning=_NOT_REACHED)
    return out, {
        "window": _var(("window",), rev.window * image.voxel_size, "m", "REV window edge"),
        "window_centred": _var(("window_centred",), edges_c, "m",
                               "edge of the centred REV window"),
        "chord_length": _var(("chord_length",), chords.length, "m", "chord length"),
        "direction": xr.Variable(("direction",), list(chords.direction)),
    }


def packing_dataset(
    packing: Packing, measures: PackingMeasures, store_image: bool = False
) -> xr.Dataset:
    """The packing file's dataset (docs/design.md §2).

    Parameters
    ----------
    packing : Packing
    measures : PackingMeasures
    store_image : bool
        Also store the solid image ``solid(vz, vy, vx)``.

    Returns
    -------
    xarray.Dataset
    """
    edges = measures.edges
    coords = {
        "particle": _var(("particle",), np.arange(packing.centers.shape[0]), "1",
                         "particle index in order of deposition"),
        "xyz": xr.Variable(("xyz",), ["x", "y", "z"]),
        "abc": xr.Variable(("abc",), ["a", "b", "c"]),
        "angle": xr.Variable(("angle",), ["phi", "theta", "psi"]),
        "zbin": _var(("zbin",), 0.5 * (edges[:-1] + edges[1:]), "m", "slice centre altitude"),
        "theta": _var(("theta",), measures.theta, "rad", "angle of the normal to z"),
    }
    data = {**_particle_variables(packing, measures), **_measure_variables(measures)}
    if store_image:
        image = measures.image
        n = image.counts.shape
        l_v = image.voxel_size
        coords["vz"] = _var(("vz",), image.z_origin + (np.arange(n[0]) + 0.5) * l_v, "m", "voxel z")
        coords["vy"] = _var(("vy",), (np.arange(n[1]) + 0.5) * l_v, "m", "voxel y")
        coords["vx"] = _var(("vx",), (np.arange(n[2]) + 0.5) * l_v, "m", "voxel x")
        data["solid"] = _var(("vz", "vy", "vx"), image.solid.astype(np.uint8), "1",
                             "1 where the voxel centre lies in a particle")
    ds = xr.Dataset(data, coords=coords)
    ds["zbin"].attrs["slice_width"] = float(edges[1] - edges[0])
    ds.attrs.update(box_width=packing.box_width, contact_distance=packing.contact_distance,
                    n_particles=int(packing.centers.shape[0]))
    return ds




class PackedBed(NamedTuple):
    """A built packing (:func:`packed_bed`).

    Attributes
    ----------
    dataset : xarray.Dataset
        The packing's dataset (:func:`build_packing`).
    image : VoxelImage
        Its voxel image (drawn by :func:`imaging.packing.figures.packing_figure`).
    """

    dataset: xr.Dataset
    image: VoxelImage


def packed_bed(settings: Mapping[str, Any]) -> PackedBed:
    """Build and measure a virtual clay porous medium: its dataset and voxel image.

    Parameters
    ----------
    settings : mapping
        One entry of ``packings``, validated: every key of the schema's packing entry
        (``workflow/schemas/config.schema.yaml``, defaults filled in), checked by
        :func:`imaging.packing.config.check_packing` (:func:`.config.packing_settings`
        makes one).

    Returns
    -------
    PackedBed
        ``(dataset, image)``.

    Raises
    ------
    ConfigError
        Naming ``box_width_m`` when the largest sampled particle (2 l_a) does not fit in
        the box (size laws without a bound, which the configuration checks cannot judge).
    """
    population = population_of(settings)
    rng = np.random.default_rng(settings["seed"])
    semi_axes = sample_semi_axes(population, int(settings["n_particles"]), rng)
    widest = 2.0 * float(semi_axes[:, 0].max())
    if widest >= settings["box_width_m"]:
        raise ConfigError(f"box_width_m: the largest sampled particle (2 l_a = {widest:.3g} m) "
                         "does not fit in the box; widen it or set basal_surface_max_m2")
    packing = deposit(semi_axes, parameters_of(settings), rng)
    diameter = population.median_diameter
    measures = measure_packing(
        packing,
        profile_bin_width=settings["profile_bin_width_m"] or 0.5 * diameter,
        contact_grid=settings["contact_grid_m"] or diameter / 40.0,
        voxel_resolution=int(settings["voxel_resolution"]),
        rocking_curve_bins=int(settings["rocking_curve_bins"]),
        density=settings["density_kg_m3"],
        z_min=settings["z_min_m"],
        z_max=settings["z_max_m"],
        zone_tolerance=settings["zone_tolerance"],
    )
    ds = packing_dataset(packing, measures, bool(settings["store_voxel_image"]))
    if settings["image_analyses"]:
        data, coords = _image_analysis_variables(measures.image, settings,
                                                 np.random.default_rng([settings["seed"], 1]))
        ds = ds.assign_coords(coords).assign(data)
    return PackedBed(ds, measures.image)


def build_packing(settings: Mapping[str, Any]) -> xr.Dataset:
    """The dataset of a virtual clay porous medium built and measured from its settings.

    Parameters
    ----------
    settings : mapping
        A validated packing entry (:func:`packed_bed`).

    Returns
    -------
    xarray.Dataset
        Per particle ``center``, ``semi_axes``, ``euler``, ``normal``, ``volume`` [m, rad,
        m3]; the linear zone's ``porosity``, order parameters ``S``, ``S_part``, ``S_vol``,
        ``eta``, ``beta``, specific surface areas ``A_B``, ``A_L``, ``A_T``, ``A_Bcont``
        [m2 g-1], ``overlap_fraction``; the ``porosity_profile`` and ``order_profile`` on
        ``zbin``, ``orientation_distribution`` and ``rocking_curve`` on ``theta``; with
        ``image_analyses`` the REV and chord-length variables; with ``store_voxel_image``
        the ``solid`` image.

    Raises
    ------
    ConfigError
        As :func:`packed_bed`.
    """
    return packed_bed(settings).dataset
