"""macro.vtk: the ParaView collection's time steps are in days, and a resumed run reads them back."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from types import SimpleNamespace

import meshio
import numpy as np
import pytest

from macro import vtk


def _tiny(model: object) -> meshio.Mesh:
    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    return meshio.Mesh(points, [("tetra", np.array([[0, 1, 2, 3]]))])


def test_collection_times_are_days(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(vtk, "snapshot_mesh", _tiny)
    series = vtk.SnapshotSeries(tmp_path, "case", 3, 10 * 86400.0, resumed=False)
    for step, seconds in ((1, 3600.0), (2, 86400.0), (3, 10 * 86400.0)):
        series.write(SimpleNamespace(steps=step, time=seconds))
    root = ET.parse(tmp_path / "case.pvd").getroot()
    days = [float(d.get("timestep")) for d in root.iter("DataSet")]
    np.testing.assert_allclose(days, [1 / 24, 1.0, 10.0])
    resumed = vtk.SnapshotSeries(tmp_path, "case", 3, 10 * 86400.0, resumed=True)
    np.testing.assert_allclose([t for t, _ in resumed.entries], [3600.0, 86400.0, 864000.0])
