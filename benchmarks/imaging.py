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


def synthetic_scan(path: Path, size: int, slabs: int = 32) -> Path:
    """A ``size``^3 uint16 raw scan written slab by slab (memory of one slab): a cylinder
    of clay (grey 33000, noise 800) in air (2000), with pores (5000) where a smooth
    random field, trilinear from a coarse 32^3 grid, exceeds its 85th percentile."""
    from scipy.ndimage import map_coordinates

    if path.exists() and path.stat().st_size == 2 * size**3:
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    coarse = rng.standard_normal((32, 32, 32))
    level = np.percentile(coarse, 85.0)
    y, x = np.mgrid[0:size, 0:size] + 0.5 - size / 2
    inside = np.hypot(y, x) < 0.45 * size
    scale = 31.0 / size
    with open(path, "wb") as handle:
        for z0 in range(0, size, slabs):
            z = np.arange(z0, min(z0 + slabs, size))
            grid = np.meshgrid(z * scale, np.arange(size) * scale, np.arange(size) * scale,
                               indexing="ij")
            field = map_coordinates(coarse, grid, order=1)
            noise = np.random.default_rng(z0).normal(0.0, 800.0, field.shape)
            grey = np.where(field > level, 5000.0, 33000.0) + noise
            grey[:, ~inside] = 2000.0 + noise[:, ~inside] / 4
            np.clip(grey, 0, 65535).astype("<u2").tofile(handle)
    return path


def bench_imaging_stage(size: int = 512) -> dict:
    """The whole CT stage (porosity grid, REV, chords) on a synthetic ``size``^3 uint16 raw
    scan read in slabs (default chunk_mb and workers); the scan's making is not timed."""
    import tempfile

    from imaging.ct import run as ct_run
    from shared.config import sample_imaging

    scan = synthetic_scan(CACHE / f"synthetic_{size}.raw", size)
    voxel = 12.8e-3 / size
    entry = {"source": "raw", "path": str(scan), "voxel_size_m": voxel,
             "raw": {"shape": [size] * 3, "dtype": "uint16", "byte_order": "little"}}
    config = {**CONFIG, "samples": {"scan": {**entry, "imaging": {"grid_spacing_m": 4e-4}}}}
    imaging = sample_imaging(config, "scan")
    phases: dict[str, float] = {}
    with tempfile.TemporaryDirectory(dir=CACHE) as tmp:
        out = Path(tmp)
        start = time.perf_counter()
        ct_run.porosity("scan", entry, imaging, CONFIG["materials"]["pellet"], (1.0, 8), scan,
                        out / "image.nc", out / "porosity.nc", out / "porosity.png")
        phases["porosity"] = time.perf_counter() - start
        start = time.perf_counter()
        ds = ct_run.rev("scan", entry, imaging, scan, out / "image.nc", out / "porosity.nc",
                        out / "rev.nc", out / "rev.png")
        phases["rev_chords"] = time.perf_counter() - start
    return {"voxels": size**3, "scan_bytes": 2 * size**3, "chunk_mb": imaging["chunk_mb"],
            "workers": imaging["workers"], "analysed_cube": float(ds.attrs["analysed_cube_edge"]),
            "phases_s": phases, "total_s": sum(phases.values())}
