"""ParaView collections: a ``.pvd`` file listing the ``.vtu`` snapshots of a run.

meshio writes single snapshots but no collections; a collection is a few lines of XML
that ParaView opens as one time-dependent data set. Written atomically.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

from shared.io import atomic_write

__all__ = ["write_collection"]


def write_collection(path: str | Path, entries: Sequence[tuple[float, str]]) -> Path:
    """Write a ParaView ``.pvd`` collection of snapshots, atomically.

    Parameters
    ----------
    path
        Output ``.pvd`` file.
    entries
        (time step, file name relative to the ``.pvd``'s directory) of each snapshot,
        in increasing time step.

    Returns
    -------
    Path
        ``path``.
    """
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    collection = ET.SubElement(root, "Collection")
    for timestep, name in entries:
        ET.SubElement(collection, "DataSet", timestep=repr(float(timestep)), group="",
                      part="0", file=str(name))
    ET.indent(root)
    tree = ET.ElementTree(root)
    return atomic_write(path, lambda tmp: tree.write(tmp, encoding="utf-8",
                                                     xml_declaration=True))
