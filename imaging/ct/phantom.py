"""A synthetic CT scan of a compacted bentonite pellet, so that the chain runs without data.

The phantom is a cylinder (axis z, the compaction axis) of compacted clay in air. Its dry
density is a spatially correlated Gaussian field whose correlation length is shorter
along z than across, as compaction flattens the aggregates; a few thin flaws normal to
the compaction axis have a lower density. Density is mapped to grey values with the same
linear law that calibration inverts (air and muscovite anchors), then blurred like a
scanner's point-spread function and given Gaussian noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import ndimage

__all__ = ["PhantomSpec", "pellet_phantom"]


@dataclass(frozen=True)
class PhantomSpec:
    """Parameters of the pellet phantom (lengths in metres, densities in kg/m3).

    Attributes
    ----------
    shape
        Voxel counts ``(nz, ny, nx)``.
    voxel_size
        Edge of a cubic voxel [m].
    radius_fraction, height_fraction
        Cylinder radius as a fraction of half the smaller lateral side, and height as a
        fraction of the z extent [-].
    mean_density
        Mean dry density of the clay [kg/m3].
    density_std
        Standard deviation of the correlated density field [kg/m3].
    correlation_length_xy, correlation_length_z
        Gaussian correlation lengths across and along the compaction axis [m].
    n_flaws
        Number of thin low-density flaws.
    flaw_thickness
        Flaw thickness [m].
    flaw_density
        Density inside a flaw [kg/m3].
    n_muscovite_grains
        Number of 5x5x5-voxel grains of muscovite (they give the brightest grey, the
        calibration's upper anchor).
    air_density, muscovite_density
        Calibration anchors [kg/m3].
    grey_air, grey_muscovite
        Grey values of air and muscovite [-].
    blur_sigma
        Standard deviation of the Gaussian point-spread function [voxel].
    noise_std
        Standard deviation of additive grey noise [-].
    seed
        Seed of the random generator.
    """

    shape: tuple[int, int, int] = (64, 64, 64)
    voxel_size: float = 2.0e-4
    radius_fraction: float = 0.92
    height_fraction: float = 0.9
    mean_density: float = 2120.0
    density_std: float = 60.0
    correlation_length_xy: float = 8.0e-4
    correlation_length_z: float = 3.0e-4
    n_flaws: int = 3
    flaw_thickness: float = 4.0e-4
    flaw_density: float = 900.0
    n_muscovite_grains: int = 12
    air_density: float = 1.13
    muscovite_density: float = 3900.0
    grey_air: float = 2000.0
    grey_muscovite: float = 60000.0
    blur_sigma: float = 0.7
    noise_std: float = 300.0
    seed: int = 0


def _correlated_field(
    spec: PhantomSpec, rng: np.random.Generator
) -> npt.NDArray[np.float32]:
    """Unit-variance Gaussian random field with anisotropic Gaussian correlation."""
    white = rng.standard_normal(spec.shape, dtype=np.float32)
    sigma_vox = (
        spec.correlation_length_z / spec.voxel_size,
        spec.correlation_length_xy / spec.voxel_size,
        spec.correlation_length_xy / spec.voxel_size,
    )
    field = ndimage.gaussian_filter(white, sigma=sigma_vox, mode="wrap")
    field -= field.mean()
    field /= field.std()
    return field


def _cylinder_mask(spec: PhantomSpec) -> npt.NDArray[np.bool_]:
    nz, ny, nx = spec.shape
    z, y, x = np.ogrid[:nz, :ny, :nx]
    radius = spec.radius_fraction * 0.5 * min(ny, nx)
    half_height = spec.height_fraction * 0.5 * nz
    inside_disc = (y - (ny - 1) / 2) ** 2 + (x - (nx - 1) / 2) ** 2 <= radius**2
    inside_height = np.abs(z - (nz - 1) / 2) <= half_height
    return inside_disc & inside_height


def _flaw_mask(spec: PhantomSpec, rng: np.random.Generator) -> npt.NDArray[np.bool_]:
    """Thin slightly tilted discs normal to the compaction axis (lamination flaws)."""
    nz, ny, nx = spec.shape
    z, y, x = np.ogrid[:nz, :ny, :nx]
    flaws = np.zeros(spec.shape, dtype=bool)
    half_thickness = max(0.5 * spec.flaw_thickness / spec.voxel_size, 0.5)
    for _ in range(spec.n_flaws):
        centre = rng.uniform(0.3, 0.7, size=3) * np.array([nz, ny, nx])
        tilt = rng.normal(0.0, 0.08, size=2)
        radius = rng.uniform(0.2, 0.35) * min(ny, nx)
        plane = (z - centre[0]) - tilt[0] * (y - centre[1]) - tilt[1] * (x - centre[2])
        lateral = (y - centre[1]) ** 2 + (x - centre[2]) ** 2 <= radius**2
        flaws |= (np.abs(plane) <= half_thickness) & lateral
    return flaws


def _grain_mask(
    spec: PhantomSpec, specimen: npt.NDArray[np.bool_], rng: np.random.Generator
) -> npt.NDArray[np.bool_]:
    """Small cubic grains of the densest mineral at random specimen voxels."""
    grains = np.zeros(spec.shape, dtype=bool)
    inside = np.flatnonzero(ndimage.binary_erosion(specimen, iterations=2))
    if inside.size == 0 or spec.n_muscovite_grains == 0:
        return grains
    centres = rng.choice(inside, size=min(spec.n_muscovite_grains, inside.size), replace=False)
    grains.reshape(-1)[centres] = True
    return ndimage.binary_dilation(grains, structure=np.ones((5, 5, 5), dtype=bool))


def pellet_phantom(spec: PhantomSpec) -> tuple[npt.NDArray[np.uint16], npt.NDArray[np.float32]]:
    """Generate the greyscale phantom and its true density field.

    Parameters
    ----------
    spec
        Phantom parameters.

    Returns
    -------
    grey : ndarray of uint16, shape ``spec.shape``
        Blurred, noisy grey values, ordered ``(z, y, x)``.
    density : ndarray of float32, shape ``spec.shape``
        The density field the grey values were made from [kg/m3].
    """
    rng = np.random.default_rng(spec.seed)
    specimen = _cylinder_mask(spec)
    density = spec.mean_density + spec.density_std * _correlated_field(spec, rng)
    density[_flaw_mask(spec, rng) & specimen] = spec.flaw_density
    density[_grain_mask(spec, specimen, rng)] = spec.muscovite_density
    density[~specimen] = spec.air_density
    slope = (spec.grey_muscovite - spec.grey_air) / (spec.muscovite_density - spec.air_density)
    grey = spec.grey_air + slope * (density - spec.air_density)
    grey = ndimage.gaussian_filter(grey, sigma=spec.blur_sigma, mode="nearest")
    grey += rng.normal(0.0, spec.noise_std, size=spec.shape).astype(np.float32)
    return np.clip(np.rint(grey), 0, np.iinfo(np.uint16).max).astype(np.uint16), density
