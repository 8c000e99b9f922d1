"""shared.vtk: a ParaView collection lists its snapshots in order, times as given."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from shared.vtk import write_collection


def test_the_collection_lists_each_snapshot_with_its_time(tmp_path: Path) -> None:
    entries = [(0.0, "run_0000.vtu"), (1.0 / 24.0, "run_0001.vtu"), (12.5, "snapshots/run_0002.vtu")]
    path = write_collection(tmp_path / "run.pvd", entries)
    assert path == tmp_path / "run.pvd"
    root = ET.parse(path).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    datasets = root.findall("./Collection/DataSet")
    assert [(float(d.get("timestep")), d.get("file")) for d in datasets] == entries
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.pvd"]  # no temporary left
    write_collection(path, entries[:1])  # rewritten whole
    assert len(ET.parse(path).getroot().findall("./Collection/DataSet")) == 1
