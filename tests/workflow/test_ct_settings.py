"""The CT rules' imaging settings: the keys the entry points read are those of the one
list (imaging/ct_keys.py) that the rules take their params from."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest

from imaging.ct import run as ct_run
from imaging.ct.io import write_tiff_stack
from imaging.ct.phantom import pellet_phantom
from imaging.ct_keys import POROSITY_KEYS, RESOURCE_KEYS, REV_KEYS
from shared.config import default_config

CONFIG = default_config()
VOXEL = 3e-4


class _Recording(dict):
    """A settings mapping that records the keys read from it (a copy for the provenance,
    ``dict(settings)``, reads none)."""

    def __init__(self, *args: Any) -> None:
        super().__init__(*args)
        self.read: set[str] = set()

    def __getitem__(self, key: str) -> Any:
        self.read.add(key)
        return super().__getitem__(key)

    def get(self, key: str, default: Any = None) -> Any:
        self.read.add(key)
        return super().get(key, default)


def test_the_entry_points_read_the_listed_keys(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """run.porosity reads the porosity keys and the resources, run.rev the REV keys and the
    resources, and neither reads any other imaging key: the rules' params lack nothing."""
    monkeypatch.setattr("imaging.ct.run.figures.porosity_figure", lambda *args: None)
    monkeypatch.setattr("imaging.ct.run.figures.rev_figure", lambda *args: None)
    spec = ct_run.phantom_spec(dict(CONFIG["phantom"], shape=[24, 24, 24], seed=3),
                               CONFIG["imaging"]["calibration"], VOXEL)
    scan = write_tiff_stack(pellet_phantom(spec)[0], tmp_path / "p.tif")
    imaging = copy.deepcopy(CONFIG["imaging"])
    imaging["rev"].update(n_positions=8, n_sizes=3)
    entry = {"source": "tiff", "path": str(scan), "voxel_size_m": VOXEL}
    porosity = _Recording(imaging)
    ct_run.porosity("p", entry, porosity, CONFIG["materials"]["pellet"], (4e-3, 64), scan,
                    tmp_path / "image.nc", tmp_path / "porosity.nc", tmp_path / "porosity.png")
    rev = _Recording(imaging)
    ct_run.rev("p", entry, rev, scan, tmp_path / "image.nc", tmp_path / "porosity.nc",
               tmp_path / "rev.nc", tmp_path / "rev.png")
    assert porosity.read == {*POROSITY_KEYS, *RESOURCE_KEYS}
    assert rev.read == {*REV_KEYS, *RESOURCE_KEYS}
    # every imaging key is read by one of them (the schema's section has no dead key)
    assert set(imaging) == {*POROSITY_KEYS, *REV_KEYS, *RESOURCE_KEYS}
