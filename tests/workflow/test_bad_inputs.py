"""A corpus of bad inputs: each is refused in one line that names the file or the key.

Every case runs through a stage's entry point (the function its rule script calls:
:func:`imaging.ct.run.porosity`, :func:`micro.run.run`, or the config validation of
``common.smk``) and asserts the error type, that the message names the file or the
config key, and that the results folder holds no new file afterwards. The user sees the
message through ``workflow/scripts/_logging.py``: the last tests check that an expected
failure prints one ``claychain:`` line and no traceback (which goes to the job's log),
in a plain Python process and in a real ``snakemake`` run of a tiny configuration.
"""

from __future__ import annotations

import copy
import errno
import importlib.util
import logging
import os
import signal
import subprocess
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import xarray as xr

from imaging.ct import run as ct_run
from imaging.ct.io import ImageError, write_tiff_stack
from imaging.ct.phantom import pellet_phantom
from imaging.ct.porosity import CLAMPED_WARNING_FRACTION
from imaging.ct.settings import ScanResources
from imaging.packing.config import check_packings
from micro import case as micro_case
from micro import run as micro_run
from micro.config import check_studies
from micro.hydration import DivergenceError
from shared.checkpointer import Checkpointer
from shared.config import ConfigError, default_config, load_config, validate_config
from shared.errors import InputError
from shared.io import OutputError, write_dataset
from tests.workflow._chain import snakemake, workdir

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = ROOT / "workflow" / "scripts"
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
"""A job's environment: the scripts import this tree's packages."""
CONFIG = default_config()
VOXEL = 3.0e-4


def _files(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*") if p.is_file()} if folder.exists() else set()


def _phantom_volume() -> np.ndarray:
    """A small 16-bit pellet scan (the project's phantom, 32^3 voxels of 0.3 mm)."""
    spec = ct_run.phantom_spec(dict(CONFIG["phantom"], shape=[32, 32, 32], seed=3),
                               CONFIG["imaging"]["calibration"], VOXEL)
    return pellet_phantom(spec)[0]


@pytest.fixture(scope="module")
def volume() -> np.ndarray:
    return _phantom_volume()


# ------------------------------------------------------------------------ CT scans


def _truncated(pages_kept: float) -> Callable[[Path, np.ndarray], tuple[str, Path]]:
    def make(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
        scan = write_tiff_stack(volume, tmp / "cut.tif")
        data = scan.read_bytes()
        scan.write_bytes(data[: int(len(data) * pages_kept)])
        return "tiff", scan
    return make


def _one_page(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    cv2.imwrite(str(tmp / "flat.tif"), volume[0])
    return "tiff", tmp / "flat.tif"


def _garbage(name: str, source: str) -> Callable[[Path, np.ndarray], tuple[str, Path]]:
    def make(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
        (tmp / name).write_bytes(b"II*\x00 this is not an image" * 10 if name.endswith("tif")
                                 else b"not a netCDF file at all")
        return source, tmp / name
    return make


def _folder_as_tiff(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    (tmp / "stack.tif").mkdir()
    return "tiff", tmp / "stack.tif"


def _file_as_slices(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    return "slices", write_tiff_stack(volume, tmp / "stack.tif")


def _empty_folder(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    (tmp / "slices").mkdir()
    (tmp / "slices" / "notes.txt").write_text("no images here")
    return "slices", tmp / "slices"


def _colour_slices(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    folder = tmp / "colour"
    folder.mkdir()
    for k, page in enumerate(volume[:4]):
        cv2.imwrite(str(folder / f"s{k}.png"), np.dstack([(page >> 8).astype(np.uint8)] * 3))
    return "slices", folder


def _mixed_slices(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    folder = tmp / "mixed"
    folder.mkdir()
    for k, page in enumerate(volume[:4]):
        cv2.imwrite(str(folder / f"s{k}.tif"), page if k else page[:-2])
    return "slices", folder


def _uniform(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    black = np.zeros((8, 16, 16), np.uint16)
    cv2.imwritemulti(str(tmp / "black.tif"), list(black))
    return "tiff", tmp / "black.tif"


def _float_tiff(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    cv2.imwritemulti(str(tmp / "float.tif"), list(volume.astype(np.float32)))
    return "tiff", tmp / "float.tif"


def _tiff_bytes(pages: int, width: int, height: int, bits: int, sample_format: int,
                pixels: bytes) -> bytes:
    """A little-endian multi-page TIFF whose pages all declare ``width`` x ``height``
    pixels of ``bits`` bits and SampleFormat ``sample_format`` and hold ``pixels`` (what
    OpenCV cannot write: 32-bit integers, or a header larger than the data)."""
    import struct

    tags = 9
    directory = 2 + 12 * tags + 4
    data_at = 8 + pages * directory
    out = [b"II*\x00", struct.pack("<I", 8)]
    for k in range(pages):
        entries = [(256, 4, width), (257, 4, height), (258, 3, bits), (259, 3, 1), (262, 3, 1),
                   (273, 4, data_at + k * len(pixels)), (278, 4, height), (279, 4, len(pixels)),
                   (339, 3, sample_format)]
        out.append(struct.pack("<H", tags))
        out += [struct.pack("<HHII", tag, kind, 1, value) for tag, kind, value in entries]
        out.append(struct.pack("<I", 0 if k == pages - 1 else 8 + (k + 1) * directory))
    return b"".join(out) + pixels * pages


def _uint32_tiff(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    pixels = volume[0, :8, :8].astype(np.uint32).tobytes()
    (tmp / "u32.tif").write_bytes(_tiff_bytes(4, 8, 8, 32, 1, pixels))
    return "tiff", tmp / "u32.tif"


def _huge_header(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    (tmp / "huge.tif").write_bytes(_tiff_bytes(2, 65_000, 65_000, 16, 1, b"\0" * 64))
    return "tiff", tmp / "huge.tif"


def _cv2_tiff(dtype: type) -> Callable[[Path, np.ndarray], tuple[str, Path]]:
    def make(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
        path = tmp / f"{np.dtype(dtype).name}.tif"
        cv2.imwritemulti(str(path), list((volume[:4] >> 9).astype(dtype)))
        return "tiff", path
    return make


def _int8_slices(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    folder = tmp / "int8"
    folder.mkdir()
    for k, page in enumerate(volume[:4]):
        cv2.imwrite(str(folder / f"s{k}.tif"), (page >> 9).astype(np.int8))
    return "slices", folder


def _short_raw(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    volume[:-1].tofile(tmp / "short.raw")
    return "raw", tmp / "short.raw"


def _netcdf_without_grey(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    ds = xr.Dataset({"density": (("z", "y", "x"), volume.astype(float),
                                 {"units": "kg m-3", "long_name": "d"})})
    return "netcdf", write_dataset(ds, tmp / "nogrey.nc", stage="imaging", title="t")


def _missing(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    return "tiff", tmp / "absent.tif"


def _missing_folder(tmp: Path, volume: np.ndarray) -> tuple[str, Path]:
    return "slices", tmp / "absent_slices"


SCANS = {
    # (how the bad scan is made, words the message must hold besides the file's name)
    "tiff_22_of_32_pages_missing": (_truncated(10.5 / 32), "truncated"),
    "tiff_cut_in_a_page_directory": (_truncated(0.5), "truncated"),
    "tiff_missing_its_last_byte": (_truncated(0.99999), "truncated"),
    "tiff_cut_inside_the_first_page": (_truncated(0.01), "truncated"),
    "tiff_single_page": (_one_page, "3-D"),
    "tiff_not_an_image": (_garbage("junk.tif", "tiff"), "TIFF"),
    "tiff_is_a_folder": (_folder_as_tiff, "is a folder"),
    "tiff_missing": (_missing, "no such file"),
    "tiff_uniform_black": (_uniform, "uniform"),
    "tiff_32_bit_float": (_float_tiff, "its pixels are float32"),
    "tiff_64_bit_float": (_cv2_tiff(np.float64), "its pixels are float64 (TIFF BitsPerSample"),
    "tiff_8_bit_signed": (_cv2_tiff(np.int8), "its pixels are int8"),
    "tiff_32_bit_unsigned": (_uint32_tiff, "its pixels are uint32"),
    "tiff_header_beyond_opencv_limits": (_huge_header, "its pages are 65000 x 65000 pixels, beyond what OpenCV"),
    "slices_8_bit_signed": (_int8_slices, "its pixels are int8"),
    "slices_given_a_file": (_file_as_slices, "is a file"),
    "slices_folder_missing": (_missing_folder, "no such folder"),
    "slices_folder_without_images": (_empty_folder, "no slice files"),
    "slices_in_colour": (_colour_slices, "single-channel"),
    "slices_of_different_shapes": (_mixed_slices, "different shapes"),
    "raw_of_the_wrong_size": (_short_raw, "bytes"),
    "raw_is_a_folder": (lambda tmp, v: ("raw", _folder_as_tiff(tmp, v)[1]), "is a folder"),
    "netcdf_without_grey": (_netcdf_without_grey, "'grey'"),
    "netcdf_not_netcdf": (_garbage("junk.nc", "netcdf"), "not a readable netCDF"),
}


def _porosity(tmp: Path, source: str, scan: Path, *, imaging: dict | None = None,
              voxel_size: float = VOXEL, shape: tuple[int, ...] = (32, 32, 32)) -> xr.Dataset:
    entry: dict[str, Any] = {"source": source, "path": str(scan), "voxel_size_m": voxel_size}
    if source == "raw":
        entry["raw"] = {"shape": list(shape), "dtype": "uint16", "byte_order": "little"}
    results = tmp / "results"
    return _ct_porosity("scan", entry, imaging or CONFIG["imaging"], (4.0e-3, 216), scan,
                        results, "scan")


def _ct_porosity(sample: str, entry: dict, imaging: dict, micro: tuple, scan: Path | str,
                 results: Path, name: str) -> xr.Dataset:
    """The imaging_porosity rule's entry point on a sample, as its script calls it."""
    config = {"sample": entry, "imaging": imaging, "material": CONFIG["materials"]["pellet"],
              "micro_spacing": micro}
    outputs = ct_run.PorosityOutputs(results / f"images/{name}.nc", results / f"porosity/{name}.nc",
                                     results / f"porosity/{name}.png")
    return ct_run.porosity(config, sample, scan, outputs, resources=ScanResources.from_mapping(imaging))


@pytest.mark.parametrize("case", sorted(SCANS))
def test_a_bad_scan_is_refused_naming_the_file(case, volume, tmp_path):
    make, words = SCANS[case]
    source, scan = make(tmp_path, volume.copy())
    before = _files(tmp_path / "results")
    with pytest.raises(ImageError) as err:
        _porosity(tmp_path, source, scan)
    message = str(err.value)
    assert str(scan) in message and words in message
    assert "\n" not in message
    assert _files(tmp_path / "results") == before == set()


def _imaging(**changes: Any) -> dict:
    imaging = copy.deepcopy(CONFIG["imaging"])
    for key, value in changes.items():
        *sections, name = key.split(".")
        node = imaging
        for section in sections:
            node = node[section]
        node[name] = value
    return imaging


GRID_SETTINGS = {
    # (imaging settings, keys the message must name)
    "every_block_outside_the_porosity_bounds": (
        {"calibration.porosity_bounds": [0.9, 0.95]},
        ["imaging.calibration.porosity_bounds", "samples.scan.voxel_size_m"]),
    "no_block_inside_the_specimen": (
        {"mask.threshold": 65535.0}, ["imaging.mask"]),
    "anchors_swapped": (
        {"calibration.grey_air": 60000.0, "calibration.grey_muscovite": 100.0},
        ["imaging.calibration"]),
    "cylinder_outside_the_field": (
        {"mask.mode": "cylinder", "mask.cylinder_radius_m": 1e-4,
         "mask.cylinder_centre_m": [1.0, 1.0]}, ["holds no voxel", "imaging.mask"]),
    "full_field_without_an_air_anchor": (
        {"mask.mode": "full"}, ["no air", "imaging.calibration.grey_air", "histogram_peaks"]),
    "histogram_peaks_of_the_wrong_order": (
        {"calibration.anchors": "histogram_peaks",
         "calibration.peak_densities_kg_m3": [2000.0, 1.13]},
        ["increasing densities", "imaging.calibration"]),
}


@pytest.mark.parametrize("case", sorted(GRID_SETTINGS))
def test_a_scan_giving_no_usable_grid_is_refused_naming_the_keys(case, volume, tmp_path):
    changes, keys = GRID_SETTINGS[case]
    scan = write_tiff_stack(volume, tmp_path / "scan.tif")
    with pytest.raises(ValueError) as err:
        _porosity(tmp_path, "tiff", scan, imaging=_imaging(**changes))
    message = str(err.value)
    assert str(scan) in message
    for key in keys:
        assert key in message
    assert not _files(tmp_path / "results")


def _core(volume: np.ndarray, grains: int = 0) -> np.ndarray:
    """The phantom's clay alone (a block inside its cylinder, no air around it), with
    ``grains`` bright muscovite grains."""
    spec = ct_run.phantom_spec(dict(CONFIG["phantom"], shape=[32, 32, 32], seed=3,
                                    n_muscovite_grains=grains),
                               CONFIG["imaging"]["calibration"], VOXEL)
    return np.ascontiguousarray(pellet_phantom(spec)[0][10:22, 10:22, 10:22])


def _one_phase(volume: np.ndarray) -> np.ndarray:
    """A single phase filling the field: one peak in the grey histogram."""
    rng = np.random.default_rng(0)
    return np.clip(rng.normal(30000.0, 500.0, (16, 16, 16)), 0, 65535).astype(np.uint16)


FILLED_FIELD = {
    # (scan filling its field of view, imaging settings, words of the message)
    "threshold_mask": (_core, {}, ["fill", "imaging.mask.mode",
                                   "samples.scan.imaging.mask.mode", "full", "histogram_peaks"]),
    "histogram_with_one_peak": (
        _one_phase, {"mask.mode": "full", "calibration.anchors": "histogram_peaks",
                     "calibration.peak_densities_kg_m3": [1.13, 2120.0]},
        ["1 peak(s)", "imaging.calibration"]),
}


@pytest.mark.parametrize("case", sorted(FILLED_FIELD))
def test_a_scan_without_air_is_refused_with_the_setting_to_change(case, volume, tmp_path):
    make, changes, words = FILLED_FIELD[case]
    scan = write_tiff_stack(make(volume), tmp_path / "core.tif")
    with pytest.raises(ValueError) as err:
        _porosity(tmp_path, "tiff", scan, imaging=_imaging(**changes))
    message = str(err.value)
    assert str(scan) in message and "\n" not in message
    for word in words:
        assert word in message
    assert not _files(tmp_path / "results")


def test_a_scan_without_air_whose_mask_looks_plausible_is_warned(volume, tmp_path, caplog):
    """Clay with bright grains and no air: the threshold takes the grains for the specimen
    and the clay for air; the clamped blocks' warning names the settings to change."""
    scan = write_tiff_stack(_core(volume, grains=12), tmp_path / "core.tif")
    with caplog.at_level(logging.WARNING, logger="imaging.ct"):
        ds = _porosity(tmp_path, "tiff", scan)
    assert "imaging.mask.mode" in ds.attrs["warnings"]
    assert any("histogram_peaks" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize("factor", [1e3, 1e-3])
def test_a_voxel_size_off_by_1000_is_warned_in_the_log_and_the_file(factor, volume, tmp_path,
                                                                   caplog):
    scan = write_tiff_stack(volume, tmp_path / "scan.tif")
    with caplog.at_level(logging.WARNING, logger="imaging.ct"):
        ds = _porosity(tmp_path, "tiff", scan, voxel_size=VOXEL * factor)
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert warned and all("samples.scan.voxel_size_m" in w for w in warned)
    assert "samples.scan.voxel_size_m" in ds.attrs["warnings"]
    written = xr.load_dataset(tmp_path / "results/porosity/scan.nc")
    assert written.attrs["warnings"] == ds.attrs["warnings"]


def test_many_clamped_blocks_are_warned(volume, tmp_path, caplog):
    scan = write_tiff_stack(volume, tmp_path / "scan.tif")
    with caplog.at_level(logging.WARNING, logger="imaging.ct"):
        ds = _porosity(tmp_path, "tiff", scan,
                       imaging=_imaging(**{"calibration.porosity_bounds": [0.2, 0.3]}))
    assert ds.attrs["clamped_fraction"] > CLAMPED_WARNING_FRACTION
    assert "imaging.calibration.porosity_bounds" in ds.attrs["warnings"]
    assert any("clamped" in r.getMessage() for r in caplog.records)


def test_a_good_scan_has_no_warning(volume, tmp_path, caplog):
    scan = write_tiff_stack(volume, tmp_path / "scan.tif")
    with caplog.at_level(logging.WARNING, logger="imaging.ct"):
        ds = _porosity(tmp_path, "tiff", scan)
    assert ds.attrs["warnings"] == ""
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]


# ------------------------------------------------------------------- porosity grids

EDGE = 4.0e-3
MICRO = copy.deepcopy(CONFIG)
MICRO["micro"].update(n_points=64, specimen_size_m=EDGE,
                      checkpoints_suction_pa=[132.0e6, 60.0e6], vtk_snapshots=False)


def _grid(values: np.ndarray, spacing: float = 5e-4, dims: tuple[str, ...] = ("z", "y", "x"),
          variable: str = "porosity") -> xr.Dataset:
    coords = {d: (d, (np.arange(n) + 0.5) * spacing, {"units": "m", "long_name": d})
              for d, n in zip(dims, values.shape, strict=True)}
    return xr.Dataset({variable: (dims, values, {"units": "1", "long_name": "porosity"})},
                      coords=coords)


def _hole() -> np.ndarray:
    values = np.full((20, 20, 20), 0.3)
    values[10, 9, 10] = np.nan
    return values


def _edge_nan() -> np.ndarray:
    values = np.full((12, 12, 12), 0.3)
    values[:2, :2, :2] = np.nan  # a corner of the scan outside the pellet
    return values


GRIDS = {
    # (dataset or file maker, expected error type, words the message must hold)
    "other_dimension_names": (_grid(np.full((20, 20, 20), 0.3), dims=("a", "b", "c")),
                              ValueError, ["dims", "micro.sample"]),
    "nan_hole_in_the_centre": (_grid(_hole()), ValueError,
                               ["hole", "imaging.min_specimen_fraction"]),
    "cube_reaches_past_the_specimen": (_grid(_edge_nan()), ValueError,
                                       ["outside the scanned pellet", "micro.specimen_size_m"]),
    "grid_smaller_than_the_cube": (_grid(np.full((6, 6, 6), 0.3)), ValueError,
                                   ["does not span", "micro.specimen_size_m"]),
    "porosity_above_one": (_grid(np.full((20, 20, 20), 1.5)), ValueError,
                           ["(0, 1)", "imaging.calibration.porosity_bounds"]),
    "grid_without_finite_value": (_grid(np.full((20, 20, 20), np.nan)), ValueError,
                                  ["no finite value", "imaging.mask"]),
    "grid_without_porosity_variable": (_grid(np.full((20, 20, 20), 0.3), variable="phi"),
                                       OutputError, ["missing variable", "porosity"]),
    "grid_file_missing": ("missing", OutputError, ["no such file"]),
    "grid_file_is_a_folder": ("folder", OutputError, ["is a folder"]),
    "grid_file_not_netcdf": ("garbage", OutputError, ["not a readable netCDF"]),
    # a grid of 0.5 mm blocks written with coordinates in mm read as m: the 4 mm cube
    # would sit inside one block (a near-uniform specimen, accepted before)
    "grid_in_millimetres": (_grid(np.full((20, 20, 20), 0.3), spacing=0.5), InputError,
                            ["spacing along", "exceeds half the 4 mm cube", "in metres"]),
}


def _grid_file(tmp: Path, grid: xr.Dataset | str) -> Path:
    path = tmp / "grids" / "pellet.nc"
    path.parent.mkdir()
    if isinstance(grid, xr.Dataset):
        write_dataset(grid, path, stage="imaging", title="porosity grid")
    elif grid == "folder":
        path.mkdir()
    elif grid == "garbage":
        path.write_text("not netCDF")
    return path


@pytest.mark.parametrize("case", sorted(GRIDS))
def test_a_bad_porosity_grid_is_refused_naming_the_file_and_key(case, tmp_path):
    grid, kind, words = GRIDS[case]
    path = _grid_file(tmp_path, grid)
    results = tmp_path / "results" / "micro"
    with pytest.raises(kind) as err:
        micro_run.run(MICRO, "heterogeneous", path, micro_run.CaseOutputs(results / "heterogeneous.nc",
                      results / "heterogeneous.png"))
    message = str(err.value)
    assert str(path) in message
    for word in words:
        assert word in message
    assert not _files(tmp_path / "results")


def test_a_grid_spanning_exactly_the_cube_is_accepted():
    """7 mm cube, 8 nodes 1 mm apart: the shift to the centre rounds, and must not refuse."""
    from micro.pellet import centred_grid

    for n, spacing in [(8, 1e-3), (11, 7e-4), (36, 2e-4)]:
        grid = _grid(np.full((n, n, n), 0.3), spacing)["porosity"]
        assert centred_grid(grid, (n - 1) * spacing).shape == (n, n, n)


def test_an_unknown_case_is_refused_naming_the_key(tmp_path):
    path = _grid_file(tmp_path, _grid(np.full((20, 20, 20), 0.3)))
    with pytest.raises(ConfigError, match=r"micro\.cases\.nowhere"):
        micro_run.run(MICRO, "nowhere", path, micro_run.CaseOutputs(tmp_path / "results/micro/nowhere.nc",
                      tmp_path / "results/micro/nowhere.png"))
    assert not _files(tmp_path / "results")


@pytest.mark.parametrize("damage", ["garbage", "cut", "empty", "older", "random-bytes"])
def test_a_damaged_checkpoint_file_is_set_aside_and_the_case_starts_afresh(damage, tmp_path, caplog):
    """A checkpoint file that cannot be read, was written without a header (an older
    version, or not by us), or has 1 KB of random bytes in one array under an intact zip
    is not resumed: it is moved aside unchanged with one log line naming it and the
    reason, and the case starts from the beginning (None)."""
    from micro.checkpoint import load_checkpoint, save_checkpoint
    from micro.hydration import FlowSystem
    from micro.pellet import SpecimenSpec, initial_state
    from tests._defaults import CLAY, DEM

    state_file = tmp_path / "heterogeneous.checkpoint.npz"
    content = {"garbage": b"PK\x03\x04 not a zip archive", "empty": b""}.get(damage)
    reason = "does not match its checksum" if damage == "random-bytes" else (
        "no header" if damage == "older" else "unreadable")
    if damage in ("cut", "older", "random-bytes"):
        state = initial_state(SpecimenSpec(edge_length=4e-3, n_points=125, seed=3), None, None, CLAY, DEM)
        save_checkpoint(Checkpointer(state_file, "abc"), state, FlowSystem.for_mesh(state.mesh), [], 1.0)
        content = state_file.read_bytes()[:300] if damage == "cut" else None
        if content is None:
            with np.load(state_file) as data:
                members = {k: data[k] for k in data.files if damage != "older" or k != "header"}
            spoilt = members["dem_positions"].view(np.uint8).reshape(-1).copy()
            spoilt[:1024] = np.random.default_rng(1).integers(0, 256, 1024, dtype=np.uint8)
            members["dem_positions"] = spoilt.view(np.float64).reshape(members["dem_positions"].shape)
            np.savez(state_file, **members)
            content = state_file.read_bytes()
    state_file.write_bytes(content)
    with caplog.at_level("WARNING", logger="micro.checkpoint"):
        checkpointer = Checkpointer(state_file, "abc", log=logging.getLogger("micro.checkpoint"))
        assert load_checkpoint(checkpointer, CLAY) is None
    aside = tmp_path / "heterogeneous.checkpoint.npz.rejected"
    assert not state_file.exists() and aside.read_bytes() == content
    [line] = [r.getMessage() for r in caplog.records]
    assert str(state_file) in line and reason in line and "\n" not in line


def test_a_divergence_names_the_case_and_leaves_no_result(tmp_path, monkeypatch):
    path = _grid_file(tmp_path, _grid(np.full((20, 20, 20), 0.3)))

    def diverge(*args: Any, **kwargs: Any) -> None:
        raise DivergenceError("pressure became non-finite")

    monkeypatch.setattr(micro_case, "advance_to_balance", diverge)
    results = tmp_path / "results" / "micro"
    with pytest.raises(DivergenceError, match="case heterogeneous, checkpoint 0"):
        micro_run.run(MICRO, "heterogeneous", path, micro_run.CaseOutputs(results / "heterogeneous.nc",
                      results / "heterogeneous.png"))
    assert not _files(tmp_path / "results")


# ------------------------------------------------------------------ macro tables


def _macro_table(tmp: Path, suction: np.ndarray) -> Path:
    """The macro tests' synthetic table with its suction coordinate replaced [Pa]."""
    from tests._macro_cases import synthetic_table

    table = synthetic_table()
    table = table.assign_coords(suction=("suction", suction, table["suction"].attrs))
    return Path(write_dataset(table, tmp / "table.nc", stage="upscaling", title="table"))


def _macro_config():
    from tests._macro_cases import small_config

    config = small_config()
    config["macro"]["numerics"].update(max_steps=3, stop_tolerance=0.0)
    return config


def test_a_table_in_mpa_is_refused_naming_it_and_both_ranges(tmp_path):
    """The case spans 1 to 132 MPa; a table whose suctions were written in MPa (0.1 to 200)
    misses it by six decades: refused before anything runs, not clamped at every look-up."""
    from macro import run as macro_run
    from tests._macro_cases import SUCTION

    table = _macro_table(tmp_path, SUCTION / 1e6)
    with pytest.raises(InputError, match=r"table\.nc: its suctions \[0\.1, 200\] Pa miss the case's "
                                         r"range \[1e\+06, 1\.32e\+08\] Pa \(macro\.boundary_suction_pa"):
        macro_run.run(_macro_config(), "small", table, macro_run.CaseOutputs(tmp_path / "out.nc"))
    assert not (tmp_path / "out.nc").exists()


def test_a_table_missing_less_than_a_decade_is_clamped_and_the_count_logged(tmp_path, caplog):
    from macro import run as macro_run

    table = _macro_table(tmp_path, np.geomspace(5e6, 1.0e8, 12))
    with caplog.at_level(logging.WARNING, logger="claychain.macro"):
        ds = macro_run.run(_macro_config(), "small", table, macro_run.CaseOutputs(tmp_path / "out.nc"))
    clamped, looked_up = ds.attrs["table_clamped_lookups"], ds.attrs["table_lookups"]
    assert 0 < clamped <= looked_up
    [line] = [r.getMessage() for r in caplog.records if "clamped" in r.getMessage()]
    assert f"{clamped} of {looked_up} table look-ups" in line and "[5e+06, 1e+08] Pa" in line


# ------------------------------------------------------------------------- configs


def _set(key: str, value: Any) -> Callable[[dict], None]:
    def edit(config: dict) -> None:
        *sections, name = key.split(".")
        node = config
        for section in sections:
            node = node[section]
        node[name] = value
    return edit


CONFIGS = {
    # (edit of the default config, key the message must name)
    "voxel_size_zero": (_set("samples.pellet.voxel_size_m", 0.0), "samples.pellet.voxel_size_m"),
    "voxel_size_text": (_set("samples.pellet.voxel_size_m", "big"),
                        "samples.pellet.voxel_size_m"),
    "unknown_source": (_set("samples.pellet.source", "jpeg"), "samples.pellet.source"),
    "scan_without_path": (_set("samples.scan", {"source": "tiff", "voxel_size_m": 1e-5}),
                          "samples.scan.path"),
    "unknown_imaging_key": (_set("imaging.colour", "red"), "imaging.colour"),
    "rev_positions_not_integer": (_set("imaging.rev.n_positions", 1.5),
                                  "imaging.rev.n_positions"),
    "porosity_bounds_three_values": (_set("imaging.calibration.porosity_bounds", [0, 0.5, 1]),
                                     "imaging.calibration.porosity_bounds"),
    "micro_sample_unknown": (_set("micro.sample", "nowhere"), "micro.sample"),
    "micro_case_sample_unknown": (_set("micro.cases.heterogeneous.sample", "nowhere"),
                                  "micro.cases.heterogeneous.sample"),
    "checkpoints_increasing": (_set("micro.checkpoints_suction_pa", [1e6, 1e7]),
                               "micro.checkpoints_suction_pa"),
    "case_material_unknown_key": (
        _set("micro.cases.heterogeneous.materials", {"colour": 1.0}),
        "micro.cases.heterogeneous.materials.colour"),
    "case_material_negative": (
        _set("micro.cases.heterogeneous.materials", {"bond_tensile_strength_pa": -1.0}),
        "micro.cases.heterogeneous.materials.bond_tensile_strength_pa"),
    "study_of_an_unknown_case": (_set("micro.studies.convergence", ["nope"]),
                                 "micro.studies.convergence"),
    "upscaling_unknown_case": (_set("upscaling.conditions.confined", ["confined", "nowhere"]),
                               "upscaling.conditions.confined"),
    "upscaling_range_reversed": (_set("upscaling.suction_range_pa", [1e8, 1e6]),
                                 "upscaling.suction_range_pa"),
    "packing_without_particles": (_set("packings", {"flat": {"n_particles": 0}}),
                                  "packings.flat.n_particles"),
    "cylinder_mask_without_radius": (_set("imaging.mask.mode", "cylinder"),
                                     "imaging.mask.cylinder_radius_m"),
    "histogram_peaks_without_densities": (_set("imaging.calibration.anchors", "histogram_peaks"),
                                          "imaging.calibration.peak_densities_kg_m3"),
    "histogram_peaks_and_a_grey_anchor": (
        _set("imaging.calibration", {"anchors": "histogram_peaks", "grey_air": 10.0,
                                     "peak_densities_kg_m3": [1.13, 2000.0]}),
        "imaging.calibration.grey_air"),
    "sample_imaging_unknown_key": (_set("samples.pellet.imaging", {"mask": {"colour": 1}}),
                                   "samples.pellet.imaging.mask.colour"),
    "sample_imaging_bad_value": (_set("samples.pellet.imaging", {"grid_spacing_m": -1.0}),
                                 "samples.pellet.imaging.grid_spacing_m"),
    "sample_cylinder_without_radius": (_set("samples.pellet.imaging",
                                            {"mask": {"mode": "cylinder"}}),
                                       "samples.pellet.imaging.mask.cylinder_radius_m"),
    "nan_value": (_set("materials.pellet.swelling_beta_per_pa", float("nan")),
                  "'materials.pellet.swelling_beta_per_pa': nan is not a finite number"),
    "infinite_value": (_set("micro.specimen_size_m", float("inf")),
                       "'micro.specimen_size_m': inf is not a finite number"),
    "negative_infinity_in_an_array": (_set("upscaling.suction_range_pa", [float("-inf"), 1e8]),
                                      "'upscaling.suction_range_pa.0': -inf is not a finite number"),
    "voxel_size_in_mm_typed_as_m": (_set("samples.pellet.voxel_size_m", 0.3),
                                    "'samples.pellet.voxel_size_m': 0.3 m is outside the plausible"),
    "voxel_size_in_um_typed_as_m": (_set("samples.pellet.voxel_size_m", 3e-8),
                                    "'samples.pellet.voxel_size_m': 3e-08 m is outside"),
    "grid_spacing_in_mm_typed_as_m": (_set("imaging.grid_spacing_m", 0.5), "'imaging.grid_spacing_m'"),
    "sample_grid_spacing_in_mm": (_set("samples.pellet.imaging", {"grid_spacing_m": 0.5}),
                                  "'samples.pellet.imaging.grid_spacing_m'"),
}


def test_a_real_voxel_size_outside_the_plausible_range_is_accepted_once_the_range_is_widened():
    config = copy.deepcopy(CONFIG)
    _set("samples.pellet.voxel_size_m", 0.02)(config)
    with pytest.raises(ConfigError, match="widen plausible_length_m"):
        validate_config(copy.deepcopy(config))
    config["plausible_length_m"] = [1e-7, 0.05]
    assert validate_config(config)["samples"]["pellet"]["voxel_size_m"] == 0.02


def test_a_swelling_strain_below_minus_one_names_the_swelling_keys():
    from shared.swelling import swollen_radius

    for strain in (np.array([0.1, -1.5]), np.array([np.nan])):
        with pytest.raises(ConfigError, match=r"got (-1\.5|nan).*materials\.pellet\.swelling_beta_per_pa"):
            swollen_radius(np.ones(strain.size), strain)


@pytest.mark.parametrize("case", sorted(CONFIGS))
def test_a_bad_config_is_refused_naming_the_key(case):
    edit, key = CONFIGS[case]
    config = copy.deepcopy(CONFIG)
    edit(config)
    with pytest.raises(ConfigError) as err:
        validate_config(config, checks=[check_packings, check_studies])
    assert key in str(err.value)


@pytest.mark.parametrize("content, words", [
    ("absent", "no such configuration file"),
    ("- a list\n- not a mapping\n", "not a YAML list"),
    ("", "is empty"),
    ("micro: {n_points: 64\n", "not valid YAML: line 2, column 1"),
    ("micro:\n  n_points: 64\nmacro: {}\nmicro: {}\n", "key 'micro' is given twice, on lines 1 and 4"),
    ("\x89PNG\r\n\x1a\n", "config.yaml: not"),
])
def test_a_bad_config_file_is_refused_naming_it(content, words, tmp_path):
    path = tmp_path / "config.yaml"
    if content != "absent":
        path.write_bytes(content.encode("latin-1"))
    with pytest.raises(ConfigError, match="config.yaml") as err:
        load_config(path)
    assert words in str(err.value) and "\n" not in str(err.value)


# ------------------------------------------------------- one line, not a traceback


def _logging_module():
    spec = importlib.util.spec_from_file_location("_claychain_logging", SCRIPTS / "_logging.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


RAISES = {
    # (statement raising the error, words of the one line; None: unexpected, traceback kept)
    "image_error": ("from imaging.ct.io import read_tiff_stack; read_tiff_stack('/nowhere.tif')",
                    "/nowhere.tif: no such file"),
    "config_error": ("from shared.config import load_config; load_config('/nowhere.yaml')",
                     "/nowhere.yaml"),
    "output_error": ("from shared.io import read_dataset; read_dataset('/nowhere.nc')",
                     "/nowhere.nc"),
    "divergence": ("from micro.hydration import DivergenceError; "
                   "raise DivergenceError('case a, checkpoint 3: non-finite pressure')",
                   "case a, checkpoint 3"),
    "our_value_error": ("from imaging.ct.grid import block_size_voxels; block_size_voxels(-1, 1)",
                        "must be > 0"),
    "read_only_results": ("raise PermissionError(13, 'Permission denied', 'results/p.nc')",
                          "cannot write results/p.nc: Permission denied"),
    "full_disk": ("import errno, os; raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "
                  "'results/p.nc')", "cannot write results/p.nc: No space left"),
    "read_only_file_system": ("import errno, os; raise OSError(errno.EROFS, "
                              "os.strerror(errno.EROFS), 'results/p.nc')", "read-only"),
    "full_disk_in_the_netcdf_library": (
        "from shared.io import atomic_write; atomic_write('results/p.nc', lambda tmp: "
        "(_ for _ in ()).throw(RuntimeError('NetCDF: HDF error')))",
        "cannot write results/p.nc: NetCDF: HDF error"),
    "read_only_results_during_an_atomic_write": (
        "from shared.io import atomic_write; atomic_write('results/p.nc', lambda tmp: "
        "(_ for _ in ()).throw(PermissionError(13, 'Permission denied', tmp)))",
        "cannot write results/p.nc: Permission denied"),
    "ctrl_c": ("raise KeyboardInterrupt", "interrupted (Ctrl-C); run the same command again to resume"),
    "a_bug": ("import numpy; numpy.zeros(3).reshape(5)", None),
    "a_value_error_of_ours_is_a_bug": ("import logging; from shared.progress import ConvergenceProgress; "
                                       "ConvergenceProgress(0.0, 'x', logging.getLogger())", None),
    "a_numpy_value_error_on_our_line": (
        "import types; exec(compile('import numpy; numpy.asarray([numpy.zeros(6), numpy.zeros(5)])', "
        "'macro/_probe.py', 'exec'), vars(types.ModuleType('macro._probe')))", None),
}


@pytest.mark.parametrize("case", sorted(RAISES))
def test_an_expected_failure_prints_one_line_and_logs_the_traceback(case, tmp_path):
    statement, words = RAISES[case]
    log = tmp_path / "job.log"
    script = tmp_path / "job.py"
    script.write_text(textwrap.dedent(f"""\
        import sys
        sys.path.insert(0, {str(SCRIPTS)!r})
        import _logging
        _logging.setup({str(log)!r})
        {statement}
        """))
    result = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                            timeout=120, cwd=tmp_path, env=ENV)
    # Python ends on an uncaught KeyboardInterrupt by SIGINT, as a shell expects of Ctrl-C
    assert result.returncode == (-signal.SIGINT if case == "ctrl_c" else 1)
    assert "Traceback" in log.read_text()
    if words is None:
        assert "Traceback" in result.stderr and "claychain:" not in result.stderr
        return
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("claychain: ") and words in lines[0]


def _subclasses(cls: type) -> list[type]:
    return [cls] + [c for sub in cls.__subclasses__() for c in _subclasses(sub)]


def test_failures_are_told_apart_by_type_alone():
    """Every ClaychainError, one of a new kind (defined here) too, is one line; a
    ValueError or RuntimeError is a bug wherever it was raised, even by a raise statement
    of ours (no bytecode or frame is read)."""
    from shared.errors import ClaychainError

    class NewKindOfUserError(ClaychainError):
        pass

    expected = _logging_module().expected_message
    kinds = _subclasses(ClaychainError)
    assert {"ConfigError", "InputError", "OutputError", "ImageError", "SnapshotError",
            "DivergenceError", "NewtonError", "SolverError", "NewKindOfUserError"} <= {k.__name__ for k in kinds}
    for kind in kinds:
        assert expected(kind("macro.x = -1:\n must be > 0")) == "macro.x = -1: must be > 0", kind
    for kind in (ValueError, RuntimeError, KeyError, TypeError):
        try:
            exec(compile("raise kind('macro.x = -1: must be > 0')", "macro/_probe.py", "exec"),
                 {"__name__": "macro._probe", "kind": kind})
        except kind as error:
            assert expected(error) is None, kind


def test_an_unwritable_log_is_one_line(tmp_path):
    (tmp_path / "logs").write_text("a file where the log folder should be")
    script = tmp_path / "job.py"
    script.write_text(f"import sys; sys.path.insert(0, {str(SCRIPTS)!r}); import _logging; "
                      f"_logging.setup({str(tmp_path / 'logs' / 'job.log')!r})\n")
    result = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                            timeout=120, env=ENV)
    assert result.returncode == 1
    assert result.stderr.strip().splitlines() == [result.stderr.strip()]
    assert "logs/job.log" in result.stderr and "Traceback" not in result.stderr


@pytest.mark.parametrize("code", [errno.EACCES, errno.ENOSPC, errno.EROFS, errno.EDQUOT])
def test_a_write_failure_of_the_porosity_grid_is_named(code, volume, tmp_path, monkeypatch):
    """The results folder read-only or full: the error carries the file's name, no temporary
    file stays behind, and the excepthook makes it one line."""
    scan = write_tiff_stack(volume, tmp_path / "scan.tif")

    def refuse(*args: Any, **kwargs: Any) -> None:
        raise OSError(code, "simulated", str(tmp_path / "results/images/scan.nc"))

    monkeypatch.setattr("shared.io.tempfile.mkstemp", refuse)
    with pytest.raises(OutputError) as err:
        _porosity(tmp_path, "tiff", scan)
    line = _logging_module().expected_message(err.value)
    assert line is not None and "results/images/scan.nc" in line
    assert not _files(tmp_path / "results")


# --------------------------------------------------------- through snakemake itself

TINY = {
    "samples": {"pellet": {"source": "phantom", "voxel_size_m": VOXEL}},
    "phantom": {"shape": [32, 32, 32], "seed": 1},
    "micro": {"specimen_size_m": 4.0e-3, "n_points": 64,
              "checkpoints_suction_pa": [132.0e6, 60.0e6],
              "cases": {"het": {"porosity": "ct"}}, "vtk_snapshots": False},
    "upscaling": {"conditions": {"free": "het", "confined": "het"},
                  "suction_range_pa": [60.0e6, 132.0e6]},
}


def _failing_run(work: Path, config: dict, *targets: str) -> subprocess.CompletedProcess:
    """Snakemake on ``config`` in ``work`` (the workflow copied there), which must fail."""
    return snakemake(workdir(work, config), *targets, ok=False)


def _outputs(workdir: Path, folders: tuple[str, ...]) -> list[Path]:
    return [p for folder in folders for p in _files(workdir / "results" / folder)]


def _cut_tiff(tmp: Path) -> Path:
    scan = write_tiff_stack(_phantom_volume(), tmp / "cut.tif")
    data = scan.read_bytes()
    scan.write_bytes(data[: int(len(data) * 10.5 / 32)])
    return scan


def _scan_folder(tmp: Path) -> Path:
    (tmp / "scan.tif").mkdir()
    return tmp / "scan.tif"


def _scan(config: dict, work: Path) -> None:
    """The sample as a TIFF scan of the phantom written here (no phantom job to run first)."""
    scan = write_tiff_stack(_phantom_volume(), work / "scan" / "pellet.tif")
    config["samples"]["pellet"] = {"source": "tiff", "path": str(scan), "voxel_size_m": VOXEL}


def _gridded_scan(config: dict, work: Path) -> None:
    """The TIFF scan and, newer than it, its porosity grid already made (by the rule's entry
    point, the products of a finished ``imaging_porosity`` job): Snakemake runs the micro
    case alone."""
    _scan(config, work)
    entry = config["samples"]["pellet"]
    micro = (TINY["micro"]["specimen_size_m"], TINY["micro"]["n_points"])
    results = work / "results"
    _ct_porosity("pellet", entry, CONFIG["imaging"], micro, entry["path"], results, "pellet")


WORKFLOWS = {
    # (config edit given the workflow's folder, target, words of the claychain line, output
    #  folders that must stay empty); the failing job is the target's, its upstream jobs
    #  are not run when the real code lets the inputs be made without them
    "truncated_tiff": (
        lambda c, tmp: c["samples"].update(
            pellet={"source": "tiff", "path": str(_cut_tiff(tmp)), "voxel_size_m": VOXEL}),
        "results/porosity/pellet.nc", ["cut.tif", "truncated"], ("images", "porosity")),
    "scan_path_is_a_folder": (
        lambda c, tmp: c["samples"].update(
            pellet={"source": "tiff", "path": str(_scan_folder(tmp)), "voxel_size_m": VOXEL}),
        "results/porosity/pellet.nc", ["scan.tif", "is a folder"], ("images", "porosity")),
    "every_block_clamped": (
        lambda c, tmp: (_scan(c, tmp), c.setdefault("imaging", {}).update(
            calibration={"porosity_bounds": [0.9, 0.95]})),
        "results/porosity/pellet.nc", ["imaging.calibration.porosity_bounds", "pellet.tif"],
        ("images", "porosity")),
    # a 7 mm cube fits the 9.6 mm scan (the check when the config loads, shared.scan_sizes)
    # but its corners reach outside the pellet of radius 4.4 mm: the micro job refuses it
    "cube_larger_than_the_specimen": (
        lambda c, tmp: (_gridded_scan(c, tmp), c["micro"].update(specimen_size_m=7.0e-3)),
        "results/micro/het.nc", ["results/porosity/pellet.nc", "micro.specimen_size_m"],
        ("micro",)),
}


@pytest.mark.parametrize("case", sorted(WORKFLOWS))
def test_snakemake_reports_a_bad_input_in_one_line(case, tmp_path):
    edit, target, words, folders = WORKFLOWS[case]
    config = copy.deepcopy(TINY)
    work = tmp_path / "wf"
    work.mkdir()
    edit(config, work)
    result = _failing_run(work, config, target)
    ours = [line for line in result.stderr.splitlines() if line.startswith("claychain: ")]
    assert len(ours) == 1, result.stderr[-3000:]
    for word in words:
        assert word in ours[0]
    assert "Traceback" not in result.stderr
    assert not _outputs(work, folders)
    logs = "".join(p.read_text() for p in (work / "results/logs").rglob("*.log"))
    assert "Traceback" in logs


def test_snakemake_refuses_an_undefined_case_as_target(tmp_path):
    """Documented in docs/howto-inspect-outputs.md: a target naming no configured case has no rule."""
    result = _failing_run(tmp_path, copy.deepcopy(TINY), "results/micro/nowhere.nc")
    assert "results/micro/nowhere.nc" in result.stderr
    assert not _files(tmp_path / "results")


def test_a_coarse_grid_is_warned_with_the_spacing_to_set(volume, tmp_path, caplog):
    """9.6 mm of scan in 2 mm blocks: 5 blocks per axis, under 8; the warning names
    imaging.grid_spacing_m and the spacing that gives 8 blocks, 9.6 mm / 8 = 1.2 mm."""
    scan = write_tiff_stack(volume, tmp_path / "scan.tif")
    with caplog.at_level(logging.WARNING, logger="imaging.ct"):
        ds = _porosity(tmp_path, "tiff", scan, imaging=_imaging(grid_spacing_m=2.0e-3))
    assert ds.sizes["z"] == 5
    assert "imaging.grid_spacing_m" in ds.attrs["warnings"]
    assert "0.0012 m" in ds.attrs["warnings"]
    assert any("grid_spacing_m" in r.getMessage() for r in caplog.records)


def test_snakemake_refuses_a_hand_edited_table_export_at_start(tmp_path):
    """The table and its CSV export as the upscaling stage leaves them, then one value of
    the export multiplied by 1000: a dry run stops at once with one line naming the CSV and
    macro.table_path (before: "Nothing to be done", the edit ignored)."""
    import hashlib

    from shared.table_export import CSV_EXPORT_ATTRIBUTE
    from tests._macro_cases import synthetic_table

    work = workdir(tmp_path, copy.deepcopy(TINY))
    export = b"condition,suction_pa,phase,axis,k_m2\nfree,100000,water,x,1e-19\n"
    table = synthetic_table()
    table.attrs[CSV_EXPORT_ATTRIBUTE] = hashlib.sha256(export).hexdigest()
    folder = work / "results" / "upscaling"
    write_dataset(table, folder / "pellet_permeability.nc", stage="upscaling", title="table")
    (folder / "pellet_permeability.csv").write_bytes(export)
    snakemake(work, "-n")
    (folder / "pellet_permeability.csv").write_bytes(export.replace(b"1e-19", b"1e-16"))
    result = snakemake(work, "-n", ok=False)
    ours = [line for line in result.stderr.splitlines() if line.startswith("claychain: ")]
    assert len(ours) == 1 and "Traceback" not in result.stderr, result.stderr[-3000:]
    assert "pellet_permeability.csv: edited since the upscaling stage wrote it" in ours[0]
    assert "macro.table_path" in ours[0]
