"""Benchmark cases of the imaging stage (timed in a process of their own by the harness)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from benchmarks.parameters import CONFIG
from imaging.ct.calibration import Calibration
from imaging.ct.grid import block_average
from imaging.ct.io import read_raw
from imaging.ct.mask import specimen_mask
from imaging.ct.phantom import PhantomSpec, pellet_phantom
from imaging.morphology import chord_lengths, rev_analysis

CACHE = Path("results/benchmarks/cache")


def _phantom_file(size: int) -> Path:
    """A phantom scan of ``size``^3 voxels on disk, made once (its making is not timed)."""
    path = CACHE / f"phantom_{size}.raw"
    if not path.exists():
        CACHE.mkdir(parents=True, exist_ok=True)
        grey, _ = pellet_phantom(PhantomSpec(shape=(size,) * 3, voxel_size=12.8e-3 / size))
        grey.tofile(path)
    return path


def bench_imaging_calibration(size: int = 512) -> dict:
    """Read a uint16 scan, mask it, calibrate and block-average it to a 0.6 mm grid."""
    path = _phantom_file(size)
    phases: dict[str, float] = {}
    start = time.perf_counter()
    grey = read_raw(path, (size,) * 3)
    phases["read"] = time.perf_counter() - start
    start = time.perf_counter()
    specimen = specimen_mask(grey)
    phases["mask"] = time.perf_counter() - start
    start = time.perf_counter()
    voxel = 12.8e-3 / size
    anchors, material = CONFIG["imaging"]["calibration"], CONFIG["materials"]["pellet"]
    calibration = Calibration(
        2000.0, 60000.0, air_density=anchors["air_density_kg_m3"],
        muscovite_density=anchors["muscovite_density_kg_m3"],
        dry_density=material["dry_density_kg_m3"], mean_porosity=material["reference_porosity"],
    )
    grid = block_average(grey, specimen, calibration, round(6e-4 / voxel), voxel)
    phases["calibrate_block_average"] = time.perf_counter() - start
    return {"voxels": size**3, "volume_bytes": grey.nbytes, "grid": list(grid.porosity.shape),
            "phases_s": phases, "total_s": sum(phases.values()) - phases["read"]}


def _binary(size: int) -> np.ndarray:
    return np.random.default_rng(0).random((size,) * 3) < 0.35


def bench_imaging_rev(size: int = 256) -> dict:
    """REV analysis (12 window sizes x 64 positions) of a random binary image."""
    image = _binary(size)
    rev_analysis(image[:16, :16, :16].astype(np.float32), 1e-6, np.random.default_rng(0),
                 binary=image[:16, :16, :16])
    start = time.perf_counter()
    rev_analysis(image.astype(np.float32), 1e-6, np.random.default_rng(0), binary=image)
    return {"voxels": size**3, "phases_s": {"rev": time.perf_counter() - start}}


def bench_imaging_chords(size: int = 256) -> dict:
    """Chord-length distributions along x, y, z of a random binary image."""
    image = _binary(size)
    chord_lengths(image[:8, :8, :8], 1e-6)
    start = time.perf_counter()
    chord_lengths(image, 1e-6)
    return {"voxels": size**3, "phases_s": {"chords": time.perf_counter() - start}}
