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


def _linear_weights(n: int, coarse: int) -> np.ndarray:
    """``(n, coarse)`` weights of linear interpolation from ``coarse`` nodes spanning
    ``n`` voxels."""
    position = np.arange(n) * (coarse - 1) / n
    low = np.minimum(position.astype(int), coarse - 2)
    weights = np.zeros((n, coarse))
    weights[np.arange(n), low] = 1.0 - (position - low)
    weights[np.arange(n), low + 1] = position - low
    return weights


def synthetic_scan(path: Path, size: int, slabs: int = 32) -> Path:
    """A ``size``^3 uint16 raw scan written slab by slab (memory of one slab): a cylinder
    of clay (grey 33000, noise 800) in air (2000), with pores (5000) where a smooth
    random field, trilinear (separably) from a coarse 32^3 grid, exceeds its 85th
    percentile."""
    if path.exists() and path.stat().st_size == 2 * size**3:
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    coarse = rng.standard_normal((32, 32, 32))
    level = np.percentile(coarse, 85.0)
    along = _linear_weights(size, 32)
    y, x = np.mgrid[0:size, 0:size] + 0.5 - size / 2
    outside = np.hypot(y, x) >= 0.45 * size
    partial_path = path.with_suffix(".partial")
    with open(partial_path, "wb") as handle:
        for z0 in range(0, size, slabs):
            planes = np.tensordot(along[z0:z0 + slabs], coarse, axes=1)  # (c, 32, 32)
            field = np.einsum("ya,cab,xb->cyx", along, planes, along, optimize=True)
            noise = np.random.default_rng(z0).standard_normal(field.shape, dtype=np.float32)
            grey = np.where(field > level, np.float32(5000.0), np.float32(33000.0))
            grey += 800.0 * noise
            grey[:, outside] = 2000.0 + 200.0 * noise[:, outside]
            np.clip(grey, 0, 65535).astype("<u2").tofile(handle)
    partial_path.rename(path)
    return path


def bench_imaging_stage(size: int = 512) -> dict:
    """The whole CT stage (porosity grid, REV, chords) on a synthetic ``size``^3 uint16 raw
    scan read in slabs (default chunk_mb and workers); the scan's making is not timed."""
    import logging
    import tempfile

    from imaging.ct import run as ct_run
    from shared.config import sample_imaging

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")

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


def imaging_scaling(folder: Path = Path("results/benchmarks")) -> dict:
    """Fitted cost exponents (time and peak memory against voxels, per phase) of the
    ``imaging_stage_*.json`` results in ``folder``, and their log-log figure
    ``imaging_stage_scaling.png`` there (``python -m benchmarks.imaging``)."""
    import json

    from matplotlib.figure import Figure

    records = sorted((json.loads(p.read_text()) for p in folder.glob("imaging_stage_*.json")),
                     key=lambda r: r["voxels"])
    voxels = np.array([r["voxels"] for r in records], dtype=float)
    series = {name: np.array([r["phases_s"][name] for r in records])
              for name in records[0]["phases_s"]}
    series["total"] = np.array([r["total_s"] for r in records])
    memory = np.array([r["peak_memory_bytes_above_baseline"] for r in records]) / 2**30
    exponents = {name: float(np.polyfit(np.log(voxels), np.log(values), 1)[0])
                 for name, values in series.items()}
    figure = Figure(figsize=(9.0, 4.0))
    axes = figure.subplots(1, 2)
    for name, values in series.items():
        axes[0].loglog(voxels, values, "o-", label=f"{name} (N^{exponents[name]:.2f})")
    axes[0].loglog(voxels, series["total"][-1] * voxels / voxels[-1], "k:", label="linear")
    axes[0].set(xlabel="voxels", ylabel="wall time [s]", title="CT stage, 2 cores")
    axes[1].semilogx(voxels, memory, "o-")
    axes[1].set_ylim(bottom=0.0)
    axes[1].set(xlabel="voxels", ylabel="peak memory above baseline [GiB]",
                title=f"chunk_mb {records[0]['chunk_mb']}, workers {records[0]['workers']}")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    figure.tight_layout()
    figure.savefig(folder / "imaging_stage_scaling.png", dpi=120)
    return {"voxels": voxels.tolist(), "exponents": exponents, "peak_gib": memory.tolist()}


if __name__ == "__main__":
    print(imaging_scaling())
